//! The `cosim` command line: run, validate, info, clean, replay, plot, and bench (which runs
//! the `cosim-bench` executable).

mod check;
mod replay;
mod results;
mod run;

pub use check::{ConformanceArgs, ValidateArgs};
pub use replay::ReplayArgs;
pub use results::{ExportArgs, InfoArgs, ParamsArgs, PlotArgs, RenderArgs};
pub use run::{RestartArgs, RunArgs};

use clap::{Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(
    name = "cosim",
    version,
    about = "Co-simulation coordinator for multiscale explicit dynamics"
)]
pub struct Cli {
    #[command(subcommand)]
    pub cmd: Cmd,
    /// More log output, from cosim and the nodes it launches: -v debug, -vv trace
    /// (the environment's COSIM_LOG or RUST_LOG filter otherwise; default info).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    pub verbose: u8,
    /// Warnings and errors only, and no progress bar or lines.
    #[arg(short, long, global = true)]
    pub quiet: bool,
}

impl Cli {
    /// The log filter the flags ask for, if they ask for one.
    pub fn log_filter(&self) -> Option<&'static str> {
        match (self.quiet, self.verbose) {
            (true, _) => Some("warn"),
            (false, 0) => None,
            (false, 1) => Some("debug,zenoh=info,iceoryx2=info"),
            (false, _) => Some("trace"),
        }
    }
}

#[derive(Debug, Subcommand)]
pub enum Cmd {
    /// Validate a case, launch its nodes, run it to the end and record everything.
    Run(RunArgs),
    /// Continue the run in RUN_DIR from its last checkpoint complete on every node, with the
    /// case as it ran. A run that finished is continued only to a later end time
    /// (`--set run.end_time=T`). The recording goes on in run.1.mcap, run.2.mcap, ...; each
    /// node's log goes on in RUN_DIR/NODE.log after a line marking the restart.
    Restart(RestartArgs),
    /// Check a case file (and every variant) without starting anything.
    Validate(ValidateArgs),
    /// Summarise a recording (RUN.mcap, or the run's output folder), after checking its bytes:
    /// a file that is not MCAP is "not a recording", one that fails its chunk or section CRCs
    /// is "corrupt at byte N" (both exit 1); one cut short by a killed run reads as
    /// INCOMPLETE, as far as its complete chunks go.
    Info(InfoArgs),
    /// Draw the run's fields at one time into a PNG (every node's VTK frame nearest it): the
    /// gas pressure with the solids over it, or the solids' deformed surfaces coloured by
    /// plastic strain and their particles by damage. `cosim run` draws the last frames into
    /// RUN/fields.png, and each node alone into RUN/fields_<node>.png.
    Render(RenderArgs),
    /// Write a run's per-window histories (every node's report and the balance) as arrays:
    /// `npz` (numpy: `np.load(F)["gas/probe1.pressure"]`), `csv` or `parquet` (one file per
    /// node: `pandas.read_parquet("RUN/history/gas.parquet")`).
    Export(ExportArgs),
    /// Remove the shared memory left by runs whose processes are all gone (a killed cosim);
    /// a run still running is never touched.
    Clean,
    /// Launch one node's executable alone, feed it its recorded inputs window by window, and
    /// compare what it sends with what the recording holds.
    ///
    /// Exit status: 0 the outputs are bit-identical to the recording over every recorded
    /// window; 3 some replayed output differs from the recorded one; 1 the replay could not
    /// run or could not compare every recorded window (a recording cut short or damaged, a
    /// node that failed or stopped early), with nothing compared differing; 2 a command-line
    /// error.
    Replay(ReplayArgs),
    /// Plot quantities of several runs on one figure each (e.g. one case at three
    /// resolutions): `cosim plot out/a out/b --series bar.com_x --series gas.point1.pressure`;
    /// with `--field`, a picture of a field; with `--fragments`, fragment-size histograms.
    Plot(PlotArgs),
    /// The parameters of a model (key, type, default, meaning; SI units), from the JSON Schema
    /// its node executable derives from the types it decodes them into; without a model, the
    /// models of the built-in nodes.
    Params(ParamsArgs),
    /// Print the JSON Schema (draft 2020-12) of case files, the one in docs/schema/case.json,
    /// for tools and editors that check TOML against a JSON Schema; with `--markdown`, the
    /// reference of every case key and every built-in model's parameters (docs/reference.md).
    Schema {
        #[arg(long)]
        markdown: bool,
    },
    /// Print a shell completion script: `cosim completions bash > ~/.local/share/bash-completion/completions/cosim`
    /// (also zsh, fish, elvish, powershell).
    Completions {
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
    /// Benchmarks (the `cosim-bench` executable beside `cosim`, with these arguments):
    /// without a subcommand, every kernel of the project at 4 sizes, written to
    /// DIR/bench.json and DIR/bench.md; `cosim bench transport`: window round trips per
    /// transport. `cosim bench --help` lists the options.
    #[command(disable_help_flag = true)]
    Bench {
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
    /// Check a node executable, in any language, against PROTOCOL.md: drive it through
    /// `--describe`, handshake, set-up, a few windows, heartbeats, a checkpoint and `Finish`
    /// against a peer that cosim plays (the node's own interface as its mesh, a small constant
    /// velocity, zero loads), and print PASS or FAIL per rule with its section and reason:
    /// `cosim conformance --model bar-1d --params right.toml -- python3 bar.py`.
    ///
    /// Exit status: 0 every rule passes; 1 a rule fails or was not reached; 2 a command-line
    /// error.
    Conformance(ConformanceArgs),
}

/// Run the command line; returns the exit code.
pub fn main_with(cli: Cli) -> i32 {
    let quiet = cli.quiet;
    match cli.cmd {
        Cmd::Run(a) => run::run(a, quiet),
        Cmd::Restart(a) => run::restart(a, quiet),
        Cmd::Validate(a) => check::validate(&a),
        Cmd::Conformance(a) => check::conformance(a),
        Cmd::Info(a) => outcome("cosim", 1, results::info(&a)),
        Cmd::Render(a) => outcome("cosim render", 1, results::render(a)),
        Cmd::Export(a) => outcome("cosim export", 1, results::export(a)),
        Cmd::Plot(a) => outcome("cosim plot", 1, results::plot(&a)),
        Cmd::Params(a) => outcome("cosim params", 2, results::params(&a)),
        Cmd::Replay(a) => replay::replay(a),
        Cmd::Schema { markdown: false } => outcome(
            "cosim",
            1,
            serde_json::to_string_pretty(&crate::case::parse::schema()).map_err(Into::into),
        ),
        Cmd::Schema { markdown: true } => outcome("cosim", 1, crate::params::reference()),
        Cmd::Completions { shell } => {
            use clap::CommandFactory;
            clap_complete::generate(shell, &mut Cli::command(), "cosim", &mut std::io::stdout());
            0
        }
        Cmd::Clean => {
            let r = protocol::transport::shm::cleanup_stale_runs();
            println!(
                "cosim clean: removed {} shared-memory files of {} ended runs; {} running runs left alone",
                r.files, r.runs, r.live
            );
            0
        }
        Cmd::Bench { args } => bench(&args),
    }
}

/// A command's text on stdout and exit code 0, or its error after `prefix` on stderr and
/// exit code `failed`.
fn outcome(prefix: &str, failed: i32, done: anyhow::Result<String>) -> i32 {
    match done {
        Ok(text) => {
            println!("{}", text.trim_end());
            0
        }
        Err(e) => {
            eprintln!("{prefix}: {e:#}");
            failed
        }
    }
}

/// `cosim bench ARGS`: run `cosim-bench ARGS` beside `cosim` and pass its exit code on.
fn bench(args: &[String]) -> i32 {
    let exe = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(|d| d.join("cosim-bench")))
        .filter(|e| e.is_file());
    let Some(exe) = exe else {
        eprintln!(
            "cosim bench: no cosim-bench executable beside cosim (build it: cargo build --release -p cosim-bench)"
        );
        return 2;
    };
    match std::process::Command::new(&exe).args(args).status() {
        Ok(s) => s.code().unwrap_or(1),
        Err(e) => {
            eprintln!("cosim bench: cannot run {}: {e}", exe.display());
            1
        }
    }
}
