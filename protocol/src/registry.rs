//! A node's models in one table: each model's name, the JSON Schema of its parameters, a
//! small parameter table it accepts, and its constructor. The node binary's `--schema` and
//! `--describe`, its `build`, `cosim params` (which asks the binary), `docs/schema/` and the
//! fuzzer all read the same table, so a model is added in one place: its module and its row.

use crate::solver::{BuildOptions, Solver, SolverError, SolverResult};

/// One model of a node.
#[derive(Clone, Copy)]
pub struct Model {
    /// The name a case file gives as `model`.
    pub name: &'static str,
    /// The JSON Schema of its parameters, derived from the types they are decoded into.
    pub schema: fn() -> serde_json::Value,
    /// A small parameter table (TOML) it accepts: the fuzzer's seed, a user's starting point.
    pub example: &'static str,
    /// Builds the solver from its parameter table as `BuildOptions` asks.
    pub build: fn(&toml::Table, &BuildOptions) -> SolverResult<Box<dyn Solver>>,
}

/// The model named `name` among `models`.
pub fn find<'m>(models: &'m [Model], name: &str) -> Option<&'m Model> {
    models.iter().find(|m| m.name == name)
}

/// The names of `models`, in order.
pub fn names(models: &[Model]) -> Vec<&'static str> {
    models.iter().map(|m| m.name).collect()
}

/// Build model `name` of `models` from `params`; an unknown name is a config error at
/// `model` that lists the node's models.
pub fn build(
    models: &[Model],
    name: &str,
    params: &toml::Table,
    opts: &BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    match find(models, name) {
        Some(m) => (m.build)(params, opts),
        None => Err(SolverError::config(
            "model",
            format!(
                "unknown model '{name}' (this node has: {})",
                names(models).join(", ")
            ),
        )),
    }
}

/// The JSON Schema of model `name`'s parameters, if `models` has it.
pub fn schema(models: &[Model], name: &str) -> Option<serde_json::Value> {
    find(models, name).map(|m| (m.schema)())
}
