//! What a run reports: each node's report per window as JSON, and `summary.json`.

use super::coord::*;
use crate::case::{self};
use protocol::stop;
use serde_json::json;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// `<out>/summary.json`, whole or not at all (never a truncated or empty file).
pub(crate) fn write_summary(out: &Path, summary: &serde_json::Value) -> anyhow::Result<()> {
    let path = out.join("summary.json");
    node_kit::whole::write(&path, serde_json::to_string_pretty(summary)?.as_bytes())
        .map_err(anyhow::Error::from)
}

/// `summary.json` of a run that ended its window loop (finished, diverged or stopped).
pub(super) fn run_summary(c: &Coord, w: &super::window::Windows) -> serde_json::Value {
    let case = c.case;
    let (a, windows, loop_s) = (&w.audit, w.windows, w.loop_s);
    let reached_t = a.rows.last().map_or(0.0, |r| r.time);
    json!({
        "run": c.run,
        "status": if c.diverged.is_some() { "diverged" } else if c.interrupted.is_some() { "interrupted" } else { "finished" },
        "divergence": c.diverged.as_ref().map(crate::guard::Diverged::to_json),
        "signal": c.interrupted.map(stop::name),
        "window_reached": c.completed,
        "time_reached": reached_t,
        "case": case.path.display().to_string(),
        "transport": case.run.transport.as_str(),
        "schedule": match case.run.schedule { case::Schedule::Serial => "serial", case::Schedule::Parallel => "parallel" },
        "end_time": case.run.end_time,
        "window": case.run.window,
        "windows": windows,
        "nodes": nodes_doc(c, loop_s),
        // Every node's warnings, "node: text" (also per node above, and in the log).
        "warnings": warnings(c, a),
        "couplings": couplings_doc(c, &w.decoupled),
        // What the run costs beyond its slowest node's own work: the coupling overhead on
        // the critical path (exchange, waiting, coordination).
        "window_loop_s": loop_s,
        // The coordinator's side of a window (this process only: a restart's segment).
        "window_breakdown": w.breakdown.clone(),
        // Gaps in which the coordinator itself did not run (no node was blamed for them).
        "coordinator_stalls": { "count": c.own.count, "longest_s": c.own.longest },
        // Per node the booking rule applies to, the windows it judged (PROTOCOL.md 4.7).
        "booking_rule": c
            .books
            .judged_nodes()
            .map(|(i, n)| (c.nodes[i].name.clone(), serde_json::json!({ "judged_windows": n })))
            .collect::<serde_json::Map<_, _>>(),
        "coupling_overhead": if loop_s > 0.0 {
            1.0 - c.nodes.iter().map(|n| n.wall_s).fold(0.0, f64::max) / loop_s
        } else {
            0.0
        },
        "balance": balance_doc(c, a),
    })
}

/// Per node: its executable and model, step, where its time went (shares of the window
/// loop's `loop_s`), its warnings and its last report.
fn nodes_doc(c: &Coord, loop_s: f64) -> BTreeMap<String, serde_json::Value> {
    let mut nodes_json = BTreeMap::new();
    for (n, cfg) in c.nodes.iter().zip(&c.case.nodes) {
        let of_loop = |x: f64| if loop_s > 0.0 { x / loop_s } else { 0.0 };
        nodes_json.insert(
            n.name.clone(),
            json!({
                "solver": cfg.solver, "model": cfg.model, "remote": cfg.remote,
                "stable_dt": n.stable_dt, "substeps": n.substeps,
                "compute_s": n.wall_s, "coupling_wait_s": n.wait_s, "idle_s": n.idle_s,
                // Shares of the window loop's wall time: computing (and sending), blocked on
                // a peer's input with a window in hand, waiting for the next window.
                "compute_fraction": of_loop(n.wall_s),
                "coupling_fraction": of_loop(n.wait_s),
                "idle_fraction": of_loop(n.idle_s),
                "finished_after_window": n.finished,
                "warnings": n.warnings,
                "final": {
                    "kinetic_energy": n.report.kinetic_energy, "internal_energy": n.report.internal_energy,
                    "external_work": n.report.external_work, "interface_work": n.report.interface_work,
                    "momentum": n.report.momentum,
                    "scalars": n.report.scalars.iter().cloned().collect::<HashMap<String, f64>>(),
                },
            }),
        );
    }
    nodes_json
}

/// Per coupling: its kind, sides, when it decoupled (`decoupled`), and for a lagrange one
/// its method and the work its sides did.
fn couplings_doc(c: &Coord, decoupled: &[Option<(u64, f64, String)>]) -> Vec<serde_json::Value> {
    c.case
        .couplings
        .iter()
        .zip(decoupled)
        .map(|(cp, d)| {
            let mut v = json!({ "name": cp.name, "kind": cp.kind.as_str(),
                    "driver": format!("{}.{}", cp.driver.0, cp.driver.1),
                    "responder": format!("{}.{}", cp.responder.0, cp.responder.1) });
            if let Some((w, t, why)) = d {
                v["decoupled"] = json!({ "before_window": w, "time": t, "reason": why });
            }
            if protocol::scheme::of(cp.kind).coordinator_solved() {
                lagrange_doc(c, cp, &mut v);
            }
            v
        })
        .collect()
}

/// A lagrange coupling's method, sides and the work done at its interface into `v`.
fn lagrange_doc(c: &Coord, cp: &case::CouplingConfig, v: &mut serde_json::Value) {
    let by_side: BTreeMap<String, f64> = cp
        .sides
        .iter()
        .filter_map(|s| {
            let i = c.node_idx(&s.0)?;
            Some((format!("{}.{}", s.0, s.1), c.nodes[i].report.interface_work))
        })
        .collect();
    let work: f64 = by_side.values().sum();
    v["sides"] = json!(
        cp.sides
            .iter()
            .map(|s| format!("{}.{}", s.0, s.1))
            .collect::<Vec<_>>()
    );
    v["method"] = json!(
        format!(
            "{:?}",
            cp.method.unwrap_or(protocol::scheme::lagrange::Method::Gs4)
        )
        .to_lowercase()
    );
    // ΔE_Γ = −Σᵢ Wᵢ: ≥ 0 is energy the interface dissipated (J).
    v["interface_work_by_side"] = json!(by_side);
    v["interface_energy"] = json!(-work);
}

/// The case's warnings, the balance's and every node's.
fn warnings(c: &Coord, a: &super::audit::Audit) -> Vec<String> {
    c.case
        .warnings
        .iter()
        .map(|w| format!("case: {w}"))
        .chain(balance_warnings(
            a,
            c.case.run.balance_momentum,
            c.case.run.balance_energy,
        ))
        .chain(
            c.nodes
                .iter()
                .flat_map(|n| n.warnings.iter().map(move |w| format!("{}: {w}", n.name))),
        )
        .collect()
}

/// A warning for each residual beyond its `[run.balance]` threshold (`momentum`, `energy`): momentum a node or a
/// coupling booked wrongly; energy the methods created (short of the divergence bound: the
/// mark of a slowly growing instability) or dissipated without any node booking it.
pub fn balance_warnings(a: &super::audit::Audit, momentum: f64, energy: f64) -> Vec<String> {
    let mut out = Vec::new();
    let p = a.momentum_relative();
    if p > momentum {
        out.push(format!(
            "balance: the momentum residual reached {p:.3e} of the largest impulse or gross momentum ({:.4e} N s; run.balance.momentum = {:e}): some impulse is not booked — a node's report or a coupling's exchange is wrong",
            a.worst_resid, momentum
        ));
    }
    let e = a.energy_relative();
    if e > energy {
        out.push(format!(
            "balance: the numerical methods created {:.1} % of the largest energy or work (energy residual {:+.4e} J; run.balance.energy = {}): a healthy run creates almost none: the coupling or an integrator may be near its stability limit (try a smaller run.window)",
            e * 100.0,
            a.worst_e_resid,
            energy
        ));
    } else if -e > energy {
        out.push(format!(
            "balance: the numerical methods lost {:.1} % of the largest energy or work (energy residual {:+.4e} J; run.balance.energy = {}): energy left the run that no node booked as dissipated: too coarse a resolution for the loading, or a coupling that does not conserve energy",
            -e * 100.0,
            a.worst_e_resid,
            energy
        ));
    }
    out
}

/// The run's balance: the largest momentum and energy residuals against their scales, the
/// guard's largest energy over budget, and every window's row.
fn balance_doc(c: &Coord, a: &super::audit::Audit) -> serde_json::Value {
    let applied_final = a.rows.last().map_or(0.0, |r| r.applied_impulse);
    json!({
        "applied_impulse": applied_final,
        "max_momentum_imbalance": a.worst_p,
        "max_momentum_imbalance_relative": if applied_final > 0.0 { a.worst_p / applied_final } else { 0.0 },
        "max_interface_impulse_sum": a.worst_iface_p,
        "impulse_scale": a.impulse_scale,
        "momentum_scale": a.momentum_scale,
        "max_momentum_residual": a.worst_resid,
        // Against the larger of the two scales: the largest impulse any node saw, and the
        // largest gross momentum of the run.
        "max_momentum_residual_relative": a.momentum_relative(),
        // Signed: negative is energy the numerical methods (and couplings) dissipated,
        // positive energy they created.
        "max_energy_residual": a.worst_e_resid,
        "energy_scale": a.energy_scale,
        // The divergence guard's reading: the largest total energy over its budget
        // (initial energy plus the largest external work so far), against
        // run.energy_bound.
        "max_energy_over_budget": c.guard.worst_ratio(),
        "energy_bound": c.case.run.energy_bound,
        "max_energy_residual_relative": a.energy_relative(),
        // The thresholds of the balance warnings ([run.balance]).
        "momentum_warning": c.case.run.balance_momentum,
        "energy_warning": c.case.run.balance_energy,
        "per_window": a.rows,
    })
}
