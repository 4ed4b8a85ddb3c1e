//! Compressible multi-material finite-volume fluid node: the node binary (wires the solvers of `fluid_node` into the participant runtime).

fn main() {
    protocol::params::register_schemas(protocol::params::Schemas {
        models: fluid_node::MODELS,
    });
    std::process::exit(protocol::participant::node_main(
        "fluid-node",
        fluid_node::build,
    ));
}
