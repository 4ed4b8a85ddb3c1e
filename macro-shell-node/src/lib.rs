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

use protocol::{BuildOptions, Solver, SolverError, SolverResult};

/// Builds the solver named `model` from its parameter table, for a run.
pub fn factory(model: &str, params: &toml::Table) -> SolverResult<Box<dyn Solver>> {
    build(model, params, &BuildOptions::RUN)
}

/// Builds the solver named `model` from its parameter table (the node's registry: one line
/// per model). This node opens no device, so describe-only builds the same solver.
/// The models this node offers.
pub const MODELS: &[&str] = &[solver::MODEL];

/// JSON Schema of a model's parameters (`macro-shell-node --schema --model M`, `cosim params M`): derived
/// from the types the parameters are decoded into, so it lists exactly what is accepted.
pub fn schema(model: &str) -> Option<serde_json::Value> {
    (model == solver::MODEL)
        .then(|| serde_json::to_value(schemars::schema_for!(setup::ShellConfig)).ok())
        .flatten()
}

pub fn build(
    model: &str,
    params: &toml::Table,
    _opts: &BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    match model {
        solver::MODEL => Ok(Box::new(ShellSolver::from_params(params)?)),
        other => Err(SolverError::config(
            "model",
            format!("unknown model '{other}' (this node has: {})", solver::MODEL),
        )),
    }
}
