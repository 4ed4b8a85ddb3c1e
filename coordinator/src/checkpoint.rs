//! The coordinator's side of checkpoints and restarts (docs/architecture.md, PROTOCOL.md §7): its
//! own state at a checkpoint (audit accumulators, per-node totals, decouplings, histories),
//! the choice of the last checkpoint complete on every node, and the check that a case may
//! continue a run.

use crate::case::Case;
use crate::engine::audit::Audit;
use protocol::StepReport;
use protocol::checkpoint::{self as ckpt, Checkpoint};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// What the coordinator keeps of one node across windows.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct NodeState {
    pub name: String,
    pub model: String,
    pub params_hash: u64,
    pub stable_dt: f64,
    pub substeps: u64,
    pub wall_s: f64,
    pub wait_s: f64,
    pub idle_s: f64,
    pub report: StepReport,
    pub initial_energy: f64,
    pub initial_momentum: [f64; 3],
    pub finished: Option<u64>,
    pub warnings: Vec<String>,
    /// Joined from another host (`remote = true`): its checkpoint file is on that host.
    pub remote: bool,
}

/// The coordinator's state at the end of a checkpointed window: with the nodes' checkpoints,
/// everything a restart needs to continue bit-identically.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CoordState {
    pub run_id: String,
    pub case_path: String,
    /// The case as it ran (variant and `--set` applied): `cosim restart` runs it again.
    pub case_text: String,
    /// [`compat_signature`] of that case.
    pub signature: String,
    pub window: u64,
    pub time: f64,
    pub nodes: Vec<NodeState>,
    pub audit: Audit,
    /// Per coupling: (window before which, time, why) once decoupled.
    pub decoupled: Vec<Option<(u64, f64, String)>>,
    pub history: crate::plot::Histories,
    /// Wall time of the window loop up to the checkpoint, s.
    pub loop_s: f64,
    /// Each lagrange coupling's interface problem (its window and last multipliers).
    pub lagrange: Vec<protocol::scheme::lagrange::HubState>,
}

/// What must not change between a run and its restart: the nodes (names, models,
/// parameters), the window, the schedule and the couplings. The end time, output and
/// checkpoint cadence, transport and timeouts may.
pub fn compat_signature(case: &Case) -> String {
    let mut s = format!(
        "window={:016x};schedule={:?}",
        case.run.window.to_bits(),
        case.run.schedule
    );
    for n in &case.nodes {
        s.push_str(&format!(
            ";node {} {} {:016x}",
            n.name,
            n.model,
            ckpt::params_hash(&params_toml(n))
        ));
    }
    for c in &case.couplings {
        s.push_str(&format!(
            ";coupling {} {} {}.{} {}.{} {:?} {:?} {:?}",
            c.name,
            c.kind.as_str(),
            c.driver.0,
            c.driver.1,
            c.responder.0,
            c.responder.1,
            c.driver_fields,
            c.responder_fields,
            c.decouple
        ));
        // A lagrange coupling's sides and method fix the checkpointed multipliers' meaning.
        if protocol::scheme::of(c.kind).coordinator_solved() {
            s.push_str(&format!(" {:?} {:?}", c.sides, c.method));
        }
    }
    s
}

/// A node's parameters as its `Welcome` carries them.
pub fn params_toml(n: &crate::case::NodeConfig) -> String {
    toml::to_string(&n.params).unwrap_or_default()
}

/// Write the coordinator's state of `st.window` (after every node acknowledged its own).
pub fn save(run_dir: &Path, st: &CoordState) -> anyhow::Result<()> {
    let c = Checkpoint {
        node: ckpt::COORDINATOR.into(),
        model: "cosim".into(),
        window: st.window,
        time: st.time,
        params_hash: ckpt::fnv1a(st.signature.as_bytes()),
        sent: Vec::new(),
        payload: ckpt::encode_state(st).map_err(|e| anyhow::anyhow!("{e}"))?,
    };
    c.write(&ckpt::file(run_dir, st.window, ckpt::COORDINATOR))?;
    Ok(())
}

/// Why the checkpoint of one window cannot be used, or its coordinator state.
fn complete(run_dir: &Path, window: u64) -> Result<CoordState, String> {
    let c = Checkpoint::read(&ckpt::file(run_dir, window, ckpt::COORDINATOR))
        .map_err(|e| e.to_string())?;
    let st: CoordState = ckpt::decode_state(&c.payload).map_err(|e| e.to_string())?;
    if st.window != window || c.window != window {
        return Err(format!("coordinator state of window {}", st.window));
    }
    for n in &st.nodes {
        let p = ckpt::file(run_dir, window, &n.name);
        // A remote node writes its checkpoint on its own host (PROTOCOL.md §4.5): its
        // `Done` acknowledged it; it is checked here only where this host can see it.
        if n.remote && !p.exists() {
            continue;
        }
        let nc = Checkpoint::read(&p).map_err(|e| e.to_string())?;
        if nc.node != n.name
            || nc.model != n.model
            || nc.window != window
            || nc.params_hash != n.params_hash
        {
            return Err(format!(
                "{}: holds node '{}' ({}) of window {}, not '{}' ({}) of window {window}",
                p.display(),
                nc.node,
                nc.model,
                nc.window,
                n.name,
                n.model
            ));
        }
    }
    Ok(st)
}

/// The last checkpoint of `run_dir` complete on every node (and the coordinator), newest
/// first; the ones skipped and why are returned too, for the user.
pub fn latest(run_dir: &Path) -> anyhow::Result<(CoordState, Vec<String>)> {
    let mut skipped = Vec::new();
    let wins = ckpt::windows(run_dir);
    if wins.is_empty() {
        anyhow::bail!(
            "{}: no checkpoint (run with run.checkpoint_every = N to write them)",
            run_dir.join("checkpoints").display()
        );
    }
    for w in wins {
        match complete(run_dir, w) {
            Ok(st) => return Ok((st, skipped)),
            Err(why) => skipped.push(format!("window {w}: {why}")),
        }
    }
    anyhow::bail!(
        "{}: no complete checkpoint ({})",
        run_dir.join("checkpoints").display(),
        skipped.join("; ")
    )
}

/// Refuse to restart the run in `run_dir` when it finished and `case` ends no later: its
/// last checkpoint lies before the end, and continuing from it would only run its last
/// windows again. A run without a summary (killed) or stopped early may continue.
pub fn check_not_finished(run_dir: &Path, case: &Case) -> Result<(), String> {
    let Ok(text) = std::fs::read_to_string(run_dir.join("summary.json")) else {
        return Ok(());
    };
    let Ok(summary) = serde_json::from_str::<serde_json::Value>(&text) else {
        return Ok(());
    };
    if summary["status"] != "finished" {
        return Ok(());
    }
    let reached = summary["window_reached"].as_u64().unwrap_or(0);
    if crate::case::window_count(case) > reached {
        return Ok(());
    }
    let t = summary["time_reached"]
        .as_f64()
        .unwrap_or(case.run.end_time);
    Err(format!(
        "the run finished at t = {t:e} s (window {reached}); give a later end time with --set run.end_time=… to continue it"
    ))
}

/// Refuse to continue the run of `st` with `case` when it changed what the state depends on;
/// the error names what differs.
pub fn check_compatible(case: &Case, st: &CoordState) -> Result<(), String> {
    let now = compat_signature(case);
    if now == st.signature {
        let windows = crate::case::window_count(case);
        if st.window >= windows {
            return Err(format!(
                "the checkpoint is of window {}, the case ends after window {windows}: nothing to continue (raise run.end_time)",
                st.window
            ));
        }
        return Ok(());
    }
    let (a, b): (Vec<&str>, Vec<&str>) =
        (st.signature.split(';').collect(), now.split(';').collect());
    let mut diffs = Vec::new();
    for x in &a {
        if !b.contains(x) {
            diffs.push(format!("the run had {x}"));
        }
    }
    for x in &b {
        if !a.contains(x) {
            diffs.push(format!("the case has {x}"));
        }
    }
    // A node's params are hashed: name the node whose parameters changed.
    for n in &case.nodes {
        if let Some(old) = st.nodes.iter().find(|o| o.name == n.name)
            && old.params_hash != ckpt::params_hash(&params_toml(n))
        {
            diffs.push(format!("nodes.{}.params changed", n.name));
        }
    }
    Err(format!(
        "the case cannot continue this run: {}",
        diffs.join("; ")
    ))
}

/// The recording segment a restart writes: `run.1.mcap`, `run.2.mcap`, ... (the first free).
pub fn next_segment(run_dir: &Path) -> PathBuf {
    (1..)
        .map(|i| run_dir.join(format!("run.{i}.mcap")))
        .find(|p| !p.exists())
        .unwrap_or_else(|| run_dir.join("run.restart.mcap"))
}
