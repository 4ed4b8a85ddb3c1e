//! The booking rule of the driver/responder couplings (PROTOCOL.md 4.7), checked as a run
//! goes: what a node books as the impulse it received through its interfaces
//! (`StepReport.interface_impulse`) must agree in sign with the `force` that crossed them.
//!
//! The responder of a kinematic or immersed coupling books `−f Δt` of the force it sends each
//! window; its driver books `+f Δt` of the same force, applied over the next window. The
//! coordinator sees every `force` on its way, so it adds up, per node and window by window,
//! the impulse those messages imply, and compares it with the node's own books since the
//! window loop began. The two are equal where the force is held over the window, and differ
//! by a bounded first-order term where a responder sub-cycles (its books integrate the force
//! over its substeps, its message is the force at the window's end). A node whose messages and
//! books point opposite ways for [`STREAK`] audited windows in a row, once the impulse matters
//! (a [`FLOOR`] of the run's impulse scale) and is not the remainder of forces that
//! cancel (a [`NET`] share of the gross impulse), has reversed the sign of the force it
//! sends (or of its books) and is stopped, named.
//!
//! Nodes in a lagrange coupling (the coordinator solves the interface there), in a coupling
//! whose responder sends no `force`, or in a coupling that has ended are not checked; nor is
//! a node whose input of some window never came (a restart continues from a checkpoint that
//! holds it).

use crate::case::{Case, CouplingConfig};
use protocol::scheme;

/// Audited windows in a row with opposite signs before a node is stopped.
pub const STREAK: u32 = 3;

/// Share of the run's impulse scale below which the interface impulse is not judged: a
/// responder that sub-cycles books the force integrated over its substeps and sends the one
/// at the window's end, which can point the other way while the force is small and rings
/// (a bolted joint at the start of its load ramp); once the interface carries a share of the
/// run's impulse, the two agree.
pub const FLOOR: f64 = 1e-3;

/// Share of the gross interface impulse (Σ over points and windows of |f| Δt) below which the
/// net one is what is left of forces that cancel (a symmetric blast on a ring), not judged.
pub const NET: f64 = 1e-3;

/// Windows of `force` kept per coupling until their audit: more than the windows in flight.
const RING: usize = 32;

/// The rule's name in messages.
pub const RULE: &str = "booking rule (PROTOCOL.md 4.7: a responder books −f Δt of the force it sends, its driver +f Δt of the force it applies)";

/// One coupling whose responder's `force` is booked by both sides.
struct Feed {
    driver: usize,
    responder: usize,
    /// The force of the windows not yet audited: (window, the sum over the points (N), the
    /// sum of their magnitudes (N)), at `window % RING`.
    ring: [Option<(u64, [f64; 3], f64)>; RING],
    /// The next window whose force the driver's books, and the responder's, take in.
    next_driver: u64,
    next_responder: u64,
}

/// One node's books against what its couplings' messages imply.
#[derive(Default, Clone)]
struct Ledger {
    /// Whether the rule applies to the node (every coupling of it is fed).
    applies: bool,
    /// Whether it is still checked (it applies, and none of its couplings has ended).
    checked: bool,
    /// Its couplings (indices into the case's).
    couplings: Vec<usize>,
    /// Its booked interface impulse when the window loop began (N s).
    base: [f64; 3],
    /// The feeds of its books: (topic, whether it is the responder there).
    feeds: Vec<(usize, bool)>,
    /// The impulse its couplings' `force` messages imply since then (N s), and its gross
    /// (Σ |f| Δt over points and windows).
    implied: [f64; 3],
    gross: f64,
    /// Its booked interface impulse since the loop began, of the audited windows not yet
    /// judged, with the run's impulse scale at that audit (which judges the window however
    /// late its forces arrive): (window, impulse, scale), at `window % RING`.
    booked: [Option<(u64, [f64; 3], f64)>; RING],
    /// The next window to judge, once every force its books of that window hold is here.
    next: u64,
    /// Audited windows in a row with the two opposite.
    streak: u32,
    /// Audited windows whose impulse was large enough to judge.
    judged: u64,
}

/// The booking check of one run.
pub struct Books {
    /// The window length (s): a `force` is held over one window.
    window: f64,
    /// Per transport topic (as the coordinator's list): the feed whose responder's `force`
    /// arrives on it.
    feeds: Vec<Option<Feed>>,
    ledgers: Vec<Ledger>,
    /// The couplings' names, for messages.
    names: Vec<String>,
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl Books {
    /// The check for `case`; `topics` gives, per transport topic, the coupling and the side
    /// whose data it carries (None: not a peer data topic).
    pub fn of(case: &Case, topics: &[Option<(usize, String)>]) -> Books {
        let nodes: Vec<&str> = case.nodes.iter().map(|n| n.name.as_str()).collect();
        Books::new(&nodes, &case.couplings, case.run.window, topics)
    }

    /// [`Books::of`] from the node names (in the case's order), the couplings and the window.
    pub fn new(
        nodes: &[&str],
        couplings: &[CouplingConfig],
        window: f64,
        topics: &[Option<(usize, String)>],
    ) -> Books {
        let idx = |n: &str| nodes.iter().position(|x| *x == n);
        let mut ledgers = vec![Ledger::default(); nodes.len()];
        let fed = |ci: usize| {
            let c = &couplings[ci];
            !scheme::of(c.kind).coordinator_solved()
                && c.responder_fields.iter().any(|f| f == "force")
        };
        for (ci, c) in couplings.iter().enumerate() {
            let members: Vec<&str> = if scheme::of(c.kind).coordinator_solved() {
                c.sides.iter().map(|s| s.0.as_str()).collect()
            } else {
                vec![c.driver.0.as_str(), c.responder.0.as_str()]
            };
            for m in members {
                if let Some(i) = idx(m) {
                    ledgers[i].couplings.push(ci);
                }
            }
        }
        for l in &mut ledgers {
            l.applies = !l.couplings.is_empty() && l.couplings.iter().all(|&ci| fed(ci));
            l.checked = l.applies;
        }
        let feeds: Vec<Option<Feed>> = topics
            .iter()
            .map(|t| {
                let (ci, side) = t.as_ref()?;
                let c = &couplings[*ci];
                if !fed(*ci) || c.responder.0 != *side {
                    return None;
                }
                Some(Feed {
                    driver: idx(&c.driver.0)?,
                    responder: idx(&c.responder.0)?,
                    ring: [None; RING],
                    next_driver: 0,
                    next_responder: 1,
                })
            })
            .collect();
        for (t, f) in feeds.iter().enumerate() {
            if let Some(f) = f {
                ledgers[f.responder].feeds.push((t, true));
                ledgers[f.driver].feeds.push((t, false));
            }
        }
        Books {
            window,
            feeds,
            ledgers,
            names: couplings.iter().map(|c| c.name.clone()).collect(),
        }
    }

    /// The window loop begins at window `first` (1, or the one after a restart's checkpoint)
    /// with every node's booked interface impulse so far (its initial report, or the one
    /// restored).
    pub fn begin<'r>(&mut self, first: u64, booked: impl Iterator<Item = &'r [f64; 3]>) {
        for (l, b) in self.ledgers.iter_mut().zip(booked) {
            l.base = *b;
            l.implied = [0.0; 3];
            l.gross = 0.0;
            l.booked = [None; RING];
            l.next = first;
            l.streak = 0;
        }
        for f in self.feeds.iter_mut().flatten() {
            // The driver's window `first` takes in the force of the window before.
            f.next_driver = first - 1;
            f.next_responder = first;
        }
    }

    /// How many audited windows of node `node` had an interface impulse large enough to judge.
    pub fn judged(&self, node: usize) -> u64 {
        self.ledgers.get(node).map_or(0, |l| l.judged)
    }

    /// Per node the rule applies to (its index): the audited windows in which it was judged
    /// (`summary.json`: `booking_rule`), so a run shows the check had something to check.
    pub fn judged_nodes(&self) -> impl Iterator<Item = (usize, u64)> + '_ {
        self.ledgers
            .iter()
            .enumerate()
            .filter(|(_, l)| l.applies)
            .map(|(i, l)| (i, l.judged))
    }

    /// Whether topic `topic` carries a `force` that is booked: [`Books::force`] wants every
    /// `Fields` on it.
    pub fn wants(&self, topic: usize) -> bool {
        self.feeds.get(topic).is_some_and(|f| f.is_some())
    }

    /// A `Fields` of window `window` (0: set-up) arrived on `topic`: `sum` and `gross` are
    /// its `force`'s sum over the points and the sum of their magnitudes ([`sum_force`]),
    /// zero where it holds none.
    pub fn force(&mut self, topic: usize, window: u64, (sum, gross): ([f64; 3], f64)) {
        if let Some(Some(f)) = self.feeds.get_mut(topic) {
            f.ring[window as usize % RING] = Some((window, sum, gross));
        }
    }

    /// Takes in, for the ledger `l`, the forces its books of window `w` hold: its responders'
    /// up to `w`, its drivers' up to `w − 1`. Returns whether all are here; a force that
    /// will never come (a later one is here instead) ends the check of the ledger.
    fn take_in(feeds: &mut [Option<Feed>], l: &mut Ledger, w: u64, dt: f64) -> bool {
        for &(t, responder) in &l.feeds {
            let Some(Some(f)) = feeds.get_mut(t) else {
                continue;
            };
            let (next, upto, sign) = if responder {
                (&mut f.next_responder, w, -1.0)
            } else {
                (&mut f.next_driver, w.saturating_sub(1), 1.0)
            };
            while *next <= upto {
                match f.ring[*next as usize % RING] {
                    Some((at, sum, gross)) if at == *next => {
                        for (i, x) in l.implied.iter_mut().zip(sum) {
                            *i += sign * x * dt;
                        }
                        l.gross += gross * dt;
                        *next += 1;
                    }
                    Some((at, ..)) if at > *next => {
                        l.checked = false;
                        return false;
                    }
                    _ => return false,
                }
            }
        }
        true
    }

    /// After the audit of window `k`: every checked node's books (`booked(i)`: its report's
    /// cumulative interface impulse; None: finished) are kept, and each window whose forces
    /// are all here is judged in order, its books since the loop began against what its
    /// messages imply (a `Fields` read after its window's audit is judged at a later one).
    /// `scale` is the run's impulse scale, `ended(ci)` whether coupling `ci` has ended. The
    /// first node whose two have pointed opposite ways for [`STREAK`] windows in a row: its
    /// index and why, with the window.
    pub fn check<'r>(
        &mut self,
        k: u64,
        booked: impl Fn(usize) -> Option<&'r [f64; 3]>,
        scale: f64,
        ended: impl Fn(usize) -> bool,
    ) -> Option<(usize, String)> {
        let (names, dt, feeds) = (&self.names, self.window, &mut self.feeds);
        for (i, l) in self.ledgers.iter_mut().enumerate() {
            if !l.checked {
                continue;
            }
            if l.couplings.iter().any(|&ci| ended(ci)) {
                l.checked = false;
                continue;
            }
            if let Some(now) = booked(i) {
                let b = [now[0] - l.base[0], now[1] - l.base[1], now[2] - l.base[2]];
                l.booked[k as usize % RING] = Some((k, b, scale));
            }
            while l.next <= k {
                let w = l.next;
                if !Self::take_in(feeds, l, w, dt) {
                    break;
                }
                l.next += 1;
                let Some((_, b, scale)) = l.booked[w as usize % RING].filter(|(at, ..)| *at == w)
                else {
                    continue;
                };
                let m = l.implied;
                let (nb, nm) = (norm(b), norm(m));
                let large = nb.max(nm) > (FLOOR * scale).max(NET * l.gross);
                l.judged += u64::from(large);
                let opposite =
                    large && nb.min(nm) > 0.25 * nb.max(nm) && dot(b, m) < -0.5 * nb * nm;
                l.streak = if opposite { l.streak + 1 } else { 0 };
                if l.streak >= STREAK {
                    let on: Vec<String> = l
                        .couplings
                        .iter()
                        .map(|&c| format!("'{}'", names[c]))
                        .collect();
                    return Some((
                        i,
                        format!(
                            "on coupling {} breaks the {RULE}: it booked an interface impulse of {} N s while the forces that crossed its interfaces imply {} N s, the opposite way: the sign of the force it sends (or of its books) is reversed (window {w})",
                            on.join(", "),
                            fmt3(b),
                            fmt3(m)
                        ),
                    ));
                }
            }
        }
        None
    }
}

/// [`sum_force`] of the `force` field among `fields` (zero where there is none).
pub fn force_of(fields: &[protocol::Field]) -> ([f64; 3], f64) {
    fields
        .iter()
        .find(|x| x.name == "force" && x.components == 3)
        .map_or(([0.0; 3], 0.0), |x| sum_force(x.values.iter().copied()))
}

/// A `force` field's values (3 components per point): their sum over the points, and the sum
/// of the points' magnitudes.
pub fn sum_force(values: impl Iterator<Item = f64>) -> ([f64; 3], f64) {
    let (mut sum, mut gross, mut point) = ([0.0; 3], 0.0, [0.0; 3]);
    for (k, x) in values.enumerate() {
        sum[k % 3] += x;
        point[k % 3] = x;
        if k % 3 == 2 {
            gross += norm(point);
        }
    }
    (sum, gross)
}

fn fmt3(v: [f64; 3]) -> String {
    format!("[{:.4e}, {:.4e}, {:.4e}]", v[0], v[1], v[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The split bar's case: `left` drives `right` on coupling `mid` (kinematic), and two data
    /// topics, the driver's then the responder's, after the two nodes' up topics.
    fn split_bar() -> Books {
        let mid = crate::case::split_bar_coupling();
        let topics = [
            None,
            None,
            Some((0, "left".to_string())),
            Some((0, "right".to_string())),
        ];
        Books::new(&["left", "right"], &[mid], 0.1, &topics)
    }

    /// A force of one point.
    fn one(f: [f64; 3]) -> ([f64; 3], f64) {
        sum_force(f.into_iter())
    }

    /// Runs `windows` windows of a responder force of 1 N along x (set-up force 1 N too):
    /// the driver books `+f Δt` a window late, the responder `sign × (−f Δt)`.
    fn play(sign: f64, windows: u64) -> Option<(usize, String)> {
        let mut books = split_bar();
        assert!(
            books.wants(3) && !books.wants(2),
            "only the responder's force is booked"
        );
        books.begin(1, [[0.0; 3], [0.0; 3]].iter());
        books.force(3, 0, one([1.0, 0.0, 0.0]));
        let dt = 0.1;
        for k in 1..=windows {
            books.force(3, k, one([1.0, 0.0, 0.0]));
            let driver = [k as f64 * dt, 0.0, 0.0];
            let responder = [-sign * k as f64 * dt, 0.0, 0.0];
            let booked = [driver, responder];
            if let Some(v) = books.check(k, |i| booked.get(i), 1.0, |_| false) {
                return Some(v);
            }
        }
        None
    }

    #[test]
    fn books_that_agree_with_the_messages_pass() {
        assert!(play(1.0, 20).is_none());
        let mut books = split_bar();
        books.begin(1, [[0.0; 3], [0.0; 3]].iter());
        books.force(3, 0, one([0.0; 3]));
        books.force(3, 1, one([1.0, 0.0, 0.0]));
        let booked = [[0.0; 3], [-0.1, 0.0, 0.0]];
        assert!(books.check(1, |i| booked.get(i), 1.0, |_| false).is_none());
        // The driver booked nothing yet (it applies the force of window 1 in window 2).
        assert_eq!((books.judged(0), books.judged(1)), (0, 1));
    }

    #[test]
    fn a_reversed_responder_is_named_after_three_windows() {
        let (node, why) = play(-1.0, 20).expect("the reversed responder is caught");
        assert_eq!(node, 1, "{why}");
        assert!(
            why.contains("booking rule") && why.contains("reversed"),
            "{why}"
        );
        // It is named at the third window in a row: not before.
        assert!(play(-1.0, 2).is_none());
        assert!(play(-1.0, 3).is_some());
    }

    #[test]
    fn forces_that_cancel_are_not_judged_by_their_remainder() {
        // Two points pushed apart by 1 N each, and a remainder of round-off, booked reversed:
        // the net is 1e-16 of the gross, nothing to judge.
        let mut books = split_bar();
        books.begin(1, [[0.0; 3], [0.0; 3]].iter());
        let pair = [1.0, 0.0, 0.0, -1.0 + 1e-16, 0.0, 0.0];
        let (sum, gross) = sum_force(pair.into_iter());
        assert_eq!(gross, 2.0);
        books.force(3, 0, (sum, gross));
        for k in 1..=10 {
            books.force(3, k, (sum, gross));
            let booked = [[0.0; 3], [sum[0] * 0.1 * k as f64, 0.0, 0.0]];
            assert!(
                books
                    .check(k, |i| booked.get(i), 1e-30, |_| false)
                    .is_none()
            );
        }
        assert_eq!(books.judged(1), 0);
    }

    /// Ten windows of a 1 N force with both sides' books reversed, judged against `scale`
    /// with every coupling `ended` or not; how many windows the responder was judged.
    fn reversed_books(scale: f64, ended: bool) -> u64 {
        let mut books = split_bar();
        books.begin(1, [[0.0; 3], [0.0; 3]].iter());
        books.force(3, 0, one([0.0; 3]));
        for k in 1..=10 {
            books.force(3, k, one([1.0, 0.0, 0.0]));
            let booked = [[-0.1 * k as f64, 0.0, 0.0], [0.1 * k as f64, 0.0, 0.0]];
            assert!(
                books
                    .check(k, |i| booked.get(i), scale, |_| ended)
                    .is_none()
            );
        }
        books.judged(1)
    }

    #[test]
    fn an_ended_coupling_or_a_small_impulse_is_not_judged() {
        // Below the floor of the scale, and ended: nothing is judged.
        assert_eq!(reversed_books(1e12, false), 0);
        assert_eq!(reversed_books(1.0, true), 0);
    }

    #[test]
    fn a_late_window_is_judged_against_the_scale_of_its_own_audit() {
        // Window 1's impulse (0.1 N s) is large against the scale of its audit (1 N s: the
        // floor is 1e-3 N s) and small against the scale at window 2's audit (1e6 N s: the
        // floor is 1e3 N s). Its force arrives only after window 2's audit: it is judged then,
        // against its own scale, so it counts whenever its force arrives.
        let mut books = split_bar();
        books.begin(1, [[0.0; 3], [0.0; 3]].iter());
        books.force(3, 0, one([0.0; 3]));
        let (b1, b2) = ([[0.0; 3], [-0.1, 0.0, 0.0]], [[0.0; 3], [-0.1, 0.0, 0.0]]);
        assert!(books.check(1, |i| b1.get(i), 1.0, |_| false).is_none());
        assert!(books.check(2, |i| b2.get(i), 1e6, |_| false).is_none());
        assert_eq!(books.judged(1), 0, "window 1 waits for its force");
        books.force(3, 1, one([1.0, 0.0, 0.0]));
        books.force(3, 2, one([0.0; 3]));
        // The check after the last window's data is in (as at the run's end): window 1 is
        // judged against 1 N s, window 2 (no impulse of its own) against 1e6 N s.
        assert!(books.check(2, |i| b2.get(i), 1e6, |_| false).is_none());
        assert_eq!(books.judged(1), 1);
    }

    #[test]
    fn a_force_late_at_the_audit_waits_and_one_that_never_comes_ends_the_check() {
        // The responder's force of window 2 is audited before it arrives: its books of window
        // 2 wait, and are judged at window 3's audit, once it is in, beside window 3's.
        let mut books = split_bar();
        books.begin(1, [[0.0; 3], [0.0; 3]].iter());
        books.force(3, 0, one([0.0; 3]));
        books.force(3, 1, one([1.0, 0.0, 0.0]));
        let booked = |k: f64| [[0.0; 3], [-0.1 * k, 0.0, 0.0]];
        let (b1, b2, b3) = (booked(1.0), booked(2.0), booked(3.0));
        assert!(books.check(1, |i| b1.get(i), 1.0, |_| false).is_none());
        assert!(books.check(2, |i| b2.get(i), 1.0, |_| false).is_none());
        assert_eq!(books.judged(1), 1);
        books.force(3, 2, one([1.0, 0.0, 0.0]));
        books.force(3, 3, one([1.0, 0.0, 0.0]));
        assert!(books.check(3, |i| b3.get(i), 1.0, |_| false).is_none());
        assert_eq!(books.judged(1), 3);
        // A restart after window 10: the driver's window 11 takes in window 10's force,
        // which is not sent again: the driver is not judged (it is let go once a later
        // force takes that window's place in the ring), the responder is.
        let mut books = split_bar();
        books.begin(11, [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]].iter());
        books.force(3, 11, one([1.0, 0.0, 0.0]));
        let booked = [[1.1, 0.0, 0.0], [-1.1, 0.0, 0.0]];
        assert!(books.check(11, |i| booked.get(i), 1.0, |_| false).is_none());
        books.force(3, 12, one([1.0, 0.0, 0.0]));
        let booked = [[1.2, 0.0, 0.0], [-1.2, 0.0, 0.0]];
        assert!(books.check(12, |i| booked.get(i), 1.0, |_| false).is_none());
        assert_eq!((books.judged(0), books.judged(1)), (0, 2));
    }
}
