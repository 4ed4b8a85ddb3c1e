//! The `[nodes.<name>.params]` schema of the fluid node (serde, `deny_unknown_fields`).
//! `setup.rs` turns it into a validated model; key paths in errors are relative to `params`.

use serde::Deserialize;
use std::collections::BTreeMap;

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// The grid (uniform cells; what its coordinates measure is `geometry`).
    pub grid: GridSpec,
    /// What the grid's coordinates measure: "cartesian" (default); "cylindrical" or
    /// "spherical" on a 1-D grid, x the distance from the axis or the centre (a cell is a
    /// shell; cylindrical sums are per metre of axis); "axisymmetric" on a 2-D grid, x the
    /// distance from the axis and y along it (a cell is a ring of the whole revolution).
    /// The radius starts at `grid.lower[0] ≥ 0`; at 0 the face `x_lower` is a symmetry
    /// (the default there) or a wall.
    #[serde(default)]
    pub geometry: Option<String>,
    /// Materials by name; each names its EOS.
    pub materials: BTreeMap<String, MaterialSpec>,
    /// Initial regions, applied in order (later ones overwrite earlier ones).
    pub regions: Vec<RegionSpec>,
    /// Boundary condition of each face of the grid (a face not given is an outflow).
    #[serde(default)]
    pub boundaries: BoundariesSpec,
    /// Courant number of the time step (0 < cfl ≤ 1).
    #[serde(default = "default_cfl")]
    pub cfl: f64,
    /// TVD limiter of the MUSCL reconstruction: "minmod", "van_leer" or "mc".
    #[serde(default = "default_limiter")]
    pub limiter: String,
    /// Points whose density, pressure and velocity are reported every window (as
    /// `NAME.pressure` …) and written to `probes.csv`.
    #[serde(default)]
    pub probes: Vec<ProbeSpec>,
    /// Lines along which a material's edges are tracked: reported every window as
    /// `NAME.first` and `NAME.last` (distance from the line's start, m; −1 when the material
    /// is not on the line) and their speeds `NAME.first_speed`, `NAME.last_speed` (m/s,
    /// positive away from the start), and written to `edges.csv`.
    #[serde(default)]
    pub edges: Vec<EdgeSpec>,
    /// Immersed-boundary responder interface (seed 002 §3).
    #[serde(default)]
    pub immersed: Option<ImmersedSpec>,
    /// Largest number of time steps per window before the node gives up (default 1e7).
    #[serde(default)]
    pub max_steps_per_window: Option<u64>,
    /// Where the step runs: "cpu" (default) or "gpu" (wgpu compute; single ideal gas, no
    /// immersed particles yet).
    #[serde(default)]
    pub device: Option<String>,
    /// Arithmetic of the GPU kernels: "f64" (default: f64 where the adapter has
    /// `SHADER_F64`, else f32 with a warning) or "f32" (faster on consumer GPUs, whose f64
    /// rate is a small fraction of f32; about 1e-6 relative accuracy, with a warning).
    #[serde(default)]
    pub precision: Option<String>,
}

fn default_cfl() -> f64 {
    0.5
}
fn default_limiter() -> String {
    "van_leer".into()
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Cells per direction; 1 in z gives a 2-D grid (one cell thick), 1 in y and z 1-D.
    pub cells: [i64; 3],
    /// Lower corner of the domain (m).
    pub lower: [f64; 3],
    /// Upper corner of the domain (m).
    pub upper: [f64; 3],
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// "ideal", "stiffened" or "jwl".
    pub eos: String,
    /// Ratio of specific heats γ (ideal, stiffened).
    pub gamma: Option<f64>,
    /// Stiffened gas p∞ (Pa), convention p = (γ-1)ρe - γ p∞.
    pub p_inf: Option<f64>,
    /// Specific gas constant (J/(kg K)) for temperatures.
    pub gas_constant: Option<f64>,
    /// JWL reference density ρ₀ of the explosive (kg/m³).
    pub rho0: Option<f64>,
    /// JWL coefficient A (Pa).
    pub a: Option<f64>,
    /// JWL coefficient B (Pa).
    pub b: Option<f64>,
    /// JWL exponent R₁ (1).
    pub r1: Option<f64>,
    /// JWL exponent R₂ (1).
    pub r2: Option<f64>,
    /// JWL Grüneisen coefficient ω (1).
    pub omega: Option<f64>,
    /// JWL detonation energy per unit initial volume e₀ (J/m³; TNT 7.0e9).
    pub e0: Option<f64>,
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// "all", "box", "sphere" (a circle on a 2-D grid) or "half_space".
    pub shape: String,
    /// Box: lower corner (m).
    pub lower: Option<[f64; 3]>,
    /// Box: upper corner (m).
    pub upper: Option<[f64; 3]>,
    /// Sphere: centre (m); also the centre of `radial_velocity`.
    pub center: Option<[f64; 3]>,
    /// Sphere: radius (m).
    pub radius: Option<f64>,
    /// Half space: the points x with (x - point)·normal ≥ 0.
    pub point: Option<[f64; 3]>,
    /// Half space: its normal (any length).
    pub normal: Option<[f64; 3]>,
    /// The material filling the region (a name of `materials`).
    pub material: String,
    /// Density (kg/m³); or give `temperature` (K) with the material's `gas_constant`.
    pub density: Option<f64>,
    /// Temperature (K), instead of `density`.
    pub temperature: Option<f64>,
    /// Pressure (Pa); or give `energy`.
    pub pressure: Option<f64>,
    /// Internal energy the region holds (J; per metre of axis in cylindrical geometry, and
    /// in the z-thickness of a 2-D Cartesian grid), instead of `pressure`: spread uniformly
    /// over the cells the region covers (after later regions overwrite theirs), so a blast
    /// of a given energy is deposited exactly whatever the resolution.
    pub energy: Option<f64>,
    /// Velocity (m/s).
    #[serde(default)]
    pub velocity: [f64; 3],
    /// Speed (m/s) away from `center` (negative: toward it), instead of `velocity`: radial
    /// in the grid's active directions (Cartesian; a sphere's radius in axisymmetric
    /// geometry, `center` on the axis); along x in cylindrical and spherical geometry,
    /// where `center` does not apply. Zero at the centre itself.
    pub radial_velocity: Option<f64>,
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BoundarySpec {
    /// "wall", "symmetry", "outflow", "non_reflecting", "periodic" or "inflow". A
    /// non-reflecting face lets waves leave and holds the far field: its `pressure` (default:
    /// the face's initial mean) and `velocity` (default 0); the impedance ρc is the face's
    /// initial mean.
    pub kind: String,
    /// Inflow: the material flowing in.
    pub material: Option<String>,
    /// Inflow: density (kg/m³).
    pub density: Option<f64>,
    /// Inflow: temperature (K), instead of density.
    pub temperature: Option<f64>,
    /// Inflow: pressure (Pa); non-reflecting: the far field's.
    pub pressure: Option<f64>,
    /// Inflow: velocity (m/s); non-reflecting: the far field's.
    pub velocity: Option<[f64; 3]>,
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum BoundaryEntry {
    Kind(String),
    Full(BoundarySpec),
}

#[derive(Debug, Clone, Default, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BoundariesSpec {
    /// Face x = lower.x: a kind ("wall", "outflow", …) or a table `{ kind = "inflow", … }`.
    pub x_lower: Option<BoundaryEntry>,
    /// Face x = upper.x (as `x_lower`).
    pub x_upper: Option<BoundaryEntry>,
    /// Face y = lower.y (as `x_lower`).
    pub y_lower: Option<BoundaryEntry>,
    /// Face y = upper.y (as `x_lower`).
    pub y_upper: Option<BoundaryEntry>,
    /// Face z = lower.z (as `x_lower`).
    pub z_lower: Option<BoundaryEntry>,
    /// Face z = upper.z (as `x_lower`).
    pub z_upper: Option<BoundaryEntry>,
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    /// The probe's name (its report scalars are `NAME.pressure`, `NAME.density`, …).
    pub name: String,
    /// Where it samples (m); the cell holding it.
    pub position: [f64; 3],
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EdgeSpec {
    /// The line's name (its report scalars are `NAME.first`, `NAME.last`, …).
    pub name: String,
    /// The material whose edges it finds (a name of `materials`): where its volume fraction
    /// first rises through 0.5 and last falls through it, going from `from` to `to`.
    pub material: String,
    /// Where the line starts (m); positions are distances along it from here.
    pub from: [f64; 3],
    /// Where the line ends (m).
    pub to: [f64; 3],
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ImmersedSpec {
    /// Interface name the solid side couples to (default "particles").
    #[serde(default = "default_interface")]
    pub interface: String,
    /// Number of particles, when known in advance (otherwise taken from the first inbox).
    pub particles: Option<usize>,
    /// How a cell the solid leaves is filled: "average" (default) gives it the mean state of
    /// its gas neighbours, booked as reclassification (external) mass, momentum and energy;
    /// "conservative" gives it back the gas the receding wall's flux carried into it (with
    /// its momentum and energy; the particles then take only the pressure's push), or, when
    /// less than 0.8 of its neighbours' mean mass was carried (a crack, a wall crossed in
    /// part), 1/(n+1) of its n gas neighbours' mass, momentum and energy taken from them:
    /// nothing is created (the average adds the gas's energy density
    /// times every volume a solid sweeps, much for a shell expanding through dense gas).
    /// Either way the gas of a cell the solid covers leaves the gas, booked. Not on the GPU.
    #[serde(default)]
    pub refill: Option<String>,
}

fn default_interface() -> String {
    "particles".into()
}
