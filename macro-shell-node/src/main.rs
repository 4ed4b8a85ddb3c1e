//! Explicit shell finite-element node: the node binary.

fn main() {
    std::process::exit(protocol::participant::node_main("macro-shell-node", macro_shell_node::factory));
}
