//! `cosim run`: a case from start to end, in the order a run takes: the output folder made
//! ready, the recording opened, the transport opened, the engine driven from launch to the
//! last window ([`crate::engine`]), everything closed whatever happened, and the summary
//! written with its plots and pictures (docs/architecture.md).

use crate::case::Case;
use crate::engine::summary::write_summary;
use crate::engine::{self, Closed};
pub use crate::engine::{Fault, RunOptions};
use crate::launch::{free_port, mark_restart, pick_run_id};
use crate::record::{self, Recorder, RecorderThread};
use anyhow::Context;
use protocol::stop;
use protocol::transport::{self, Transport, TransportKind, TransportSpec};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What a finished run reports.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub output: PathBuf,
    pub summary: serde_json::Value,
    /// The stop signal that ended the run early (summary status "interrupted").
    pub interrupted: Option<i32>,
    /// Why the run was stopped as diverged (summary status "diverged").
    pub diverged: Option<crate::guard::Diverged>,
}

/// Run a case to the end. On a fault the nodes are stopped, the recording is closed and the
/// fault returned; the caller prints it and exits non-zero.
pub fn run(case: &Case, opts: &RunOptions) -> anyhow::Result<Result<Outcome, Fault>> {
    let restart = opts.restart.as_ref();
    let run_id = opts
        .run_id
        .clone()
        .or_else(|| restart.map(|st| st.run_id.clone()))
        .unwrap_or_else(|| pick_run_id(&case.run.name));
    let out = opts
        .output
        .clone()
        .unwrap_or_else(|| case.run.output.clone());
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let segment = prepare_output(case, &out, restart)?;
    let rec = open_recording(case, &run_id, &segment, restart)?;
    let kind = case.run.transport;
    let (t, listen) = open_transport(case, &run_id)?;
    let mut c = engine::Coord::new(case, run_id.clone(), t, rec)?;
    let started = Instant::now();
    let outcome = engine::drive(&mut c, &out, &listen, opts);
    let wall = started.elapsed().as_secs_f64();
    let closed = c.close(outcome);
    transport::cleanup(kind, &run_id);
    report(case, &run_id, &out, &segment, restart, closed, wall)
}

/// The output folder `out` made ready, and the recording segment to write: a restart's next
/// segment (each local node's log marked where it continues), or a new run's `run.mcap`
/// with what an earlier run there left for restarts removed.
fn prepare_output(
    case: &Case,
    out: &Path,
    restart: Option<&crate::checkpoint::CoordState>,
) -> anyhow::Result<PathBuf> {
    Ok(match restart {
        // A restart continues the recording in the next segment (read as one run), and each
        // node's log after a line that marks where.
        Some(st) => {
            let segment = crate::checkpoint::next_segment(out);
            for n in case.nodes.iter().filter(|n| !n.remote) {
                mark_restart(&out.join(format!("{}.log", n.name)), st.window, &segment)?;
            }
            segment
        }
        None => {
            // A new run: what an earlier run in this directory left for restarts goes, and
            // the node logs a restart would have appended to.
            for p in record::segments(&out.join("run.mcap")).iter().skip(1) {
                std::fs::remove_file(p)
                    .with_context(|| format!("cannot remove {}", p.display()))?;
            }
            for n in &case.nodes {
                let log = out.join(format!("{}.log", n.name));
                match std::fs::remove_file(&log) {
                    Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                        return Err(e).with_context(|| format!("cannot remove {}", log.display()));
                    }
                    _ => {}
                }
            }
            let ck = out.join("checkpoints");
            if ck.exists() {
                std::fs::remove_dir_all(&ck)
                    .with_context(|| format!("cannot remove {}", ck.display()))?;
            }
            out.join("run.mcap")
        }
    })
}

/// The recording, on its own thread, opened with the case it records.
fn open_recording(
    case: &Case,
    run_id: &str,
    segment: &Path,
    restart: Option<&crate::checkpoint::CoordState>,
) -> anyhow::Result<RecorderThread> {
    let mut rec = Recorder::create(segment)?;
    let mut case_doc =
        json!({ "run": run_id, "case": case.path.display().to_string(), "toml": case.text });
    if let Some(st) = restart {
        case_doc["restart_from_window"] = json!(st.window);
    }
    rec.json("/cosim/case", "cosim.Case", 0.0, &case_doc)?;
    // On disk at once: a cosim killed before its first window leaves a recording that still
    // names its case (a chunk closes only on a flush).
    rec.flush()?;
    RecorderThread::spawn(rec)
}

/// The coordinator's end of the transport, with what earlier runs left swept, and the
/// endpoint remote nodes connect to.
fn open_transport(case: &Case, run_id: &str) -> anyhow::Result<(Box<dyn Transport>, String)> {
    let kind = case.run.transport;
    transport::cleanup(kind, run_id);
    // What earlier runs whose processes are all gone left in shared memory (a killed cosim).
    let swept = transport::shm::cleanup_stale_runs();
    if swept.files > 0 {
        tracing::info!(
            "removed {} shared-memory files of {} ended runs",
            swept.files,
            swept.runs
        );
    }
    let mut listen = case.run.listen.clone();
    if kind == TransportKind::Zenoh && listen.ends_with(":0") {
        listen = format!("{}{}", &listen[..listen.len() - 1], free_port()?);
    }
    let spec = TransportSpec {
        kind,
        run: run_id.to_string(),
        endpoint: "coordinator".into(),
        listen: if kind == TransportKind::Zenoh {
            vec![listen.clone()]
        } else {
            vec![]
        },
        connect: vec![],
    };
    let mut t = transport::open(&spec).context("cannot open the transport")?;
    // Nodes that joined from elsewhere watch this token: it goes when cosim dies.
    t.declare_alive()?;
    Ok((t, listen))
}

/// The plots and pictures of a run closed in `out`, listed in its `summary`. They are a
/// convenience: a failure to draw them is reported, not fatal. A run stopped on request exits
/// within the 2 s a scheduler allows and draws none (a crash tube's pictures take longer);
/// its restart draws them for the whole run.
fn draw(
    case: &Case,
    out: &Path,
    history: &crate::plot::Histories,
    interrupted: bool,
    summary: &mut serde_json::Value,
) {
    if interrupted {
        summary["plots"] = json!([]);
        summary["plots_skipped"] = json!("interrupted: the restart, or `cosim plot`, draws them");
        tracing::info!("no plots drawn: the run was interrupted");
        return;
    }
    // the default set: the balance, the energies, a chart per physical quantity, the
    // methods' counters (`cosim plot RUN --all` draws every quantity on its own)
    let rows = summary["balance"]["per_window"]
        .as_array()
        .cloned()
        .unwrap_or_default();
    let charts = crate::charts::curated(history, &crate::charts::balance_histories(&rows));
    match crate::charts::draw(&charts, &out.join("plots")) {
        Ok(files) => summary["plots"] = json!(files),
        Err(e) => tracing::warn!("plots of {}: {e:#}", out.display()),
    }
    let pictures = case.run.pictures;
    if pictures == crate::case::Pictures::None || !crate::fields::has_series(out) {
        return;
    }
    let png = out.join("fields.png");
    match crate::fields::render(out, None, &png, None, None, Default::default()) {
        Ok(_) => summary["fields"] = json!(png),
        Err(e) => tracing::warn!("fields picture of {}: {e:#}", out.display()),
    }
    // and each node alone where there are several (fields_<node>.png)
    match crate::fields::render_nodes(out) {
        Ok(files) => summary["node_fields"] = json!(files),
        Err(e) => tracing::warn!("node pictures of {}: {e:#}", out.display()),
    }
    // run.pictures = "frames": every written frame of each node alone
    if pictures == crate::case::Pictures::Frames {
        let mut files = Vec::new();
        for node in crate::fields::nodes_with_series(out) {
            match crate::fields::render_all(out, None, Some(&node), Default::default()) {
                Ok(list) => files.extend(list.into_iter().map(|(png, _)| png)),
                Err(e) => tracing::warn!("frames of node {node}: {e:#}"),
            }
        }
        summary["frame_pictures"] = json!(files.len());
    }
}

/// The summary of a closed run written to `out` (with its plots and pictures where it
/// finished), and the outcome the command reports; `wall`: the run's wall time, s.
fn report(
    case: &Case,
    run_id: &str,
    out: &Path,
    segment: &Path,
    restart: Option<&crate::checkpoint::CoordState>,
    closed: Closed,
    wall: f64,
) -> anyhow::Result<Result<Outcome, Fault>> {
    let Closed {
        outcome,
        interrupted,
        completed,
        diverged,
        history,
        messages,
        bytes,
    } = closed;
    match outcome {
        Ok(mut summary) => {
            summary["wall_s"] = json!(wall);
            summary["recording"] = json!({
                "path": out.join("run.mcap"), "segment": segment,
                "messages": messages, "bytes": bytes,
            });
            if let Some(st) = restart {
                summary["restarted_from_window"] = json!(st.window);
            }
            draw(case, out, &history, interrupted.is_some(), &mut summary);
            write_summary(out, &summary)?;
            Ok(Ok(Outcome {
                output: out.to_path_buf(),
                summary,
                interrupted,
                diverged: diverged.clone(),
            }))
        }
        Err(f) if interrupted.is_some() => {
            // Stopped at once (during set-up, or a second Ctrl-C): no window-boundary summary.
            let summary = json!({
                "run": run_id, "status": "interrupted",
                "signal": interrupted.map(stop::name),
                "window_reached": completed,
                "reason": f.reason, "wall_s": wall,
                "recording": { "path": out.join("run.mcap"), "messages": messages, "bytes": bytes },
            });
            write_summary(out, &summary)?;
            Ok(Ok(Outcome {
                output: out.to_path_buf(),
                summary,
                interrupted,
                diverged: diverged.clone(),
            }))
        }
        Err(f) => {
            let summary = json!({ "run": run_id, "status": "failed", "fault": { "node": f.node, "reason": f.reason }, "wall_s": wall });
            // The fault is what the user must hear; a summary that cannot be written too (the
            // disk that ended the run is full) is said beside it.
            if let Err(e) = write_summary(out, &summary) {
                tracing::warn!("{e:#}");
            }
            Ok(Err(f))
        }
    }
}
