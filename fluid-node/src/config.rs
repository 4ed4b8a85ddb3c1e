//! The `[nodes.<name>.params]` schema of the fluid node (serde, `deny_unknown_fields`).
//! `setup.rs` turns it into a validated model; key paths in errors are relative to `params`.

use serde::Deserialize;
use std::collections::BTreeMap;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    pub grid: GridSpec,
    /// Materials by name; each names its EOS.
    pub materials: BTreeMap<String, MaterialSpec>,
    /// Initial regions, applied in order (later ones overwrite earlier ones).
    pub regions: Vec<RegionSpec>,
    #[serde(default)]
    pub boundaries: BoundariesSpec,
    /// Courant number of the time step (0 < cfl ≤ 1).
    #[serde(default = "default_cfl")]
    pub cfl: f64,
    /// TVD limiter of the MUSCL reconstruction: "minmod", "van_leer" or "mc".
    #[serde(default = "default_limiter")]
    pub limiter: String,
    #[serde(default)]
    pub probes: Vec<ProbeSpec>,
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

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Cells per direction; 1 in z gives a 2-D grid (one cell thick), 1 in y and z 1-D.
    pub cells: [i64; 3],
    pub lower: [f64; 3],
    pub upper: [f64; 3],
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// "ideal", "stiffened" or "jwl".
    pub eos: String,
    pub gamma: Option<f64>,
    /// Stiffened gas p∞ (Pa), convention p = (γ-1)ρe - γ p∞.
    pub p_inf: Option<f64>,
    /// Specific gas constant (J/(kg K)) for temperatures.
    pub gas_constant: Option<f64>,
    pub rho0: Option<f64>,
    pub a: Option<f64>,
    pub b: Option<f64>,
    pub r1: Option<f64>,
    pub r2: Option<f64>,
    pub omega: Option<f64>,
    pub e0: Option<f64>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// "all", "box", "sphere" (a circle on a 2-D grid) or "half_space".
    pub shape: String,
    pub lower: Option<[f64; 3]>,
    pub upper: Option<[f64; 3]>,
    pub center: Option<[f64; 3]>,
    pub radius: Option<f64>,
    /// Half space: the points x with (x - point)·normal ≥ 0.
    pub point: Option<[f64; 3]>,
    pub normal: Option<[f64; 3]>,
    pub material: String,
    pub density: Option<f64>,
    pub temperature: Option<f64>,
    pub pressure: f64,
    #[serde(default)]
    pub velocity: [f64; 3],
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundarySpec {
    /// "wall", "symmetry", "outflow", "periodic" or "inflow".
    pub kind: String,
    pub material: Option<String>,
    pub density: Option<f64>,
    pub temperature: Option<f64>,
    pub pressure: Option<f64>,
    pub velocity: Option<[f64; 3]>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum BoundaryEntry {
    Kind(String),
    Full(BoundarySpec),
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundariesSpec {
    pub x_lower: Option<BoundaryEntry>,
    pub x_upper: Option<BoundaryEntry>,
    pub y_lower: Option<BoundaryEntry>,
    pub y_upper: Option<BoundaryEntry>,
    pub z_lower: Option<BoundaryEntry>,
    pub z_upper: Option<BoundaryEntry>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbeSpec {
    pub name: String,
    pub position: [f64; 3],
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImmersedSpec {
    /// Interface name the solid side couples to (default "particles").
    #[serde(default = "default_interface")]
    pub interface: String,
    /// Number of particles, when known in advance (otherwise taken from the first inbox).
    pub particles: Option<usize>,
}

fn default_interface() -> String {
    "particles".into()
}
