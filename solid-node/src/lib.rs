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
/// The models this node offers.
pub const MODELS: &[&str] = &[
    "bar-1d",
    "fem-2d",
    "pd-bond",
    "pd-correspondence",
    "pd-rk-ba",
];

/// JSON Schema of a model's parameters (`solid-node --schema --model M`, `cosim params M`): derived
/// from the types the parameters are decoded into, so it lists exactly what is accepted.
pub fn schema(model: &str) -> Option<serde_json::Value> {
    let s = match model {
        "bar-1d" => schemars::schema_for!(bar::BarParams),
        "fem-2d" => schemars::schema_for!(fem2d::Fem2dParams),
        "pd-bond" | "pd-correspondence" | "pd-rk-ba" => schemars::schema_for!(pd::solver::PdParams),
        _ => return None,
    };
    serde_json::to_value(s).ok()
}

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
