//! Peridynamic solid models (being written).

use protocol::{Solver, SolverResult};

/// The peridynamic models of this node by config name; `None` when `model` is not one.
pub fn factory(model: &str, params: &toml::Table) -> Option<SolverResult<Box<dyn Solver>>> {
    let _ = (model, params);
    None
}
