//! The audit of every window: momentum against the external impulse, energy against the
//! work done, and the interface impulse still in flight between the nodes.

use protocol::StepReport;
use serde::{Deserialize, Serialize};

/// One row of the per-window balance (summary.json `balance.per_window`, `/cosim/balance`).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct BalanceRow {
    pub window: u64,
    pub time: f64,
    pub momentum: f64,
    pub external_impulse: f64,
    pub applied_impulse: f64,
    pub momentum_imbalance: f64,
    pub interface_impulse_sum: f64,
    pub momentum_residual: f64,
    pub energy: f64,
    pub external_work: f64,
    pub interface_work_sum: f64,
    pub energy_residual: f64,
}

/// The audit of a run so far: every window's balance and the worst values.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Audit {
    pub rows: Vec<BalanceRow>,
    pub worst_p: f64,
    pub worst_resid: f64,
    /// Energy not explained by the work done on the system since the start (signed).
    pub worst_e_resid: f64,
    /// The largest energy of the run or work done on it.
    pub energy_scale: f64,
    /// Largest impulse any node saw (applied, supports and walls, coupling).
    pub impulse_scale: f64,
    /// Largest gross momentum (Σ m|v| over the nodes).
    pub momentum_scale: f64,
    pub worst_iface_p: f64,
}

/// Window `k`'s balance (ending at `t1`) from every node's report and initial momentum,
/// folded into the run's audit `a` (`e0`: the initial energy).
pub fn balance<'r>(
    nodes: impl Iterator<Item = (&'r StepReport, [f64; 3])> + Clone,
    k: u64,
    t1: f64,
    e0: f64,
    a: &mut Audit,
) -> BalanceRow {
    let mut p = [0.0; 3];
    let mut p0 = [0.0; 3];
    let mut jx = [0.0; 3];
    let mut ji = [0.0; 3];
    let (mut e, mut wext, mut wif, mut applied) = (0.0, 0.0, 0.0, 0.0);
    for (r, initial_momentum) in nodes.clone() {
        for d in 0..3 {
            p[d] += r.momentum[d];
            // the balance is against the start: a node may begin moving (an inflow, a
            // launched block)
            p0[d] += initial_momentum[d];
            jx[d] += r.external_impulse[d];
            ji[d] += r.interface_impulse[d];
        }
        // dissipated energy (plastic work, broken bonds) left the elastic store but not
        // the body: it counts on the energy side of the balance
        e += r.kinetic_energy + r.internal_energy + r.dissipated();
        wext += r.external_work;
        wif += r.interface_work;
        applied += r.applied_impulse;
    }
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let dp = [p[0] - p0[0], p[1] - p0[1], p[2] - p0[2]];
    let imb = norm([dp[0] - jx[0], dp[1] - jx[1], dp[2] - jx[2]]);
    // What neither the external loads nor the impulse still in flight between the nodes
    // (given by one side, not yet applied by the other: the coupling lag) explains.
    let resid = norm([
        dp[0] - jx[0] - ji[0],
        dp[1] - jx[1] - ji[1],
        dp[2] - jx[2] - ji[2],
    ]);
    a.worst_p = a.worst_p.max(imb);
    a.worst_resid = a.worst_resid.max(resid);
    let e_resid = e - e0 - wext;
    if e_resid.abs() > a.worst_e_resid.abs() {
        a.worst_e_resid = e_resid;
    }
    a.energy_scale = a.energy_scale.max(e.abs()).max(e0.abs()).max(wext.abs());
    a.worst_iface_p = a.worst_iface_p.max(norm(ji));
    a.momentum_scale = a
        .momentum_scale
        .max(nodes.clone().map(|(r, _)| r.momentum_gross).sum());
    for (r, _) in nodes {
        a.impulse_scale = a
            .impulse_scale
            .max(r.applied_impulse)
            .max(norm(r.external_impulse))
            .max(norm(r.interface_impulse));
    }
    BalanceRow {
        window: k,
        time: t1,
        momentum: norm(p),
        external_impulse: norm(jx),
        applied_impulse: applied,
        momentum_imbalance: imb,
        interface_impulse_sum: norm(ji),
        momentum_residual: resid,
        energy: e,
        external_work: wext,
        interface_work_sum: wif,
        energy_residual: e_resid,
    }
}
