//! The validated fluid model and its state buffers (structure of arrays in the row-blocked
//! layout of `grid.rs`). Built by `setup.rs`, advanced by `step.rs`, wrapped by `solver.rs`.
//!
//! Variables (NM materials): conserved `[α_kρ_k (NM), ρu, ρv, ρw, E, α_k (NM-1)]`,
//! primitive `[α_kρ_k (NM), u, v, w, p, α_k (NM-1)]` — the five-equation model of Allaire,
//! Clerc & Kokh (2002), the equilibrium limit of seed 002's six-equation model (eq. 9–15).

use crate::boundary::Boundary;
use crate::grid::Grid;
use crate::immersed::body::Immersed;
use crate::limiter::Limiter;
use crate::mixture::Phase;
use crate::simd::Simd;

/// A probe: a cell whose state is recorded every window.
#[derive(Debug, Clone)]
pub struct Probe {
    pub name: String,
    pub position: [f64; 3],
    /// Row and x index of its cell.
    pub row: usize,
    pub i: usize,
}

/// A line across the grid and the material whose edges it tracks (the data; `edges.rs`
/// builds it and measures along it).
#[derive(Debug, Clone)]
pub struct EdgeLine {
    pub name: String,
    /// Index of the material.
    pub material: usize,
    /// The cells the line crosses, in order from its start: (row, x index, distance of the
    /// cell centre's projection on the line from its start).
    pub cells: Vec<(usize, usize, f64)>,
    /// How far an edge must move from where it started before its speed is fitted: one cell.
    pub moved: f64,
}

#[derive(Debug, Clone)]
pub struct Fluid {
    pub grid: Grid,
    pub phases: Vec<Phase>,
    pub material_names: Vec<String>,
    pub limiter: Limiter,
    pub cfl: f64,
    pub bc: [[Boundary; 2]; 3],
    /// Number of variables (conserved = primitive): 2·NM + 3.
    pub nv: usize,
    pub cons: Vec<f64>,
    pub cons0: Vec<f64>,
    pub prim: Vec<f64>,
    /// The next RK stage's primitives, written by a fused stage as it updates each row (no
    /// immersed body), then swapped with `prim`.
    pub prim_next: Vec<f64>,
    /// Face fluxes per direction (nv + 1 entries: the last is the face velocity), indexed
    /// by the cell left of the face.
    pub flux: [Vec<f64>; 3],
    /// The fluxes through the two domain boundary x faces of every row, `[lower (nv + 1),
    /// upper (nv + 1)]` per row, read by the boundary impulse: the fused stages store these
    /// and no `flux[0]` (one contiguous line per row instead of 2·(nv + 1) scattered
    /// writes), the unfused ones copy them from `flux[0]`.
    pub x_bound: Vec<f64>,
    /// Per-row scratch for deterministic reductions.
    pub row_max: Vec<f64>,
    pub row_bad: Vec<Option<(usize, usize, f64)>>,
    pub time: f64,
    pub steps: u64,
    /// Impulse of the domain boundaries on the gas since the start (N s).
    pub boundary_impulse: [f64; 3],
    /// Work of the domain boundaries on the gas since the start (J): the energy carried in
    /// and out through inflow and outflow faces (walls and symmetry planes carry none).
    pub boundary_work: f64,
    pub probes: Vec<Probe>,
    /// Lines along which a material's edges are tracked.
    pub edges: Vec<EdgeLine>,
    pub immersed: Option<Immersed>,
    pub max_steps_per_window: u64,
    /// True once `prim` holds the primitives of `cons` (interior cells).
    pub prim_valid: bool,
    /// Widest instruction set the row kernels may use (`Simd::detect()` by default; every
    /// choice gives bit-identical results).
    pub simd: Simd,
    /// Run each RK stage's fluxes and update fused per block of rows (2-D and 3-D, with or
    /// without an immersed body; the default). `false` runs the unfused kernels, which give
    /// bit-identical results (the tests compare the two).
    pub fused: bool,
    /// Where the steps' time went since the model was built (not in checkpoints).
    pub timing: StepTiming,
}

/// Wall-clock time of the steps since the model was built, by kind of work (s), and the
/// cell-updates they made: what the node reports in every window (`time_*_s` scalars).
#[derive(Debug, Clone, Default)]
pub struct StepTiming {
    /// Whole steps (`step::step`).
    pub steps_s: f64,
    /// The fluid kernels: primitive recovery, wave rates, fluxes, stage updates, boundary
    /// fluxes.
    pub kernels_s: f64,
    /// Immersed work inside the steps: solid-cell fills, wall fluxes and the impulses they
    /// give, projections.
    pub immersed_s: f64,
    /// Ghost-cell fills.
    pub ghosts_s: f64,
    /// Immersed work once per window: classification of the cells, refills, forces.
    pub immersed_window_s: f64,
    /// Interior cells × steps.
    pub cell_updates: f64,
}

impl Fluid {
    pub fn nmat(&self) -> usize {
        self.phases.len()
    }
    /// Number of flux entries per face.
    pub fn nf(&self) -> usize {
        self.nv + 1
    }
    /// Index of the x-velocity (primitive) / x-momentum (conserved).
    pub fn vel0(&self) -> usize {
        self.nmat()
    }
    /// Index of the pressure (primitive) / total energy (conserved).
    pub fn ip(&self) -> usize {
        self.nmat() + 3
    }
}
