//! The divergence guard of the window loop: a run whose solution blows up ends with the
//! status `diverged` and its own exit code, never as "finished".
//!
//! Three signs end a run, checked on every window after its audit:
//!
//! * a node's `Failed` saying it was about to send a non-finite value (the divergence rule
//!   of the participant runtime, `protocol::diverged`);
//! * a non-finite quantity in a node's window report (the same check, for nodes that do not
//!   check themselves);
//! * the run's total energy E (kinetic, internal and dissipated, every node) beyond
//!   `run.energy_bound` times its budget B plus `run.energy_floor`, where B is the initial
//!   energy plus the largest external work so far, |E₀| + max |W_ext|. A healthy run keeps E
//!   within its budget up to the error of its methods; an unstable one grows geometrically
//!   and crosses any fixed multiple of it within a few windows.
//!
//! Besides the window where it stops, the guard names the first window from which the
//! energy stayed more than [`OVER_BUDGET`] above its budget: where the trouble began.

use protocol::diverged::Divergence;
use protocol::message::StepReport;
use serde_json::json;

/// Exit code of `cosim run` for a diverged run (0 finished, 1 a node or coordinator fault,
/// 2 a bad case, 128 + the signal for a run stopped on request).
pub const EXIT_DIVERGED: i32 = 4;

/// Relative excess of the energy over its budget from which a window counts as the start of
/// a divergence (for the message only; the bound is what stops a run).
pub const OVER_BUDGET: f64 = 0.1;

/// Default `run.balance.energy`: the energy residual (created or dissipated, as a share of
/// the largest energy or work) beyond which a run that ends within its bound is still warned
/// of. Every example's default run stays within it (docs/user-guide.md, "Balance warnings").
pub const ENERGY_WARNING: f64 = 0.05;

/// Default `run.balance.momentum`: the momentum residual (as a share of the larger of the
/// largest impulse and the largest gross momentum) beyond which a run is warned of. Every
/// example's default run stays within round-off, ten orders below it.
pub const MOMENTUM_WARNING: f64 = 1e-6;

/// Default `run.energy_bound`: a multiple of the energy budget.
pub const DEFAULT_FACTOR: f64 = 10.0;

/// Default `run.energy_floor` (J): what a run that starts at rest may hold before any work is
/// done (round-off of energies that should be zero).
pub const DEFAULT_FLOOR: f64 = 1e-9;

/// Why a run diverged, where and since when.
#[derive(Debug, Clone, PartialEq)]
pub struct Diverged {
    pub node: String,
    pub window: u64,
    pub time: f64,
    /// The quantity and its value: `kinetic_energy is NaN`, `total energy 6.2e14 J …`.
    pub quantity: String,
    /// The first window (and its end time) since which the energy exceeded its budget.
    pub since: Option<(u64, f64)>,
}

impl std::fmt::Display for Diverged {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "node '{}' diverged in window {} (t = {:.6e} s): {}",
            self.node, self.window, self.time, self.quantity
        )?;
        if let Some((w, t)) = self.since {
            write!(
                f,
                "; the energy has exceeded its budget (initial energy plus external work) by more than {:.0} % since window {w} (t = {t:.6e} s)",
                OVER_BUDGET * 100.0
            )?;
        }
        Ok(())
    }
}

impl Diverged {
    /// The `divergence` object of `summary.json`.
    pub fn to_json(&self) -> serde_json::Value {
        json!({
            "node": self.node,
            "window": self.window,
            "time": self.time,
            "quantity": self.quantity,
            "energy_over_budget_since_window": self.since.map(|s| s.0),
            "energy_over_budget_since_time": self.since.map(|s| s.1),
            "message": self.to_string(),
        })
    }
}

/// One node's part of a window, as the guard reads it.
pub struct NodeWindow<'a> {
    pub name: &'a str,
    pub report: &'a StepReport,
    /// Its energy after set-up (J).
    pub initial_energy: f64,
}

/// The guard's state across windows.
#[derive(Debug, Clone)]
pub struct Guard {
    factor: f64,
    floor: f64,
    /// Largest |W_ext| so far (J).
    work: f64,
    /// The first window of the current stretch above budget.
    over_since: Option<(u64, f64)>,
    /// The largest |E| / (budget + floor) so far: how close the run came to its bound.
    worst: f64,
}

impl Guard {
    /// `factor` 0 turns the energy bound off (non-finite values still end the run).
    pub fn new(factor: f64, floor: f64) -> Guard {
        Guard {
            factor,
            floor,
            work: 0.0,
            over_since: None,
            worst: 0.0,
        }
    }

    /// A restarted run's guard: the windows before its checkpoint, (window, end time, total
    /// energy, external work) as audited, read again, so that it continues as the run
    /// would have.
    pub fn resume(&mut self, rows: impl Iterator<Item = (u64, f64, f64, f64)>, e0: f64) {
        for (window, time, e, wext) in rows {
            self.energy(window, time, e, e0, wext);
        }
    }

    /// Takes window `window`'s total energy `e` into the budget, the worst ratio and the
    /// stretch over budget; returns the bound and the budget.
    fn energy(&mut self, window: u64, time: f64, e: f64, e0: f64, wext: f64) -> (f64, f64) {
        self.work = self.work.max(wext.abs());
        let budget = e0.abs() + self.work;
        if budget + self.floor > 0.0 {
            self.worst = self.worst.max(e.abs() / (budget + self.floor));
        }
        if e.abs() > (1.0 + OVER_BUDGET) * budget + self.floor {
            self.over_since.get_or_insert((window, time));
        } else {
            self.over_since = None;
        }
        (self.factor * budget + self.floor, budget)
    }

    /// The largest ratio of the total energy to its budget (|E₀| + max |W_ext|, plus the
    /// floor) over the windows checked: `summary.json`'s `max_energy_over_budget`, to set
    /// `run.energy_bound` against.
    pub fn worst_ratio(&self) -> f64 {
        self.worst
    }

    /// Where the trouble began, as far as the energy tells.
    pub fn since(&self) -> Option<(u64, f64)> {
        self.over_since
    }

    /// A node's own report of divergence (its `Failed`), with what the energy told so far.
    pub fn from_node(&self, node: &str, d: Divergence, time: f64) -> Diverged {
        Diverged {
            node: node.to_string(),
            window: d.window,
            time,
            quantity: d.what,
            since: self.over_since,
        }
    }

    /// Checks window `window` (ending at `time`): every report finite, the total energy
    /// within its bound. `e0` is the total energy after set-up, `wext` the external work so
    /// far.
    pub fn window<'a>(
        &mut self,
        window: u64,
        time: f64,
        nodes: impl Iterator<Item = NodeWindow<'a>> + Clone,
        e0: f64,
        wext: f64,
    ) -> Result<(), Diverged> {
        for n in nodes.clone() {
            if let Err(d) = protocol::diverged::check_report(window, n.report) {
                return Err(self.from_node(n.name, d, time));
            }
        }
        let energy = |r: &StepReport| r.kinetic_energy + r.internal_energy + r.dissipated();
        let e: f64 = nodes.clone().map(|n| energy(n.report)).sum();
        let (bound, _) = self.energy(window, time, e, e0, wext);
        if self.factor > 0.0 && e.abs() > bound {
            // The node whose energy grew the most since set-up carries the blame.
            let worst = nodes
                .map(|n| (n.name, energy(n.report) - n.initial_energy))
                .fold(None, |best: Option<(&str, f64)>, (name, g)| match best {
                    Some((_, bg)) if bg >= g => best,
                    _ => Some((name, g)),
                });
            let (node, growth) = worst.unwrap_or(("coordinator", e - e0));
            return Err(Diverged {
                node: node.to_string(),
                window,
                time,
                quantity: format!(
                    "the run's total energy {e:.4e} J (this node's grew by {growth:.4e} J) exceeds run.energy_bound × (initial energy + external work) + run.energy_floor = {} × ({:.4e} + {:.4e}) + {:.1e} = {bound:.4e} J",
                    self.factor,
                    e0.abs(),
                    self.work,
                    self.floor,
                ),
                since: self.over_since,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(ke: f64) -> StepReport {
        StepReport {
            kinetic_energy: ke,
            ..Default::default()
        }
    }

    fn nodes<'a>(r: &'a [StepReport; 2]) -> impl Iterator<Item = NodeWindow<'a>> + Clone {
        ["left", "right"]
            .into_iter()
            .zip(r)
            .map(|(name, report)| NodeWindow {
                name,
                report,
                initial_energy: 0.0,
            })
    }

    #[test]
    fn energy_within_ten_times_its_budget_passes_and_beyond_it_stops_naming_the_grower() {
        let mut g = Guard::new(10.0, 1e-9);
        // 1 J of work done, 9.9 J held: within 10 × 1 J.
        let r = [report(4.9), report(5.0)];
        assert_eq!(g.window(1, 0.1, nodes(&r), 0.0, 1.0), Ok(()));
        assert!((g.worst_ratio() - 9.9 / (1.0 + 1e-9)).abs() < 1e-12);
        // The over-budget stretch starts at window 1 (9.9 > 1.1 J).
        assert_eq!(g.since(), Some((1, 0.1)));
        let r = [report(0.5), report(10.0)];
        let d = g.window(2, 0.2, nodes(&r), 0.0, 1.0).unwrap_err();
        assert_eq!((d.node.as_str(), d.window, d.time), ("right", 2, 0.2));
        assert_eq!(d.since, Some((1, 0.1)));
        assert!(d.quantity.contains("1.0500e1 J"), "{}", d.quantity);
        assert!(d.to_string().contains("since window 1"), "{d}");
    }

    #[test]
    fn a_run_back_within_its_budget_forgets_where_it_was_over() {
        let mut g = Guard::new(10.0, 0.0);
        let over = [report(1.5), report(0.0)];
        let within = [report(1.0), report(0.0)];
        g.window(1, 0.1, nodes(&over), 1.0, 0.0).unwrap();
        assert_eq!(g.since(), Some((1, 0.1)));
        g.window(2, 0.2, nodes(&within), 1.0, 0.0).unwrap();
        assert_eq!(g.since(), None);
        g.window(3, 0.3, nodes(&over), 1.0, 0.0).unwrap();
        assert_eq!(g.since(), Some((3, 0.3)));
    }

    #[test]
    fn the_largest_external_work_so_far_stays_in_the_budget() {
        // Work done, then given back (unloading): the budget keeps the largest |W|.
        let mut g = Guard::new(2.0, 0.0);
        let r = [report(3.0), report(0.0)];
        g.window(1, 0.1, nodes(&r), 0.0, 2.0).unwrap();
        assert_eq!(g.window(2, 0.2, nodes(&r), 0.0, 0.0), Ok(()));
        let r = [report(4.1), report(0.0)];
        assert!(g.window(3, 0.3, nodes(&r), 0.0, 0.0).is_err());
    }

    #[test]
    fn the_floor_lets_a_run_at_rest_hold_round_off_and_a_zero_factor_turns_the_bound_off() {
        let r = [report(1e-12), report(0.0)];
        assert_eq!(
            Guard::new(10.0, 1e-9).window(1, 0.1, nodes(&r), 0.0, 0.0),
            Ok(())
        );
        assert!(
            Guard::new(10.0, 0.0)
                .window(1, 0.1, nodes(&r), 0.0, 0.0)
                .is_err()
        );
        let huge = [report(1e300), report(0.0)];
        assert_eq!(
            Guard::new(0.0, 0.0).window(1, 0.1, nodes(&huge), 0.0, 0.0),
            Ok(())
        );
        let nan = [report(f64::NAN), report(0.0)];
        let d = Guard::new(0.0, 0.0)
            .window(4, 0.4, nodes(&nan), 0.0, 0.0)
            .unwrap_err();
        assert_eq!(
            (d.node.as_str(), d.quantity.as_str()),
            ("left", "kinetic_energy is NaN")
        );
    }
}
