//! Peridynamic solid models (seed 000 App. A–C, seed 001 ch. 4): particles and families,
//! the model family behind one trait (`model`), one file per model, the velocity-Verlet
//! body, VTK output and the `Solver` implementation with its coupling sides.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

#[cfg(target_arch = "x86_64")]
mod avx512;
pub mod bond;
pub mod cases;
pub mod checkpoint;
pub mod correspondence;
pub mod family;
pub mod fracture;
pub mod geometry;
pub mod gpu;
pub mod integrate;
pub mod model;
pub mod output;
pub mod rk_ba;
pub mod solver;

use protocol::{BuildOptions, Solver, SolverResult};

/// The peridynamic models of this node by config name, for a run; `None` when `model` is
/// not one.
pub fn factory(model: &str, params: &toml::Table) -> Option<SolverResult<Box<dyn Solver>>> {
    build(model, params, &BuildOptions::RUN)
}

/// As `factory`, as `opts` asks (describe-only opens no GPU).
pub fn build(
    model: &str,
    params: &toml::Table,
    opts: &BuildOptions,
) -> Option<SolverResult<Box<dyn Solver>>> {
    match model {
        "pd-bond" | "pd-correspondence" | "pd-rk-ba" => Some(
            protocol::params::decode(params)
                .and_then(|p| solver::PdSolver::build(model, p, opts))
                .map(|s| Box::new(s) as Box<dyn Solver>),
        ),
        _ => None,
    }
}
