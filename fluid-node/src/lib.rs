//! Compressible multi-material finite-volume fluid node (seed 002 §2.2–§4): Euler equations
//! on structured 1-D/2-D/3-D grids, MUSCL + HLLC + SSP-RK3, a five-equation two-material
//! model, ideal / stiffened / JWL equations of state, and the responder side of the immersed
//! particle coupling.
//!
//! Layout: `config` (params schema) → `setup` (validated model) → `step` (the time loop,
//! kernels over flat arrays) with `riemann`, `limiter`, `eos`, `mixture`, `boundary`,
//! `immersed`; `solver` wraps it all in the `Solver` trait; `output`, `diagnostics`, `edges`
//! (a material's edges along a line, for reports); `exact` holds the exact solutions of the
//! radial verification problems (Noh, Sedov), which use none of the solver's code.

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
pub mod edges;
pub mod eos;
pub mod exact;
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

use protocol::{BuildOptions, Solver, SolverResult};

use protocol::registry::Model;

/// Builds the solver named `model` from its parameter table, for a run.
pub fn factory(model: &str, params: &toml::Table) -> SolverResult<Box<dyn Solver>> {
    build(model, params, &BuildOptions::RUN)
}

/// The models this node offers: name, parameter schema, example parameters, constructor.
pub const MODELS: &[Model] = &[Model {
    name: "euler",
    schema: || serde_json::to_value(schemars::schema_for!(config::Params)).unwrap_or_default(),
    example: EULER_EXAMPLE,
    build: |p, o| Ok(Box::new(EulerSolver::build(p, o)?)),
}];

/// A 12-cell tube of air with a water drop, an inflow and an outflow.
const EULER_EXAMPLE: &str = r#"
cfl = 0.5
[grid]
cells = [12, 1, 1]
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
[materials.air]
eos = "ideal"
gamma = 1.4
[materials.water]
eos = "stiffened"
gamma = 4.4
p_inf = 6e8
[[regions]]
shape = "all"
material = "air"
density = 1.0
pressure = 1.0
[[regions]]
shape = "sphere"
center = [0.5, 0.5, 0.5]
radius = 0.2
material = "water"
density = 1000.0
pressure = 1.0
[boundaries]
x_lower = { kind = "inflow", material = "air", density = 1.5, velocity = [0.3, 0.0, 0.0], pressure = 1.5 }
x_upper = { kind = "outflow" }
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
