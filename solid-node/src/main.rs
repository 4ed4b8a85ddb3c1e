//! Peridynamic solid node (and the 1-D elastic bar): the node binary (wires the solvers of `solid_node` into the participant runtime).

fn main() {
    protocol::params::register_schemas(protocol::params::Schemas {
        models: solid_node::MODELS,
    });
    std::process::exit(protocol::participant::node_main(
        "solid-node",
        solid_node::build,
    ));
}
