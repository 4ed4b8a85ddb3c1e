//! Momentum-consistent SPG meso-scale joint node (seed 004 §2–3): Lagrangian particles with
//! first-order RK shape functions, direct nodal integration, the momentum-consistent velocity
//! smoothing (eq. 2–11), J2 kinematic hardening, bond failure (eq. 15–17), rigid bodies and
//! the responder side of the shell kinematic coupling (eq. 29–33).
//!
//! Layout: `config` (parameters and validation), `geometry` (particle sets), `shape`
//! (supports and shape functions), `model` (state and the time step), `profile` (time per
//! phase of the step), `output` (VTK, CSV),
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
pub mod solver;

use protocol::{BuildOptions, Solver, SolverError, SolverResult};

/// Builds the solver named `model` from its parameter table, for a run.
pub fn factory(model: &str, params: &toml::Table) -> SolverResult<Box<dyn Solver>> {
    build(model, params, &BuildOptions::RUN)
}

/// Builds the solver named `model` from its parameter table (the node's registry: one line
/// per model). This node opens no device, so describe-only builds the same solver.
/// The models this node offers.
pub const MODELS: &[&str] = &["mc-spg"];

/// JSON Schema of a model's parameters (`meso-joint-node --schema --model M`, `cosim params M`): derived
/// from the types the parameters are decoded into, so it lists exactly what is accepted.
pub fn schema(model: &str) -> Option<serde_json::Value> {
    (model == "mc-spg")
        .then(|| serde_json::to_value(schemars::schema_for!(config::Params)).ok())
        .flatten()
}

pub fn build(
    model: &str,
    params: &toml::Table,
    _opts: &BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    match model {
        "mc-spg" => Ok(Box::new(solver::SpgSolver::new(
            config::Params::from_table(params)?,
        )?)),
        _ => Err(SolverError::config(
            "model",
            format!("unknown model '{model}' (known: mc-spg)"),
        )),
    }
}
