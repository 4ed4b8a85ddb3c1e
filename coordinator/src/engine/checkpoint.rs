//! Checkpoints of a run: saving the coordinator's state with the nodes', and resuming from
//! the last complete one.

use super::audit::Audit;
use super::coord::*;
use crate::record::{self};
use protocol::*;
use serde_json::json;
use std::path::Path;

/// Restore every node from its checkpoint of window `st.window` (after set-up), then the
/// coordinator's own state; tell the nodes of the decouplings that had happened, finish those
/// that had finished, and mark the recording where the continued windows begin.
pub(super) fn resume(
    c: &mut Coord,
    st: &crate::checkpoint::CoordState,
    all: &[usize],
) -> Result<(), Fault> {
    let k = st.window;
    c.window = k;
    c.sim_t = st.time;
    restore_hubs(c, st)?;
    for &i in all {
        c.send(
            i,
            &Message::Advance(Advance {
                window: k,
                t0: st.time,
                t1: st.time,
                write_output: false,
                checkpoint: true,
            }),
        )?;
    }
    c.wait_all(all, "restore", None, |n| n.done == Some(k))?;
    restore_books(c, st)?;
    replay_commands(c, st)?;
    c.history = st.history.clone();
    c.completed = k;
    c.rec
        .json(
            record::RESUMED_TOPIC,
            "cosim.Resumed",
            st.time,
            &json!({ "window": k, "time": st.time }),
        )
        .map_err(|e| Fault {
            node: "coordinator".into(),
            reason: format!("recording: {e:#}"),
        })?;
    eprintln!(
        "cosim: restarted from the checkpoint of window {k} (t = {:e} s)",
        st.time
    );
    Ok(())
}

/// The interface problems continue from their checkpointed multipliers (set up again with
/// the sides, before any side steps the next window).
fn restore_hubs(c: &mut Coord, st: &crate::checkpoint::CoordState) -> Result<(), Fault> {
    for hs in &st.lagrange {
        let Some((hub, _)) = c.hubs.iter_mut().find(|(h, _)| h.coupling == hs.coupling) else {
            return Err(Fault {
                node: "coordinator".into(),
                reason: format!(
                    "lagrange coupling '{}' in the checkpoint but not in the case",
                    hs.coupling
                ),
            });
        };
        hub.restore(hs).map_err(|e| Fault {
            node: "coordinator".into(),
            reason: format!("coupling {}: {e}", hs.coupling),
        })?;
    }
    Ok(())
}

/// What the coordinator kept of each node: its step and time accounts, its last report, its
/// initial totals and its warnings.
fn restore_books(c: &mut Coord, st: &crate::checkpoint::CoordState) -> Result<(), Fault> {
    for ns in &st.nodes {
        let Some(i) = c.node_idx(&ns.name) else {
            return Err(Fault {
                node: ns.name.clone(),
                reason: "in the checkpoint but not in the case".into(),
            });
        };
        let n = &mut c.nodes[i];
        n.stable_dt = ns.stable_dt;
        n.substeps = ns.substeps;
        n.wall_s = ns.wall_s;
        n.wait_s = ns.wait_s;
        n.idle_s = ns.idle_s;
        n.report = ns.report.clone();
        n.initial_energy = ns.initial_energy;
        n.initial_momentum = ns.initial_momentum;
        n.warnings = ns.warnings.clone();
    }
    Ok(())
}

/// The commands that had changed the run before the checkpoint, sent again: the
/// decouplings to both nodes of each coupling, a `Finish` to each node that had finished.
fn replay_commands(c: &mut Coord, st: &crate::checkpoint::CoordState) -> Result<(), Fault> {
    let case = c.case;
    for (ci, d) in st.decoupled.iter().enumerate() {
        let (Some((w, _, why)), Some(cp)) = (d, case.couplings.get(ci)) else {
            continue;
        };
        for node in [&cp.driver.0, &cp.responder.0] {
            if let Some(i) = c.node_idx(node) {
                c.send(
                    i,
                    &Message::Decouple(Decouple {
                        coupling: cp.name.clone(),
                        window: *w,
                        reason: why.clone(),
                    }),
                )?;
            }
        }
    }
    for ns in &st.nodes {
        if let (Some(w), Some(i)) = (ns.finished, c.node_idx(&ns.name)) {
            c.send(
                i,
                &Message::Finish(Finish {
                    reason: "decoupled: the solid goes on alone".into(),
                }),
            )?;
            c.nodes[i].finished = Some(w);
        }
    }
    Ok(())
}

/// Every node has written its state at the end of window `k` (its `Done` acknowledged it):
/// mark the point in the recording, push it to disk, then write the coordinator's own state,
/// which makes the checkpoint complete.
pub(super) fn save_checkpoint(
    c: &mut Coord,
    out: &Path,
    a: &Audit,
    decoupled: &[Option<(u64, f64, String)>],
    k: u64,
    t1: f64,
    loop_s: f64,
) -> Result<(), Fault> {
    use crate::checkpoint as ck;
    let case = c.case;
    let fault = |e: anyhow::Error| Fault {
        node: "coordinator".into(),
        reason: format!("checkpoint of window {k}: {e:#}"),
    };
    let st = ck::CoordState {
        run_id: c.run.clone(),
        case_path: case.path.display().to_string(),
        case_text: case.text.clone(),
        signature: ck::compat_signature(case),
        window: k,
        time: t1,
        nodes: c
            .nodes
            .iter()
            .zip(&case.nodes)
            .map(|(n, cfg)| ck::NodeState {
                name: n.name.clone(),
                model: cfg.model.clone(),
                params_hash: protocol::checkpoint::params_hash(&ck::params_toml(cfg)),
                stable_dt: n.stable_dt,
                substeps: n.substeps,
                wall_s: n.wall_s,
                wait_s: n.wait_s,
                idle_s: n.idle_s,
                report: n.report.clone(),
                initial_energy: n.initial_energy,
                initial_momentum: n.initial_momentum,
                finished: n.finished,
                warnings: n.warnings.clone(),
                remote: cfg.remote,
            })
            .collect(),
        audit: a.clone(),
        decoupled: decoupled.to_vec(),
        history: c.history.clone(),
        loop_s,
        lagrange: c.hubs.iter().filter_map(|(h, _)| h.save()).collect(),
    };
    let dir = protocol::checkpoint::dir(out, k);
    c.rec
        .json(
            record::CHECKPOINT_TOPIC,
            "cosim.Checkpoint",
            t1,
            &json!({ "window": k, "time": t1, "dir": dir }),
        )
        .map_err(fault)?;
    c.rec.flush().map_err(fault)?;
    ck::save(out, &st).map_err(fault)
}
