//! Momentum-consistent SPG meso-scale joint node: the node binary (wires the solvers of `meso_joint_node` into the participant runtime).

fn main() {
    protocol::params::register_schemas(protocol::params::Schemas {
        models: meso_joint_node::MODELS,
    });
    std::process::exit(protocol::participant::node_main(
        "meso-joint-node",
        meso_joint_node::build,
    ));
}
