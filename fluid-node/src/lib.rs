//! Compressible multi-material finite-volume fluid node (seed 002 §2.2–§4): Euler equations
//! on structured 1-D/2-D/3-D grids, MUSCL + HLLC + SSP-RK3, a five-equation two-material
//! model, ideal / stiffened / JWL equations of state, and the responder side of the immersed
//! particle coupling.
//!
//! Layout: `config` (params schema) → `setup` (validated model) → `step` (the time loop,
//! kernels over flat arrays) with `riemann`, `limiter`, `eos`, `mixture`, `boundary`,
//! `immersed`; `solver` wraps it all in the `Solver` trait; `output`, `diagnostics`.

// `!(x > 0.0)` is deliberate throughout: it rejects NaN as well as non-positive values.
// Index loops over small fixed-size arrays mirror the component-wise equations.
#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    clippy::needless_range_loop,
    clippy::too_many_arguments,
    clippy::type_complexity
)]

pub mod boundary;
pub mod config;
pub mod diagnostics;
pub mod eos;
pub mod gpu;
pub mod grid;
pub mod immersed;
pub mod limiter;
pub mod mixture;
pub mod model;
pub mod output;
pub mod riemann;
pub mod setup;
pub use mechanics::simd;
pub mod solver;
pub mod step;

pub use solver::EulerSolver;

use protocol::{BuildOptions, Solver, SolverError, SolverResult};

/// Builds the solver named `model` from its parameter table, for a run.
pub fn factory(model: &str, params: &toml::Table) -> SolverResult<Box<dyn Solver>> {
    build(model, params, &BuildOptions::RUN)
}

/// Builds the solver named `model` from its parameter table as `opts` asks (the node's
/// registry: one line per model; describe-only opens no GPU).
/// The models this node offers.
pub const MODELS: &[&str] = &["euler"];

/// JSON Schema of a model's parameters (`fluid-node --schema --model M`, `cosim params M`): derived
/// from the types the parameters are decoded into, so it lists exactly what is accepted.
pub fn schema(model: &str) -> Option<serde_json::Value> {
    (model == "euler")
        .then(|| serde_json::to_value(schemars::schema_for!(config::Params)).ok())
        .flatten()
}

pub fn build(
    model: &str,
    params: &toml::Table,
    opts: &BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    match model {
        "euler" => Ok(Box::new(EulerSolver::build(params, opts)?)),
        other => Err(SolverError::config(
            "model",
            format!("unknown model '{other}' (this node has: euler)"),
        )),
    }
}
