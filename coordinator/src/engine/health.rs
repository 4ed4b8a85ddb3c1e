//! Who is alive: the nodes' processes and heartbeats, the coordinator's own stalls, and
//! waiting for every node of a list to reach a state.

use super::coord::*;
use crate::case::{self};
use crate::launch::{describe_status, log_note};
use crate::profile::Phase;
use std::time::{Duration, Instant};

impl Coord<'_> {
    /// Forgive the nodes the silence the coordinator was not awake to observe: when it has not
    /// looked at them for [`crate::clock::OWN_STALL`] of the heartbeat timeout or longer, the nodes' beats
    /// of that time are still queued, unread, and their clocks start again now.
    /// Only while nodes are judged by their beats (`beating`): before the Welcome the gap is
    /// the launch.
    pub(super) fn forgive_own_stall(&mut self, beating: bool) {
        let timeout = self.case.run.heartbeat_timeout;
        let Some(gap) = self.own.look(timeout, beating) else {
            return;
        };
        let now = Instant::now();
        for n in &mut self.nodes {
            n.last_seen = now;
            if let Some(w) = n.waiting_since.as_mut() {
                *w = now;
            }
        }
        let msg = format!(
            "cosim: the coordinator itself did not run for {gap:.1} s during window {} (a busy machine, a stopped process, a suspend): no node is blamed for that silence (run.heartbeat_timeout = {timeout} s)",
            self.window
        );
        tracing::warn!("{msg}");
    }

    /// Check children and heartbeats; returns the first fault.
    pub(super) fn check_health(&mut self, waiting_on: &[usize]) -> Result<(), Fault> {
        self.forgive_own_stall(!waiting_on.is_empty());
        self.check_exits()?;
        self.check_beats(waiting_on)?;
        // Alive but stuck: every node we wait for has been blocked on a peer's input for the
        // stall timeout (two nodes waiting for each other, say), so none can ever deliver.
        let stall = Duration::from_secs_f64(self.case.run.stall_timeout);
        if !waiting_on.is_empty()
            && waiting_on.iter().all(|&i| {
                self.nodes[i]
                    .waiting_since
                    .is_some_and(|t| t.elapsed() > stall)
            })
        {
            return Err(self.deadlock(waiting_on));
        }
        for lost in self.t.lost_endpoints() {
            // Before its accepted Hello a name may be tried by a rejected process: not a fault.
            if self
                .node_idx(&lost)
                .is_some_and(|i| self.nodes[i].hello && self.nodes[i].finished.is_none())
            {
                return Err(Fault {
                    node: lost,
                    reason: "connection lost (liveliness token dropped)".into(),
                });
            }
        }
        Ok(())
    }

    /// A node's process that exited without being told to finish: the fault, after its last
    /// words (a `Failed` message) had a moment to arrive.
    fn check_exits(&mut self) -> Result<(), Fault> {
        for i in 0..self.nodes.len() {
            let n = &mut self.nodes[i];
            if n.finished.is_some() {
                continue; // told to finish: its exit is expected
            }
            if n.exited.is_none()
                && let Some(c) = n.child.as_mut()
                && let Ok(Some(st)) = c.try_wait()
            {
                n.exited = Some(describe_status(st));
            }
            if let Some(why) = n.exited.clone() {
                let name = n.name.clone();
                let log = n.log.as_deref().map(log_note).unwrap_or_default();
                let deadline = Instant::now() + Duration::from_millis(100);
                while Instant::now() < deadline {
                    self.pump_one(Duration::from_millis(10))?;
                }
                return Err(Fault {
                    node: name,
                    reason: format!("{why} during window {}{log}", self.window),
                });
            }
        }
        Ok(())
    }

    /// A node of `waiting_on` silent for longer than the heartbeat timeout, once the beats
    /// queued behind the coordinator's own work are read.
    fn check_beats(&mut self, waiting_on: &[usize]) -> Result<(), Fault> {
        let timeout = Duration::from_secs_f64(self.case.run.heartbeat_timeout);
        if waiting_on
            .iter()
            .any(|&i| self.nodes[i].last_seen.elapsed() > timeout)
        {
            for _ in 0..QUEUED_MAX {
                if !self.pump_one(Duration::ZERO)? {
                    break;
                }
            }
        }
        for &i in waiting_on {
            let n = &self.nodes[i];
            if n.last_seen.elapsed() > timeout {
                return Err(Fault {
                    node: n.name.clone(),
                    reason: format!(
                        "no heartbeat for {:.1} s (timeout {} s) during window {}",
                        n.last_seen.elapsed().as_secs_f64(),
                        self.case.run.heartbeat_timeout,
                        self.window
                    ),
                });
            }
        }
        Ok(())
    }

    /// The deadlock of the nodes `waiting_on`, all blocked on a peer's input: what each waits
    /// for and who owes it, the first such sender named.
    fn deadlock(&self, waiting_on: &[usize]) -> Fault {
        let names: Vec<&str> = waiting_on
            .iter()
            .map(|&i| self.nodes[i].name.as_str())
            .collect();
        let mut missing = Vec::new();
        for &i in waiting_on {
            let n = &self.nodes[i];
            let working = n.done.map_or(0, |d| d + 1);
            let bindings = case::bindings_of(self.case, &n.name);
            missing.extend(crate::deadlock::missing(
                &n.name,
                working,
                &bindings,
                |c, s| self.fields_seen(c, s),
                |c| {
                    let ci = self.case.couplings.iter().position(|x| x.name == c)?;
                    self.until[ci]
                },
            ));
        }
        let said = if missing.is_empty() {
            "; every input they wait for was sent, as far as the coordinator saw (lost on its way?)"
                .to_string()
        } else {
            let what: Vec<&str> = missing.iter().map(|m| m.what.as_str()).collect();
            format!(": {}", what.join("; "))
        };
        Fault {
            node: missing
                .first()
                .map_or(names[0], |m| m.sender.as_str())
                .to_string(),
            reason: format!(
                "deadlock: {} s during window {} with every running node ({}) waiting for a peer's input{said}",
                self.case.run.stall_timeout,
                self.window,
                names.join(", ")
            ),
        }
    }

    /// Pump until `pred` holds for every node in `who`.
    /// Wait until `pred` holds for every node of `who`, checking their health meanwhile;
    /// `limit` is the longest wait and the reason given when it passes.
    pub(super) fn wait_all(
        &mut self,
        who: &[usize],
        what: &str,
        limit: Option<(Duration, &str)>,
        pred: impl Fn(&NodeRt) -> bool,
    ) -> Result<(), Fault> {
        let start = Instant::now();
        // Nodes beat from the Welcome on: before it only an exit is a fault.
        let beating = what != "Hello";
        // Reused across calls: a window's wait allocates nothing.
        let mut pending = std::mem::take(&mut self.pending);
        loop {
            pending.clear();
            pending.extend(who.iter().copied().filter(|&i| !pred(&self.nodes[i])));
            if pending.is_empty() {
                self.pending = pending;
                return Ok(());
            }
            let t = Instant::now();
            self.stop_now()?;
            // Children, heartbeats and stalls are looked at every few milliseconds, not after
            // every message (a window brings several): faults are judged in seconds.
            if self.own.since(t) >= HEALTH_EVERY {
                self.check_health(if beating { &pending } else { &[] })?;
            }
            self.prof.lap(Phase::Health, t);
            if let Some((l, why)) = limit
                && start.elapsed() > l
            {
                return Err(Fault {
                    node: self.nodes[pending[0]].name.clone(),
                    reason: format!("no {what} within {} s: {why}", l.as_secs_f64()),
                });
            }
            if !self.pump_one(Duration::from_millis(20))? {
                // Idle: what the recorder was given so far goes to its thread now.
                let _ = self.rec.commit();
            }
        }
    }
}
