//! Peridynamic solid node (and the 1-D elastic bar of the spine, and the 2-D elastic
//! finite elements `fem-2d`).
//! Models are chosen by name in the case config; each lives in its own module.

pub mod bar;
pub mod fem2d;
pub mod lagrange;
pub mod pd;

use protocol::{BuildOptions, Solver, SolverError, SolverResult};

/// Builds the solver named `model` from its parameter table, for a run.
pub fn factory(model: &str, params: &toml::Table) -> SolverResult<Box<dyn Solver>> {
    build(model, params, &BuildOptions::RUN)
}

/// Builds the solver named `model` from its parameter table as `opts` asks (the node
/// binary's `SolverFactory`: describe-only opens no GPU).
pub fn build(
    model: &str,
    params: &toml::Table,
    opts: &BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    if model == "bar-1d" {
        return Ok(Box::new(bar::Bar::from_params(params)?));
    }
    if model == "fem-2d" {
        return Ok(Box::new(fem2d::Fem2d::from_params(params)?));
    }
    if let Some(s) = pd::build(model, params, opts) {
        return s;
    }
    Err(SolverError::config(
        "model",
        format!("unknown model '{model}'"),
    ))
}
