//! `cosim run` and `cosim restart`: a case loaded, its output folder locked and made ready (or
//! its checkpoint found), then the run with stop signals handled.

use crate::case::{self, load_variant, load_variant_text};
use crate::checkpoint::CoordState;
use std::path::{Path, PathBuf};

/// `cosim run`'s command line.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    pub case: PathBuf,
    /// Output directory (default: the case's run.output).
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    /// Run id (namespaces shared memory and topics; default: name-pid-time).
    #[arg(long)]
    pub run_id: Option<String>,
    /// Override a node parameter: NODE.KEY=VALUE (NODE.params.KEY for a parameter named
    /// model, solver or remote); swap a node's model or executable: NODE.model=NAME,
    /// NODE.solver=EXE; a run setting: run.KEY=VALUE; a coupling's:
    /// couplings.NAME.KEY=VALUE (repeatable; applied after the variant's).
    #[arg(long = "set")]
    pub sets: Vec<String>,
    /// Run a named variant of the case (its `[variants.NAME]` settings); the output goes
    /// to `<run.output>/<NAME>` unless the variant sets `run.output`.
    #[arg(long)]
    pub variant: Option<String>,
    /// Replace the results of an earlier run in the output directory (they are deleted
    /// first; the folders of other variants inside it are kept). Without it, an output
    /// directory holding anything but such folders is refused. A directory a run is still
    /// writing into is refused either way (it holds that run's lock, .cosim.lock).
    #[arg(long, conflicts_with = "restart")]
    pub overwrite: bool,
    /// Continue the run in this directory from its last checkpoint complete on every
    /// node (written with run.checkpoint_every); the case must match the run's nodes,
    /// parameters, window and couplings (its end time may grow).
    #[arg(long, value_name = "RUN_DIR")]
    pub restart: Option<PathBuf>,
}

/// `cosim restart`'s command line.
#[derive(Debug, clap::Args)]
pub struct RestartArgs {
    pub run_dir: PathBuf,
    /// Change the case as it ran before continuing it: run.KEY=VALUE (e.g.
    /// run.end_time=2e-3); what a checkpoint depends on (nodes, parameters, window,
    /// couplings) must stay as it was (repeatable).
    #[arg(long = "set")]
    pub sets: Vec<String>,
}

/// `cosim run`: returns the exit code.
pub(super) fn run(a: RunArgs, quiet: bool) -> i32 {
    let c = match load_variant(&a.case, a.variant.as_deref(), &a.sets) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("cosim: {}: {e}", a.case.display());
            return 2;
        }
    };
    // Held until the run ends: no other cosim writes into the folder meanwhile.
    let folder = a
        .restart
        .clone()
        .or_else(|| a.output.clone())
        .unwrap_or_else(|| c.run.output.clone());
    let _lock = match crate::lock::acquire(&folder, &crate::lock::command_line()) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("cosim: {e}");
            return 2;
        }
    };
    let (restart, output) = match a.restart {
        None => {
            if let Err(e) = prepare_output(&folder, a.overwrite) {
                eprintln!("cosim: {e}");
                return 2;
            }
            (None, a.output)
        }
        Some(dir) => match restart_state(&c, &dir) {
            Ok(st) => (Some(st), Some(dir)),
            Err(e) => {
                eprintln!("cosim: --restart {}: {e:#}", dir.display());
                return 2;
            }
        },
    };
    if let Some(id) = &a.run_id
        && !valid_run_id(id)
    {
        eprintln!("cosim: --run-id: must be 1–32 characters of [A-Za-z0-9_-], got '{id}'");
        return 2;
    }
    let opts = crate::run::RunOptions {
        run_id: a.run_id,
        output,
        quiet,
        restart,
    };
    run_case(&c, &opts)
}

/// A run id names shared-memory files and topics: 1–32 characters of `[A-Za-z0-9_-]`.
fn valid_run_id(id: &str) -> bool {
    !id.is_empty()
        && id.len() <= 32
        && id
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
}

/// `cosim restart`: returns the exit code.
pub(super) fn restart(a: RestartArgs, quiet: bool) -> i32 {
    let _lock = match crate::lock::acquire(&a.run_dir, &crate::lock::command_line()) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("cosim restart: {e}");
            return 2;
        }
    };
    let (st, skipped) = match crate::checkpoint::latest(&a.run_dir) {
        Ok(x) => x,
        Err(e) => {
            eprintln!("cosim restart: {e:#}");
            return 2;
        }
    };
    for s in skipped {
        eprintln!("cosim restart: skipped the checkpoint of {s}");
    }
    let c = match load_variant_text(&st.case_text, Path::new(&st.case_path), None, &a.sets) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("cosim restart: the run's case ({}): {e}", st.case_path);
            return 2;
        }
    };
    if let Err(e) = crate::checkpoint::check_not_finished(&a.run_dir, &c)
        .and_then(|()| crate::checkpoint::check_compatible(&c, &st))
    {
        eprintln!("cosim restart: {e}");
        return 2;
    }
    let opts = crate::run::RunOptions {
        run_id: None,
        output: Some(a.run_dir),
        quiet,
        restart: Some(st),
    };
    run_case(&c, &opts)
}

/// Make `out` ready for a new run: absent or empty is fine; with `overwrite`, whatever an
/// earlier run left there is deleted (folders holding runs of their own — other variants —
/// are kept); without it, anything there but such folders is refused, so that two runs'
/// results (VTK series, logs, plots) never mix.
fn prepare_output(out: &Path, overwrite: bool) -> Result<(), String> {
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

/// The state to continue the run in `dir` from with case `c`: its last complete checkpoint,
/// if the case may continue it.
fn restart_state(c: &case::Case, dir: &Path) -> anyhow::Result<CoordState> {
    crate::checkpoint::check_not_finished(dir, c).map_err(|e| anyhow::anyhow!(e))?;
    let (st, skipped) = crate::checkpoint::latest(dir)?;
    for s in skipped {
        eprintln!("cosim: skipped the checkpoint of {s}");
    }
    crate::checkpoint::check_compatible(c, &st).map_err(|e| anyhow::anyhow!(e))?;
    Ok(st)
}

/// Run (or continue) a case with stop signals handled; returns the exit code.
fn run_case(c: &case::Case, opts: &crate::run::RunOptions) -> i32 {
    // Ctrl-C and SIGTERM stop the run at the next window boundary (a second Ctrl-C at
    // once), with the recording finalised and shared memory removed.
    if let Err(e) = protocol::stop::install(&[libc::SIGINT, libc::SIGTERM]) {
        eprintln!("cosim: cannot handle stop signals: {e}");
    }
    for w in &c.warnings {
        eprintln!("cosim: warning: {w}");
    }
    match crate::run::run(c, opts) {
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
            print_finished(c, &o);
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

/// The line of a run that finished: its windows, wall time, balance and output; the
/// scalars `run.print` names, then the balance warnings, last.
fn print_finished(c: &case::Case, o: &crate::run::Outcome) {
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
    let warned: Vec<&str> = o.summary["warnings"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|w| w.as_str())
        .filter(|w| w.starts_with("balance: "))
        .collect();
    let with = match warned.len() {
        0 => String::new(),
        1 => " with a balance warning".to_string(),
        n => format!(" with {n} balance warnings"),
    };
    println!(
        "cosim: {} finished{with}: {} windows in {:.2} s; {balance}; {energy}; output in {}",
        c.run.name,
        o.summary["windows"],
        o.summary["wall_s"].as_f64().unwrap_or(0.0),
        o.output.display()
    );
    match crate::joints::collect(&o.output) {
        Ok(rows) if !rows.is_empty() => {
            println!("cosim: joints (joint_report.csv):");
            for l in crate::joints::lines(&rows) {
                println!("  {l}");
            }
        }
        Ok(_) => {}
        Err(e) => eprintln!("cosim: warning: joint report: {e}"),
    }
    for (node, scalar) in &c.run.print {
        // a named scalar of the node's report, or one of its energies
        let last = &o.summary["nodes"][node]["final"];
        match last["scalars"][scalar].as_f64().or(last[scalar].as_f64()) {
            Some(v) => println!("cosim: {node}.{scalar} = {v}"),
            None => println!("cosim: {node}.{scalar}: not in the node's last report"),
        }
    }
    // the balance warnings last, where a user reads first
    for w in warned {
        eprintln!("cosim: warning: {w}");
    }
}
