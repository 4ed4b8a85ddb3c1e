//! Momentum-consistent SPG meso-scale joint node (being written).

use protocol::{Solver, SolverError, SolverResult};

/// Builds the solver named `model` from its parameter table.
pub fn factory(model: &str, params: &toml::Table) -> SolverResult<Box<dyn Solver>> {
    let _ = params;
    Err(SolverError::config("model", format!("unknown model '{model}' (this node has none yet)")))
}
