//! `cosim replay`: one node driven by its recorded inputs, and the report of how its outputs
//! compare with the recording.

use super::results::recording_of;
use crate::replay::{self, ReplayOptions, ReplayReport};
use std::path::{Path, PathBuf};

/// `cosim replay`'s command line.
#[derive(Debug, clap::Args)]
pub struct ReplayArgs {
    /// RUN.mcap, or the run's output folder.
    pub recording: PathBuf,
    #[arg(long)]
    pub node: String,
    /// Override a parameter of the node (KEY=VALUE, or model=NAME), repeatable.
    #[arg(long = "set")]
    pub sets: Vec<String>,
    /// Launch this executable instead of the recorded one (a path, or a name beside cosim).
    #[arg(long)]
    pub solver: Option<PathBuf>,
    /// Run id of the replay (namespaces its shared memory; default: a fresh one).
    #[arg(long)]
    pub run_id: Option<String>,
    /// Directory for the node's log and output (default: replay-NODE beside the
    /// recording). A folder holding a run's results (its run.mcap or summary.json) is
    /// refused: the replayed node's log and frames would overwrite the run's own.
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    /// Relative drift of the interface motion that triggers a warning.
    #[arg(long, default_value_t = 1e-6)]
    pub tolerance: f64,
    /// Write the per-window report as CSV here.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write PNG charts of the node's reported quantities, recorded against replayed,
    /// into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// `cosim replay`: returns the exit code (0 identical, 3 different, 1 incomplete or failed).
pub(super) fn replay(a: ReplayArgs) -> i32 {
    let opts = ReplayOptions {
        sets: a.sets,
        solver: a.solver,
        tolerance: a.tolerance,
        run_id: a.run_id,
        output: a.output,
    };
    let r = match replay::replay(&recording_of(&a.recording), &a.node, &opts) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("cosim replay: {e:#}");
            return 1;
        }
    };
    print_replay(&r, &a.node, &opts.sets, a.report.as_deref());
    if let Some(dir) = a.plot {
        match replay::plot(&r, &a.node, &dir) {
            Ok(files) => println!("{} charts in {}", files.len(), dir.display()),
            Err(e) => {
                eprintln!("cosim replay: plots: {e:#}");
                return 1;
            }
        }
    }
    r.exit_code()
}

/// The replay's result: what was compared, whether it matched (and where not), the drift
/// warning, what could not be compared; the per-window CSV report at `csv`.
fn print_replay(r: &ReplayReport, node: &str, sets: &[String], csv: Option<&Path>) {
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
        print_differences(r);
    }
    if let Some((k, f, d)) = &r.drift {
        eprintln!(
            "warning: replay is open-loop and the interface motion drifted: {f} differs by {d:.3e} (relative) at window {k}; recorded peer inputs no longer match this node's motion"
        );
    }
    if let Some(p) = csv
        && let Err(e) = std::fs::write(p, report_csv(r))
    {
        eprintln!("cosim replay: cannot write {}: {e}", p.display());
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

/// How many fields and report values differ, and the largest difference per window (about
/// 20 windows of them, the last always).
fn print_differences(r: &ReplayReport) {
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
    // The largest difference over all fields of a window.
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

/// The per-window report: one row per compared field and report value.
fn report_csv(r: &ReplayReport) -> String {
    use std::fmt::Write;
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
    s
}
