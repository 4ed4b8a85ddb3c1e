//! `cosim`: the coordinator binary.

use clap::Parser;

fn main() {
    protocol::participant::init_logging();
    protocol::participant::tune_allocator();
    let cli = coordinator::cli::Cli::parse();
    std::process::exit(coordinator::cli::main_with(cli));
}
