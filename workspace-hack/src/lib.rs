//! No code: the dependencies in `Cargo.toml` are the point. They ask for the union of the
//! features the workspace's commands would otherwise resolve differently, so `cargo build`,
//! `cargo test` and maturin's build of the Python package compile each crate once.
