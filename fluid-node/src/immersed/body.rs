//! The immersed body as the fluid sees it: the particles of a window, the class of every
//! cell (fluid, interface, solid), the wall faces between gas and solid and the totals a
//! restart needs. Data only; the coupling's kernels over the fluid model are in the parent
//! module.

pub const FLUID: u8 = 0;
pub const INTERFACE: u8 = 1;
pub const SOLID: u8 = 2;

#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct WallFace {
    pub d: usize,
    /// Flat index (row·mx + i) of the cell below the face along d (the flux slot).
    pub left: usize,
    pub right: usize,
    /// True when the gas (interface) cell is the left one.
    pub gas_left: bool,
}

/// Everything here is state a restart needs (serde: the checkpoint payload).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Immersed {
    pub interface: String,
    /// Number of particles (0 until known).
    pub n: usize,
    pub positions: Vec<[f64; 3]>,
    pub velocities: Vec<[f64; 3]>,
    pub volumes: Vec<f64>,
    /// Per-cell class, flat index row·mx + i.
    pub kind: Vec<u8>,
    pub prev_kind: Vec<u8>,
    /// Occupied cells (sorted flat indices), their class and velocity (eq. 31).
    pub cells: Vec<usize>,
    pub cell_kind: Vec<u8>,
    pub cell_vel: Vec<[f64; 3]>,
    /// CSR: particles of occupied cell c are parts[off[c]..off[c+1]].
    pub off: Vec<usize>,
    pub parts: Vec<usize>,
    pub cell_of: Vec<usize>,
    pub walls: Vec<WallFace>,
    /// Impulse given to each particle in the current window (N s).
    pub impulse: Vec<[f64; 3]>,
    /// Total impulse given to the particles since the start (N s).
    pub total_impulse: [f64; 3],
    /// Momentum created (+) or removed (-) by cells changing class since the start.
    pub reclass_momentum: [f64; 3],
    /// Gas mass created (+) by refilled cells and removed (-) by cells turning solid since
    /// the start (kg).
    pub reclass_mass: f64,
    /// Gas energy ρE V created (+) by refilled cells and removed (-) by cells turning solid
    /// since the start (J): the gas a solid covers leaves the gas's books (the first
    /// classification removes what the initial condition put where the solid is).
    pub reclass_energy: f64,
    /// Reclassification shares the gas among a cell and its neighbours instead of creating
    /// or removing it (`immersed.refill = "conservative"`).
    pub conservative: bool,
    /// Whether the cells have been classified once: the first classification removes what
    /// the initial condition put where the solid is, whatever `conservative` says.
    pub classified: bool,
    /// With `conservative`: per cell, the partial densities', momentum's and energy's
    /// content (per cell, not per volume) that the moving walls' fluxes have carried into the
    /// cell while it was solid, the energy without the wall's work p*·v (which went to the
    /// particles); handed back when the solid leaves the cell. Empty until a wall flux.
    pub held: Vec<f64>,
    /// Energy the walls' fluxes carried into solid cells since the start (J, booked out of
    /// the gas with `conservative`; handed back through `reclass_energy`).
    pub held_energy: f64,
    /// Momentum the walls' fluxes carried into solid cells since the start (kg m/s, booked
    /// out of the gas with `conservative`; handed back through `reclass_momentum`).
    pub held_momentum: [f64; 3],
    /// Gas mass that entered the gas (+) through the moving wall faces since the start (kg).
    pub wall_mass: f64,
    /// Fluxes of the wall faces in the current RK stage (nf per wall, in `walls` order).
    #[serde(skip)]
    pub wall_flux: Vec<f64>,
    /// Wall indices sorted by (direction, left cell): the walls of one line of faces, for the
    /// fused stage. Cleared by the classification, rebuilt by [`wall_fluxes`] when its
    /// length is not that of `walls` (also after a restart, which does not store it).
    #[serde(skip)]
    pub wall_order: Vec<usize>,
    /// Scratch of the classification's counting sort (one entry per cell).
    #[serde(skip)]
    pub(super) sort_scratch: Vec<usize>,
}

impl Immersed {
    pub fn new(interface: String, n: usize, cells: usize) -> Self {
        Immersed {
            interface,
            n,
            positions: Vec::new(),
            velocities: Vec::new(),
            volumes: Vec::new(),
            kind: vec![FLUID; cells],
            prev_kind: vec![FLUID; cells],
            cells: Vec::new(),
            cell_kind: Vec::new(),
            cell_vel: Vec::new(),
            off: Vec::new(),
            parts: Vec::new(),
            cell_of: Vec::new(),
            walls: Vec::new(),
            impulse: Vec::new(),
            total_impulse: [0.0; 3],
            reclass_momentum: [0.0; 3],
            reclass_mass: 0.0,
            reclass_energy: 0.0,
            conservative: false,
            classified: false,
            held: Vec::new(),
            held_energy: 0.0,
            held_momentum: [0.0; 3],
            wall_mass: 0.0,
            wall_flux: Vec::new(),
            wall_order: Vec::new(),
            sort_scratch: Vec::new(),
        }
    }

    /// Window-averaged force on each particle (impulse / window length), flat xyz.
    pub fn forces(&self, window_length: f64, out: &mut [f64]) {
        for (p, imp) in self.impulse.iter().enumerate() {
            for d in 0..3 {
                out[3 * p + d] = imp[d] / window_length;
            }
        }
    }
}
