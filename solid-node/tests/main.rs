//! Every integration test of the solid node in one binary: one build and one link for all of
//! them (each file is a module; `cargo test -p solid-node -- pd_rk_ba::` runs one file's).

mod bar_gs4;
mod decouple;
mod fem2d_lagrange;
mod fem2d_node;
mod fracture_report;
mod gpu_fracture;
mod gpu_node;
mod gpu_pd;
mod lagrange_chain;
mod lagrange_checkpoint;
mod lagrange_split_bar;
mod overlap;
mod pd_blast_solid;
mod pd_energy;
mod pd_fracture;
mod pd_no_fail;
mod pd_offset;
mod pd_rk_ba;
mod pd_solver;
mod pd_verification;
mod pd_walls;
