//! What comes in: every message on the run's topics, read, checked, recorded and acted on.

use super::coord::*;
use crate::case::{self};
use crate::contract::Contract;
use crate::profile::Phase;
use protocol::codec::{self, encode_into};
use protocol::transport::TopicId;
use protocol::*;
use std::time::{Duration, Instant};

impl Coord<'_> {
    /// Receive, record and act on one message. Returns whether one arrived.
    pub(super) fn pump_one(&mut self, timeout: Duration) -> Result<bool, Fault> {
        let start = Instant::now();
        let r = self.pump_inner(timeout);
        // What was neither blocked nor recording: decoding and acting on the message.
        let total = start.elapsed().as_nanos() as u64;
        let (blocked, recorded) = self.last_recv_ns;
        self.prof
            .add_ns(Phase::Handle, total.saturating_sub(blocked + recorded));
        r
    }

    pub(super) fn pump_inner(&mut self, timeout: Duration) -> Result<bool, Fault> {
        let mut got: Option<(TopicId, Got)> = None;
        let rec = &mut self.rec;
        let topics = &self.topics;
        let contracts = &self.contracts;
        let books = &mut self.books;
        // The window of the `Fields` received, on its topic.
        let mut fields_seen: Option<(usize, u64)> = None;
        // The first breach of a `Fields` against its contract (only then is anything written).
        let mut breach: Option<String> = None;
        let sim_t = self.sim_t;
        let every = self.case.run.record_every;
        // Peer data nobody here consumes (no lagrange hub) is checked and recorded where it
        // lies: a large field is never copied out of the transport's buffer.
        let in_place = self.hubs.is_empty();
        let (run, nodes) = (self.run.as_str(), &self.nodes);
        let inbox = &mut self.inbox;
        let entered = Instant::now();
        let (mut in_cb, mut recorded) = (0u64, 0u64);
        // Allocations in the transport's receive, its callback (ours) excepted.
        let (a0, mut cb_allocs) = (crate::profile::allocations_now(), 0u64);
        let r = self.t.recv(timeout, &mut |id, bytes| {
            let cb = Instant::now();
            let cb_a0 = crate::profile::allocations_now();
            let kind = codec::header(bytes).map(|h| h.kind).ok();
            let owner = topics.get(id).map(|(_, t)| match t {
                Topic::Up(i) | Topic::Data(i) => *i,
            });
            let claimed = |sender: &str, r: &str| {
                (r == run && owner.is_some_and(|i| nodes[i].name == sender))
                    .then_some(())
                    .ok_or_else(|| (sender.to_string(), r.to_string()))
            };
            let (dec, fields_window) = if let Some(report) = owner
                .and_then(|i| inbox.get_mut(i))
                .filter(|_| kind == Some(codec::DONE_KIND))
            {
                // Every node's Done, every window: its report is read in place.
                match codec::decode_done_into(bytes, report) {
                    Ok(h) => (Got::Done(claimed(h.sender, h.run).map(|_| h.window)), None),
                    Err(e) => (Got::Full(Err(e)), None),
                }
            } else if in_place && kind == Some(codec::FIELDS_KIND) {
                let contract = contracts.get(id).and_then(Option::as_ref);
                let mut check = contract.map(Contract::check);
                let booked = books.wants(id);
                let mut force = ([0.0; 3], 0.0);
                let head = codec::decode_fields_each(bytes, &mut |f| {
                    if let Some(c) = check.as_mut() {
                        c.field(f.name, f.components, f.len());
                    }
                    if booked && f.name == "force" && f.components == 3 {
                        force = crate::books::sum_force(f.values());
                    }
                });
                match head {
                    Ok(v) => {
                        breach = check.and_then(|c| c.finish(v.window).err());
                        if booked && breach.is_none() {
                            books.force(id, v.window, force);
                        }
                        (Got::Fields(claimed(v.sender, v.run)), Some(v.window))
                    }
                    Err(e) => (Got::Full(Err(e)), None),
                }
            } else {
                // Run and sender stay in the bytes: a heartbeat allocates nothing.
                match codec::decode_ref(bytes) {
                    Ok(e) => {
                        let w = match &e.message {
                            Message::Fields(f) => {
                                if let Some(c) = contracts.get(id).and_then(Option::as_ref) {
                                    let mut check = c.check();
                                    for x in &f.fields {
                                        check.field(&x.name, x.components, x.values.len());
                                    }
                                    breach = check.finish(f.window).err();
                                }
                                if breach.is_none() && books.wants(id) {
                                    books.force(id, f.window, crate::books::force_of(&f.fields));
                                }
                                Some(f.window)
                            }
                            _ => None,
                        };
                        (
                            Got::Full(Ok(claimed(e.sender, e.run).map(|_| e.message))),
                            w,
                        )
                    }
                    Err(e) => (Got::Full(Err(e)), None),
                }
            };
            fields_seen = fields_window.map(|w| (id, w));
            let keep = fields_window.is_none_or(|w| every <= 1 || w % every == 0);
            let r0 = Instant::now();
            if keep && let Some((name, _)) = topics.get(id) {
                let _ = rec.message(name, sim_t, bytes);
            }
            got = Some((id, dec));
            recorded += r0.elapsed().as_nanos() as u64;
            in_cb += cb.elapsed().as_nanos() as u64;
            cb_allocs += crate::profile::allocations_now() - cb_a0;
        });
        let transport = crate::profile::allocations_now() - a0 - cb_allocs;
        self.prof.add_transport_allocs(transport);
        let blocked = (entered.elapsed().as_nanos() as u64).saturating_sub(in_cb);
        self.prof.add_ns(Phase::Blocked, blocked);
        self.prof.add_ns(Phase::RecordMessages, recorded);
        self.last_recv_ns = (blocked, recorded);
        if let Err(e) = r {
            return Err(Fault {
                node: "coordinator".into(),
                reason: format!("transport: {e}"),
            });
        }
        let Some((id, dec)) = got else {
            return Ok(false);
        };
        if let Some((t, w)) = fields_seen
            && let Some(last) = self.last_fields.get_mut(t)
        {
            *last = Some(last.map_or(w, |l| l.max(w)));
        }
        let owner = match self.topics[id].1 {
            Topic::Up(i) | Topic::Data(i) => i,
        };
        let tname = self.topics[id].0.as_str();
        let dec = match dec {
            Got::Full(dec) => dec,
            Got::Fields(claimed) => {
                let n = &mut self.nodes[owner];
                if let Err((sender, run)) = claimed {
                    return Err(Fault {
                        node: n.name.clone(),
                        reason: format!(
                            "message on {tname} claims sender '{sender}' of run '{run}'"
                        ),
                    });
                }
                if let Some(reason) = breach {
                    return Err(Fault {
                        node: n.name.clone(),
                        reason,
                    });
                }
                n.last_seen = Instant::now();
                return Ok(true);
            }
            Got::Done(claimed) => {
                let n = &mut self.nodes[owner];
                match claimed {
                    Err((sender, run)) => {
                        return Err(Fault {
                            node: n.name.clone(),
                            reason: format!(
                                "message on {tname} claims sender '{sender}' of run '{run}'"
                            ),
                        });
                    }
                    Ok(w) => {
                        n.last_seen = Instant::now();
                        let (inbox, spare) = (&mut self.inbox[owner], &mut self.spare[owner]);
                        take_done(n, w, self.window, inbox, spare);
                        return Ok(true);
                    }
                }
            }
        };
        let claimed = dec.map_err(|e| Fault {
            node: self.nodes[owner].name.clone(),
            reason: format!("malformed message on {tname}: {e}"),
        })?;
        let n = &mut self.nodes[owner];
        let message = claimed.map_err(|(sender, run)| Fault {
            node: n.name.clone(),
            reason: format!("message on {tname} claims sender '{sender}' of run '{run}'"),
        })?;
        if let Some(reason) = breach {
            return Err(Fault {
                node: n.name.clone(),
                reason,
            });
        }
        n.last_seen = Instant::now();
        self.take_message(owner, id, message)
    }

    /// A whole message `message` from node `owner` on topic `id`, checked for its sender and
    /// contract: the hand-shake's, a heartbeat, a `Done` read in full, a failure, or a
    /// lagrange side's data. Ok(true): it was taken.
    fn take_message(&mut self, owner: usize, id: TopicId, message: Message) -> Result<bool, Fault> {
        let tname = self.topics[id].0.as_str();
        let n = &mut self.nodes[owner];
        match message {
            Message::Hello(h) => {
                if h.protocol_version != codec::PROTOCOL_VERSION {
                    return Err(Fault {
                        node: n.name.clone(),
                        reason: format!(
                            "speaks protocol {}, cosim {}",
                            h.protocol_version,
                            codec::PROTOCOL_VERSION
                        ),
                    });
                }
                let remote = self.case.nodes[owner].remote;
                if remote && h.token != self.token {
                    let i = owner;
                    let _ = self.send(
                        i,
                        &Message::Reject(Reject {
                            reason: "wrong run token".into(),
                        }),
                    );
                    tracing::warn!(
                        "rejected a node presenting a wrong token as '{}'",
                        self.nodes[i].name
                    );
                    return Ok(true);
                }
                n.hello = true;
            }
            Message::Describe(d) => {
                // A remote node not described before the run is checked now, before any
                // window: its interfaces and fields against every coupling it is in.
                if self.case.nodes[owner].interfaces.is_none() {
                    case::check_joined(self.case, &n.name, &d.interfaces).map_err(|e| Fault {
                        node: n.name.clone(),
                        reason: format!("refused at the handshake: {e}"),
                    })?;
                    // Its interfaces size the data of the couplings it drives.
                    for c in self.contracts.iter_mut().flatten() {
                        for i in &d.interfaces {
                            c.learn(&n.name, i);
                        }
                    }
                }
                n.described += 1;
                n.stable_dt = d.stable_dt;
                for w in d.warnings {
                    if !n.warnings.contains(&w) {
                        tracing::warn!("node '{}': {w}", n.name);
                        n.warnings.push(w);
                    }
                }
            }
            Message::Done(mut d) => {
                take_done(
                    n,
                    d.window,
                    self.window,
                    &mut d.report,
                    &mut self.spare[owner],
                );
            }
            Message::Heartbeat(h) => {
                if !h.waiting {
                    n.waiting_since = None;
                } else if n.waiting_since.is_none() {
                    n.waiting_since = Some(Instant::now());
                }
            }
            Message::Failed(f) => {
                let log = n
                    .log
                    .as_deref()
                    .map(|l| format!(" (its log: {})", l.display()))
                    .unwrap_or_default();
                let failed = Fault {
                    node: n.name.clone(),
                    reason: format!("{}{log}", f.reason),
                };
                return Err(self.culprit(failed));
            }
            Message::Mesh(m) => {
                let name = n.name.clone();
                return self.lagrange_input(&name, LagIn::Mesh(m)).map(|_| true);
            }
            Message::Fields(f) => {
                let name = n.name.clone();
                return self.lagrange_input(&name, LagIn::Fields(f)).map(|_| true);
            }
            other => {
                return Err(Fault {
                    node: n.name.clone(),
                    reason: format!("unexpected {} on {tname}", other.type_name()),
                });
            }
        }
        Ok(true)
    }

    /// The fault to report for node `failed`'s `Failed`: a node often fails on what a peer
    /// sent it, and the peer's breaking `Fields` may still be queued here (another topic).
    /// What is queued is read for a moment; a breach found there names the node at fault.
    pub(super) fn culprit(&mut self, failed: Fault) -> Fault {
        if self.draining {
            return failed;
        }
        self.draining = true;
        let deadline = Instant::now() + Duration::from_millis(100);
        let mut found = None;
        while found.is_none() && Instant::now() < deadline {
            match self.pump_one(Duration::from_millis(10)) {
                Err(f) if f.reason.starts_with(crate::contract::BREACH) => found = Some(f),
                Err(_) | Ok(false) => break,
                Ok(true) => {}
            }
        }
        self.draining = false;
        found.unwrap_or(failed)
    }

    /// A side's mesh or fields on a lagrange coupling: to its hub, and what the hub answers
    /// (the multipliers) to the sides, recorded like every message.
    pub(super) fn lagrange_input(&mut self, node: &str, input: LagIn) -> Result<(), Fault> {
        let coupling = match &input {
            LagIn::Mesh(m) => m.coupling.clone(),
            LagIn::Fields(f) => f.coupling.clone(),
        };
        let Some(h) = self.hubs.iter().position(|(h, _)| h.coupling == coupling) else {
            return Ok(());
        };
        let fault = |reason: String| Fault {
            node: node.to_string(),
            reason: format!("coupling {coupling}: {reason}"),
        };
        let hub = &mut self.hubs[h].0;
        let out = match input {
            LagIn::Mesh(m) => hub.on_mesh(node, m.mesh),
            LagIn::Fields(f) => hub.on_fields(node, f),
        }
        .map_err(fault)?;
        for f in out {
            self.publish_lagrange(h, f)?;
        }
        Ok(())
    }

    /// Publish (and record) a coordinator message of lagrange hub `h`.
    pub(super) fn publish_lagrange(&mut self, h: usize, f: Fields) -> Result<(), Fault> {
        self.seq += 1;
        let name = self.hubs[h].0.coupling.clone();
        let fault = |reason: String| Fault {
            node: "coordinator".into(),
            reason: format!("coupling {name}: {reason}"),
        };
        let time = f.time;
        encode_into(
            &mut self.buf,
            &self.run,
            "coordinator",
            self.seq,
            &Message::Fields(f),
        )
        .map_err(|e| fault(format!("cannot encode the multipliers: {e}")))?;
        let tp = topic::data(&self.run, &name, protocol::scheme::lagrange::wire::PEER);
        let _ = self.rec.message(&tp, time, &self.buf);
        self.hubs[h]
            .1
            .send(&self.buf)
            .map_err(|e| fault(format!("send failed: {e}")))
    }
}

/// A node's `Done` of `window` (its report in `report`) while the coordinator is at window
/// `at`: the node's totals, and the report as the node's current one, or queued when it is of
/// a later window (pipelining). `report` is swapped, not moved: it comes back holding a
/// report's buffers (the replaced one, or a spare), so reading the next `Done` into it
/// allocates nothing.
pub(super) fn take_done(
    n: &mut NodeRt,
    window: u64,
    at: u64,
    report: &mut StepReport,
    spare: &mut Vec<StepReport>,
) {
    n.done = Some(window);
    n.waiting_since = None;
    n.substeps += report.substeps;
    n.idle_s += report.idle_s;
    n.wall_s += report.wall_s;
    n.wait_s += report.coupling_wait_s;
    if window == 0 {
        n.initial_energy = report.kinetic_energy + report.internal_energy + report.dissipated();
        n.initial_momentum = report.momentum;
    }
    if window > at {
        let mut queued = spare.pop().unwrap_or_default();
        std::mem::swap(&mut queued, report);
        n.ahead.push_back((window, queued));
    } else {
        std::mem::swap(&mut n.report, report);
    }
}
