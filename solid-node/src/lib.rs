//! Peridynamic solid node (and the 1-D elastic bar of the spine, and the 2-D elastic
//! finite elements `fem-2d`).
//! Models are chosen by name in the case config; each lives in its own module.

pub mod bar;
pub mod fem2d;
pub mod fixtures;
pub mod lagrange;
pub mod pd;

use protocol::{BuildOptions, Solver, SolverResult};

use protocol::registry::Model;

/// Builds the solver named `model` from its parameter table, for a run.
pub fn factory(model: &str, params: &toml::Table) -> SolverResult<Box<dyn Solver>> {
    build(model, params, &BuildOptions::RUN)
}

/// The models this node offers: name, parameter schema, example parameters, constructor.
pub const MODELS: &[Model] = &[
    Model {
        name: "bar-1d",
        schema: || schema_of::<bar::BarParams>(),
        example: "length = 0.5\nelements = 10\nyoung = 200e9\ndensity = 7860.0\narea = 1e-4\ntip_force = 1e3\ninterfaces = { tip = \"right\" }\n",
        build: |p, _| Ok(Box::new(bar::Bar::from_params(p)?)),
    },
    Model {
        name: "fem-2d",
        schema: || schema_of::<fem2d::Fem2dParams>(),
        example: FEM_EXAMPLE,
        build: |p, _| Ok(Box::new(fem2d::Fem2d::from_params(p)?)),
    },
    Model {
        name: "pd-bond",
        schema: || schema_of::<pd::solver::PdParams>(),
        example: PD_EXAMPLE,
        build: |p, o| pd::build(&pd::models::bond::DEF, p, o),
    },
    Model {
        name: "pd-correspondence",
        schema: || schema_of::<pd::solver::PdParams>(),
        example: PD_EXAMPLE,
        build: |p, o| pd::build(&pd::models::correspondence::DEF, p, o),
    },
    Model {
        name: "pd-rk-ba",
        schema: || schema_of::<pd::solver::PdParams>(),
        example: PD_EXAMPLE,
        build: |p, o| pd::build(&pd::models::rk_ba::DEF, p, o),
    },
];

/// A small 2-D plane-stress bar, fixed at its left edge and pulled at its right.
const FEM_EXAMPLE: &str = r#"
length = 1.0
height = 0.25
nx = 4
ny = 2
young = 72e9
poisson = 0.3
density = 2700.0
plane = "stress"
thickness = 1.0
fixed = ["left"]
loads = [{ edge = "right", traction = [10000.0, 0.0], ramp = "step" }]
"#;

/// A small 3-D block with a hole, a moving end, interfaces and bond damage.
const PD_EXAMPLE: &str = r#"
dimension = "3d"
spacing = 1e-3
horizon = 3.015e-3
density = 7850.0
young = 200e9
poisson = 0.25
bodies = [{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.004, 0.003, 0.003] }]
holes = [{ shape = "disc", center = [0.002, 0.0015, 0.0], radius = 0.0004 }]
interfaces = [{ name = "surface", select = "surface" }, { name = "left", select = "all", region = { shape = "box", min = [0.0, 0.0, 0.0], max = [0.0011, 0.003, 0.003] } }]
initial_velocity = [{ region = { shape = "box", min = [0.0, 0.0, 0.0], max = [0.004, 0.003, 0.003] }, velocity = [1.0, 0.0, 0.0] }]
damage = { kind = "critical_stretch", critical_stretch = 0.01 }
"#;

/// The JSON Schema of the parameter type `T`.
fn schema_of<T: schemars::JsonSchema>() -> serde_json::Value {
    serde_json::to_value(schemars::schema_for!(T)).unwrap_or_default()
}

/// JSON Schema of a model's parameters (`solid-node --schema --model M`, `cosim params M`): derived
/// from the types the parameters are decoded into, so it lists exactly what is accepted.
pub fn schema(model: &str) -> Option<serde_json::Value> {
    protocol::registry::schema(MODELS, model)
}

/// Builds the solver named `model` from its parameter table as `opts` asks (the node
/// binary's `SolverFactory`: describe-only opens no GPU).
pub fn build(
    model: &str,
    params: &toml::Table,
    opts: &BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    protocol::registry::build(MODELS, model, params, opts)
}
