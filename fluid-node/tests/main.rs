//! Every integration test of the fluid node in one binary: one build and one link for all of
//! them (each file is a module; `cargo test -p fluid-node -- radial::` runs one file's).

mod bad_input;
mod common;
mod determinism;
mod edges;
mod fused_stages;
mod ghost_fills;
mod gpu;
mod gpu_immersed;
mod immersed_moving;
mod immersed_wall;
mod interface_advection;
mod jwl_cj_state;
mod momentum_balance;
mod non_reflecting;
mod output_files;
mod radial;
mod riemann;
mod sedov_cylindrical;
mod shock_reflection;
mod sod_shock_tube;
mod three_d;
