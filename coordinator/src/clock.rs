//! The coordinator's own stalls (docs/architecture.md, "Failures"): `cosim` looks at its
//! nodes every few milliseconds while it waits, so a long gap between two looks is its own
//! (not scheduled on a busy machine, stopped by SIGSTOP, a suspended laptop, a long write),
//! not the nodes'. Their beats of that time are still queued, unread; their clocks start
//! again instead of one being blamed. `cosim run` and `cosim replay` keep one each.

use std::time::{Duration, Instant};

/// The share of the heartbeat timeout that `cosim` may go without looking at its nodes before
/// the gap counts as its own stall.
pub const OWN_STALL: f64 = 0.5;

/// When `cosim` last looked at its nodes, and the stalls of its own it has seen.
pub struct OwnClock {
    at: Instant,
    /// How many own stalls, and the longest (s).
    pub count: u64,
    pub longest: f64,
}

impl Default for OwnClock {
    fn default() -> Self {
        OwnClock {
            at: Instant::now(),
            count: 0,
            longest: 0.0,
        }
    }
}

impl OwnClock {
    /// The clock starts now (the nodes are welcomed: they beat from here on).
    pub fn restart(&mut self) {
        self.at = Instant::now();
    }

    /// Time since the last look.
    pub fn since(&self, now: Instant) -> Duration {
        now.saturating_duration_since(self.at)
    }

    /// A look at the nodes now. When the gap since the last one is [`OWN_STALL`] of
    /// `timeout_s` or more while the nodes are judged by their beats (`beating`: before the
    /// Welcome the gap is the launch), it is counted and returned (s): the caller restarts
    /// the nodes' clocks.
    pub fn look(&mut self, timeout_s: f64, beating: bool) -> Option<f64> {
        let now = Instant::now();
        let gap = self.since(now).as_secs_f64();
        self.at = now;
        if !beating || gap < OWN_STALL * timeout_s {
            return None;
        }
        self.count += 1;
        self.longest = self.longest.max(gap);
        Some(gap)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gap_of_half_the_timeout_is_an_own_stall_while_beating() {
        let mut c = OwnClock::default();
        std::thread::sleep(Duration::from_millis(30));
        // 30 ms against a 1 s timeout: no stall.
        assert_eq!(c.look(1.0, true), None);
        std::thread::sleep(Duration::from_millis(30));
        // Against a 50 ms timeout it is one, but not before the nodes beat.
        assert_eq!(c.look(0.05, false), None);
        std::thread::sleep(Duration::from_millis(30));
        let gap = c.look(0.05, true).expect("a stall");
        assert!(gap >= 0.03, "{gap}");
        assert_eq!(c.count, 1);
        assert_eq!(c.longest, gap);
    }
}
