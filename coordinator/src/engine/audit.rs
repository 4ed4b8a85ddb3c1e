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
    /// What the residuals are measured against so far: the largest energy or work, and the
    /// larger of the largest impulse any node saw and the largest gross momentum.
    #[serde(default)]
    pub energy_scale: f64,
    #[serde(default)]
    pub momentum_scale: f64,
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

impl Audit {
    /// The scale of the momentum residual: the larger of the largest impulse any node saw
    /// and the largest gross momentum.
    pub fn residual_scale(&self) -> f64 {
        self.impulse_scale.max(self.momentum_scale)
    }

    /// The largest momentum residual over its scale (0 while nothing has moved).
    pub fn momentum_relative(&self) -> f64 {
        relative(self.worst_resid, self.residual_scale())
    }

    /// The largest energy residual (signed: created > 0, dissipated < 0) over its scale.
    pub fn energy_relative(&self) -> f64 {
        relative(self.worst_e_resid, self.energy_scale)
    }
}

/// `x / scale`, 0 where the scale is 0.
pub fn relative(x: f64, scale: f64) -> f64 {
    if scale > 0.0 { x / scale } else { 0.0 }
}

/// The nodes' reports summed for the balance of one window.
struct Sums {
    /// Momentum now and at the start (a node may begin moving: an inflow, a launched
    /// block).
    p: [f64; 3],
    p0: [f64; 3],
    /// External and interface impulse since the start.
    jx: [f64; 3],
    ji: [f64; 3],
    /// Energy (kinetic, internal and dissipated: plastic work and broken bonds left the
    /// elastic store but not the body), external work, interface work, applied impulse.
    e: f64,
    wext: f64,
    wif: f64,
    applied: f64,
}

impl Sums {
    // d indexes five arrays at once
    #[allow(clippy::needless_range_loop)]
    fn of<'r>(nodes: impl Iterator<Item = (&'r StepReport, [f64; 3])>) -> Sums {
        let mut s = Sums {
            p: [0.0; 3],
            p0: [0.0; 3],
            jx: [0.0; 3],
            ji: [0.0; 3],
            e: 0.0,
            wext: 0.0,
            wif: 0.0,
            applied: 0.0,
        };
        for (r, initial_momentum) in nodes {
            for d in 0..3 {
                s.p[d] += r.momentum[d];
                s.p0[d] += initial_momentum[d];
                s.jx[d] += r.external_impulse[d];
                s.ji[d] += r.interface_impulse[d];
            }
            s.e += r.kinetic_energy + r.internal_energy + r.dissipated();
            s.wext += r.external_work;
            s.wif += r.interface_work;
            s.applied += r.applied_impulse;
        }
        s
    }
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
    let Sums {
        p,
        p0,
        jx,
        ji,
        e,
        wext,
        wif,
        applied,
    } = Sums::of(nodes.clone());
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
        energy_scale: a.energy_scale,
        momentum_scale: a.residual_scale(),
    }
}
