//! `cosim`: the coordinator binary.

use clap::Parser;

/// Counts the window loop's allocations for `summary.json` (`window_breakdown`).
#[global_allocator]
static ALLOC: coordinator::profile::CountingAlloc = coordinator::profile::CountingAlloc;

fn main() {
    let cli = coordinator::cli::Cli::parse();
    if let Some(filter) = cli.log_filter() {
        // SAFETY: the process has one thread here (nothing has started yet); the nodes
        // launched later inherit the filter.
        unsafe { std::env::set_var("COSIM_LOG", filter) };
    }
    protocol::participant::init_logging();
    protocol::participant::tune_allocator();
    std::process::exit(coordinator::cli::main_with(cli));
}
