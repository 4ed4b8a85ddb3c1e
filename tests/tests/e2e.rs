//! The end-to-end tests that share one test binary: each file of this folder is a module
//! here, so the workspace compiles and links them once and the harness runs them side by side
//! (two at a time on two cores) instead of one file after another. The tests that load the
//! whole machine or time it (`bench`, `fault_campaigns`, `own_stalls`, `signals`) stay
//! binaries of their own, run alone. Run one file's tests with
//! `cargo test --release -p cosim-tests --test e2e FILE::`.

mod blast_solids;
mod build_once;
mod chamber_shock;
mod config_errors;
mod conformance;
mod crash_tube;
mod decouple;
mod disk_full;
mod divergence;
mod docs_examples;
mod docs_links;
mod external;
mod failures;
mod fields_contract;
mod fluid_cases;
mod glass_plate;
mod gpu;
mod immersed;
mod joints;
mod kinematic_in_process;
mod lagrange;
mod lagrange_chain;
mod node_describe;
mod node_stderr_full;
mod output_lock;
mod overlap_wave;
mod params_schema;
mod pipelining;
mod protocol_example;
mod recording;
mod recording_checks;
mod remote_node;
mod replay;
mod reruns_and_swaps;
mod restart;
mod restart_and_replay_outputs;
mod seed003;
mod seed003_lagrange;
mod split_bar;
mod toolchain;
mod two_hosts;
mod vtk_series;
