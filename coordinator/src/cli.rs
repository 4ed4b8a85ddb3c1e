//! The `cosim` command line: run, validate, info, clean, replay, plot, and bench (which runs
//! the `cosim-bench` executable).

use crate::{config, replay, run};
use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Parser)]
#[command(
    name = "cosim",
    version,
    about = "Co-simulation coordinator for multiscale explicit dynamics"
)]
pub struct Cli {
    #[command(subcommand)]
    pub cmd: Cmd,
}

#[derive(Debug, Subcommand)]
pub enum Cmd {
    /// Validate a case, launch its nodes, run it to the end and record everything.
    Run {
        case: PathBuf,
        /// Output directory (default: the case's run.output).
        #[arg(long, short)]
        output: Option<PathBuf>,
        /// Run id (namespaces shared memory and topics; default: name-pid-time).
        #[arg(long)]
        run_id: Option<String>,
        /// Override a node parameter: NODE.KEY=VALUE, a run setting: run.KEY=VALUE, or a
        /// coupling's: couplings.NAME.KEY=VALUE (repeatable; applied after the variant's).
        #[arg(long = "set")]
        sets: Vec<String>,
        /// Run a named variant of the case (its `[variants.NAME]` settings); the output goes
        /// to `<run.output>/<NAME>` unless the variant sets `run.output`.
        #[arg(long)]
        variant: Option<String>,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
    },
    /// Check a case file (and every variant) without starting anything.
    Validate {
        case: PathBuf,
        /// Check with these overrides (NODE.KEY=VALUE, run.KEY=VALUE, couplings.NAME.KEY=VALUE).
        #[arg(long = "set")]
        sets: Vec<String>,
        /// Check only this variant.
        #[arg(long)]
        variant: Option<String>,
    },
    /// Summarise a recording.
    Info { recording: PathBuf },
    /// Remove the shared memory left by runs whose processes are all gone (a killed cosim);
    /// a run still running is never touched.
    Clean,
    /// Launch one node's executable alone, feed it its recorded inputs window by window, and
    /// compare what it sends with what the recording holds (exit 1 when incomplete).
    Replay {
        recording: PathBuf,
        #[arg(long)]
        node: String,
        /// Override a parameter of the node (KEY=VALUE, or model=NAME), repeatable.
        #[arg(long = "set")]
        sets: Vec<String>,
        /// Launch this executable instead of the recorded one (a path, or a name beside cosim).
        #[arg(long)]
        solver: Option<PathBuf>,
        /// Run id of the replay (namespaces its shared memory; default: a fresh one).
        #[arg(long)]
        run_id: Option<String>,
        /// Directory for the node's log and output (default: replay-NODE beside the recording).
        #[arg(long, short)]
        output: Option<PathBuf>,
        /// Relative drift of the interface motion that triggers a warning.
        #[arg(long, default_value_t = 1e-6)]
        tolerance: f64,
        /// Write the per-window report as CSV here.
        #[arg(long)]
        report: Option<PathBuf>,
        /// Write PNG charts of the node's reported quantities, recorded against replayed,
        /// into this directory.
        #[arg(long)]
        plot: Option<PathBuf>,
    },
    /// Plot quantities of several runs on one figure each (e.g. one case at three
    /// resolutions): `cosim plot out/a out/b --series bar.com_x --series gas.point1.pressure`.
    Plot {
        /// Runs: output directories (holding run.mcap) or recordings.
        #[arg(required = true)]
        runs: Vec<PathBuf>,
        /// NODE.QUANTITY to plot (a scalar of the node's report, kinetic_energy,
        /// internal_energy, momentum_x, ...), repeatable; `*.QUANTITY`: whichever node of each
        /// run reports it.
        #[arg(long = "series", required = true)]
        series: Vec<String>,
        /// Directory for the PNG files.
        #[arg(long, short, default_value = "plots")]
        output: PathBuf,
        /// NODE.QUANTITY for the horizontal axis instead of time (e.g. a displacement, for a
        /// force–displacement curve).
        #[arg(long)]
        x: Option<String>,
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
}

/// Load a case and apply `node.key=value` overrides; errors are (key, reason).
pub fn load_case(
    path: &std::path::Path,
    sets: &[String],
) -> Result<config::Case, config::ConfigError> {
    load_variant(path, None, sets)
}

/// `couplings.NAME.KEY=VALUE`: set a key of the `[[couplings]]` entry named NAME (its
/// `name`, or the default `driver-responder` node pair).
fn set_coupling(doc: &mut toml::Table, s: &str, rest: &str) -> Result<(), config::ConfigError> {
    let bad = |reason: String| config::ConfigError {
        key: format!("--set {s}"),
        reason,
    };
    let (name, kv) = rest
        .split_once('.')
        .ok_or_else(|| bad("must be couplings.NAME.KEY=VALUE".into()))?;
    let list = doc
        .get_mut("couplings")
        .and_then(|c| c.as_array_mut())
        .ok_or_else(|| bad("the case has no [[couplings]]".into()))?;
    let node_of = |t: &toml::Table, k: &str| -> String {
        t.get(k)
            .and_then(|v| v.as_str())
            .and_then(|v| v.split_once('.'))
            .map(|(n, _)| n.to_string())
            .unwrap_or_default()
    };
    let mut names = Vec::new();
    for c in list.iter_mut() {
        let Some(t) = c.as_table_mut() else { continue };
        let this = t
            .get("name")
            .and_then(|v| v.as_str())
            .map(str::to_string)
            .unwrap_or_else(|| format!("{}-{}", node_of(t, "driver"), node_of(t, "responder")));
        if this == name {
            return config::apply_sets(t, &[kv.to_string()]);
        }
        names.push(this);
    }
    Err(bad(format!(
        "no coupling named '{name}' (the case has {})",
        names.join(", ")
    )))
}

/// Load a case, apply the settings of variant `variant` (if any), then `sets`.
pub fn load_variant(
    path: &std::path::Path,
    variant: Option<&str>,
    sets: &[String],
) -> Result<config::Case, config::ConfigError> {
    if sets.is_empty() && variant.is_none() {
        return config::load(path);
    }
    let text = std::fs::read_to_string(path).map_err(|e| config::ConfigError {
        key: path.display().to_string(),
        reason: format!("cannot read: {e}"),
    })?;
    load_variant_text(&text, path, variant, sets)
}

/// As [`load_variant`], with the case file's text in hand (`path` names it in errors and
/// locates what the case refers to).
pub fn load_variant_text(
    text: &str,
    path: &std::path::Path,
    variant: Option<&str>,
    sets: &[String],
) -> Result<config::Case, config::ConfigError> {
    if sets.is_empty() && variant.is_none() {
        return config::parse(text, path);
    }
    let mut doc: toml::Table = toml::from_str(text).map_err(|e| config::ConfigError {
        key: path.display().to_string(),
        reason: e.message().to_string(),
    })?;
    let mut all: Vec<String> = Vec::new();
    if let Some(name) = variant {
        let v = config::variant_sets(&doc, name)?;
        config::apply_variant_structure(&mut doc, name)?;
        // A variant writes beside the others unless it says where.
        if !v.iter().any(|s| {
            s.split_once('=')
                .is_some_and(|(k, _)| k.trim() == "run.output")
        }) {
            let base = doc
                .get("run")
                .and_then(|r| r.get("output"))
                .and_then(|o| o.as_str())
                .unwrap_or("out")
                .to_string();
            all.push(format!("run.output={:?}", format!("{base}/{name}")));
        }
        all.extend(v);
    }
    all.extend(sets.iter().cloned());
    for s in &all {
        let (node, rest) = s.split_once('.').ok_or_else(|| config::ConfigError {
            key: format!("--set {s}"),
            reason: "must be NODE.KEY=VALUE or run.KEY=VALUE".into(),
        })?;
        if node == "run" && doc.get("nodes").is_none_or(|n| n.get("run").is_none()) {
            let t = doc
                .get_mut("run")
                .and_then(|r| r.as_table_mut())
                .ok_or_else(|| config::ConfigError {
                    key: "run".into(),
                    reason: "missing [run] table".into(),
                })?;
            config::apply_sets(t, &[rest.to_string()])?;
            continue;
        }
        if node == "couplings"
            && doc
                .get("nodes")
                .is_none_or(|n| n.get("couplings").is_none())
        {
            set_coupling(&mut doc, s, rest)?;
            continue;
        }
        let params = doc
            .get_mut("nodes")
            .and_then(|n| n.get_mut(node))
            .and_then(|n| n.as_table_mut())
            .ok_or_else(|| config::ConfigError {
                key: format!("--set {s}"),
                reason: format!("unknown node '{node}'"),
            })?
            .entry("params")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        let t = params.as_table_mut().ok_or_else(|| config::ConfigError {
            key: format!("nodes.{node}.params"),
            reason: "--set needs inline params".into(),
        })?;
        config::apply_sets(t, &[rest.to_string()])?;
    }
    let text = toml::to_string(&doc).map_err(|e| config::ConfigError {
        key: "--set".into(),
        reason: e.to_string(),
    })?;
    config::parse(&text, path)
}

/// Run the command line; returns the exit code.
pub fn main_with(cli: Cli) -> i32 {
    match cli.cmd {
        Cmd::Plot {
            runs,
            series,
            output,
            x,
        } => match crate::plot::compare(&runs, &series, x.as_deref(), &output) {
            Ok(files) => {
                for f in files {
                    println!("{}", f.display());
                }
                0
            }
            Err(e) => {
                eprintln!("cosim plot: {e:#}");
                1
            }
        },
        Cmd::Validate {
            case,
            sets,
            variant,
        } => match load_variant(&case, variant.as_deref(), &sets) {
            Ok(c) => {
                let order = config::window_order(&c)
                    .map(|o| o.join(" → "))
                    .unwrap_or_default();
                println!(
                    "{}: ok — {} nodes, {} couplings, {} windows, order {}",
                    case.display(),
                    c.nodes.len(),
                    c.couplings.len(),
                    ((c.run.end_time / c.run.window) - 1e-9).ceil(),
                    order
                );
                for n in &c.nodes {
                    match &n.interfaces {
                        Some(i) => println!(
                            "  node {}: {} {} described by its executable — interfaces {}",
                            n.name,
                            n.solver,
                            n.model,
                            if i.is_empty() {
                                "none".to_string()
                            } else {
                                i.join(", ")
                            }
                        ),
                        None => println!(
                            "  node {}: remote, '{}' is not on this host — its parameters are checked when it joins",
                            n.name, n.solver
                        ),
                    }
                }
                // Every variant must build too.
                let others = if variant.is_none() && sets.is_empty() {
                    c.variants.clone()
                } else {
                    Vec::new()
                };
                for v in &others {
                    match load_variant(&case, Some(v), &[]) {
                        Ok(cv) => println!(
                            "  variant {v}: ok — {} windows, output {}",
                            ((cv.run.end_time / cv.run.window) - 1e-9).ceil(),
                            cv.run.output.display()
                        ),
                        Err(e) => {
                            eprintln!("cosim: {} (variant {v}): {e}", case.display());
                            return 2;
                        }
                    }
                }
                0
            }
            Err(e) => {
                eprintln!("cosim: {}: {e}", case.display());
                2
            }
        },
        Cmd::Run {
            case,
            output,
            run_id,
            sets,
            variant,
            quiet,
        } => {
            let c = match load_variant(&case, variant.as_deref(), &sets) {
                Ok(c) => c,
                Err(e) => {
                    eprintln!("cosim: {}: {e}", case.display());
                    return 2;
                }
            };
            if let Some(id) = &run_id
                && (id.is_empty()
                    || id.len() > 32
                    || !id
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_'))
            {
                eprintln!("cosim: --run-id: must be 1–32 characters of [A-Za-z0-9_-], got '{id}'");
                return 2;
            }
            let opts = run::RunOptions {
                run_id,
                output,
                quiet,
            };
            // Ctrl-C and SIGTERM stop the run at the next window boundary (a second Ctrl-C at
            // once), with the recording finalised and shared memory removed.
            if let Err(e) = protocol::stop::install(&[libc::SIGINT, libc::SIGTERM]) {
                eprintln!("cosim: cannot handle stop signals: {e}");
            }
            match run::run(&c, &opts) {
                Ok(Ok(o)) if o.interrupted.is_some() => {
                    let sig = o.interrupted.unwrap_or(libc::SIGINT);
                    eprintln!(
                        "cosim: {} interrupted by {} after window {} of {}; output in {}",
                        c.run.name,
                        protocol::stop::name(sig),
                        o.summary["window_reached"],
                        ((c.run.end_time / c.run.window) - 1e-9).ceil().max(1.0),
                        o.output.display()
                    );
                    protocol::stop::exit_code(sig)
                }
                Ok(Ok(o)) => {
                    let b = &o.summary["balance"];
                    let f = |k: &str| b[k].as_f64().unwrap_or(0.0);
                    let balance = if f("applied_impulse") > 0.0 {
                        format!(
                            "largest momentum imbalance {:.3e} of the applied impulse",
                            f("max_momentum_imbalance_relative")
                        )
                    } else {
                        format!(
                            "largest momentum residual {:.3e} of the largest impulse or gross momentum",
                            f("max_momentum_residual_relative")
                        )
                    };
                    let energy = format!(
                        "largest energy residual {:+.3e} of the largest energy or work",
                        f("max_energy_residual_relative")
                    );
                    println!(
                        "cosim: {} finished: {} windows in {:.2} s; {balance}; {energy}; output in {}",
                        c.run.name,
                        o.summary["windows"],
                        o.summary["wall_s"].as_f64().unwrap_or(0.0),
                        o.output.display()
                    );
                    0
                }
                Ok(Err(f)) => {
                    eprintln!("cosim: {f}");
                    1
                }
                Err(e) => {
                    eprintln!("cosim: {e:#}");
                    1
                }
            }
        }
        Cmd::Clean => {
            let r = protocol::transport::shm::cleanup_stale_runs();
            println!(
                "cosim clean: removed {} shared-memory files of {} ended runs; {} running runs left alone",
                r.files, r.runs, r.live
            );
            0
        }
        Cmd::Info { recording } => match replay::info(&recording) {
            Ok(s) => {
                print!("{s}");
                0
            }
            Err(e) => {
                eprintln!("cosim: {e:#}");
                1
            }
        },
        Cmd::Replay {
            recording,
            node,
            sets,
            solver,
            run_id,
            output,
            tolerance,
            report,
            plot,
        } => {
            let opts = replay::ReplayOptions {
                sets,
                solver,
                tolerance,
                run_id,
                output,
            };
            match replay::replay(&recording, &node, &opts) {
                Ok(r) => {
                    print_replay(&r, &node, &opts.sets, report.as_deref());
                    if let Some(dir) = plot {
                        match replay::plot(&r, &node, &dir) {
                            Ok(files) => println!("{} charts in {}", files.len(), dir.display()),
                            Err(e) => {
                                eprintln!("cosim replay: plots: {e:#}");
                                return 1;
                            }
                        }
                    }
                    if r.incomplete.is_empty() { 0 } else { 1 }
                }
                Err(e) => {
                    eprintln!("cosim replay: {e:#}");
                    1
                }
            }
        }
        Cmd::Bench { args } => bench(&args),
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

fn print_replay(
    r: &replay::ReplayReport,
    node: &str,
    sets: &[String],
    csv: Option<&std::path::Path>,
) {
    use std::fmt::Write;
    println!(
        "replayed node '{node}' ({}, model {}){}: {} of {} recorded windows compared, {} fields ({} values) and {} report values",
        r.exe.display(),
        r.model,
        if sets.is_empty() {
            String::new()
        } else {
            format!(" with {}", sets.join(", "))
        },
        r.windows,
        r.recorded_windows,
        r.fields_compared,
        r.values_compared,
        r.report_values_compared,
    );
    if r.bit_identical() {
        println!("outputs are bit-identical to the recording");
    } else if r.all_equal {
        println!("every compared value is equal, but the comparison is incomplete");
    } else {
        let differ = r.rows.iter().filter(|row| !row.3.identical).count();
        let sdiffer = r
            .scalars
            .iter()
            .filter(|s| s.2.to_bits() != s.3.to_bits())
            .count();
        println!(
            "outputs differ: {differ} of {} fields, {sdiffer} of {} report values",
            r.rows.len(),
            r.scalars.len()
        );
        // Per-window difference report: the largest difference over all fields of a window.
        let mut per: std::collections::BTreeMap<u64, (f64, f64)> = Default::default();
        for (k, _, _, d) in &r.rows {
            let e = per.entry(*k).or_default();
            e.0 = e.0.max(d.max_abs);
            e.1 = e.1.max(d.max_rel);
        }
        let stride = (per.len() / 20).max(1);
        println!(
            "{:>8} {:>14} {:>14}",
            "window", "max |diff|", "max rel diff"
        );
        for (i, (k, (a, rel))) in per.iter().enumerate() {
            if i % stride == 0 || i + 1 == per.len() {
                println!("{k:>8} {a:>14.4e} {rel:>14.4e}");
            }
        }
    }
    if let Some((k, f, d)) = &r.drift {
        eprintln!(
            "warning: replay is open-loop and the interface motion drifted: {f} differs by {d:.3e} (relative) at window {k}; recorded peer inputs no longer match this node's motion"
        );
    }
    if let Some(p) = csv {
        let mut s = String::from("window,coupling,field,max_abs,max_rel,identical\n");
        for (k, c, f, d) in &r.rows {
            let _ = writeln!(
                s,
                "{k},{c},{f},{:e},{:e},{}",
                d.max_abs, d.max_rel, d.identical
            );
        }
        for (k, n, v, rec) in &r.scalars {
            let _ = writeln!(
                s,
                "{k},scalar,{n},{:e},{:e},{}",
                (v - rec).abs(),
                if *rec != 0.0 {
                    (v - rec).abs() / rec.abs()
                } else {
                    (v - rec).abs()
                },
                v.to_bits() == rec.to_bits()
            );
        }
        if let Err(e) = std::fs::write(p, s) {
            eprintln!("cosim replay: cannot write {}: {e}", p.display());
        }
    }
    if !r.incomplete.is_empty() {
        eprintln!("cosim replay: INCOMPLETE, not every recorded output could be compared:");
        // The first few say why; the rest are counted.
        for why in r.incomplete.iter().take(10) {
            eprintln!("  {why}");
        }
        if r.incomplete.len() > 10 {
            eprintln!("  ... and {} more", r.incomplete.len() - 10);
        }
    }
}
