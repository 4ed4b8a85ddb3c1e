//! `cosim replay` and `cosim info` (docs/architecture.md). Replay launches one node's executable as
//! a real node process on a fresh shared-memory run, plays the coordinator and every peer of
//! that node from the recording (Welcome, peer meshes and fields, Advance, Decouple, Finish),
//! and compares what the node sends with what the original node sent, window by window.
//!
//! The node is known only through the protocol, so a built-in node, one written in another
//! language, or another executable named with `--solver` replay alike. A replay is complete
//! only when every window the recording holds of the node was compared; anything less (a cut
//! recording, a node that stops early, a missing field) is reported as incomplete.

use crate::launch::{describe_status, log_note, pick_run_id, spawn_node};
use crate::record::{self, Recorded};
use anyhow::{Context, bail};
use protocol::codec::{self, encode_into};
use protocol::participant::is_motion;
use protocol::transport::{self, Publisher, TopicId, Transport, TransportKind, TransportSpec};
use protocol::*;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Child;
use std::time::{Duration, Instant};

/// Largest differences of one field in one window.
#[derive(Debug, Clone, Default)]
pub struct Diff {
    pub max_abs: f64,
    pub max_rel: f64,
    pub identical: bool,
}

fn diff(a: &[f64], b: &[f64]) -> Diff {
    if a.len() != b.len() {
        return Diff {
            max_abs: f64::INFINITY,
            max_rel: f64::INFINITY,
            identical: false,
        };
    }
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let mut d = Diff {
        identical: true,
        ..Default::default()
    };
    for (x, y) in a.iter().zip(b) {
        if x.to_bits() != y.to_bits() {
            d.identical = false;
        }
        let e = (x - y).abs();
        d.max_abs = d.max_abs.max(e);
    }
    d.max_rel = if scale > 0.0 {
        d.max_abs / scale
    } else {
        d.max_abs
    };
    d
}

/// What `cosim replay` may change about the node it replays.
#[derive(Debug, Clone, Default)]
pub struct ReplayOptions {
    /// Parameter overrides, `KEY=VALUE` or `model=NAME`.
    pub sets: Vec<String>,
    /// Executable to launch instead of the recorded one.
    pub solver: Option<PathBuf>,
    /// Relative drift of the interface motion that triggers a warning.
    pub tolerance: f64,
    /// Run id of the replay (namespaces its shared memory; default: a fresh one).
    pub run_id: Option<String>,
    /// Where the node's log and output go (default: `replay-<node>` beside the recording).
    pub output: Option<PathBuf>,
}

/// Result of a replay.
#[derive(Debug, Clone, Default)]
pub struct ReplayReport {
    /// The executable that was replayed, and its model.
    pub exe: PathBuf,
    pub model: String,
    /// Windows of the node the recording holds (its `Done` of windows ≥ 1).
    pub recorded_windows: u64,
    /// Windows of the node replayed and compared.
    pub windows: u64,
    /// Field arrays compared (one per field, coupling and window, set-up included) and the
    /// values in them.
    pub fields_compared: u64,
    pub values_compared: u64,
    /// Report values compared (energies, momenta and the node's named scalars).
    pub report_values_compared: u64,
    /// Every compared value was bitwise equal.
    pub all_equal: bool,
    /// Why the replay is incomplete (each makes `cosim replay` exit non-zero).
    pub incomplete: Vec<String>,
    /// (window, coupling, field) → difference, for every compared field.
    pub rows: Vec<(u64, String, String, Diff)>,
    /// Report values: (window, name, replayed, recorded).
    pub scalars: Vec<(u64, String, f64, f64)>,
    /// End time of each replayed window: (window, t1).
    pub times: Vec<(u64, f64)>,
    /// First window where the node's interface motion drifted past the tolerance.
    pub drift: Option<(u64, String, f64)>,
}

/// `cosim replay`'s exit status when the replayed outputs differ from the recorded ones: apart
/// from 1 (the replay could not run, or could not compare every recorded window) so that a
/// regression suite tells a changed result from a broken set-up.
pub const EXIT_DIFFER: i32 = 3;

impl ReplayReport {
    /// The exit status of `cosim replay`: 0 when bit-identical; [`EXIT_DIFFER`] when a
    /// compared value differs (whether or not every window could be compared: a difference
    /// is a finding); 1 when nothing compared differs but the comparison is incomplete.
    pub fn exit_code(&self) -> i32 {
        if !self.all_equal {
            EXIT_DIFFER
        } else if self.bit_identical() {
            0
        } else {
            1
        }
    }

    /// Every recorded window was compared, nothing was missing, and every value matched.
    pub fn bit_identical(&self) -> bool {
        self.incomplete.is_empty()
            && self.windows > 0
            && self.windows == self.recorded_windows
            && self.fields_compared > 0
            && self.all_equal
    }
}

/// A recorded protocol message, decoded, with its topic.
pub(crate) struct Decoded {
    pub(crate) topic: String,
    pub(crate) env: Envelope,
}

/// The protocol messages of a recording (its JSON channels and undecodable messages left
/// out).
pub(crate) fn decode_all(msgs: &[Recorded]) -> Vec<Decoded> {
    msgs.iter()
        .filter(|m| !m.json)
        .filter_map(|m| {
            codec::decode(&m.data).ok().map(|env| Decoded {
                topic: m.topic.clone(),
                env,
            })
        })
        .collect()
}

/// The recorded case: its effective TOML and the path it was read from.
pub(crate) fn case_of(msgs: &[Recorded]) -> anyhow::Result<(toml::Table, PathBuf)> {
    let m = msgs
        .iter()
        .find(|m| m.topic == "/cosim/case")
        .context("the recording has no /cosim/case channel")?;
    let v: serde_json::Value = serde_json::from_slice(&m.data)?;
    let text = v["toml"].as_str().context("/cosim/case has no toml")?;
    let path = PathBuf::from(v["case"].as_str().unwrap_or(""));
    Ok((toml::from_str(text)?, path))
}

/// What the recording says about one node: what it was sent, by the coordinator and by its
/// peers, and what it answered.
struct Plan {
    welcome: Welcome,
    /// The executable the case named for the node, and the case file's directory.
    solver: String,
    case_dir: PathBuf,
    heartbeat_timeout: f64,
    stall_timeout: f64,
    /// Windows the case planned (end time over window).
    planned: u64,
    /// Peer meshes and peer fields, by the index of the node's binding they arrive on, in
    /// recorded order.
    peer_meshes: Vec<(usize, Mesh)>,
    peer_fields: Vec<(usize, Fields)>,
    advances: Vec<Advance>,
    decouples: Vec<Decouple>,
    /// The node's recorded outputs, by [`OutKey`], and its reports by window.
    outputs: BTreeMap<OutKey, Fields>,
    reports: BTreeMap<u64, StepReport>,
}

/// A node's output message: (window, coupling, step). The step is a lagrange side's coupling
/// step within the window (it sends one message per step; PROTOCOL.md §4.6), else 0.
type OutKey = (u64, String, usize);

fn out_key(f: &Fields) -> OutKey {
    let step = protocol::scheme::lagrange::wire::step_of(f).unwrap_or(0);
    (f.window, f.coupling.clone(), step)
}

fn plan(msgs: &[Recorded], node: &str) -> anyhow::Result<Plan> {
    let (case, case_path) = case_of(msgs)?;
    let n = case
        .get("nodes")
        .and_then(|n| n.get(node))
        .with_context(|| format!("node '{node}' is not in the recorded case"))?;
    let solver = n
        .get("solver")
        .and_then(|s| s.as_str())
        .with_context(|| format!("nodes.{node}.solver is missing in the recorded case"))?
        .to_string();
    let run_t = case.get("run");
    let get = |k: &str, default: f64| {
        run_t
            .and_then(|r| r.get(k))
            .and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
            .unwrap_or(default)
    };
    let dec = decode_all(msgs);
    let run = dec
        .first()
        .map(|d| d.env.run.clone())
        .context("the recording holds no protocol message")?;
    let down = topic::down(&run, node);
    let welcome = dec
        .iter()
        .find_map(|d| match &d.env.message {
            Message::Welcome(w) if d.topic == down => Some(w.clone()),
            _ => None,
        })
        .with_context(|| format!("no Welcome to node '{node}' in the recording"))?;
    let mut p = Plan {
        welcome,
        solver,
        case_dir: case_path
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default(),
        heartbeat_timeout: get("heartbeat_timeout", 3.0),
        stall_timeout: get("stall_timeout", 30.0),
        planned: ((get("end_time", 0.0) / get("window", 1.0)) - 1e-9)
            .ceil()
            .max(0.0) as u64,
        peer_meshes: Vec::new(),
        peer_fields: Vec::new(),
        advances: Vec::new(),
        decouples: Vec::new(),
        outputs: BTreeMap::new(),
        reports: BTreeMap::new(),
    };
    p.sort(&dec, node, &run);
    Ok(p)
}

impl Plan {
    /// The recorded messages `dec` of run `run` that concern node `node`, each to its list:
    /// what its peers sent it, its own outputs, the coordinator's commands and its reports.
    fn sort(&mut self, dec: &[Decoded], node: &str, run: &str) {
        let (down, up) = (topic::down(run, node), topic::up(run, node));
        let bindings = &self.welcome.bindings;
        let inputs: Vec<String> = bindings
            .iter()
            .map(|b| topic::data(run, &b.coupling, &b.peer))
            .collect();
        let outputs: Vec<String> = bindings
            .iter()
            .map(|b| topic::data(run, &b.coupling, node))
            .collect();
        for d in dec {
            let input = inputs.iter().position(|t| *t == d.topic);
            match &d.env.message {
                Message::Mesh(m) if input.is_some() => {
                    self.peer_meshes.extend(input.map(|i| (i, m.clone())));
                }
                Message::Fields(f) if input.is_some() => {
                    self.peer_fields.extend(input.map(|i| (i, f.clone())));
                }
                Message::Fields(f) if outputs.contains(&d.topic) => {
                    self.outputs.insert(out_key(f), f.clone());
                }
                Message::Advance(a) if d.topic == down && a.window > 0 => self.advances.push(*a),
                Message::Decouple(x) if d.topic == down => self.decouples.push(x.clone()),
                Message::Done(dn) if d.topic == up && dn.window > 0 => {
                    self.reports.insert(dn.window, dn.report.clone());
                }
                _ => {}
            }
        }
    }
}

/// The peer output window that window `window` of the node consumes on binding `b`, once
/// the coupling is decoupled before window `until`: the participant runtime's
/// driver/responder rule ([`protocol::scheme::driver_responder_input`]).
fn needed(b: &Binding, until: Option<u64>, window: u64) -> Option<u64> {
    protocol::scheme::driver_responder_input(b.role, b.input_lag, until, window)
}

/// One node process and the transport on which `cosim replay` and `cosim conformance` play
/// its coordinator and peers.
pub(crate) struct Session {
    t: Box<dyn Transport>,
    pub(crate) run: String,
    pub(crate) node: String,
    child: Option<Child>,
    down: Box<dyn Publisher>,
    /// One publisher per binding of the node, on the peer's data topic.
    peers: Vec<(String, Box<dyn Publisher>)>,
    up: TopicId,
    /// The node's data topics as the recorder subscribed to them; the replay also holds a
    /// second subscription to each in the peer's place (the node waits for both readers).
    outs: Vec<TopicId>,
    buf: Vec<u8>,
    seq: u64,
    log: PathBuf,
    heartbeat_timeout: Duration,
    stall_timeout: Duration,
    last_seen: Instant,
    /// Whether the node has been welcomed (and so sends heartbeats).
    beating: bool,
    waiting_since: Option<Instant>,
    /// When the node was last looked at, and `cosim`'s own stalls seen.
    own: crate::clock::OwnClock,
    pub(crate) window: u64,
    pub(crate) hello: bool,
    /// The node's `Describe`s, in order.
    pub(crate) describes: Vec<Describe>,
    pub(crate) done: Option<(u64, StepReport)>,
    /// The windows of the node's `Done`s, in order.
    pub(crate) dones: Vec<u64>,
    /// The node's fields as they arrive, compared by the caller.
    pub(crate) arrived: Vec<Fields>,
    /// The node's meshes as they arrive.
    pub(crate) meshes: Vec<Mesh>,
    /// Heartbeats received, and the longest time between two (from the `Welcome` on).
    pub(crate) beats: u64,
    pub(crate) longest_gap: Duration,
    last_beat: Option<Instant>,
    /// Why [`Session::check_health`] gave up on the node: it exited, or went silent.
    pub(crate) gone: Option<Gone>,
}

/// How a node was lost while a [`Session`] waited for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Gone {
    Exited,
    Silent,
}

impl Session {
    /// Launch `exe args…` as node `node` of a fresh shared-memory run `run`, with the
    /// coordinator's and the peers' ports of `bindings` open on this side, its log in `log`;
    /// it is given up on after the heartbeat and stall timeouts.
    pub(crate) fn launch(
        exe: &Path,
        args: &[String],
        run: &str,
        node: &str,
        bindings: &[Binding],
        log: PathBuf,
        (heartbeat_timeout, stall_timeout): (Duration, Duration),
    ) -> anyhow::Result<Session> {
        let spec = TransportSpec {
            kind: TransportKind::Shm,
            run: run.to_string(),
            endpoint: "coordinator".into(),
            listen: vec![],
            connect: vec![],
        };
        let mut t = transport::open(&spec).context("cannot open the transport")?;
        let up = t.subscribe(&topic::up(run, node))?;
        let mut outs = Vec::new();
        let mut peers = Vec::new();
        let me = vec![node.to_string()];
        for b in bindings {
            let tp = topic::data(run, &b.coupling, node);
            outs.push(t.subscribe(&tp)?);
            t.subscribe(&tp)?;
            let pub_ = t.publisher(&topic::data(run, &b.coupling, &b.peer), &me)?;
            peers.push((b.coupling.clone(), pub_));
        }
        let down = t.publisher(&topic::down(run, node), &me)?;
        let child = spawn_node(exe, args, run, node, TransportKind::Shm, None, &log)
            .map_err(|e| anyhow::anyhow!("node '{node}': {e}"))?;
        Ok(Session {
            t,
            run: run.to_string(),
            node: node.to_string(),
            child: Some(child),
            down,
            peers,
            up,
            outs,
            buf: Vec::new(),
            seq: 0,
            log,
            heartbeat_timeout,
            stall_timeout,
            last_seen: Instant::now(),
            beating: false,
            waiting_since: None,
            own: Default::default(),
            window: 0,
            hello: false,
            describes: Vec::new(),
            done: None,
            dones: Vec::new(),
            arrived: Vec::new(),
            meshes: Vec::new(),
            beats: 0,
            longest_gap: Duration::ZERO,
            last_beat: None,
            gone: None,
        })
    }

    /// Send `welcome` (the heartbeat clock starts), wait up to 60 s for the node's
    /// `Describe`, and send the set-up command (`Advance{0}`).
    pub(crate) fn welcome_and_set_up(&mut self, welcome: &Welcome) -> anyhow::Result<()> {
        self.welcome(welcome)?;
        self.set_up()
    }

    /// Send `welcome` (the heartbeat clock starts) and wait up to 60 s for the node's
    /// `Describe`.
    pub(crate) fn welcome(&mut self, welcome: &Welcome) -> anyhow::Result<()> {
        self.send_down(&Message::Welcome(welcome.clone()))?;
        self.beating = true;
        self.own.restart();
        self.last_seen = Instant::now();
        self.last_beat = Some(self.last_seen);
        self.wait("Describe", Some(Duration::from_secs(60)), |s| {
            !s.describes.is_empty()
        })
    }

    /// Send the set-up command (`Advance{0}`).
    pub(crate) fn set_up(&mut self) -> anyhow::Result<()> {
        self.send_down(&Message::Advance(Advance {
            window: 0,
            t0: 0.0,
            t1: 0.0,
            write_output: false,
            checkpoint: false,
        }))
    }

    /// Wait up to `limit` until `want` readers listen on binding `i`'s peer topic (`peer`'s
    /// data of that coupling), so that a first message there is not sent into the void.
    pub(crate) fn wait_readers(
        &mut self,
        i: usize,
        peer: &str,
        want: usize,
        limit: Duration,
    ) -> anyhow::Result<()> {
        let tp = topic::data(&self.run, &self.peers[i].0, peer);
        let start = Instant::now();
        while self.t.readers(&tp).is_some_and(|r| r < want) {
            self.check_health()?;
            if start.elapsed() > limit {
                return Err(self.fault(format!(
                    "never subscribed to {tp} within {} s",
                    limit.as_secs()
                )));
            }
            self.pump(Duration::from_millis(5))?;
        }
        Ok(())
    }

    fn fault(&self, reason: impl std::fmt::Display) -> anyhow::Error {
        anyhow::anyhow!(
            "node '{}': {reason} (its log: {})",
            self.node,
            self.log.display()
        )
    }

    pub(crate) fn send_down(&mut self, m: &Message) -> anyhow::Result<()> {
        self.seq += 1;
        encode_into(&mut self.buf, &self.run, "coordinator", self.seq, m)?;
        self.down
            .send(&self.buf)
            .map_err(|e| self.fault(format!("sending {}: {e}", m.type_name())))
    }

    /// Send a recorded peer message on binding `i`, from the peer.
    pub(crate) fn send_peer(&mut self, i: usize, peer: &str, m: &Message) -> anyhow::Result<()> {
        self.seq += 1;
        encode_into(&mut self.buf, &self.run, peer, self.seq, m)?;
        let p = &mut self.peers[i];
        let coupling = p.0.clone();
        p.1.send(&self.buf)
            .map_err(|e| self.fault(format!("sending {}'s data of '{coupling}': {e}", peer)))
    }

    /// Receive and act on one message; returns whether one arrived.
    pub(crate) fn pump(&mut self, timeout: Duration) -> anyhow::Result<bool> {
        let mut got = None;
        self.t.recv(timeout, &mut |id, bytes| {
            got = Some((id, codec::decode(bytes)));
        })?;
        let Some((id, dec)) = got else {
            return Ok(false);
        };
        let is_up = id == self.up;
        if !is_up && !self.outs.contains(&id) {
            return Ok(true); // the peer's copy of what the recorder copy already holds
        }
        let env = dec.map_err(|e| self.fault(format!("malformed message: {e}")))?;
        if env.sender != self.node || env.run != self.run {
            return Err(self.fault(format!(
                "a message claims sender '{}' of run '{}'",
                env.sender, env.run
            )));
        }
        self.last_seen = Instant::now();
        match env.message {
            Message::Hello(h) if is_up => {
                if h.protocol_version != codec::PROTOCOL_VERSION {
                    return Err(self.fault(format!(
                        "speaks protocol {}, cosim {}",
                        h.protocol_version,
                        codec::PROTOCOL_VERSION
                    )));
                }
                self.hello = true;
            }
            Message::Describe(d) if is_up => self.describes.push(d),
            Message::Done(d) if is_up => {
                self.waiting_since = None;
                self.dones.push(d.window);
                self.done = Some((d.window, d.report));
            }
            Message::Heartbeat(h) if is_up => {
                let now = Instant::now();
                if let Some(t) = self.last_beat {
                    self.longest_gap = self.longest_gap.max(now - t);
                }
                self.last_beat = Some(now);
                self.beats += 1;
                if !h.waiting {
                    self.waiting_since = None;
                } else if self.waiting_since.is_none() {
                    self.waiting_since = Some(Instant::now());
                }
            }
            Message::Failed(f) if is_up => return Err(self.fault(f.reason)),
            Message::Fields(f) if !is_up => self.arrived.push(f),
            Message::Mesh(m) if !is_up => self.meshes.push(m),
            other => {
                return Err(self.fault(format!("unexpected {}", other.type_name())));
            }
        }
        Ok(true)
    }

    /// The node exited, went silent, or waits for an input the replay will never send.
    fn check_health(&mut self) -> anyhow::Result<()> {
        if let Some(c) = self.child.as_mut()
            && let Ok(Some(st)) = c.try_wait()
        {
            // A dying node's last words (a Failed message) name the cause: read them first.
            // Whatever they are (or a transport's complaint about the dead sender), the exit
            // status is the certain fact and leads the message.
            let until = Instant::now() + Duration::from_millis(100);
            let mut last_words = String::new();
            while Instant::now() < until {
                if let Err(e) = self.pump(Duration::from_millis(10)) {
                    last_words = format!(" ({e:#})");
                    break;
                }
            }
            self.gone = Some(Gone::Exited);
            return Err(anyhow::anyhow!(
                "node '{}': {} during window {}{last_words}{}",
                self.node,
                describe_status(st),
                self.window,
                log_note(&self.log)
            ));
        }
        // A long gap since the last look was cosim's own stall: the node's beats of that time
        // are still queued, and its clocks start again.
        let timeout = self.heartbeat_timeout.as_secs_f64();
        if let Some(gap) = self.own.look(timeout, self.beating) {
            let now = Instant::now();
            self.last_seen = now;
            if let Some(w) = self.waiting_since.as_mut() {
                *w = now;
            }
            tracing::warn!(
                "cosim: cosim itself did not run for {gap:.1} s during window {} (a busy machine, a stopped process, a suspend): the node is not blamed for that silence (heartbeat timeout {timeout} s)",
                self.window
            );
        }
        // Heartbeats start with the Welcome; before it the Hello has its own limit.
        if self.beating && self.last_seen.elapsed() > self.heartbeat_timeout {
            self.gone = Some(Gone::Silent);
            return Err(self.fault(format!(
                "no heartbeat for {:.1} s (timeout {} s) during window {}",
                self.last_seen.elapsed().as_secs_f64(),
                self.heartbeat_timeout.as_secs_f64(),
                self.window
            )));
        }
        if self
            .waiting_since
            .is_some_and(|t| t.elapsed() > self.stall_timeout)
        {
            return Err(self.fault(format!(
                "waited {} s during window {} for an input the recording does not give",
                self.stall_timeout.as_secs_f64(),
                self.window
            )));
        }
        Ok(())
    }

    /// Pump until `pred` holds, failing on a fault or after `limit`.
    pub(crate) fn wait(
        &mut self,
        what: &str,
        limit: Option<Duration>,
        pred: impl Fn(&Session) -> bool,
    ) -> anyhow::Result<()> {
        let start = Instant::now();
        while !pred(self) {
            self.check_health()?;
            if let Some(l) = limit
                && start.elapsed() > l
            {
                return Err(self.fault(format!("no {what} within {} s", l.as_secs())));
            }
            self.pump(Duration::from_millis(20))?;
        }
        Ok(())
    }

    /// Wait for `Done` of `window`; returns its report.
    pub(crate) fn done(&mut self, window: u64) -> anyhow::Result<StepReport> {
        self.wait(&format!("Done of window {window}"), None, |s| {
            s.done.as_ref().is_some_and(|d| d.0 == window)
        })?;
        self.done
            .take()
            .map(|d| d.1)
            .ok_or_else(|| self.fault("Done vanished"))
    }

    /// End the node: `Finish` after a replay that went through (it exits on its own), `Abort`
    /// after a fault; killed if it has not exited in time. Then no process of the replay
    /// remains. Returns how the node ended.
    pub(crate) fn stop(&mut self, finish: bool) -> Option<String> {
        let m = if finish {
            Message::Finish(Finish {
                reason: "end of the replay".into(),
            })
        } else {
            Message::Abort(Abort {
                reason: "the replay failed".into(),
            })
        };
        let _ = self.send_down(&m);
        let mut child = self.child.take()?;
        let deadline = Instant::now() + Duration::from_secs(if finish { 10 } else { 1 });
        loop {
            match child.try_wait() {
                Ok(Some(st)) => return Some(describe_status(st)),
                Ok(None) if Instant::now() < deadline => {
                    // Keep reading: the node must not block on a full queue while it ends.
                    let _ = self.pump(Duration::from_millis(10));
                }
                _ => {
                    let _ = child.kill();
                    let _ = child.wait();
                    return Some("was killed after it did not exit".into());
                }
            }
        }
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        if let Some(c) = self.child.as_mut() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// Compares what the node sends with what the recording holds.
struct Comparer<'a> {
    recorded: &'a BTreeMap<OutKey, Fields>,
    seen: BTreeSet<OutKey>,
    tolerance: f64,
}

impl Comparer<'_> {
    fn fields(&mut self, rep: &mut ReplayReport, f: &Fields) {
        let key = out_key(f);
        let Some(r) = self.recorded.get(&key) else {
            rep.incomplete.push(format!(
                "window {} coupling '{}': the node sent fields the recording does not hold",
                f.window, f.coupling
            ));
            return;
        };
        self.seen.insert(key);
        for rf in &r.fields {
            let Some(field) = f.get(&rf.name) else {
                rep.incomplete.push(format!(
                    "window {} coupling '{}': field '{}' is recorded but the node did not send it",
                    f.window, f.coupling, rf.name
                ));
                continue;
            };
            let d = diff(&field.values, &rf.values);
            rep.fields_compared += 1;
            rep.values_compared += rf.values.len() as u64;
            rep.all_equal &= d.identical;
            if is_motion(&rf.name) && d.max_rel > self.tolerance && rep.drift.is_none() {
                rep.drift = Some((f.window, format!("{}/{}", f.coupling, rf.name), d.max_rel));
            }
            rep.rows
                .push((f.window, f.coupling.clone(), rf.name.clone(), d));
        }
        for field in &f.fields {
            if r.get(&field.name).is_none() {
                rep.incomplete.push(format!(
                    "window {} coupling '{}': the node sent field '{}', which the recording does not hold",
                    f.window, f.coupling, field.name
                ));
            }
        }
    }
}

/// The values of a step report that a deterministic node reproduces (not its timings).
fn report_values(r: &StepReport) -> Vec<(String, f64)> {
    let mut v = vec![
        ("kinetic_energy".to_string(), r.kinetic_energy),
        ("internal_energy".into(), r.internal_energy),
        ("external_work".into(), r.external_work),
        ("interface_work".into(), r.interface_work),
        ("momentum_gross".into(), r.momentum_gross),
        ("applied_impulse".into(), r.applied_impulse),
        ("substeps".into(), r.substeps as f64),
    ];
    for (name, x) in [
        ("momentum", r.momentum),
        ("external_impulse", r.external_impulse),
        ("interface_impulse", r.interface_impulse),
    ] {
        for (axis, c) in ["x", "y", "z"].iter().zip(x) {
            v.push((format!("{name}_{axis}"), c));
        }
    }
    v.extend(
        r.scalars
            .iter()
            .filter(|(n, _)| !message::is_timing_scalar(n))
            .cloned(),
    );
    v
}

fn compare_report(rep: &mut ReplayReport, window: u64, got: &StepReport, recorded: &StepReport) {
    let got = report_values(got);
    for (name, r) in report_values(recorded) {
        match got.iter().find(|(n, _)| *n == name) {
            Some(&(_, v)) => {
                rep.all_equal &= v.to_bits() == r.to_bits();
                rep.report_values_compared += 1;
                rep.scalars.push((window, name, v, r));
            }
            None => rep.incomplete.push(format!(
                "window {window}: the node's report lacks the recorded '{name}'"
            )),
        }
    }
}

/// Replay node `node` of the recording at `path` (see the module doc). An `Err` is a replay
/// that could not run or whose node failed; a report with `incomplete` entries is one that
/// ran but could not compare every recorded window.
pub fn replay(path: &Path, node: &str, opts: &ReplayOptions) -> anyhow::Result<ReplayReport> {
    let (msgs, complete) = record::read_all(path)?;
    let cut = "the recording is incomplete (no summary, or cut inside a chunk: its writer was stopped or the file truncated)";
    let p = match plan(&msgs, node) {
        Ok(p) => p,
        Err(e) if !complete => bail!("{cut}, and what is readable of it cannot be replayed: {e:#}"),
        Err(e) => return Err(e),
    };
    let mut rep = ReplayReport {
        recorded_windows: p.reports.len() as u64,
        all_equal: true,
        ..Default::default()
    };
    if !complete {
        rep.incomplete.push(format!(
            "{cut}: only the {} windows of node '{node}' it still holds were replayed (the case planned {})",
            rep.recorded_windows, p.planned
        ));
    }
    rep.exe = replayed_exe(&p, node, opts)?;
    let mut params: toml::Table = toml::from_str(&p.welcome.params_toml)
        .context("the recorded Welcome's parameters are not TOML")?;
    rep.model = p.welcome.model.clone();
    let mut param_sets = Vec::new();
    for s in &opts.sets {
        match s.strip_prefix("model=") {
            Some(m) => rep.model = m.trim_matches('"').to_string(),
            None => param_sets.push(s.clone()),
        }
    }
    crate::case::apply_sets(&mut params, &param_sets).map_err(|e| anyhow::anyhow!("{e}"))?;
    let run = opts
        .run_id
        .clone()
        .unwrap_or_else(|| pick_run_id(&format!("replay-{node}")));
    let out = replay_folder(path, node, opts)?;
    let welcome = Welcome {
        run: run.clone(),
        model: rep.model.clone(),
        params_toml: toml::to_string(&params)?,
        bindings: p.welcome.bindings.clone(),
        output_dir: out.join(node).display().to_string(),
        heartbeat_ms: p.welcome.heartbeat_ms,
    };
    let kind = TransportKind::Shm;
    transport::cleanup(kind, &run);
    let result = open_and_drive(&p, &welcome, &mut rep, node, &run, &out, opts.tolerance);
    // Every port of this process is closed by now; no process of the replay remains.
    transport::cleanup(kind, &run);
    result?;
    if rep.windows < rep.recorded_windows {
        rep.incomplete.push(format!(
            "{} of the {} recorded windows were replayed",
            rep.windows, rep.recorded_windows
        ));
    }
    if rep.windows == 0 {
        rep.incomplete
            .push(format!("no window of node '{node}' was replayed"));
    }
    Ok(rep)
}

/// The executable to replay: `--solver`, else the one the case named for the node (beside
/// cosim, at its path relative to the case, or relative to here).
fn replayed_exe(p: &Plan, node: &str, opts: &ReplayOptions) -> anyhow::Result<PathBuf> {
    match &opts.solver {
        Some(s) => {
            let s = s.to_string_lossy();
            crate::launch::resolve_exe(&s, Path::new("."))
                .with_context(|| format!("--solver {s}: no such executable"))
        }
        None => crate::launch::resolve_exe(&p.solver, &p.case_dir)
            .or_else(|| crate::launch::resolve_exe(&p.solver, Path::new(".")))
            .with_context(|| {
                format!(
                    "the recorded executable of node '{node}', '{}', is neither beside cosim nor at that path (relative to {}); name one with --solver",
                    p.solver,
                    p.case_dir.display()
                )
            }),
    }
}

/// The replay's folder (`--output`, else `replay-<node>` beside the recording), created, and
/// without the log of a previous replay. The replayed node writes `<out>/<node>.log` and
/// `<out>/<node>/`, the very names a run gives its own log and frames: a run's folder, live
/// or finished, is refused.
fn replay_folder(path: &Path, node: &str, opts: &ReplayOptions) -> anyhow::Result<PathBuf> {
    let out = match &opts.output {
        Some(o) => o.clone(),
        None => path
            .parent()
            .unwrap_or(Path::new("."))
            .join(format!("replay-{node}")),
    };
    crate::lock::check_free(&out)?;
    if crate::lock::holds_a_run(&out) {
        bail!(
            "{} holds a run's results (run.mcap or summary.json), whose node log and frames the replay would overwrite: leave out --output (the replay goes to replay-{node} beside the recording) or name another folder",
            out.display()
        );
    }
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    // The log of this replay only (a node's log is appended to: a restarted run keeps its
    // killed run's lines).
    let log = out.join(format!("{node}.log"));
    match std::fs::remove_file(&log) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => bail!("cannot remove the previous replay's {}: {e}", log.display()),
    }
    Ok(out)
}

fn open_and_drive(
    p: &Plan,
    welcome: &Welcome,
    rep: &mut ReplayReport,
    node: &str,
    run: &str,
    out: &Path,
    tolerance: f64,
) -> anyhow::Result<()> {
    let log = out.join(format!("{node}.log"));
    let mut s = Session::launch(
        &rep.exe,
        &[],
        run,
        node,
        &welcome.bindings,
        log,
        (
            Duration::from_secs_f64(p.heartbeat_timeout),
            Duration::from_secs_f64(p.stall_timeout),
        ),
    )?;
    let mut cmp = Comparer {
        recorded: &p.outputs,
        seen: BTreeSet::new(),
        tolerance,
    };
    let r = drive(&mut s, p, welcome, rep, &mut cmp);
    let ended = s.stop(r.is_ok());
    // The node's last fields may still be queued behind its Done.
    for f in std::mem::take(&mut s.arrived) {
        cmp.fields(rep, &f);
    }
    r?;
    if let Some(how) = ended
        && how != "exited with status 0"
    {
        rep.incomplete.push(format!("after Finish the node {how}"));
    }
    // Every recorded output of a replayed window must have been sent again.
    let last = rep.times.last().map_or(0, |t| t.0);
    for key @ (w, c, _) in p.outputs.keys() {
        if *w <= last && !cmp.seen.contains(key) {
            rep.incomplete.push(format!(
                "window {w} coupling '{c}': the recording holds the node's fields, the replayed node did not send them"
            ));
        }
    }
    Ok(())
}

fn drive(
    s: &mut Session,
    p: &Plan,
    welcome: &Welcome,
    rep: &mut ReplayReport,
    cmp: &mut Comparer,
) -> anyhow::Result<()> {
    let bindings = &welcome.bindings;
    s.wait("Hello", Some(Duration::from_secs(30)), |s| s.hello)?;
    s.welcome_and_set_up(welcome)?;
    for (i, m) in &p.peer_meshes {
        s.send_peer(*i, &bindings[*i].peer, &Message::Mesh(m.clone()))?;
    }
    // Which peer fields the recording holds, and how many have been sent.
    let held: BTreeSet<(usize, u64)> = p.peer_fields.iter().map(|(i, f)| (*i, f.window)).collect();
    let mut sent = 0;
    let mut until: Vec<Option<u64>> = vec![None; bindings.len()];
    for k in std::iter::once(0).chain(p.advances.iter().map(|a| a.window)) {
        if k > 0 && !p.reports.contains_key(&k) {
            // The recorded run ended inside this window: there is nothing to compare with.
            break;
        }
        for x in p.decouples.iter().filter(|x| x.window == k) {
            if let Some(i) = bindings.iter().position(|b| b.coupling == x.coupling) {
                until[i] = Some(until[i].map_or(x.window, |u| u.min(x.window)));
            }
            s.send_down(&Message::Decouple(x.clone()))?;
        }
        let lacking = lacking(bindings, &until, &held, k);
        if !lacking.is_empty() {
            rep.incomplete.push(format!(
                "the recording lacks the peer fields {} that window {k} needs; the replay stopped there",
                lacking.join(", ")
            ));
            break;
        }
        // Every recorded peer output up to this window, in recorded order: the node's
        // buffers pick what each window consumes by its label, so the lags act as recorded.
        while sent < p.peer_fields.len() && p.peer_fields[sent].1.window <= k {
            let (i, f) = &p.peer_fields[sent];
            s.send_peer(*i, &bindings[*i].peer, &Message::Fields(f.clone()))?;
            sent += 1;
        }
        s.window = k;
        let t1 = advance(s, p, k)?;
        let report = s.done(k)?;
        for f in std::mem::take(&mut s.arrived) {
            cmp.fields(rep, &f);
        }
        if let Some(r) = p.reports.get(&k) {
            compare_report(rep, k, &report, r);
            rep.windows += 1;
            rep.times.push((k, t1));
        }
    }
    // Outputs of the last window may still be on their way (another topic than Done).
    let quiet_until = Instant::now() + Duration::from_secs(2);
    while Instant::now() < quiet_until && s.pump(Duration::from_millis(50))? {}
    Ok(())
}

/// The peer fields (`'COUPLING' of window W`) window `k` of the node needs on each binding
/// and the recording does not hold (`held`: binding and window of each recorded one), the
/// couplings decoupled before `until`.
fn lacking(
    bindings: &[Binding],
    until: &[Option<u64>],
    held: &BTreeSet<(usize, u64)>,
    k: u64,
) -> Vec<String> {
    bindings
        .iter()
        .enumerate()
        .filter_map(|(i, b)| {
            let w = needed(b, until[i], k)?;
            (!held.contains(&(i, w))).then(|| format!("'{}' of window {w}", b.coupling))
        })
        .collect()
}

/// Window `k`'s recorded `Advance` sent to the node (no output, no checkpoint): its end
/// time (0 for the set-up, window 0, which has none).
fn advance(s: &mut Session, p: &Plan, k: u64) -> anyhow::Result<f64> {
    if k == 0 {
        return Ok(0.0);
    }
    let a = p
        .advances
        .iter()
        .find(|a| a.window == k)
        .context("advance vanished")?;
    s.send_down(&Message::Advance(Advance {
        write_output: false,
        checkpoint: false,
        ..*a
    }))?;
    Ok(a.t1)
}

/// One PNG per reported quantity of the replayed node in `dir`: the recorded and the
/// replayed history on one chart (e.g. a bar's displacement under two solid models).
pub fn plot(rep: &ReplayReport, node: &str, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    use crate::plot::{Series, line_chart};
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let time: BTreeMap<u64, f64> = rep.times.iter().copied().collect();
    let mut names: Vec<&str> = rep.scalars.iter().map(|s| s.1.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    let mut files = Vec::new();
    for name in names {
        let pick = |replayed: bool| -> Vec<(f64, f64)> {
            rep.scalars
                .iter()
                .filter(|s| s.1 == name)
                .filter_map(|s| Some((*time.get(&s.0)?, if replayed { s.2 } else { s.3 })))
                .collect()
        };
        let p = dir.join(format!(
            "replay_{node}_{}.png",
            crate::plot::file_stem(name)
        ));
        let series = [
            Series {
                label: "recorded".into(),
                points: pick(false),
            },
            Series {
                label: "replayed".into(),
                points: pick(true),
            },
        ];
        line_chart(&p, &format!("{node}: {name}"), "t [s]", name, &series)?;
        files.push(p);
    }
    Ok(files)
}
