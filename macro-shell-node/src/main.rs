//! Explicit shell finite-element node: the node binary (wires the solvers of `macro_shell_node` into the participant runtime).

fn main() {
    protocol::params::register_schemas(protocol::params::Schemas {
        models: macro_shell_node::MODELS,
    });
    std::process::exit(protocol::participant::node_main(
        "macro-shell-node",
        macro_shell_node::build,
    ));
}
