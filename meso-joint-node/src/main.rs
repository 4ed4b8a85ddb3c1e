//! Momentum-consistent SPG meso-scale joint node: the node binary.

fn main() {
    std::process::exit(protocol::participant::node_main("meso-joint-node", meso_joint_node::factory));
}
