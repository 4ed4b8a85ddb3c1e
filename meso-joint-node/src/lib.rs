//! Momentum-consistent SPG meso-scale joint node (seed 004 §2–3): Lagrangian particles with
//! first-order RK shape functions, direct nodal integration, the momentum-consistent velocity
//! smoothing (eq. 2–11), J2 kinematic hardening, bond failure (eq. 15–17), rigid bodies and
//! the responder side of the shell kinematic coupling (eq. 29–33).
//!
//! Layout: `config` (parameters and validation), `geometry` (particle sets, and their split
//! into an SPG core and hexahedra), `shape` (supports and shape functions), `model` (state
//! and the time step), `solid` (the hexahedra around an SPG core, sharing its boundary
//! particles), `profile` (time per phase of the step), `output` (VTK, CSV),
//! `solver` (the `Solver` implementation; its coupling particles follow the shell through the
//! participant runtime's mapping).

// Index loops mirror the tensor formulas; `!(x > 0.0)` is used on purpose to reject NaN.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod config;
pub mod geometry;
pub mod model;
pub mod output;
pub mod profile;
pub mod shape;
pub mod solid;
pub mod solver;

use protocol::{BuildOptions, Solver, SolverResult};

use protocol::registry::Model;

/// Builds the solver named `model` from its parameter table, for a run.
pub fn factory(model: &str, params: &toml::Table) -> SolverResult<Box<dyn Solver>> {
    build(model, params, &BuildOptions::RUN)
}

/// The models this node offers: name, parameter schema, example parameters, constructor.
pub const MODELS: &[Model] = &[Model {
    name: "mc-spg",
    schema: || serde_json::to_value(schemars::schema_for!(config::Params)).unwrap_or_default(),
    example: SPG_EXAMPLE,
    build: |p, _| {
        Ok(Box::new(solver::SpgSolver::new(
            config::Params::from_table(p)?,
        )?))
    },
}];

/// A 4 × 3 × 3 mm J2 block pulled at one end.
const SPG_EXAMPLE: &str = r#"
spacing = 1e-3
kernel_support = 2e-3
density = 7850.0
young = 210e9
poisson = 0.3
yield_stress = 0.2e9
tangent_modulus = 20e9
eps_crit = 0.1
velocity_bc = [{ name = "left", velocity = [-0.02, 0.0, 0.0], ramp = 1e-3, region = { lo = [-1.0, -1.0, -1.0], hi = [0.5e-3, 1.0, 1.0] } }]
[geometry]
kind = "block"
origin = [0.0, 0.0, 0.0]
size = [4e-3, 3e-3, 3e-3]
"#;

/// JSON Schema of a model's parameters (`meso-joint-node --schema --model M`, `cosim params M`): derived
/// from the types the parameters are decoded into, so it lists exactly what is accepted.
pub fn schema(model: &str) -> Option<serde_json::Value> {
    protocol::registry::schema(MODELS, model)
}

/// Builds the solver named `model` from its parameter table (this node opens no device, so
/// describe-only builds the same solver).
pub fn build(
    model: &str,
    params: &toml::Table,
    opts: &BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    protocol::registry::build(MODELS, model, params, opts)
}
