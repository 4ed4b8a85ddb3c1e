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

    /// Receive one message (waiting up to `timeout`): read and checked by a [`Reader`] inside
    /// the transport's callback, recorded there (a `Fields` every `record_every` windows),
    /// then acted on. Returns whether one arrived.
    pub(super) fn pump_inner(&mut self, timeout: Duration) -> Result<bool, Fault> {
        let mut read: Option<(TopicId, Read)> = None;
        let rec = &mut self.rec;
        let sim_t = self.sim_t;
        let every = self.case.run.record_every;
        let mut reader = Reader {
            run: self.run.as_str(),
            nodes: &self.nodes,
            topics: &self.topics,
            contracts: &self.contracts,
            books: &mut self.books,
            inbox: &mut self.inbox,
            // Peer data nobody here consumes (no lagrange hub) is checked and recorded where
            // it lies: a large field is never copied out of the transport's buffer.
            in_place: self.hubs.is_empty(),
        };
        let entered = Instant::now();
        let (mut in_cb, mut recorded) = (0u64, 0u64);
        // Allocations in the transport's receive, its callback (ours) excepted.
        let (a0, mut cb_allocs) = (crate::profile::allocations_now(), 0u64);
        let r = self.t.recv(timeout, &mut |id, bytes| {
            let cb = Instant::now();
            let cb_a0 = crate::profile::allocations_now();
            let got = reader.read(id, bytes);
            let keep = got
                .fields_window
                .is_none_or(|w| every <= 1 || w % every == 0);
            let r0 = Instant::now();
            if keep && let Some((name, _)) = reader.topics.get(id) {
                let _ = rec.message(name, sim_t, bytes);
            }
            read = Some((id, got));
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
        match read {
            Some((id, got)) => self.act(id, got).map(|()| true),
            None => Ok(false),
        }
    }

    /// Act on message `got` read on topic `id`: a message that claims another sender or
    /// run, is malformed or breaches its contract is the topic's node's fault; a `Fields`
    /// checked in place and a `Done` are taken here, anything else by
    /// [`Coord::take_message`].
    fn act(&mut self, id: TopicId, got: Read) -> Result<(), Fault> {
        if let Some(w) = got.fields_window
            && let Some(last) = self.last_fields.get_mut(id)
        {
            *last = Some(last.map_or(w, |l| l.max(w)));
        }
        let owner = match self.topics[id].1 {
            Topic::Up(i) | Topic::Data(i) => i,
        };
        let message = match got.got {
            Got::Fields(claimed) => {
                claimed.map_err(|c| self.claims(owner, id, c))?;
                None
            }
            Got::Done(claimed) => {
                let w = claimed.map_err(|c| self.claims(owner, id, c))?;
                let n = &mut self.nodes[owner];
                n.last_seen = Instant::now();
                let (inbox, spare) = (&mut self.inbox[owner], &mut self.spare[owner]);
                take_done(n, w, self.window, inbox, spare);
                return Ok(());
            }
            Got::Full(dec) => {
                let claimed = dec.map_err(|e| Fault {
                    node: self.nodes[owner].name.clone(),
                    reason: format!("malformed message on {}: {e}", self.topics[id].0),
                })?;
                Some(claimed.map_err(|c| self.claims(owner, id, c))?)
            }
        };
        if let Some(reason) = got.breach {
            return Err(Fault {
                node: self.nodes[owner].name.clone(),
                reason,
            });
        }
        self.nodes[owner].last_seen = Instant::now();
        match message {
            Some(m) => self.take_message(owner, id, m),
            None => Ok(()),
        }
    }

    /// Node `owner`'s fault: a message on topic `id` that claims another sender or run.
    fn claims(&self, owner: usize, id: TopicId, (sender, run): (String, String)) -> Fault {
        Fault {
            node: self.nodes[owner].name.clone(),
            reason: format!(
                "message on {} claims sender '{sender}' of run '{run}'",
                self.topics[id].0
            ),
        }
    }

    /// A whole message `message` from node `owner` on topic `id`, checked for its sender and
    /// contract: the hand-shake's, a heartbeat, a `Done` read in full, a failure, or a
    /// lagrange side's data.
    fn take_message(&mut self, owner: usize, id: TopicId, message: Message) -> Result<(), Fault> {
        let n = &mut self.nodes[owner];
        match message {
            Message::Hello(h) => self.take_hello(owner, &h)?,
            Message::Describe(d) => self.take_describe(owner, d)?,
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
                self.lagrange_input(&name, LagIn::Mesh(m))?;
            }
            Message::Fields(f) => {
                let name = n.name.clone();
                self.lagrange_input(&name, LagIn::Fields(f))?;
            }
            other => {
                return Err(Fault {
                    node: n.name.clone(),
                    reason: format!("unexpected {} on {}", other.type_name(), self.topics[id].0),
                });
            }
        }
        Ok(())
    }

    /// Node `owner`'s `Hello`: its protocol version, and a remote node's run token (a wrong
    /// one is rejected and the node stays unknown).
    fn take_hello(&mut self, owner: usize, h: &Hello) -> Result<(), Fault> {
        if h.protocol_version != codec::PROTOCOL_VERSION {
            return Err(Fault {
                node: self.nodes[owner].name.clone(),
                reason: format!(
                    "speaks protocol {}, cosim {}",
                    h.protocol_version,
                    codec::PROTOCOL_VERSION
                ),
            });
        }
        if self.case.nodes[owner].remote && h.token != self.token {
            let _ = self.send(
                owner,
                &Message::Reject(Reject {
                    reason: "wrong run token".into(),
                }),
            );
            tracing::warn!(
                "rejected a node presenting a wrong token as '{}'",
                self.nodes[owner].name
            );
            return Ok(());
        }
        self.nodes[owner].hello = true;
        Ok(())
    }

    /// Node `owner`'s `Describe`: a remote node not described before the run is checked now,
    /// before any window, its interfaces and fields against every coupling it is in.
    fn take_describe(&mut self, owner: usize, d: Describe) -> Result<(), Fault> {
        let n = &mut self.nodes[owner];
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
        Ok(())
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

/// What reading a message on the run's topics needs of the coordinator, borrowed apart from
/// its recorder and transport.
struct Reader<'a> {
    run: &'a str,
    nodes: &'a [NodeRt],
    topics: &'a [(String, Topic)],
    contracts: &'a [Option<Contract>],
    books: &'a mut crate::books::Books,
    inbox: &'a mut [StepReport],
    /// Peer data is checked in place, not decoded whole (no lagrange hub reads it).
    in_place: bool,
}

/// One message read on a topic.
struct Read {
    got: Got,
    /// A `Fields`'s window.
    fields_window: Option<u64>,
    /// The first breach of a `Fields` against its topic's contract.
    breach: Option<String>,
}

impl Reader<'_> {
    /// Read `bytes`, which arrived on topic `id`: a `Done`'s report into the node's inbox, a
    /// `Fields` checked in place against its contract (or decoded whole for a lagrange hub),
    /// anything else decoded whole; a `Fields`'s force is booked for the booking rule.
    fn read(&mut self, id: TopicId, bytes: &[u8]) -> Read {
        let kind = codec::header(bytes).map(|h| h.kind).ok();
        let owner = self.topics.get(id).map(|(_, t)| match t {
            Topic::Up(i) | Topic::Data(i) => *i,
        });
        let (run, nodes) = (self.run, self.nodes);
        let claimed = |sender: &str, r: &str| {
            (r == run && owner.is_some_and(|i| nodes[i].name == sender))
                .then_some(())
                .ok_or_else(|| (sender.to_string(), r.to_string()))
        };
        let plain = |got| Read {
            got,
            fields_window: None,
            breach: None,
        };
        if let Some(report) = owner
            .and_then(|i| self.inbox.get_mut(i))
            .filter(|_| kind == Some(codec::DONE_KIND))
        {
            // Every node's Done, every window: its report is read in place.
            return plain(match codec::decode_done_into(bytes, report) {
                Ok(h) => Got::Done(claimed(h.sender, h.run).map(|_| h.window)),
                Err(e) => Got::Full(Err(e)),
            });
        }
        if self.in_place && kind == Some(codec::FIELDS_KIND) {
            return self.read_fields(id, bytes, claimed);
        }
        // Run and sender stay in the bytes: a heartbeat allocates nothing.
        let e = match codec::decode_ref(bytes) {
            Ok(e) => e,
            Err(e) => return plain(Got::Full(Err(e))),
        };
        let (mut fields_window, mut breach) = (None, None);
        if let Message::Fields(f) = &e.message {
            if let Some(c) = self.contracts.get(id).and_then(Option::as_ref) {
                let mut check = c.check();
                for x in &f.fields {
                    check.field(&x.name, x.components, x.values.len());
                }
                breach = check.finish(f.window).err();
            }
            if breach.is_none() && self.books.wants(id) {
                self.books
                    .force(id, f.window, crate::books::force_of(&f.fields));
            }
            fields_window = Some(f.window);
        }
        Read {
            got: Got::Full(Ok(claimed(e.sender, e.run).map(|_| e.message))),
            fields_window,
            breach,
        }
    }

    /// A `Fields` checked where it lies: its fields against the topic's contract and its
    /// force summed for the booking rule, nothing copied.
    fn read_fields(
        &mut self,
        id: TopicId,
        bytes: &[u8],
        claimed: impl Fn(&str, &str) -> Result<(), (String, String)>,
    ) -> Read {
        let contract = self.contracts.get(id).and_then(Option::as_ref);
        let mut check = contract.map(Contract::check);
        let booked = self.books.wants(id);
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
                let breach = check.and_then(|c| c.finish(v.window).err());
                if booked && breach.is_none() {
                    self.books.force(id, v.window, force);
                }
                Read {
                    got: Got::Fields(claimed(v.sender, v.run)),
                    fields_window: Some(v.window),
                    breach,
                }
            }
            Err(e) => Read {
                got: Got::Full(Err(e)),
                fields_window: None,
                breach: None,
            },
        }
    }
}
