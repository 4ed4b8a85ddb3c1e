//! Explicit shell finite-element node: the node binary (wires the solvers of `macro_shell_node` into the participant runtime).

fn main() {
    std::process::exit(protocol::participant::node_main(
        "macro-shell-node",
        macro_shell_node::build,
    ));
}
