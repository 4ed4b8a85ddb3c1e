//! The `cosim` command line: run, validate, info, clean, replay, plot, and bench (which runs
//! the `cosim-bench` executable).

use crate::case::{load_variant, load_variant_text};
use crate::{case, replay, run};
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
    Run {
        case: PathBuf,
        /// Output directory (default: the case's run.output).
        #[arg(long, short)]
        output: Option<PathBuf>,
        /// Run id (namespaces shared memory and topics; default: name-pid-time).
        #[arg(long)]
        run_id: Option<String>,
        /// Override a node parameter: NODE.KEY=VALUE (NODE.params.KEY for a parameter named
        /// model, solver or remote); swap a node's model or executable: NODE.model=NAME,
        /// NODE.solver=EXE; a run setting: run.KEY=VALUE; a coupling's:
        /// couplings.NAME.KEY=VALUE (repeatable; applied after the variant's).
        #[arg(long = "set")]
        sets: Vec<String>,
        /// Run a named variant of the case (its `[variants.NAME]` settings); the output goes
        /// to `<run.output>/<NAME>` unless the variant sets `run.output`.
        #[arg(long)]
        variant: Option<String>,
        /// Replace the results of an earlier run in the output directory (they are deleted
        /// first; the folders of other variants inside it are kept). Without it, an output
        /// directory holding anything but such folders is refused. A directory a run is still
        /// writing into is refused either way (it holds that run's lock, .cosim.lock).
        #[arg(long, conflicts_with = "restart")]
        overwrite: bool,
        /// Continue the run in this directory from its last checkpoint complete on every
        /// node (written with run.checkpoint_every); the case must match the run's nodes,
        /// parameters, window and couplings (its end time may grow).
        #[arg(long, value_name = "RUN_DIR")]
        restart: Option<PathBuf>,
    },
    /// Continue the run in RUN_DIR from its last checkpoint complete on every node, with the
    /// case as it ran. A run that finished is continued only to a later end time
    /// (`--set run.end_time=T`). The recording goes on in run.1.mcap, run.2.mcap, ...; each
    /// node's log goes on in RUN_DIR/NODE.log after a line marking the restart.
    Restart {
        run_dir: PathBuf,
        /// Change the case as it ran before continuing it: run.KEY=VALUE (e.g.
        /// run.end_time=2e-3); what a checkpoint depends on (nodes, parameters, window,
        /// couplings) must stay as it was (repeatable).
        #[arg(long = "set")]
        sets: Vec<String>,
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
        /// Print the result as one JSON document on stdout: `{"ok": true, "nodes": [...],
        /// "variants": [...]}` or `{"ok": false, "key": "nodes.gas.params...", "reason": ...}`
        /// (the exit codes are the same).
        #[arg(long)]
        json: bool,
    },
    /// Summarise a recording (RUN.mcap, or the run's output folder), after checking its bytes:
    /// a file that is not MCAP is "not a recording", one that fails its chunk or section CRCs
    /// is "corrupt at byte N" (both exit 1); one cut short by a killed run reads as
    /// INCOMPLETE, as far as its complete chunks go.
    Info {
        recording: PathBuf,
        /// Print the summary as one JSON document (nodes, couplings, windows, channels, the
        /// last balance row).
        #[arg(long)]
        json: bool,
    },
    /// Draw the run's fields at one time into a PNG (every node's VTK frame nearest it): the
    /// gas pressure with the solids over it, or the solids' deformed surfaces coloured by
    /// plastic strain and their particles by damage. `cosim run` draws the last frames into
    /// RUN/fields.png, and each node alone into RUN/fields_<node>.png.
    Render {
        /// The run's output folder.
        run: PathBuf,
        /// Simulated time (s) to draw (default: the last frames).
        #[arg(long, conflicts_with_all = ["all", "gif"])]
        time: Option<f64>,
        /// Colour NODE by one of its VTK fields (NODE.FIELD, e.g. gas.density, bar.velocity).
        #[arg(long)]
        field: Option<String>,
        /// Draw this node alone (its name as in the case, e.g. bar).
        #[arg(long, conflicts_with = "per_node")]
        node: Option<String>,
        /// Draw each node alone, one picture (or series, or GIF) per node:
        /// RUN/fields_<node>.png, RUN/frames/<node>_<k>.png, RUN/<node>.gif.
        #[arg(long)]
        per_node: bool,
        /// Every written frame: RUN/frames/fields_<k>.png (or <node>_<k>.png), k from 0.
        #[arg(long, conflicts_with = "gif")]
        all: bool,
        /// Every written frame as one animated GIF: RUN/fields.gif (or RUN/<node>.gif).
        #[arg(long)]
        gif: bool,
        /// Milliseconds per GIF frame.
        #[arg(long, default_value_t = 125, requires = "gif")]
        frame_ms: u32,
        /// The PNG (or GIF) file (default: RUN/fields.png, RUN/fields_<time>.png with --time,
        /// RUN/fields.gif with --gif).
        #[arg(long, short, conflicts_with_all = ["all", "per_node"])]
        output: Option<PathBuf>,
    },
    /// Write a run's per-window histories (every node's report and the balance) as arrays:
    /// `npz` (numpy: `np.load(F)["gas/probe1.pressure"]`), `csv` or `parquet` (one file per
    /// node: `pandas.read_parquet("RUN/history/gas.parquet")`).
    Export {
        /// The run's output folder or its recording.
        run: PathBuf,
        #[arg(long, default_value = "npz", value_parser = ["npz", "csv", "parquet"])]
        format: String,
        /// Output file (npz) or directory (csv, parquet); default: RUN/history.npz or
        /// RUN/history/.
        #[arg(long, short)]
        output: Option<PathBuf>,
        /// Only these series: NODE/KEY with `*` as a wildcard, or NODE for all of its keys
        /// (`balance` is the coordinator's); repeatable or comma-separated.
        #[arg(long, value_delimiter = ',')]
        series: Vec<String>,
        /// Also write the interface fields of every coupling message to RUN/fields.npz
        /// (COUPLING/SENDER/FIELD as (messages, points, components), with .window and .time).
        #[arg(long)]
        fields: bool,
    },
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
    Replay {
        /// RUN.mcap, or the run's output folder.
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
        /// Directory for the node's log and output (default: replay-NODE beside the
        /// recording). A folder holding a run's results (its run.mcap or summary.json) is
        /// refused: the replayed node's log and frames would overwrite the run's own.
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
        #[arg(long = "series", required_unless_present = "field")]
        series: Vec<String>,
        /// Instead of time histories, a picture of a field: NODE.FIELD of the node's VTK
        /// frames (e.g. gas.pressure, bar.damage), per run, at `--at` (default the end).
        #[arg(long, conflicts_with_all = ["series", "x"])]
        field: Option<String>,
        /// Simulated time (s) of the field picture (the frame nearest it).
        #[arg(long, requires = "field")]
        at: Option<f64>,
        /// Directory for the PNG files.
        #[arg(long, short, default_value = "plots")]
        output: PathBuf,
        /// NODE.QUANTITY for the horizontal axis instead of time (e.g. a displacement, for a
        /// force–displacement curve).
        #[arg(long)]
        x: Option<String>,
    },
    /// The parameters of a model (key, type, default, meaning; SI units), from the JSON Schema
    /// its node executable derives from the types it decodes them into; without a model, the
    /// models of the built-in nodes.
    Params {
        /// A model: bar-1d, fem-2d, pd-bond, pd-correspondence, pd-rk-ba, euler, blt-shell,
        /// mc-spg, or one of `--solver`'s.
        model: Option<String>,
        /// Print the JSON Schema itself (for editors and tools) instead of the listing.
        #[arg(long)]
        json: bool,
        /// Ask this node executable instead of the built-in ones (one that supports --schema).
        #[arg(long)]
        solver: Option<PathBuf>,
    },
    /// Print the JSON Schema (draft 2020-12) of case files, the one in docs/schema/case.json,
    /// for tools and editors that check TOML against a JSON Schema.
    Schema,
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

/// Make `out` ready for a new run: absent or empty is fine; with `overwrite`, whatever an
/// earlier run left there is deleted (folders holding runs of their own — other variants —
/// are kept); without it, anything there but such folders is refused, so that two runs'
/// results (VTK series, logs, plots) never mix.
fn prepare_output(out: &std::path::Path, overwrite: bool) -> Result<(), String> {
    let Ok(entries) = std::fs::read_dir(out) else {
        return Ok(());
    };
    let mut stale = Vec::new();
    for e in entries.flatten() {
        let p = e.path();
        // The lock this process holds on the folder is not a result.
        if e.file_name() == crate::lock::LOCK_FILE {
            continue;
        }
        if !(p.is_dir() && crate::lock::holds_a_run(&p)) {
            stale.push(p);
        }
    }
    if stale.is_empty() {
        return Ok(());
    }
    if !overwrite {
        return Err(format!(
            "{} already holds results ({} entries, e.g. {}): add --overwrite to replace them, or --output DIR for a new folder",
            out.display(),
            stale.len(),
            stale[0]
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        ));
    }
    for p in stale {
        let r = if p.is_dir() && !p.is_symlink() {
            std::fs::remove_dir_all(&p)
        } else {
            std::fs::remove_file(&p)
        };
        r.map_err(|e| format!("--overwrite: cannot remove {}: {e}", p.display()))?;
    }
    Ok(())
}

/// A run folder stands for its recording (`cosim plot` takes either, so do `info` and
/// `replay`).
fn recording_of(path: &std::path::Path) -> PathBuf {
    if path.is_dir() {
        path.join("run.mcap")
    } else {
        path.to_path_buf()
    }
}

/// `cosim validate`: the case (and every variant when neither a variant nor overrides are
/// given) checked without starting anything; exit 2 naming the key of the first error.
fn validate(case: &std::path::Path, variant: Option<&str>, sets: &[String], json: bool) -> i32 {
    use serde_json::json;
    let refuse = |e: &case::ConfigError, variant: Option<&str>| {
        if json {
            println!(
                "{}",
                json!({ "ok": false, "case": case, "variant": variant, "key": e.key, "reason": e.reason })
            );
        } else {
            match variant {
                Some(v) => eprintln!("cosim: {} (variant {v}): {e}", case.display()),
                None => eprintln!("cosim: {}: {e}", case.display()),
            }
        }
        2
    };
    let c = match load_variant(case, variant, sets) {
        Ok(c) => c,
        Err(e) => return refuse(&e, variant),
    };
    let windows = |c: &case::Case| ((c.run.end_time / c.run.window) - 1e-9).ceil();
    let order = case::window_order(&c).unwrap_or_default();
    let mut doc = json!({
        "ok": true, "case": case, "variant": variant, "nodes": [], "variants": [],
        "couplings": c.couplings.len(), "windows": windows(&c), "order": order,
        "warnings": c.warnings,
    });
    if !json {
        println!(
            "{}: ok — {} nodes, {} couplings, {} windows, order {}",
            case.display(),
            c.nodes.len(),
            c.couplings.len(),
            windows(&c),
            order.join(" → ")
        );
        for w in &c.warnings {
            println!("  warning: {w}");
        }
    }
    for n in &c.nodes {
        if let Some(a) = doc["nodes"].as_array_mut() {
            a.push(json!({
                "name": n.name, "solver": n.solver, "model": n.model,
                "remote": n.interfaces.is_none(), "interfaces": n.interfaces,
            }));
        }
        if json {
            continue;
        }
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
        match load_variant(case, Some(v), &[]) {
            Ok(cv) => {
                if let Some(a) = doc["variants"].as_array_mut() {
                    a.push(json!({ "name": v, "windows": windows(&cv), "output": cv.run.output }));
                }
                if !json {
                    println!(
                        "  variant {v}: ok — {} windows, output {}",
                        windows(&cv),
                        cv.run.output.display()
                    );
                }
            }
            Err(e) => return refuse(&e, Some(v)),
        }
    }
    if json {
        println!("{doc}");
    }
    0
}

/// Run the command line; returns the exit code.
pub fn main_with(cli: Cli) -> i32 {
    match cli.cmd {
        Cmd::Params {
            model,
            json,
            solver,
        } => {
            let shown = match &model {
                None => crate::params::models(solver.as_deref()).map(|all| {
                    if json {
                        let v: Vec<serde_json::Value> = all
                            .iter()
                            .map(|(m, e)| serde_json::json!({ "model": m, "solver": e }))
                            .collect();
                        serde_json::Value::Array(v).to_string()
                    } else {
                        let mut s = String::from("model               solver\n");
                        for (m, e) in &all {
                            s += &format!("{m:<20}{e}\n");
                        }
                        s + "cosim params MODEL lists a model's parameters"
                    }
                }),
                Some(m) => crate::params::schema(m, solver.as_deref()).map(|(v, exe)| {
                    if json {
                        serde_json::to_string_pretty(&v).unwrap_or_default()
                    } else {
                        crate::params::table(m, &exe, &crate::params::rows(&v))
                    }
                }),
            };
            match shown {
                Ok(s) => {
                    println!("{}", s.trim_end());
                    0
                }
                Err(e) => {
                    eprintln!("cosim params: {e:#}");
                    2
                }
            }
        }
        Cmd::Schema => match serde_json::to_string_pretty(&case::parse::schema()) {
            Ok(text) => {
                println!("{text}");
                0
            }
            Err(e) => {
                eprintln!("cosim: {e}");
                1
            }
        },
        Cmd::Completions { shell } => {
            use clap::CommandFactory;
            clap_complete::generate(shell, &mut Cli::command(), "cosim", &mut std::io::stdout());
            0
        }
        Cmd::Render {
            run,
            time,
            field,
            node,
            per_node,
            all,
            gif,
            frame_ms,
            output,
        } => {
            let nodes: Vec<Option<String>> = if per_node {
                crate::fields::nodes_with_series(&run)
                    .into_iter()
                    .map(Some)
                    .collect()
            } else {
                vec![node]
            };
            let drawn = field
                .as_deref()
                .map(crate::fields::Choice::parse)
                .transpose()
                .and_then(|choice| {
                    let mut list = Vec::new();
                    for node in &nodes {
                        let node = node.as_deref();
                        let stem = node.unwrap_or("fields");
                        if all {
                            list.extend(crate::fields::render_all(&run, choice, node)?);
                        } else if gif {
                            let file = output
                                .clone()
                                .unwrap_or_else(|| run.join(format!("{stem}.gif")));
                            let (n, t) =
                                crate::fields::render_gif(&run, &file, choice, node, frame_ms)?;
                            eprintln!("{}: {n} frames", file.display());
                            list.push((file, t));
                        } else {
                            let png = output.clone().unwrap_or_else(|| match (time, node) {
                                (Some(t), None) => run.join(format!("fields_{t:e}.png")),
                                (Some(t), Some(n)) => run.join(format!("fields_{n}_{t:e}.png")),
                                (None, None) => run.join("fields.png"),
                                (None, Some(n)) => run.join(format!("fields_{n}.png")),
                            });
                            let t = crate::fields::render(&run, time, &png, choice, node)?;
                            list.push((png, t));
                        }
                    }
                    if list.is_empty() {
                        anyhow::bail!("{}: no node wrote a VTK series", run.display());
                    }
                    Ok(list)
                });
            match drawn {
                Ok(list) => {
                    for (png, t) in list {
                        println!("{} (t = {t:e} s)", png.display());
                    }
                    0
                }
                Err(e) => {
                    eprintln!("cosim render: {e:#}");
                    1
                }
            }
        }
        Cmd::Export {
            run,
            format,
            output,
            series,
            fields,
        } => {
            let rec = recording_of(&run);
            let base = if run.is_dir() {
                run.clone()
            } else {
                run.parent().map(PathBuf::from).unwrap_or_default()
            };
            let done = crate::export::tables(&rec).and_then(|mut t| {
                crate::export::filter(&mut t, &series)?;
                let mut note = String::new();
                if fields {
                    let (f, ragged) = crate::export::field_series(&rec)?;
                    let path = base.join("fields.npz");
                    let n = crate::export::write_fields_npz(&f, &path)?;
                    note = format!("; {n} interface fields in {}", path.display());
                    if !ragged.is_empty() {
                        note += &format!(
                            " (left out, their point count changes between messages: {})",
                            ragged.join(", ")
                        );
                    }
                }
                if format == "csv" || format == "parquet" {
                    let dir = output.unwrap_or_else(|| base.join("history"));
                    let files = if format == "csv" {
                        crate::export::write_csv(&t, &dir)?
                    } else {
                        crate::export::write_parquet(&t, &dir)?
                    };
                    Ok(format!("{} tables in {}{note}", files.len(), dir.display()))
                } else {
                    let f = output.unwrap_or_else(|| base.join("history.npz"));
                    let n = crate::export::write_npz(&t, &f)?;
                    Ok(format!("{n} arrays in {}{note}", f.display()))
                }
            });
            match done {
                Ok(s) => {
                    println!("{s}");
                    0
                }
                Err(e) => {
                    eprintln!("cosim export: {e:#}");
                    1
                }
            }
        }
        Cmd::Plot {
            runs,
            field: Some(field),
            at,
            output,
            ..
        } => {
            let drawn = crate::fields::Choice::parse(&field).and_then(|choice| {
                std::fs::create_dir_all(&output)
                    .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", output.display()))?;
                let mut out = Vec::new();
                for run in &runs {
                    let dir = if run.is_dir() {
                        run.clone()
                    } else {
                        run.parent().map(PathBuf::from).unwrap_or_default()
                    };
                    let name = dir
                        .file_name()
                        .map(|n| n.to_string_lossy().into_owned())
                        .unwrap_or_else(|| "run".into());
                    let at_name = at.map(|t| format!("_{t:e}")).unwrap_or_default();
                    let png = output.join(format!(
                        "{name}_{}{at_name}.png",
                        crate::plot::file_stem(&field)
                    ));
                    let t = crate::fields::render(&dir, at, &png, Some(choice), None)?;
                    out.push((png, t));
                }
                Ok(out)
            });
            match drawn {
                Ok(list) => {
                    for (png, t) in list {
                        println!("{} (t = {t:e} s)", png.display());
                    }
                    0
                }
                Err(e) => {
                    eprintln!("cosim plot: {e:#}");
                    1
                }
            }
        }
        Cmd::Plot {
            runs,
            series,
            output,
            x,
            ..
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
            json,
        } => validate(&case, variant.as_deref(), &sets, json),
        Cmd::Run {
            case,
            output,
            run_id,
            sets,
            variant,
            overwrite,
            restart,
        } => {
            let c = match load_variant(&case, variant.as_deref(), &sets) {
                Ok(c) => c,
                Err(e) => {
                    eprintln!("cosim: {}: {e}", case.display());
                    return 2;
                }
            };
            // Held until the run ends: no other cosim writes into the folder meanwhile.
            let folder = restart
                .clone()
                .or_else(|| output.clone())
                .unwrap_or_else(|| c.run.output.clone());
            let _lock = match crate::lock::acquire(&folder, &crate::lock::command_line()) {
                Ok(l) => l,
                Err(e) => {
                    eprintln!("cosim: {e}");
                    return 2;
                }
            };
            let (restart, output) = match restart {
                None => {
                    if let Err(e) = prepare_output(&folder, overwrite) {
                        eprintln!("cosim: {e}");
                        return 2;
                    }
                    (None, output)
                }
                Some(dir) => match restart_state(&c, &dir) {
                    Ok(st) => (Some(st), Some(dir)),
                    Err(e) => {
                        eprintln!("cosim: --restart {}: {e:#}", dir.display());
                        return 2;
                    }
                },
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
                quiet: cli.quiet,
                restart,
            };
            run_case(&c, &opts)
        }
        Cmd::Restart { run_dir, sets } => {
            let _lock = match crate::lock::acquire(&run_dir, &crate::lock::command_line()) {
                Ok(l) => l,
                Err(e) => {
                    eprintln!("cosim restart: {e}");
                    return 2;
                }
            };
            let (st, skipped) = match crate::checkpoint::latest(&run_dir) {
                Ok(x) => x,
                Err(e) => {
                    eprintln!("cosim restart: {e:#}");
                    return 2;
                }
            };
            for s in skipped {
                eprintln!("cosim restart: skipped the checkpoint of {s}");
            }
            let c = match load_variant_text(
                &st.case_text,
                std::path::Path::new(&st.case_path),
                None,
                &sets,
            ) {
                Ok(c) => c,
                Err(e) => {
                    eprintln!("cosim restart: the run's case ({}): {e}", st.case_path);
                    return 2;
                }
            };
            if let Err(e) = crate::checkpoint::check_not_finished(&run_dir, &c)
                .and_then(|()| crate::checkpoint::check_compatible(&c, &st))
            {
                eprintln!("cosim restart: {e}");
                return 2;
            }
            let opts = run::RunOptions {
                run_id: None,
                output: Some(run_dir),
                quiet: cli.quiet,
                restart: Some(st),
            };
            run_case(&c, &opts)
        }
        Cmd::Clean => {
            let r = protocol::transport::shm::cleanup_stale_runs();
            println!(
                "cosim clean: removed {} shared-memory files of {} ended runs; {} running runs left alone",
                r.files, r.runs, r.live
            );
            0
        }
        Cmd::Info { recording, json } => match if json {
            replay::run_info(&recording_of(&recording))
                .and_then(|i| Ok(serde_json::to_string_pretty(&i)? + "\n"))
        } else {
            replay::info(&recording_of(&recording))
        } {
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
            match replay::replay(&recording_of(&recording), &node, &opts) {
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
                    r.exit_code()
                }
                Err(e) => {
                    eprintln!("cosim replay: {e:#}");
                    1
                }
            }
        }
        Cmd::Bench { args } => bench(&args),
        Cmd::Conformance(args) => conformance(args),
    }
}

/// `cosim conformance`'s command line.
#[derive(Debug, clap::Args)]
pub struct ConformanceArgs {
    /// The model inside the executable, as in a case's `nodes.NAME.model`.
    #[arg(long)]
    model: String,
    /// The node's parameters: a TOML file holding the body of `[nodes.NAME.params]`.
    #[arg(long)]
    params: Option<PathBuf>,
    /// The interface to couple (default: the first the node describes).
    #[arg(long)]
    interface: Option<String>,
    /// The coupling kind: kinematic or immersed.
    #[arg(long, default_value = "kinematic")]
    kind: String,
    /// The node's role, driver or responder; cosim plays the other.
    #[arg(long, default_value = "responder")]
    role: String,
    /// Windows to run after the set-up (a checkpoint is asked in the one before the last).
    #[arg(long, default_value_t = 4)]
    windows: u64,
    /// The window (s); default: the node's stable step.
    #[arg(long)]
    window: Option<f64>,
    /// Directory for the node's log, output and checkpoint (default: a fresh one under
    /// the system's temporary directory).
    #[arg(long, short)]
    output: Option<PathBuf>,
    /// The node's command: an executable (a path, or a name beside cosim) and its own
    /// arguments.
    #[arg(required = true, last = true)]
    command: Vec<String>,
}

/// `cosim conformance`: check the node, print a line per rule; returns the exit code.
fn conformance(a: ConformanceArgs) -> i32 {
    use crate::conformance::{self, Options};
    use protocol::{CouplingKind, Role};
    let kind = match a.kind.as_str() {
        "kinematic" => CouplingKind::Kinematic,
        "immersed" => CouplingKind::Immersed,
        k => {
            eprintln!("cosim conformance: --kind {k}: kinematic or immersed");
            return 2;
        }
    };
    let role = match a.role.as_str() {
        "driver" => Role::Driver,
        "responder" => Role::Responder,
        r => {
            eprintln!("cosim conformance: --role {r}: driver or responder");
            return 2;
        }
    };
    let params = match &a.params {
        None => toml::Table::new(),
        Some(p) => match std::fs::read_to_string(p)
            .map_err(|e| e.to_string())
            .and_then(|t| toml::from_str::<toml::Table>(&t).map_err(|e| e.to_string()))
        {
            Ok(t) => t,
            Err(e) => {
                eprintln!("cosim conformance: --params {}: {e}", p.display());
                return 2;
            }
        },
    };
    if a.windows < 2 {
        eprintln!("cosim conformance: --windows must be at least 2 (one holds the checkpoint)");
        return 2;
    }
    let output = a.output.unwrap_or_else(|| {
        std::env::temp_dir().join(crate::launch::pick_run_id("cosim-conformance"))
    });
    let o = Options {
        command: a.command,
        model: a.model,
        params,
        interface: a.interface,
        kind,
        role,
        windows: a.windows,
        window: a.window,
        output,
    };
    println!(
        "cosim conformance: `{}` (model {}) as the {} {} node, {} windows; its log: {}",
        o.command.join(" "),
        o.model,
        a.kind,
        a.role,
        o.windows,
        o.output.join("node.log").display()
    );
    match conformance::check(&o) {
        Ok(verdicts) => {
            for v in &verdicts {
                println!("{v}");
            }
            let passed = verdicts
                .iter()
                .filter(|v| v.outcome == conformance::Outcome::Pass)
                .count();
            println!("{passed} of {} rules pass", verdicts.len());
            if conformance::all_pass(&verdicts) {
                0
            } else {
                1
            }
        }
        Err(e) => {
            eprintln!("cosim conformance: {e:#}");
            1
        }
    }
}

/// The state to continue the run in `dir` from with case `c`: its last complete checkpoint,
/// if the case may continue it.
fn restart_state(
    c: &case::Case,
    dir: &std::path::Path,
) -> anyhow::Result<crate::checkpoint::CoordState> {
    crate::checkpoint::check_not_finished(dir, c).map_err(|e| anyhow::anyhow!(e))?;
    let (st, skipped) = crate::checkpoint::latest(dir)?;
    for s in skipped {
        eprintln!("cosim: skipped the checkpoint of {s}");
    }
    crate::checkpoint::check_compatible(c, &st).map_err(|e| anyhow::anyhow!(e))?;
    Ok(st)
}

/// Run (or continue) a case with stop signals handled; returns the exit code.
fn run_case(c: &case::Case, opts: &run::RunOptions) -> i32 {
    // Ctrl-C and SIGTERM stop the run at the next window boundary (a second Ctrl-C at
    // once), with the recording finalised and shared memory removed.
    if let Err(e) = protocol::stop::install(&[libc::SIGINT, libc::SIGTERM]) {
        eprintln!("cosim: cannot handle stop signals: {e}");
    }
    for w in &c.warnings {
        eprintln!("cosim: warning: {w}");
    }
    match run::run(c, opts) {
        Ok(Ok(o)) if o.diverged.is_some() => {
            if let Some(d) = &o.diverged {
                eprintln!(
                    "cosim: {} diverged: {d}; output in {}",
                    c.run.name,
                    o.output.display()
                );
            }
            crate::guard::EXIT_DIVERGED
        }
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
            for w in o.summary["warnings"].as_array().into_iter().flatten() {
                if let Some(w) = w.as_str().filter(|w| w.starts_with("balance: ")) {
                    eprintln!("cosim: warning: {w}");
                }
            }
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
