//! The window loop: windows sent ahead (pipelining), decouplings, and each window audited,
//! recorded and checkpointed in order.

use super::audit::{Audit, BalanceRow};
use super::checkpoint::{resume, save_checkpoint};
use super::coord::*;
use crate::case::{self, Case};
use crate::profile::{Phase, Profile};
use crate::progress::Progress;
use protocol::stop;
use protocol::*;
use serde_json::json;
use std::collections::VecDeque;
use std::path::Path;
use std::time::{Duration, Instant};

/// Decouple every coupling whose rule fires before window `k` (starting at `t0`): tell both
/// sides, then finish each responder none of whose couplings is left (seed 000 §4: the solid
/// goes on alone). Returns whether a node was finished.
pub(super) fn decouple_due(
    c: &mut Coord,
    decoupled: &mut [Option<(u64, f64, String)>],
    k: u64,
    t0: f64,
) -> Result<bool, Fault> {
    let case = c.case;
    let mut any = false;
    for (ci, cp) in case.couplings.iter().enumerate() {
        if decoupled[ci].is_some() || !cp.decouple.is_set() {
            continue;
        }
        let Some(why) = decouple_reason(c, ci, k, t0)? else {
            continue;
        };
        c.progress.note(&format!(
            "cosim: coupling '{}' ends before window {k} ({why}); '{}' goes on alone",
            cp.name, cp.driver.0
        ));
        for node in [&cp.driver.0, &cp.responder.0] {
            if let Some(i) = c.node_idx(node)
                && c.nodes[i].finished.is_none()
            {
                c.send(
                    i,
                    &Message::Decouple(Decouple {
                        coupling: cp.name.clone(),
                        window: k,
                        reason: why.clone(),
                    }),
                )?;
            }
        }
        decoupled[ci] = Some((k, t0, why));
        c.until[ci] = Some(k);
        any = true;
    }
    if !any {
        return Ok(false);
    }
    finish_alone(c, decoupled, k)
}

/// Why coupling `ci` ends before window `k` (starting at `t0`), if its rule fires: its time
/// `decouple_at` reached, or the scalar its `decouple_when` names at its level in the node's
/// last report (a scalar the node does not report is a fault).
fn decouple_reason(c: &Coord, ci: usize, k: u64, t0: f64) -> Result<Option<String>, Fault> {
    let cp = &c.case.couplings[ci];
    if let Some(at) = cp.decouple.at
        && t0 >= at * (1.0 - 1e-12)
    {
        return Ok(Some(format!(
            "t = {t0:.6e} s reached decouple_at = {at:e} s"
        )));
    }
    let Some((node, q, level)) = &cp.decouple.when else {
        return Ok(None);
    };
    let Some(i) = c.node_idx(node).filter(|_| k > 1) else {
        return Ok(None);
    };
    let r = &c.nodes[i].report;
    match r.scalars.iter().find(|(n, _)| n == q) {
        Some(&(_, v)) if v >= *level => Ok(Some(format!("{node}.{q} = {v} reached {level}"))),
        Some(_) => Ok(None),
        None => {
            let have: Vec<&str> = r.scalars.iter().map(|(n, _)| n.as_str()).collect();
            Err(Fault {
                node: node.clone(),
                reason: format!(
                    "couplings[{ci}].decouple_when: the node does not report '{q}' (it reports: {})",
                    if have.is_empty() {
                        "nothing".to_string()
                    } else {
                        have.join(", ")
                    }
                ),
            })
        }
    }
}

/// Finish each node still running that responds in a decoupled coupling and has no coupling
/// left, after window `k - 1`. Returns whether a node was finished.
fn finish_alone(
    c: &mut Coord,
    decoupled: &[Option<(u64, f64, String)>],
    k: u64,
) -> Result<bool, Fault> {
    let case = c.case;
    let mut finished = false;
    for (i, n) in case.nodes.iter().enumerate() {
        if c.nodes[i].finished.is_some() {
            continue;
        }
        let mine: Vec<usize> = (0..case.couplings.len())
            .filter(|&ci| {
                let cp = &case.couplings[ci];
                cp.driver.0 == n.name || cp.responder.0 == n.name
            })
            .collect();
        let responder_of_decoupled = mine
            .iter()
            .any(|&ci| case.couplings[ci].responder.0 == n.name && decoupled[ci].is_some());
        if responder_of_decoupled && mine.iter().all(|&ci| decoupled[ci].is_some()) {
            c.send(
                i,
                &Message::Finish(Finish {
                    reason: "decoupled: the solid goes on alone".into(),
                }),
            )?;
            c.nodes[i].finished = Some(k - 1);
            c.progress.note(&format!(
                "cosim: node '{}' finished after window {}",
                n.name,
                k - 1
            ));
            finished = true;
        }
    }
    Ok(finished)
}

/// Start and end time of window `k` of `windows` (the last one ends at the end time).
pub(super) fn window_span(case: &Case, k: u64, windows: u64) -> (f64, f64) {
    let t0 = (k - 1) as f64 * case.run.window;
    let t1 = if k == windows {
        case.run.end_time
    } else {
        k as f64 * case.run.window
    };
    (t0, t1)
}

/// Windows in flight at most (the one awaited included), fixed by `COSIM_WINDOWS_AHEAD`
/// (1 to [`MAX_AHEAD`]; 1 is the lockstep schedule, each Advance after the last window's
/// audit); `None`: chosen by [`Ahead`].
pub(super) fn windows_ahead_fixed() -> Option<u64> {
    std::env::var("COSIM_WINDOWS_AHEAD")
        .ok()
        .and_then(|s| s.parse::<u64>().ok())
        .map(|a| a.clamp(1, MAX_AHEAD))
}

/// The fewest windows in flight by default: the awaited window and the next one, so the
/// nodes never wait for the audit or the recorder.
pub const WINDOWS_AHEAD: u64 = 2;
/// How much wall time the windows in flight may span (see [`Ahead`]).
pub(super) const AHEAD_SPAN: Duration = Duration::from_millis(2);

/// How many windows may be in flight: [`WINDOWS_AHEAD`] for long windows, up to
/// [`MAX_AHEAD`] for windows so short that that many still take under [`AHEAD_SPAN`] of wall
/// time (the mean spacing of completed windows). Sent in batches (the next ones go out when
/// half have ended), short windows cost the coordinator one wake-up of each node per batch
/// instead of one per window; the span bounds how long a stop request or a checkpoint waits for
/// the windows already sent.
pub(super) struct Ahead {
    pub(super) fixed: Option<u64>,
    /// When the last window completed, and the mean spacing of completions (s).
    pub(super) last: Option<Instant>,
    pub(super) spacing: f64,
    pub(super) measured: u32,
    /// The sum of the allowed counts at each completion, and the completions (their mean
    /// goes to `summary.json`).
    pub(super) allowed_sum: u64,
    pub(super) completions: u64,
}

impl Ahead {
    pub(super) fn new() -> Self {
        Self::with_fixed(windows_ahead_fixed())
    }

    pub(super) fn with_fixed(fixed: Option<u64>) -> Self {
        Ahead {
            fixed,
            last: None,
            spacing: 0.0,
            measured: 0,
            allowed_sum: 0,
            completions: 0,
        }
    }

    /// The mean number of windows allowed in flight over the completed windows.
    pub(super) fn mean(&self) -> f64 {
        self.allowed_sum as f64 / self.completions.max(1) as f64
    }

    /// A window completed now.
    pub(super) fn completed(&mut self) {
        let now = Instant::now();
        let dt = self.last.map(|l| now.duration_since(l).as_secs_f64());
        self.last = Some(now);
        self.completed_after(dt);
    }

    /// A window completed `dt` seconds after the last one (`None`: the first).
    pub(super) fn completed_after(&mut self, dt: Option<f64>) {
        if let Some(dt) = dt {
            // A running mean over the first windows, then exponential (1/8): a slow stretch
            // (output, a checkpoint) lowers the count for a while.
            self.measured = self.measured.saturating_add(1);
            let w = 1.0 / f64::from(self.measured.min(8));
            self.spacing += w * (dt - self.spacing);
        }
        self.allowed_sum += self.count();
        self.completions += 1;
    }

    pub(super) fn count(&self) -> u64 {
        if let Some(a) = self.fixed {
            return a;
        }
        if self.measured < 4 || self.spacing <= 0.0 {
            return WINDOWS_AHEAD;
        }
        let fit = (AHEAD_SPAN.as_secs_f64() / self.spacing) as u64;
        fit.clamp(WINDOWS_AHEAD, MAX_AHEAD)
    }
}

/// Whether the window after the last one sent may start before the awaited window's end:
/// not when that end decides something about it — a checkpoint there (nothing may run past
/// a checkpoint before it is complete), a decoupling rule still to fire (it reads the
/// reports), a lagrange hub (it answers within the window), a stop request.
pub(super) fn may_run_ahead(
    c: &Coord,
    decoupled: &[Option<(u64, f64, String)>],
    last_checkpoints: bool,
) -> bool {
    !last_checkpoints
        && c.hubs.is_empty()
        && stop::requested().is_none()
        && c.case
            .couplings
            .iter()
            .zip(decoupled)
            .all(|(cp, d)| d.is_some() || !cp.decouple.is_set())
}

/// Send window `k`'s `Advance` to every node still running, in the coupling graph's order,
/// after the decouplings due before it; returns whether the window checkpoints.
/// `quiet`: the nodes are not woken ([`Coord::ring`] them after the batch).
pub(super) fn send_window(
    c: &mut Coord,
    order_idx: &[usize],
    decoupled: &mut [Option<(u64, f64, String)>],
    active: &mut Vec<usize>,
    k: u64,
    stop_after: bool,
    quiet: bool,
) -> Result<bool, Fault> {
    let case = c.case;
    let windows = case::window_count(case);
    let (t0, t1) = window_span(case, k, windows);
    let every = case.run.checkpoint_every;
    // The last window needs no checkpoint: the run ends there.
    let checkpoint = every > 0 && (k.is_multiple_of(every) || stop_after) && k < windows;
    // Log times never go back on a channel: with windows in flight the coordinator has
    // already recorded messages of later windows.
    c.sim_t = c.sim_t.max(t0);
    if decouple_due(c, decoupled, k, t0)? {
        active.retain(|&i| c.nodes[i].finished.is_none());
    }
    c.sim_t = c.sim_t.max(t1);
    let write_output =
        k == windows || (case.run.output_every > 0 && k.is_multiple_of(case.run.output_every));
    let sending = Instant::now();
    for &i in order_idx {
        if c.nodes[i].finished.is_some() {
            continue;
        }
        c.send_ringing(
            i,
            &Message::Advance(Advance {
                window: k,
                t0,
                t1,
                write_output,
                checkpoint,
            }),
            !quiet,
        )?;
    }
    c.prof.lap(Phase::Advance, sending);
    Ok(checkpoint)
}

/// Send the windows after `sent` up to `upto` while [`may_run_ahead`] allows, noting each in
/// `in_flight` (window, whether it checkpoints): quietly, then each node is woken once.
pub(super) fn run_ahead(
    c: &mut Coord,
    order_idx: &[usize],
    decoupled: &mut [Option<(u64, f64, String)>],
    active: &mut Vec<usize>,
    in_flight: &mut VecDeque<(u64, bool)>,
    sent: &mut u64,
    upto: u64,
) -> Result<(), Fault> {
    let before = *sent;
    while *sent < upto && may_run_ahead(c, decoupled, in_flight.back().is_some_and(|w| w.1)) {
        let ck = send_window(c, order_idx, decoupled, active, *sent + 1, false, true)?;
        in_flight.push_back((*sent + 1, ck));
        *sent += 1;
    }
    if *sent > before {
        let ringing = Instant::now();
        for &i in order_idx {
            if c.nodes[i].finished.is_none() {
                c.ring(i)?;
            }
        }
        c.prof.lap(Phase::Advance, ringing);
    }
    Ok(())
}

/// What the window loop leaves for the summary.
pub(super) struct Windows {
    pub audit: Audit,
    /// Per coupling: (window, time, reason) once it decoupled.
    pub decoupled: Vec<Option<(u64, f64, String)>>,
    /// The nodes still running.
    pub active: Vec<usize>,
    pub windows: u64,
    /// The window loop's wall time (a restart's includes the run before it), s.
    pub loop_s: f64,
    pub breakdown: serde_json::Value,
}

/// The windows from the first (after a restart's checkpoint) to the last, or to where the
/// run diverged or was stopped: each sent ahead where it may be, awaited, audited, recorded
/// and checkpointed in order.
pub(super) fn run_windows(
    c: &mut Coord,
    out: &Path,
    order: &[String],
    opts: &RunOptions,
) -> Result<Windows, Fault> {
    let mut l = Loop::begin(c, order, opts)?;
    for k in l.first..=l.windows {
        let (_, t1) = window_span(c.case, k, l.windows);
        c.window = k;
        if l.sent < k {
            let ck = send_window(
                c,
                &l.order,
                &mut l.decoupled,
                &mut l.active,
                k,
                l.stop_after,
                false,
            )?;
            l.in_flight.push_back((k, ck));
            l.sent = k;
        }
        // Pipelining: the next windows' Advances go out now, so that the nodes go on while
        // this one is audited and recorded; only where nothing decided at this window's end
        // can change them (module doc).
        l.top_up(c, k - 1)?;
        c.sim_t = c.sim_t.max(t1);
        if !l.await_done(c, k)? {
            break;
        }
        let checkpoint = l.in_flight.pop_front().is_some_and(|w| w.1);
        l.ahead.completed();
        // The window after the next goes out now, before this one's audit and records: the
        // driver finishes its next window while the responder computes, and then needs it
        // (the coordinator's own work per window would otherwise stand in its way). Not past
        // a checkpoint at this window: it is complete only once saved below.
        if l.ahead.count() > 1 && !checkpoint {
            l.top_up(c, k)?;
        }
        let flushing = l.audit(c, k, t1)?;
        if !l.within_bounds(c, k, t1) {
            break;
        }
        c.progress.window(k, t1);
        c.completed = k;
        if checkpoint {
            let loop_s = l.loop_before + l.loop_start.elapsed().as_secs_f64();
            save_checkpoint(c, out, &l.audit, &l.decoupled, k, t1, loop_s)?;
        }
        // Completed windows reach the disk (a killed cosim leaves them recoverable).
        let _ = c.rec.window_end(Duration::from_millis(20));
        c.prof.lap(Phase::Flush, flushing);
        // A stop signal ends the run here, at the window boundary; with checkpoints, after
        // one more window that checkpoints, so that a restart continues from where it stopped.
        if let Some(sig) = stop::requested() {
            if l.sent > k {
                continue; // windows already under way end first, each at its boundary
            }
            if l.every > 0 && !checkpoint && !l.stop_after {
                l.stop_after = true;
                continue;
            }
            c.interrupted = Some(sig);
            break;
        }
    }
    Ok(l.end(c))
}

/// The window loop's state between windows.
struct Loop {
    /// The nodes' indices in window order.
    order: Vec<usize>,
    /// The run's windows, and the first this loop runs (after a restart's checkpoint).
    windows: u64,
    first: u64,
    /// The audit (docs/architecture.md) so far: restored from the checkpoint on a restart.
    audit: Audit,
    /// Decouplings: (window, time, reason) per coupling once it happened.
    decoupled: Vec<Option<(u64, f64, String)>>,
    /// The nodes still running.
    active: Vec<usize>,
    /// The energy after set-up, J.
    e0: f64,
    /// Windows whose Advance is out and whose Done is not yet all in: (window, checkpoint).
    in_flight: VecDeque<(u64, bool)>,
    ahead: Ahead,
    /// The last window sent.
    sent: u64,
    /// A stop was requested: checkpoint the next window and stop there.
    stop_after: bool,
    /// `run.checkpoint_every`.
    every: u64,
    /// The loop's wall time before a restart, s, and when this one started.
    loop_before: f64,
    loop_start: Instant,
    /// The recorder's allocations at the start.
    lag0: u64,
}

impl Loop {
    /// The loop's state at its first window: on a restart, the nodes and the coordinator
    /// restored from the checkpoint; the guard, the booking rule, progress and profile
    /// started.
    fn begin(c: &mut Coord, order: &[String], opts: &RunOptions) -> Result<Loop, Fault> {
        let case = c.case;
        let all: Vec<usize> = (0..c.nodes.len()).collect();
        let mut l = Loop {
            order: order.iter().filter_map(|n| c.node_idx(n)).collect(),
            windows: case::window_count(case),
            first: 1,
            audit: Audit::default(),
            decoupled: vec![None; case.couplings.len()],
            active: all.clone(),
            e0: 0.0,
            in_flight: VecDeque::with_capacity(MAX_AHEAD as usize + 1),
            ahead: Ahead::new(),
            sent: 0,
            stop_after: false,
            every: case.run.checkpoint_every,
            loop_before: 0.0,
            loop_start: Instant::now(),
            lag0: 0,
        };
        // A restart continues after its checkpoint's window, from the state the nodes and
        // the coordinator saved there.
        if let Some(st) = &opts.restart {
            resume(c, st, &all)?;
            l.audit = st.audit.clone();
            l.decoupled = st.decoupled.clone();
            for (u, d) in c.until.iter_mut().zip(&l.decoupled) {
                *u = d.as_ref().map(|d| d.0);
            }
            l.active.retain(|&i| c.nodes[i].finished.is_none());
            (l.first, l.loop_before) = (st.window + 1, st.loop_s);
        }
        l.sent = l.first - 1;
        l.e0 = c.nodes.iter().map(|n| n.initial_energy).sum();
        // A restart's guard reads the audited windows before its checkpoint again.
        let rows = l.audit.rows.iter();
        c.guard.resume(
            rows.map(|r| (r.window, r.time, r.energy, r.external_work)),
            l.e0,
        );
        // The booking rule judges the impulse booked from here on.
        c.books
            .begin(l.first, c.nodes.iter().map(|n| &n.report.interface_impulse));
        c.progress = Progress::new(l.windows, case.run.end_time, opts.quiet);
        c.progress.resume_after(l.first - 1);
        l.loop_start = Instant::now();
        c.in_windows = true;
        c.prof = Profile::default();
        c.prof.start();
        l.lag0 = c.rec.lag_allocations;
        Ok(l)
    }

    /// Once no more than half of the windows allowed in flight are left after window
    /// `completed`, the windows after the last one sent up to that count, while they may run
    /// ahead (one batch: each node is woken once for it).
    fn top_up(&mut self, c: &mut Coord, completed: u64) -> Result<(), Fault> {
        let n = self.ahead.count();
        if self.sent - completed > n / 2 {
            return Ok(());
        }
        run_ahead(
            c,
            &self.order,
            &mut self.decoupled,
            &mut self.active,
            &mut self.in_flight,
            &mut self.sent,
            (completed + n).min(self.windows),
        )
    }

    /// Wait for every running node's Done of window `k`; false when a node said it was about
    /// to send a non-finite value and left: the run diverged there.
    fn await_done(&mut self, c: &mut Coord, k: u64) -> Result<bool, Fault> {
        let Err(f) = c.wait_all(&self.active, "Done", None, |n| {
            n.done.is_some_and(|d| d >= k)
        }) else {
            return Ok(true);
        };
        let Some(mut d) = protocol::diverged::Divergence::parse(&f.reason) else {
            return Err(f);
        };
        // The quantity alone: the node's log is in the output folder.
        if let Some(at) = d.what.find(" (its log: ") {
            d.what.truncate(at);
        }
        let t = window_span(c.case, d.window.clamp(1, self.windows), self.windows).1;
        c.diverged = Some(c.guard.from_node(&f.node, d, t));
        Ok(false)
    }

    /// Window `k`'s audit, ending at `t1`: the nodes' reports of it, its balance row, the
    /// booking rule, and its records; returns when the flush phase starts.
    fn audit(&mut self, c: &mut Coord, k: u64, t1: f64) -> Result<Instant, Fault> {
        let auditing = Instant::now();
        // Reports of later windows that came in meanwhile wait for their own audit.
        for (n, spare) in c.nodes.iter_mut().zip(&mut c.spare) {
            while n.ahead.front().is_some_and(|(w, _)| *w <= k) {
                if let Some((_, r)) = n.ahead.pop_front() {
                    spare.push(std::mem::replace(&mut n.report, r));
                }
            }
        }
        let reports = c.nodes.iter().map(|n| (&n.report, n.initial_momentum));
        let row = super::audit::balance(reports, k, t1, self.e0, &mut self.audit);
        judge_books(c, k, self.audit.impulse_scale, &self.decoupled)?;
        let reporting = c.prof.lap(Phase::Audit, auditing);
        record_window(c, k, t1, self.windows, &row);
        self.audit.rows.push(row);
        Ok(c.prof.lap(Phase::Reports, reporting))
    }

    /// Whether window `k`, audited, keeps within the divergence guard's bounds; when not,
    /// the run diverged there and its records are flushed.
    fn within_bounds(&mut self, c: &mut Coord, k: u64, t1: f64) -> bool {
        let wext = self.audit.rows.last().map_or(0.0, |r| r.external_work);
        let nodes = c.nodes.iter().map(|n| crate::guard::NodeWindow {
            name: &n.name,
            report: &n.report,
            initial_energy: n.initial_energy,
        });
        let Err(d) = c.guard.window(k, t1, nodes, self.e0, wext) else {
            return true;
        };
        c.diverged = Some(d);
        c.completed = k;
        let _ = c.rec.window_end(Duration::from_millis(20));
        false
    }

    /// What the loop leaves for the summary, its progress and profile closed.
    fn end(self, c: &mut Coord) -> Windows {
        c.progress.finish();
        let loop_s = self.loop_before + self.loop_start.elapsed().as_secs_f64();
        c.prof
            .add_recorder_lag_allocs(c.rec.lag_allocations - self.lag0);
        c.prof.stop();
        let mut breakdown = c
            .prof
            .per_window(c.completed.saturating_sub(self.first - 1));
        breakdown["windows_in_flight"] = self.ahead.mean().into();
        Windows {
            audit: self.audit,
            decoupled: self.decoupled,
            active: self.active,
            windows: self.windows,
            loop_s,
            breakdown,
        }
    }
}

/// Record window `k`'s balance `row`, every running node's report and each lagrange hub's
/// multipliers, at `t1`; the reports also go to the plots' histories.
pub(super) fn record_window(c: &mut Coord, k: u64, t1: f64, windows: u64, row: &BalanceRow) {
    let _ = c.rec.json_doc(
        "/cosim/balance",
        "cosim.Balance",
        t1,
        row,
        &mut std::iter::empty(),
    );
    for n in c.nodes.iter_mut().filter(|n| n.finished.is_none()) {
        n.record_plan.update(&n.report);
        let r = &n.report;
        let doc = super::report::NodeReportDoc {
            window: k,
            time: t1,
            r,
            plan: &n.record_plan,
        };
        let _ = c.rec.json_doc(
            &n.report_topic,
            "cosim.NodeReport",
            t1,
            &doc,
            &mut doc.scalar_keys(),
        );
        crate::plot::add_node_report(&mut c.history, &n.name, t1, r, windows as usize);
    }
    for h in 0..c.hubs.len() {
        let (name, sides) = (c.hubs[h].0.coupling.clone(), c.hubs[h].0.sides.clone());
        // ΔE_Γ: the energy the interface took out of the sides, −Σᵢ Wᵢ (seed 003 §4).
        let work: f64 = sides
            .iter()
            .filter_map(|s| c.node_idx(s))
            .map(|i| c.nodes[i].report.interface_work)
            .sum();
        for (w, lambda) in c.hubs[h].0.take_finished() {
            let _ = c.rec.json(
                &format!("/cosim/lagrange/{name}"),
                "cosim.Lagrange",
                t1,
                &json!({ "window": w, "time": t1, "lambda": lambda,
                             "interface_work": work, "interface_energy": -work }),
            );
        }
    }
}

/// The booking rule after the audit of window `k` (`scale`: the run's impulse scale so far,
/// `decoupled`: per coupling, whether it has ended): a node whose books and messages point
/// opposite ways is stopped.
fn judge_books(
    c: &mut Coord,
    k: u64,
    scale: f64,
    decoupled: &[Option<(u64, f64, String)>],
) -> Result<(), Fault> {
    let nodes = &c.nodes;
    match c.books.check(
        k,
        |i| {
            let n = &nodes[i];
            n.finished.is_none().then_some(&n.report.interface_impulse)
        },
        scale,
        |ci| decoupled[ci].is_some(),
    ) {
        Some((i, why)) => Err(fault(&c.nodes[i].name, why)),
        None => Ok(()),
    }
}

/// The run's end for the nodes: the last window's data still queued is recorded (and the
/// windows whose forces came in after their audit are judged by the booking rule, so that a
/// run judges every window whose forces all arrived), every running node is told to finish
/// and given 10 s to exit on its own.
pub(super) fn finish_nodes(c: &mut Coord, w: &Windows) -> Result<(), Fault> {
    let active = &w.active;
    // A node publishes its last window's data before its Done, but on another topic: that
    // data may still be queued here. Record it before the nodes go (a quiet 50 ms, at most
    // 2 s), so the recording holds every message of every window.
    let drain_until = Instant::now() + Duration::from_secs(2);
    while Instant::now() < drain_until {
        match c.pump_one(Duration::from_millis(50)) {
            Ok(true) => {}
            Ok(false) => break,
            // Nodes a diverged run left behind may fail in the windows after (their peer gone).
            Err(_) if c.diverged.is_some() => break,
            Err(f) => return Err(f),
        }
    }
    if c.diverged.is_none() && c.completed > 0 {
        judge_books(c, c.completed, w.audit.impulse_scale, &w.decoupled)?;
    }
    let end_reason = match (&c.interrupted, &c.diverged) {
        (_, Some(d)) => format!("the run diverged: {d}"),
        (Some(sig), None) => format!(
            "interrupted by {} after window {}",
            stop::name(*sig),
            c.completed
        ),
        (None, None) => "end time reached".into(),
    };
    for &i in active.iter() {
        let sent = c.send(
            i,
            &Message::Finish(Finish {
                reason: end_reason.clone(),
            }),
        );
        // A diverged node may be gone already.
        if c.diverged.is_none() {
            sent?;
        }
    }
    // Let the nodes exit on their own.
    let deadline = Instant::now() + Duration::from_secs(10);
    for n in &mut c.nodes {
        if let Some(ch) = n.child.as_mut() {
            while Instant::now() < deadline {
                if let Ok(Some(_)) = ch.try_wait() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(5));
            }
        }
    }
    Ok(())
}
#[cfg(test)]
mod tests {
    use super::*;

    /// The windows in flight follow the spacing of the windows' completions, between two
    /// and eight, unless fixed.
    #[test]
    fn windows_in_flight_fill_the_span_between_two_and_eight() {
        let spaced = |dt: f64| {
            let mut a = Ahead::with_fixed(None);
            a.completed_after(None);
            assert_eq!(a.count(), 2, "before any spacing is known");
            for _ in 0..20 {
                a.completed_after(Some(dt));
            }
            a.count()
        };
        // 2 ms of windows in flight: 2 ms / 100 µs = 20, at most 8; 2 ms / 350 µs = 5.7;
        // 2 ms / 900 µs = 2.2; 2 ms / 10 ms = 0.2, at least 2.
        assert_eq!(spaced(100e-6), 8);
        assert_eq!(spaced(350e-6), 5);
        assert_eq!(spaced(900e-6), 2);
        assert_eq!(spaced(10e-3), 2);
        // A slow stretch after fast windows lowers the count within a few windows.
        let mut a = Ahead::with_fixed(None);
        for _ in 0..20 {
            a.completed_after(Some(100e-6));
        }
        assert_eq!(a.count(), 8);
        for _ in 0..20 {
            a.completed_after(Some(5e-3));
        }
        assert_eq!(a.count(), 2);
        assert_eq!(a.completions, 40);
        // A fixed count (COSIM_WINDOWS_AHEAD) is kept whatever the spacing.
        let mut f = Ahead::with_fixed(Some(1));
        for _ in 0..10 {
            f.completed_after(Some(1e-6));
        }
        assert_eq!(f.count(), 1);
        assert_eq!(f.mean(), 1.0);
    }
}
