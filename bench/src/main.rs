//! `cosim-bench`: the benchmark suite of the project, outside the coordinator (which builds no
//! solver). `cosim bench ARGS` runs this binary with the same arguments.

mod suite;
mod window;

use clap::{Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(
    name = "cosim-bench",
    version,
    about = "Benchmarks: without a subcommand, every kernel of the project (transport, whole coupled windows, fluid, pd-bond, pd-correspondence, shell, joint, joint-solid; CPU at 1 and 2 threads, GPU where an adapter exists) at 4 sizes each, written to DIR/bench.json and DIR/bench.md",
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    what: Option<BenchCmd>,
    #[command(flatten)]
    suite: suite::SuiteArgs,
}

#[derive(Debug, Subcommand)]
enum BenchCmd {
    /// Round trip of one window exchange (Advance → Fields → Done) per transport and size.
    Transport {
        /// Rounds per size (medians are taken over them, after a warm-up).
        #[arg(long, default_value_t = 300)]
        rounds: usize,
        /// shm | zenoh | local | all
        #[arg(long, default_value = "all")]
        transport: String,
        /// Payload sizes in bytes, comma-separated.
        #[arg(long, value_delimiter = ',', default_values_t = protocol::transport::bench::DEFAULT_SIZES.to_vec())]
        sizes: Vec<usize>,
    },
    /// Internal: the echo side of the transport benchmark (configured by its environment).
    #[command(hide = true)]
    Echo,
}

fn main() {
    protocol::participant::init_logging();
    protocol::participant::tune_allocator();
    let cli = Cli::parse();
    let code = match cli.what {
        Some(BenchCmd::Transport {
            rounds,
            transport,
            sizes,
        }) => suite::bench_transport(rounds, &transport, &sizes),
        Some(BenchCmd::Echo) => suite::bench_echo(),
        None => suite::suite(&cli.suite),
    };
    std::process::exit(code);
}
