//! Explicit shell finite-element node: the macro-scale structure of seed 004 (§3, eq. 18–33,
//! Fig. 4). Belytschko–Lin–Tsay shells with J2 plane-stress plasticity, central-difference
//! time integration with mass scaling, and the driver side of the kinematic shell–joint
//! coupling.
//!
//! Layout: `setup` (params → validated model), `mesh` (geometry → quads and named sets),
//! `element` (the BLT kernel), `lanes` (its elastic
//! form on four elements at once), `model` (state arrays), `step` (the time loop), `coupling`
//! (driver side), `output` (VTK, CSV), `solver` (the `Solver` impl).

// Kernels index several small fixed-size arrays with one index; range loops read clearer.
#![allow(clippy::needless_range_loop)]

pub mod contact;
pub mod coupling;
pub mod element;
pub mod lanes;
pub mod mesh;
pub mod model;
pub mod output;
pub mod setup;
pub mod solver;
pub mod step;

pub use solver::ShellSolver;

use protocol::{BuildOptions, Solver, SolverResult};

use protocol::registry::Model;

/// Builds the solver named `model` from its parameter table, for a run.
pub fn factory(model: &str, params: &toml::Table) -> SolverResult<Box<dyn Solver>> {
    build(model, params, &BuildOptions::RUN)
}

/// The models this node offers: name, parameter schema, example parameters, constructor.
pub const MODELS: &[Model] = &[Model {
    name: solver::MODEL,
    schema: || serde_json::to_value(schemars::schema_for!(setup::ShellConfig)).unwrap_or_default(),
    example: SHELL_EXAMPLE,
    build: |p, _| Ok(Box::new(ShellSolver::from_params(p)?)),
}];

/// A 4 × 3 J2 plate moving at one edge, with an interface on that edge.
const SHELL_EXAMPLE: &str = r#"
mesh = { kind = "plate", length = 4e-3, width = 3e-3, nx = 4, ny = 3 }
material = { model = "j2", density = 7850.0, youngs_modulus = 210e9, poisson_ratio = 0.3, yield_stress = 1e9, tangent_modulus = 1e9, kinematic_fraction = 1.0 }
section = { thickness = 1e-3, integration_points = 3 }
node_sets = [{ name = "left", box = [-1.0, -1.0, -1.0, 1.0e-4, 1.0, 1.0] }]
velocity = [{ node_set = "left", x = -0.02, y = 0.0, z = 0.0 }]
fixed = [{ node_set = "left", dofs = ["rotations"] }]
element_sets = [{ name = "edge", boxes = [[-1.0, -1.0, -1.0, 1.1e-3, 1.0, 1.0]] }]
interfaces = [{ name = "edge", element_set = "edge" }]
"#;

/// JSON Schema of a model's parameters (`NODE --schema --model M`, `cosim params M`): derived
/// from the types the parameters are decoded into, so it lists exactly what is accepted.
pub fn schema(model: &str) -> Option<serde_json::Value> {
    protocol::registry::schema(MODELS, model)
}

/// Builds the solver named `model` from its parameter table as `opts` asks (the node
/// binary's `SolverFactory`).
pub fn build(
    model: &str,
    params: &toml::Table,
    opts: &BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    protocol::registry::build(MODELS, model, params, opts)
}
