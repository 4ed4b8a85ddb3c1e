//! Every integration test of the joint node in one binary: one build and one link for all of
//! them (each file is a module; `cargo test -p meso-joint-node -- solid::` runs one file's).

mod johnson_cook;
mod momentum;
mod patch;
mod solid;
mod solver;
mod tension;
mod threads;
