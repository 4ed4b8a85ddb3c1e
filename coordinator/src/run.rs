//! `cosim run`: launch the nodes, handshake, drive the windows, record everything, audit
//! energy and momentum per window, and end cleanly whatever happens (docs/architecture.md).
//!
//! Within a window the coordinator sends `Advance` to every node in the coupling graph's
//! order and waits for every `Done`; the serial data dependencies (a responder needs its
//! driver's motion of the same window) are enforced by the nodes themselves, which wait for
//! their inputs, so the same loop serves the serial and the parallel schedules.
//!
//! The coordinator is kept off the window's critical path: the next window's
//! `Advance` goes out before the last window is audited and recorded (two windows in flight,
//! [`WINDOWS_AHEAD`]), so the nodes exchange peer to peer and never wait for the audit or
//! the recorder; it waits where a window's end decides the next (checkpoint, decoupling rule,
//! lagrange hub, stop request). Reports of a window ahead are kept until its own audit.

use crate::config::{self, Case};
use crate::contract::Contract;
use crate::profile::{Phase, Profile};
use crate::progress::Progress;
use crate::record::{self, Recorder, RecorderThread};
use anyhow::Context;
use protocol::codec::{self, encode_into};
use protocol::stop;
use protocol::transport::{self, Publisher, TopicId, Transport, TransportKind, TransportSpec};
use protocol::*;
use serde_json::json;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A fault that ends the run: which node, and why.
#[derive(Debug, thiserror::Error)]
#[error("node '{node}': {reason}")]
pub struct Fault {
    pub node: String,
    pub reason: String,
}

#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Run id (default: name, pid and time); namespaces shared memory and topics.
    pub run_id: Option<String>,
    /// Output directory instead of the case's `run.output`.
    pub output: Option<PathBuf>,
    /// Hide the progress bar.
    pub quiet: bool,
    /// Continue a run from this checkpoint state (`cosim run --restart`, `cosim restart`):
    /// the output directory is the run's, the recording goes on in a new segment.
    pub restart: Option<crate::checkpoint::CoordState>,
}

/// Number of windows of a case (the last one may be shorter).
pub fn window_count(case: &Case) -> u64 {
    ((case.run.end_time / case.run.window) - 1e-9)
        .ceil()
        .max(1.0) as u64
}

/// What a finished run reports.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub output: PathBuf,
    pub summary: serde_json::Value,
    /// The stop signal that ended the run early (summary status "interrupted").
    pub interrupted: Option<i32>,
    /// Why the run was stopped as diverged (summary status "diverged").
    pub diverged: Option<crate::guard::Diverged>,
}

enum Topic {
    Up(usize),
    Data(usize),
}

struct NodeRt {
    name: String,
    child: Option<Child>,
    down: Box<dyn Publisher>,
    last_seen: Instant,
    /// Since when the node's heartbeats say it is blocked on a peer's input.
    waiting_since: Option<Instant>,
    idle_s: f64,
    hello: bool,
    described: u32,
    stable_dt: f64,
    done: Option<u64>,
    report: StepReport,
    /// Energy and momentum after set-up: the audit balances against them.
    initial_energy: f64,
    initial_momentum: [f64; 3],
    substeps: u64,
    wall_s: f64,
    wait_s: f64,
    exited: Option<String>,
    /// Where its stdout and stderr go (launched nodes).
    log: Option<PathBuf>,
    /// Finished before the end (its couplings ended, seed 000 §4): the window after which.
    finished: Option<u64>,
    /// What the node warned of in its descriptions (each once).
    warnings: Vec<String>,
    /// Reports of windows after the one being audited (pipelining), oldest first.
    ahead: VecDeque<(u64, StepReport)>,
    /// The recording's channel of its per-window reports: `/cosim/node/<name>`.
    report_topic: String,
    /// The topic of what the coordinator sends it (its recording channel).
    down_topic: String,
}

/// A node's report of one window as recorded on `/cosim/node/<name>` (schema
/// `cosim.NodeReport`): the window, its end time, the report's quantities and its named
/// scalars as keys of their own (a scalar named like a quantity replaces it). Written
/// straight from the report, without an intermediate `Value`.
struct NodeReportDoc<'a> {
    window: u64,
    time: f64,
    r: &'a StepReport,
}

/// The keys a node report has besides its named scalars.
const BUILTIN_KEYS: [&str; 13] = [
    "window",
    "time",
    "kinetic_energy",
    "internal_energy",
    "external_work",
    "interface_work",
    "momentum",
    "momentum_gross",
    "external_impulse",
    "interface_impulse",
    "substeps",
    "wall_s",
    "coupling_wait_s",
];

impl serde::Serialize for NodeReportDoc<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let r = self.r;
        let mut m = s.serialize_map(None)?;
        let shadowed = |k: &str| r.scalars.iter().any(|(n, _)| n == k);
        macro_rules! put {
            ($k:expr, $v:expr) => {
                if !shadowed($k) {
                    m.serialize_entry($k, $v)?;
                }
            };
        }
        put!("window", &self.window);
        put!("time", &self.time);
        put!("kinetic_energy", &r.kinetic_energy);
        put!("internal_energy", &r.internal_energy);
        put!("external_work", &r.external_work);
        put!("interface_work", &r.interface_work);
        put!("momentum", &r.momentum);
        put!("momentum_gross", &r.momentum_gross);
        put!("external_impulse", &r.external_impulse);
        put!("interface_impulse", &r.interface_impulse);
        put!("substeps", &r.substeps);
        put!("wall_s", &r.wall_s);
        put!("coupling_wait_s", &r.coupling_wait_s);
        // A dotted name is recorded nested (`point1.pressure` as `{"point1": {"pressure": …}}`,
        // Foxglove's path syntax), unless a prefix of it is a key itself.
        let is_key = |k: &str| BUILTIN_KEYS.contains(&k) || shadowed(k);
        for (name, val) in &r.scalars {
            if !crate::nest::nests(name, is_key) {
                m.serialize_entry(name, val)?;
            }
        }
        crate::nest::Group {
            scalars: &r.scalars,
            prefix: "",
            is_key: &is_key,
        }
        .entries(&mut m)?;
        m.end()
    }
}

struct Coord<'a> {
    case: &'a Case,
    run: String,
    token: String,
    t: Box<dyn Transport>,
    topics: Vec<(String, Topic)>,
    /// Per topic (as `topics`), what its node's `Fields` must hold on a data topic that is
    /// not a lagrange side's.
    contracts: Vec<Option<Contract>>,
    /// The booking rule's check: the `force` that crossed the interfaces against the nodes'
    /// booked interface impulse.
    books: crate::books::Books,
    /// Per topic (as `topics`), the coupling and side whose data it carries (None: a node's
    /// up topic), and the last window of `Fields` seen on it.
    sides: Vec<Option<(usize, String)>>,
    last_fields: Vec<Option<u64>>,
    /// Per coupling, the window before which it ended (decoupled), for the deadlock message.
    until: Vec<Option<u64>>,
    /// In [`Coord::culprit`]: reading what is queued behind a `Failed`.
    draining: bool,
    nodes: Vec<NodeRt>,
    /// The recorder, on its own thread: recording never holds the window loop up.
    rec: RecorderThread,
    buf: Vec<u8>,
    seq: u64,
    sim_t: f64,
    window: u64,
    faults: Vec<Fault>,
    /// Every node's reported quantities per window, for the plots written at the end.
    history: crate::plot::Histories,
    /// The last window completed by every node.
    completed: u64,
    /// In the window loop: a first stop signal waits for the window boundary there.
    in_windows: bool,
    /// The stop signal that ends the run, once acted on.
    interrupted: Option<i32>,
    /// The divergence guard, and why it stopped the run.
    guard: crate::guard::Guard,
    diverged: Option<crate::guard::Diverged>,
    /// The bar or progress lines of the window loop; messages go through it.
    progress: Progress,
    /// The lagrange couplings (the interface problems solved here) and their publishers.
    hubs: Vec<(crate::lagrange::Hub, Box<dyn Publisher>)>,
    /// Where the window loop's time goes (`summary.json`: `window_breakdown`).
    prof: Profile,
    /// The last receive's time blocked and recording (ns), for [`Coord::pump_one`].
    last_recv_ns: (u64, u64),
    /// [`Coord::wait_all`]'s list of the nodes still awaited.
    pending: Vec<usize>,
    /// When [`Coord::check_health`] last ran, and the coordinator's own stalls seen
    /// (`summary.json`: `coordinator_stalls`).
    own: crate::clock::OwnClock,
    /// Per node, the report of its `Done` being received, read in place
    /// (`codec::decode_done_into`), then swapped with the node's: once the node's scalar
    /// names have been seen, the window loop allocates nothing for it.
    inbox: Vec<StepReport>,
    /// Per node, its reports returned from `NodeRt::ahead` once audited, reused for the next
    /// ones.
    spare: Vec<Vec<StepReport>>,
}

/// How often [`Coord::wait_all`] checks the nodes' health while messages keep arriving.
const HEALTH_EVERY: Duration = Duration::from_millis(2);

/// At most this many queued messages are read before a node is judged silent.
const QUEUED_MAX: usize = 4096;

/// A message as [`Coord::pump_one`] received it.
enum Got {
    /// Decoded in full: the message if it came from the topic's node and run, else the sender
    /// and run it claims.
    Full(Result<Result<Message, (String, String)>, codec::CodecError>),
    /// Peer data checked in place (no lagrange hub reads it): whether it came from the topic's
    /// node and run, else the sender and run it claims.
    Fields(Result<(), (String, String)>),
    /// A `Done`, its report read into the node's `Coord::inbox`: its window if it came from
    /// the topic's node and run, else the sender and run it claims.
    Done(Result<u64, (String, String)>),
}

/// What a lagrange hub takes from a side.
enum LagIn {
    Mesh(Mesh),
    Fields(Fields),
}

pub(crate) fn pick_run_id(name: &str) -> String {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() % 1_000_000)
        .unwrap_or(0);
    let mut s = format!("{}-{}-{t}", name, std::process::id());
    if s.len() > 32 {
        s = s[s.len() - 32..].to_string();
    }
    s
}

fn free_port() -> anyhow::Result<u16> {
    let l = std::net::TcpListener::bind("127.0.0.1:0")?;
    Ok(l.local_addr()?.port())
}

/// Kill the child when the coordinator dies, whatever the cause (Linux).
fn die_with_parent(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: prctl is async-signal-safe; nothing else runs between fork and exec here.
    unsafe {
        cmd.pre_exec(|| {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
            Ok(())
        });
    }
}

/// Append to a node's log the line that marks where a restart from the checkpoint of
/// `window` begins (the killed run's lines above it are kept).
fn mark_restart(log: &Path, window: u64, segment: &Path) -> anyhow::Result<()> {
    use std::io::Write;
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
        .with_context(|| format!("cannot open {}", log.display()))?;
    writeln!(
        f,
        "---- cosim restart from the checkpoint of window {window}; recording {} ----",
        segment.file_name().unwrap_or_default().to_string_lossy()
    )
    .with_context(|| format!("cannot write {}", log.display()))
}

/// Start node `name` of run `run` from its executable, as `cosim run`, `cosim replay` and
/// `cosim conformance` do: `exe args… --run …` (`args`: the command's own arguments, e.g. a
/// script an interpreter runs); its stdout and stderr are appended to `log`, and it dies with
/// this process. `connect` is the zenoh endpoint to join, where the transport needs one.
pub(crate) fn spawn_node(
    exe: &Path,
    args: &[String],
    run: &str,
    name: &str,
    kind: TransportKind,
    connect: Option<&str>,
    log: &Path,
) -> Result<Child, String> {
    let out = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
        .map_err(|e| format!("cannot open its log {}: {e}", log.display()))?;
    let err = out.try_clone().map_err(|e| e.to_string())?;
    let mut cmd = Command::new(exe);
    cmd.args(args);
    cmd.args(["--run", run, "--node", name, "--transport", kind.as_str()]);
    if let Some(endpoint) = connect {
        cmd.args(["--connect", endpoint]);
    }
    cmd.stdin(Stdio::null()).stdout(out).stderr(err);
    // A node built on the participant runtime turns this into SIGTERM for itself, so it can
    // remove its shared memory; another executable is killed with us.
    cmd.env(
        protocol::watchdog::PARENT_ENV,
        std::process::id().to_string(),
    );
    die_with_parent(&mut cmd);
    cmd.spawn()
        .map_err(|e| format!("cannot start {}: {e}", exe.display()))
}

/// What the log of a node that exited says last: its path and its last lines (at most 12,
/// from its last 8 KiB), indented, for the fault message.
pub(crate) fn log_note(log: &Path) -> String {
    use std::io::{Read, Seek, SeekFrom};
    let mut text = String::new();
    if let Ok(mut f) = std::fs::File::open(log) {
        let len = f.metadata().map(|m| m.len()).unwrap_or(0);
        let mut buf = Vec::new();
        if f.seek(SeekFrom::Start(len.saturating_sub(8192))).is_ok()
            && f.read_to_end(&mut buf).is_ok()
        {
            text = String::from_utf8_lossy(&buf).into_owned();
        }
    }
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    if lines.is_empty() {
        return format!(" (its log, {}, is empty)", log.display());
    }
    let tail = &lines[lines.len().saturating_sub(12)..];
    let mut s = format!("; its log, {}, ends:", log.display());
    for l in tail {
        s.push_str("\n    ");
        s.push_str(l);
    }
    s
}

/// How a node process ended, in words.
pub(crate) fn describe_status(s: std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (s.code(), s.signal()) {
        (Some(c), _) => format!("exited with status {c}"),
        (None, Some(sig)) => format!(
            "was killed by signal {sig}{}",
            match sig {
                9 => " (SIGKILL)",
                11 => " (SIGSEGV)",
                15 => " (SIGTERM)",
                6 => " (SIGABRT)",
                _ => "",
            }
        ),
        _ => "ended".into(),
    }
}

impl<'a> Coord<'a> {
    /// The last window of `Fields` seen from `sender` on coupling `coupling` (None: none).
    fn fields_seen(&self, coupling: &str, sender: &str) -> Option<u64> {
        let ci = self
            .case
            .couplings
            .iter()
            .position(|c| c.name == coupling)?;
        self.sides
            .iter()
            .zip(&self.last_fields)
            .find(|(s, _)| s.as_ref().is_some_and(|(c, n)| *c == ci && n == sender))
            .and_then(|(_, w)| *w)
    }

    fn node_idx(&self, name: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.name == name)
    }

    /// Stop now on a stop signal received during set-up (there is no window boundary to wait
    /// for) or on the second one (a second Ctrl-C); the cleanup still runs.
    fn stop_now(&mut self) -> Result<(), Fault> {
        if let Some(sig) = stop::requested()
            && (!self.in_windows || stop::count() >= 2)
        {
            self.interrupted = Some(sig);
            return Err(Fault {
                node: "coordinator".into(),
                reason: format!(
                    "interrupted by {} after window {}",
                    stop::name(sig),
                    self.completed
                ),
            });
        }
        Ok(())
    }

    fn send(&mut self, i: usize, m: &Message) -> Result<(), Fault> {
        self.send_ringing(i, m, true)
    }

    /// [`Coord::send`], waking the node only if `ring` (a batch of `Advance`s goes quietly and
    /// rings once, [`Coord::ring`]).
    fn send_ringing(&mut self, i: usize, m: &Message, ring: bool) -> Result<(), Fault> {
        self.seq += 1;
        encode_into(&mut self.buf, &self.run, "coordinator", self.seq, m).map_err(|e| Fault {
            node: self.nodes[i].name.clone(),
            reason: format!("cannot encode {}: {e}", m.type_name()),
        })?;
        let _ = self
            .rec
            .message(&self.nodes[i].down_topic, self.sim_t, &self.buf);
        let down = &mut self.nodes[i].down;
        let a0 = crate::profile::allocations_now();
        let r = if ring {
            down.send(&self.buf)
        } else {
            down.send_quiet(&self.buf)
        };
        self.prof
            .add_transport_allocs(crate::profile::allocations_now() - a0);
        r.map_err(|e| Fault {
            node: self.nodes[i].name.clone(),
            reason: format!("send failed: {e}"),
        })
    }

    /// Wake node `i` for what was sent to it quietly.
    fn ring(&mut self, i: usize) -> Result<(), Fault> {
        let a0 = crate::profile::allocations_now();
        let r = self.nodes[i].down.ring();
        self.prof
            .add_transport_allocs(crate::profile::allocations_now() - a0);
        r.map_err(|e| Fault {
            node: self.nodes[i].name.clone(),
            reason: format!("waking the node failed: {e}"),
        })
    }

    /// Forgive the nodes the silence the coordinator was not awake to observe: when it has not
    /// looked at them for [`crate::clock::OWN_STALL`] of the heartbeat timeout or longer, the nodes' beats
    /// of that time are still queued, unread, and their clocks start again now.
    /// Only while nodes are judged by their beats (`beating`): before the Welcome the gap is
    /// the launch.
    fn forgive_own_stall(&mut self, beating: bool) {
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
    fn check_health(&mut self, waiting_on: &[usize]) -> Result<(), Fault> {
        self.forgive_own_stall(!waiting_on.is_empty());
        let timeout = Duration::from_secs_f64(self.case.run.heartbeat_timeout);
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
                // Give a dying node's last words (a Failed message) a moment to arrive.
                let name = n.name.clone();
                let log = n.log.as_deref().map(log_note).unwrap_or_default();
                let deadline = Instant::now() + Duration::from_millis(100);
                while Instant::now() < deadline {
                    match self.pump_one(Duration::from_millis(10)) {
                        Ok(_) => {}
                        Err(f) => return Err(f),
                    }
                }
                return Err(Fault {
                    node: name,
                    reason: format!("{why} during window {}{log}", self.window),
                });
            }
        }
        // Beats may wait unread behind the coordinator's own work: read them before judging.
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
            let names: Vec<&str> = waiting_on
                .iter()
                .map(|&i| self.nodes[i].name.as_str())
                .collect();
            // What each waits for, and who owes it: the first such sender is the one named.
            let mut missing = Vec::new();
            for &i in waiting_on {
                let n = &self.nodes[i];
                let working = n.done.map_or(0, |d| d + 1);
                let bindings = config::bindings_of(self.case, &n.name);
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
                "; every input they wait for was sent, as far as the coordinator saw (lost on its way?)".to_string()
            } else {
                let what: Vec<&str> = missing.iter().map(|m| m.what.as_str()).collect();
                format!(": {}", what.join("; "))
            };
            return Err(Fault {
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
            });
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

    /// Receive, record and act on one message. Returns whether one arrived.
    fn pump_one(&mut self, timeout: Duration) -> Result<bool, Fault> {
        let start = Instant::now();
        let r = self.pump_inner(timeout);
        // What was neither blocked nor recording: decoding and acting on the message.
        let total = start.elapsed().as_nanos() as u64;
        let (blocked, recorded) = self.last_recv_ns;
        self.prof
            .add_ns(Phase::Handle, total.saturating_sub(blocked + recorded));
        r
    }

    fn pump_inner(&mut self, timeout: Duration) -> Result<bool, Fault> {
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
                    config::check_joined(self.case, &n.name, &d.interfaces).map_err(|e| Fault {
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
    fn culprit(&mut self, failed: Fault) -> Fault {
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
    fn lagrange_input(&mut self, node: &str, input: LagIn) -> Result<(), Fault> {
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
    fn publish_lagrange(&mut self, h: usize, f: Fields) -> Result<(), Fault> {
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

    /// Pump until `pred` holds for every node in `who`.
    /// Wait until `pred` holds for every node of `who`, checking their health meanwhile;
    /// `limit` is the longest wait and the reason given when it passes.
    fn wait_all(
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

    fn abort_all(&mut self, reason: &str) {
        for i in 0..self.nodes.len() {
            let _ = self.send(
                i,
                &Message::Abort(Abort {
                    reason: reason.to_string(),
                }),
            );
        }
        let deadline = Instant::now() + Duration::from_millis(1000);
        for n in &mut self.nodes {
            if let Some(c) = n.child.as_mut() {
                loop {
                    match c.try_wait() {
                        Ok(Some(_)) => break,
                        _ if Instant::now() > deadline => {
                            let _ = c.kill();
                            let _ = c.wait();
                            break;
                        }
                        _ => std::thread::sleep(Duration::from_millis(10)),
                    }
                }
            }
        }
    }
}

/// Wait for the remote nodes to join (docs/architecture.md): as long as a person needs, up to
/// `run.join_timeout`, naming who is still missing every few seconds. The local nodes wait
/// meanwhile (they are alive; only their exit or lost connection is a fault).
/// A node's `Done` of `window` (its report in `report`) while the coordinator is at window
/// `at`: the node's totals, and the report as the node's current one, or queued when it is of
/// a later window (pipelining). `report` is swapped, not moved: it comes back holding a
/// report's buffers (the replaced one, or a spare), so reading the next `Done` into it
/// allocates nothing.
fn take_done(
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

fn wait_for_joins(c: &mut Coord, remote: &[usize]) -> Result<(), Fault> {
    const NOTE_EVERY: Duration = Duration::from_secs(5);
    let limit = c.case.run.join_timeout;
    let start = Instant::now();
    let mut next_note = start + NOTE_EVERY;
    loop {
        let missing: Vec<usize> = remote
            .iter()
            .copied()
            .filter(|&i| !c.nodes[i].hello)
            .collect();
        let Some(&first) = missing.first() else {
            return Ok(());
        };
        let names = missing
            .iter()
            .map(|&i| format!("'{}'", c.nodes[i].name))
            .collect::<Vec<_>>()
            .join(", ");
        c.stop_now()?;
        c.check_health(&[])?;
        let waited = start.elapsed().as_secs_f64();
        if waited > limit {
            return Err(Fault {
                node: c.nodes[first].name.clone(),
                reason: format!(
                    "remote node(s) {names} did not join within run.join_timeout = {limit} s"
                ),
            });
        }
        if Instant::now() >= next_note {
            eprintln!(
                "cosim: still waiting for remote node(s) {names}: {waited:.0} s of run.join_timeout = {limit} s"
            );
            next_note += NOTE_EVERY;
        }
        c.pump_one(Duration::from_millis(50))?;
        for &i in &missing {
            if c.nodes[i].hello {
                eprintln!("cosim: remote node '{}' joined", c.nodes[i].name);
            }
        }
    }
}

/// Decouple every coupling whose rule fires before window `k` (starting at `t0`): tell both
/// sides, then finish each responder none of whose couplings is left (seed 000 §4: the solid
/// goes on alone). Returns whether a node was finished.
fn decouple_due(
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
        let mut why = None;
        if let Some(at) = cp.decouple.at
            && t0 >= at * (1.0 - 1e-12)
        {
            why = Some(format!("t = {t0:.6e} s reached decouple_at = {at:e} s"));
        }
        if why.is_none()
            && k > 1
            && let Some((node, q, level)) = &cp.decouple.when
            && let Some(i) = c.node_idx(node)
        {
            let r = &c.nodes[i].report;
            match r.scalars.iter().find(|(n, _)| n == q) {
                Some(&(_, v)) if v >= *level => {
                    why = Some(format!("{node}.{q} = {v} reached {level}"));
                }
                Some(_) => {}
                None => {
                    let have: Vec<&str> = r.scalars.iter().map(|(n, _)| n.as_str()).collect();
                    return Err(Fault {
                        node: node.clone(),
                        reason: format!(
                            "couplings[{ci}].decouple_when: the node does not report '{q}' (it reports: {})",
                            if have.is_empty() {
                                "nothing".to_string()
                            } else {
                                have.join(", ")
                            }
                        ),
                    });
                }
            }
        }
        let Some(why) = why else { continue };
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

/// Run a case to the end. On a fault the nodes are stopped, the recording is closed and the
/// fault returned; the caller prints it and exits non-zero.
pub fn run(case: &Case, opts: &RunOptions) -> anyhow::Result<Result<Outcome, Fault>> {
    let restart = opts.restart.as_ref();
    let run_id = opts
        .run_id
        .clone()
        .or_else(|| restart.map(|st| st.run_id.clone()))
        .unwrap_or_else(|| pick_run_id(&case.run.name));
    let out = opts
        .output
        .clone()
        .unwrap_or_else(|| case.run.output.clone());
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let segment = match restart {
        // A restart continues the recording in the next segment (read as one run), and each
        // node's log after a line that marks where.
        Some(st) => {
            let segment = crate::checkpoint::next_segment(&out);
            for n in case.nodes.iter().filter(|n| !n.remote) {
                mark_restart(&out.join(format!("{}.log", n.name)), st.window, &segment)?;
            }
            segment
        }
        None => {
            // A new run: what an earlier run in this directory left for restarts goes, and
            // the node logs a restart would have appended to.
            for p in record::segments(&out.join("run.mcap")).iter().skip(1) {
                std::fs::remove_file(p)
                    .with_context(|| format!("cannot remove {}", p.display()))?;
            }
            for n in &case.nodes {
                let log = out.join(format!("{}.log", n.name));
                match std::fs::remove_file(&log) {
                    Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                        return Err(e).with_context(|| format!("cannot remove {}", log.display()));
                    }
                    _ => {}
                }
            }
            let ck = out.join("checkpoints");
            if ck.exists() {
                std::fs::remove_dir_all(&ck)
                    .with_context(|| format!("cannot remove {}", ck.display()))?;
            }
            out.join("run.mcap")
        }
    };
    let mut rec = Recorder::create(&segment)?;
    let mut case_doc =
        json!({ "run": run_id, "case": case.path.display().to_string(), "toml": case.text });
    if let Some(st) = restart {
        case_doc["restart_from_window"] = json!(st.window);
    }
    rec.json("/cosim/case", "cosim.Case", 0.0, &case_doc)?;
    // On disk at once: a cosim killed before its first window leaves a recording that still
    // names its case (a chunk closes only on a flush).
    rec.flush()?;
    let rec = RecorderThread::spawn(rec)?;
    let kind = case.run.transport;
    transport::cleanup(kind, &run_id);
    // What earlier runs whose processes are all gone left in shared memory (a killed cosim).
    let swept = transport::shm::cleanup_stale_runs();
    if swept.files > 0 {
        tracing::info!(
            "removed {} shared-memory files of {} ended runs",
            swept.files,
            swept.runs
        );
    }
    let mut listen = case.run.listen.clone();
    if kind == TransportKind::Zenoh && listen.ends_with(":0") {
        listen = format!("{}{}", &listen[..listen.len() - 1], free_port()?);
    }
    let spec = TransportSpec {
        kind,
        run: run_id.clone(),
        endpoint: "coordinator".into(),
        listen: if kind == TransportKind::Zenoh {
            vec![listen.clone()]
        } else {
            vec![]
        },
        connect: vec![],
    };
    let mut t = transport::open(&spec).context("cannot open the transport")?;
    // Nodes that joined from elsewhere watch this token: it goes when cosim dies.
    t.declare_alive()?;
    let mut topics = Vec::new();
    let mut contracts = Vec::new();
    // Per topic, the coupling and side whose data it carries (the booking rule's feeds).
    let mut sides: Vec<Option<(usize, String)>> = Vec::new();
    let order = config::window_order(case).map_err(|e| anyhow::anyhow!("{e}"))?;
    let idx = |n: &str| case.nodes.iter().position(|x| x.name == n).unwrap_or(0);
    for (i, n) in case.nodes.iter().enumerate() {
        let tp = topic::up(&run_id, &n.name);
        t.subscribe(&tp)?;
        topics.push((tp, Topic::Up(i)));
        contracts.push(None);
        sides.push(None);
    }
    let mut hubs = Vec::new();
    for (ci, c) in case.couplings.iter().enumerate() {
        // A scheme the coordinator solves has a hub here (the lagrange interface problem).
        if protocol::scheme::of(c.kind).coordinator_solved() {
            let readers: Vec<String> = c.sides.iter().map(|s| s.0.clone()).collect();
            let p = t.publisher(
                &topic::data(&run_id, &c.name, protocol::scheme::lagrange::wire::PEER),
                &readers,
            )?;
            hubs.push((crate::lagrange::Hub::new(c, case.run.window), p));
        }
        for (k, (side, _)) in c.members().into_iter().enumerate() {
            let tp = topic::data(&run_id, &c.name, side);
            t.subscribe(&tp)?;
            topics.push((tp, Topic::Data(idx(side))));
            sides.push(Some((ci, side.to_string())));
            // Members are the driver, then the responder, where there is a contract.
            let role = if k == 0 {
                Role::Driver
            } else {
                Role::Responder
            };
            contracts
                .push((c.kind != CouplingKind::Lagrange).then(|| Contract::in_case(case, c, role)));
        }
    }
    let token = format!("{:016x}", {
        let t = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0);
        (t as u64) ^ ((std::process::id() as u64) << 32) ^ 0x9e37_79b9_7f4a_7c15
    });
    let mut nodes = Vec::new();
    for n in &case.nodes {
        let down = t.publisher(
            &topic::down(&run_id, &n.name),
            std::slice::from_ref(&n.name),
        )?;
        nodes.push(NodeRt {
            name: n.name.clone(),
            child: None,
            down,
            last_seen: Instant::now(),
            waiting_since: None,
            idle_s: 0.0,
            hello: false,
            described: 0,
            warnings: Vec::new(),
            stable_dt: 0.0,
            done: None,
            report: StepReport::default(),
            initial_energy: 0.0,
            initial_momentum: [0.0; 3],
            substeps: 0,
            wall_s: 0.0,
            wait_s: 0.0,
            exited: None,
            log: None,
            finished: None,
            ahead: VecDeque::with_capacity(4),
            report_topic: format!("/cosim/node/{}", n.name),
            down_topic: topic::down(&run_id, &n.name),
        });
    }
    let mut c = Coord {
        case,
        run: run_id.clone(),
        token,
        t,
        topics,
        contracts,
        books: crate::books::Books::of(case, &sides),
        last_fields: vec![None; sides.len()],
        until: vec![None; case.couplings.len()],
        sides,
        draining: false,
        nodes,
        rec,
        buf: Vec::new(),
        seq: 0,
        sim_t: 0.0,
        window: 0,
        faults: Vec::new(),
        history: Default::default(),
        completed: 0,
        in_windows: false,
        interrupted: None,
        guard: crate::guard::Guard::new(case.run.energy_bound, case.run.energy_floor),
        diverged: None,
        progress: Progress::quiet(),
        hubs,
        prof: Profile::default(),
        last_recv_ns: (0, 0),
        pending: Vec::with_capacity(case.nodes.len()),
        own: Default::default(),
        inbox: vec![StepReport::default(); case.nodes.len()],
        spare: (0..case.nodes.len())
            .map(|_| Vec::with_capacity(MAX_AHEAD as usize + 1))
            .collect(),
    };
    let started = Instant::now();
    let result = drive(&mut c, &out, &order, &listen, opts);
    let outcome = match result {
        Ok(summary) => Ok(summary),
        Err(f) => {
            c.abort_all(&f.to_string());
            c.faults.push(Fault {
                node: f.node.clone(),
                reason: f.reason.clone(),
            });
            Err(f)
        }
    };
    // Close everything whatever happened: children, recording, shared memory.
    for n in &mut c.nodes {
        if let Some(ch) = n.child.as_mut() {
            let _ = ch.kill();
            let _ = ch.wait();
        }
    }
    let wall = started.elapsed().as_secs_f64();
    let (interrupted, completed) = (c.interrupted, c.completed);
    let diverged = c.diverged.clone();
    let Coord {
        rec,
        t,
        nodes,
        history,
        hubs,
        ..
    } = c;
    // A recording that could not be written (a full disk) fails the run, whose summary is
    // still written where it can be.
    let (outcome, (messages, bytes)) = match (outcome, rec.finish()) {
        (o, Ok(counts)) => (o, counts),
        (Err(f), Err(_)) => (Err(f), (0, 0)),
        (Ok(_), Err(e)) => (
            Err(Fault {
                node: "coordinator".into(),
                reason: format!("recording: {e:#}"),
            }),
            (0, 0),
        ),
    };
    // Every port of this process goes before the sweep, which only runs once no participant
    // of the run is alive.
    drop(nodes);
    drop(hubs);
    drop(t);
    transport::cleanup(kind, &run_id);
    match outcome {
        Ok(mut summary) => {
            summary["wall_s"] = json!(wall);
            summary["recording"] = json!({
                "path": out.join("run.mcap"), "segment": segment,
                "messages": messages, "bytes": bytes,
            });
            if let Some(st) = restart {
                summary["restarted_from_window"] = json!(st.window);
            }
            // Plots are a convenience: a failure to draw them is reported, not fatal. A run
            // stopped on request exits within the 2 s a scheduler allows and draws none (a
            // crash tube's 200 plots take longer); its restart draws them for the whole run.
            if interrupted.is_some() {
                summary["plots"] = json!([]);
                summary["plots_skipped"] =
                    json!("interrupted: the restart, or `cosim plot`, draws them");
                tracing::info!("no plots drawn: the run was interrupted");
            } else {
                match crate::plot::run_plots(&history, &out) {
                    Ok(files) => summary["plots"] = json!(files),
                    Err(e) => tracing::warn!("plots of {}: {e:#}", out.display()),
                }
            }
            let pictures = case.run.pictures;
            if interrupted.is_none()
                && pictures != crate::config::Pictures::None
                && crate::fields::has_series(&out)
            {
                let png = out.join("fields.png");
                match crate::fields::render(&out, None, &png, None, None) {
                    Ok(_) => summary["fields"] = json!(png),
                    Err(e) => tracing::warn!("fields picture of {}: {e:#}", out.display()),
                }
                // and each node alone where there are several (fields_<node>.png)
                match crate::fields::render_nodes(&out) {
                    Ok(files) => summary["node_fields"] = json!(files),
                    Err(e) => tracing::warn!("node pictures of {}: {e:#}", out.display()),
                }
                // run.pictures = "frames": every written frame of each node alone
                if pictures == crate::config::Pictures::Frames {
                    let mut files = Vec::new();
                    for node in crate::fields::nodes_with_series(&out) {
                        match crate::fields::render_all(&out, None, Some(&node)) {
                            Ok(list) => files.extend(list.into_iter().map(|(png, _)| png)),
                            Err(e) => tracing::warn!("frames of node {node}: {e:#}"),
                        }
                    }
                    summary["frame_pictures"] = json!(files.len());
                }
            }
            write_summary(&out, &summary)?;
            Ok(Ok(Outcome {
                output: out,
                summary,
                interrupted,
                diverged: diverged.clone(),
            }))
        }
        Err(f) if interrupted.is_some() => {
            // Stopped at once (during set-up, or a second Ctrl-C): no window-boundary summary.
            let summary = json!({
                "run": run_id, "status": "interrupted",
                "signal": interrupted.map(stop::name),
                "window_reached": completed,
                "reason": f.reason, "wall_s": wall,
                "recording": { "path": out.join("run.mcap"), "messages": messages, "bytes": bytes },
            });
            write_summary(&out, &summary)?;
            Ok(Ok(Outcome {
                output: out,
                summary,
                interrupted,
                diverged: diverged.clone(),
            }))
        }
        Err(f) => {
            let summary = json!({ "run": run_id, "status": "failed", "fault": { "node": f.node, "reason": f.reason }, "wall_s": wall });
            // The fault is what the user must hear; a summary that cannot be written too (the
            // disk that ended the run is full) is said beside it.
            if let Err(e) = write_summary(&out, &summary) {
                tracing::warn!("{e:#}");
            }
            Ok(Err(f))
        }
    }
}

/// `<out>/summary.json`, whole or not at all (never a truncated or empty file).
fn write_summary(out: &Path, summary: &serde_json::Value) -> anyhow::Result<()> {
    let path = out.join("summary.json");
    node_kit::whole::write(&path, serde_json::to_string_pretty(summary)?.as_bytes())
        .map_err(anyhow::Error::from)
}

/// Restore every node from its checkpoint of window `st.window` (after set-up), then the
/// coordinator's own state; tell the nodes of the decouplings that had happened, finish those
/// that had finished, and mark the recording where the continued windows begin.
fn resume(c: &mut Coord, st: &crate::checkpoint::CoordState, all: &[usize]) -> Result<(), Fault> {
    let case = c.case;
    let k = st.window;
    c.window = k;
    c.sim_t = st.time;
    // The interface problems continue from their checkpointed multipliers (set up again
    // with the sides, before any side steps window k + 1).
    for hs in &st.lagrange {
        let Some((hub, _)) = c.hubs.iter_mut().find(|(h, _)| h.coupling == hs.coupling) else {
            return Err(Fault {
                node: "coordinator".into(),
                reason: format!(
                    "lagrange coupling '{}' in the checkpoint but not in the case",
                    hs.coupling
                ),
            });
        };
        hub.restore(hs).map_err(|e| Fault {
            node: "coordinator".into(),
            reason: format!("coupling {}: {e}", hs.coupling),
        })?;
    }
    for &i in all {
        c.send(
            i,
            &Message::Advance(Advance {
                window: k,
                t0: st.time,
                t1: st.time,
                write_output: false,
                checkpoint: true,
            }),
        )?;
    }
    c.wait_all(all, "restore", None, |n| n.done == Some(k))?;
    for ns in &st.nodes {
        let Some(i) = c.node_idx(&ns.name) else {
            return Err(Fault {
                node: ns.name.clone(),
                reason: "in the checkpoint but not in the case".into(),
            });
        };
        let n = &mut c.nodes[i];
        n.stable_dt = ns.stable_dt;
        n.substeps = ns.substeps;
        n.wall_s = ns.wall_s;
        n.wait_s = ns.wait_s;
        n.idle_s = ns.idle_s;
        n.report = ns.report.clone();
        n.initial_energy = ns.initial_energy;
        n.initial_momentum = ns.initial_momentum;
        n.warnings = ns.warnings.clone();
    }
    for (ci, d) in st.decoupled.iter().enumerate() {
        let (Some((w, _, why)), Some(cp)) = (d, case.couplings.get(ci)) else {
            continue;
        };
        for node in [&cp.driver.0, &cp.responder.0] {
            if let Some(i) = c.node_idx(node) {
                c.send(
                    i,
                    &Message::Decouple(Decouple {
                        coupling: cp.name.clone(),
                        window: *w,
                        reason: why.clone(),
                    }),
                )?;
            }
        }
    }
    for ns in &st.nodes {
        if let (Some(w), Some(i)) = (ns.finished, c.node_idx(&ns.name)) {
            c.send(
                i,
                &Message::Finish(Finish {
                    reason: "decoupled: the solid goes on alone".into(),
                }),
            )?;
            c.nodes[i].finished = Some(w);
        }
    }
    c.history = st.history.clone();
    c.completed = k;
    c.rec
        .json(
            record::RESUMED_TOPIC,
            "cosim.Resumed",
            st.time,
            &json!({ "window": k, "time": st.time }),
        )
        .map_err(|e| Fault {
            node: "coordinator".into(),
            reason: format!("recording: {e:#}"),
        })?;
    eprintln!(
        "cosim: restarted from the checkpoint of window {k} (t = {:e} s)",
        st.time
    );
    Ok(())
}

/// Every node has written its state at the end of window `k` (its `Done` acknowledged it):
/// mark the point in the recording, push it to disk, then write the coordinator's own state,
/// which makes the checkpoint complete.
fn save_checkpoint(
    c: &mut Coord,
    out: &Path,
    a: &crate::checkpoint::Audit,
    decoupled: &[Option<(u64, f64, String)>],
    k: u64,
    t1: f64,
    loop_s: f64,
) -> Result<(), Fault> {
    use crate::checkpoint as ck;
    let case = c.case;
    let fault = |e: anyhow::Error| Fault {
        node: "coordinator".into(),
        reason: format!("checkpoint of window {k}: {e:#}"),
    };
    let st = ck::CoordState {
        run_id: c.run.clone(),
        case_path: case.path.display().to_string(),
        case_text: case.text.clone(),
        signature: ck::compat_signature(case),
        window: k,
        time: t1,
        nodes: c
            .nodes
            .iter()
            .zip(&case.nodes)
            .map(|(n, cfg)| ck::NodeState {
                name: n.name.clone(),
                model: cfg.model.clone(),
                params_hash: protocol::checkpoint::params_hash(&ck::params_toml(cfg)),
                stable_dt: n.stable_dt,
                substeps: n.substeps,
                wall_s: n.wall_s,
                wait_s: n.wait_s,
                idle_s: n.idle_s,
                report: n.report.clone(),
                initial_energy: n.initial_energy,
                initial_momentum: n.initial_momentum,
                finished: n.finished,
                warnings: n.warnings.clone(),
                remote: cfg.remote,
            })
            .collect(),
        audit: a.clone(),
        decoupled: decoupled.to_vec(),
        history: c.history.clone(),
        loop_s,
        lagrange: c.hubs.iter().filter_map(|(h, _)| h.save()).collect(),
    };
    let dir = protocol::checkpoint::dir(out, k);
    c.rec
        .json(
            record::CHECKPOINT_TOPIC,
            "cosim.Checkpoint",
            t1,
            &json!({ "window": k, "time": t1, "dir": dir }),
        )
        .map_err(fault)?;
    c.rec.flush().map_err(fault)?;
    ck::save(out, &st).map_err(fault)
}

/// Start and end time of window `k` of `windows` (the last one ends at the end time).
fn window_span(case: &Case, k: u64, windows: u64) -> (f64, f64) {
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
fn windows_ahead_fixed() -> Option<u64> {
    std::env::var("COSIM_WINDOWS_AHEAD")
        .ok()
        .and_then(|s| s.parse::<u64>().ok())
        .map(|a| a.clamp(1, MAX_AHEAD))
}

/// The fewest windows in flight by default: the awaited window and the next one, so the
/// nodes never wait for the audit or the recorder.
pub const WINDOWS_AHEAD: u64 = 2;
/// The most windows in flight: the control topics queue them
/// (`transport::shm::CONTROL_BUFFER`), and a stop request lets them end first.
pub const MAX_AHEAD: u64 = 8;
/// How much wall time the windows in flight may span (see [`Ahead`]).
const AHEAD_SPAN: Duration = Duration::from_millis(2);

/// How many windows may be in flight: [`WINDOWS_AHEAD`] for long windows, up to
/// [`MAX_AHEAD`] for windows so short that that many still take under [`AHEAD_SPAN`] of wall
/// time (the mean spacing of completed windows). Sent in batches (the next ones go out when
/// half have ended), short windows cost the coordinator one wake-up of each node per batch
/// instead of one per window; the span bounds how long a stop request or a checkpoint waits for
/// the windows already sent.
struct Ahead {
    fixed: Option<u64>,
    /// When the last window completed, and the mean spacing of completions (s).
    last: Option<Instant>,
    spacing: f64,
    measured: u32,
    /// The sum of the allowed counts at each completion, and the completions (their mean
    /// goes to `summary.json`).
    allowed_sum: u64,
    completions: u64,
}

impl Ahead {
    fn new() -> Self {
        Self::with_fixed(windows_ahead_fixed())
    }

    fn with_fixed(fixed: Option<u64>) -> Self {
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
    fn mean(&self) -> f64 {
        self.allowed_sum as f64 / self.completions.max(1) as f64
    }

    /// A window completed now.
    fn completed(&mut self) {
        let now = Instant::now();
        let dt = self.last.map(|l| now.duration_since(l).as_secs_f64());
        self.last = Some(now);
        self.completed_after(dt);
    }

    /// A window completed `dt` seconds after the last one (`None`: the first).
    fn completed_after(&mut self, dt: Option<f64>) {
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

    fn count(&self) -> u64 {
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
fn may_run_ahead(
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
fn send_window(
    c: &mut Coord,
    order_idx: &[usize],
    decoupled: &mut [Option<(u64, f64, String)>],
    active: &mut Vec<usize>,
    k: u64,
    stop_after: bool,
    quiet: bool,
) -> Result<bool, Fault> {
    let case = c.case;
    let windows = window_count(case);
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
fn run_ahead(
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

fn drive(
    c: &mut Coord,
    out: &Path,
    order: &[String],
    listen: &str,
    opts: &RunOptions,
) -> Result<serde_json::Value, Fault> {
    let case = c.case;
    let fault = |node: &str, reason: String| Fault {
        node: node.to_string(),
        reason,
    };
    // Launch local nodes; tell the user how to start remote ones.
    for (i, n) in case.nodes.iter().enumerate() {
        if n.remote {
            eprintln!(
                "cosim: waiting for remote node '{}': {} --run {} --node {} --transport {} --connect {} --token {}",
                n.name,
                n.solver,
                c.run,
                n.name,
                case.run.transport.as_str(),
                listen,
                c.token
            );
            if let Some(st) = &opts.restart {
                eprintln!(
                    "cosim: remote node '{}' resumes from its checkpoint of window {}, on its own host: start it there as before (with the same --output DIR if it had one)",
                    n.name, st.window
                );
            }
            continue;
        }
        let Some(exe) = &n.exe else { continue };
        let connect = (case.run.transport == TransportKind::Zenoh).then_some(listen);
        let log = out.join(format!("{}.log", n.name));
        let child = spawn_node(exe, &[], &c.run, &n.name, case.run.transport, connect, &log)
            .map_err(|e| fault(&n.name, e))?;
        c.nodes[i].child = Some(child);
        c.nodes[i].log = Some(log);
        c.nodes[i].last_seen = Instant::now();
    }
    let all: Vec<usize> = (0..c.nodes.len()).collect();
    let local: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&i| !case.nodes[i].remote)
        .collect();
    let remote: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&i| case.nodes[i].remote)
        .collect();
    let start = Duration::from_secs_f64(case.run.start_timeout);
    c.wait_all(
        &local,
        "Hello",
        Some((
            start,
            "the node is running but has not joined (a slow start? raise run.start_timeout)",
        )),
        |n| n.hello,
    )?;
    wait_for_joins(c, &remote)?;
    // Every node's silence so far was spent waiting for the others: the heartbeat clock
    // starts with the Welcome (nodes beat from then on), and so does the coordinator's own.
    for n in &mut c.nodes {
        n.last_seen = Instant::now();
    }
    c.own.restart();
    for (i, n) in case.nodes.iter().enumerate() {
        let w = Message::Welcome(Welcome {
            run: c.run.clone(),
            model: n.model.clone(),
            params_toml: toml::to_string(&n.params).map_err(|e| fault(&n.name, e.to_string()))?,
            bindings: config::bindings_of(case, &n.name),
            output_dir: out.join(&n.name).display().to_string(),
            heartbeat_ms: case.run.heartbeat_ms,
        });
        c.send(i, &w)?;
    }
    c.wait_all(
        &all,
        "Describe",
        Some((
            Duration::from_secs(60),
            "the node did not finish building its solver",
        )),
        |n| n.described >= 1,
    )?;
    // Lagrange couplings: every side subscribed before its Describe; once shared memory
    // shows them connected, each gets the coupling's request (system step, method).
    for h in 0..c.hubs.len() {
        let tp = topic::data(
            &c.run,
            &c.hubs[h].0.coupling,
            protocol::scheme::lagrange::wire::PEER,
        );
        let want = c.hubs[h].0.sides.len();
        let since = Instant::now();
        while c.t.readers(&tp).is_some_and(|r| r < want) {
            if since.elapsed() > Duration::from_secs(60) {
                return Err(fault(
                    &c.hubs[h].0.sides[0],
                    format!(
                        "the sides of coupling {} never subscribed to {tp}",
                        c.hubs[h].0.coupling
                    ),
                ));
            }
            c.pump_one(Duration::from_millis(5))?;
        }
        let req = c.hubs[h].0.request();
        c.publish_lagrange(h, req)?;
    }
    // Set-up (window 0).
    for i in 0..c.nodes.len() {
        c.send(
            i,
            &Message::Advance(Advance {
                window: 0,
                t0: 0.0,
                t1: 0.0,
                write_output: false,
                checkpoint: false,
            }),
        )?;
    }
    c.wait_all(&all, "set-up", None, |n| n.done == Some(0))?;
    // The hand-shake and set-up reach the disk before the first window.
    c.rec
        .flush()
        .map_err(|e| fault("coordinator", format!("recording: {e:#}")))?;
    let windows = window_count(case);
    let order_idx: Vec<usize> = order.iter().filter_map(|n| c.node_idx(n)).collect();
    // The audit (docs/architecture.md) so far: restored from the checkpoint on a restart.
    let mut a = crate::checkpoint::Audit::default();
    // Decouplings (seed 000 §4): (window, time, reason) per coupling once it happened.
    let mut decoupled: Vec<Option<(u64, f64, String)>> = vec![None; case.couplings.len()];
    let mut active: Vec<usize> = all.clone();
    // A restart continues after its checkpoint's window, from the state the nodes and the
    // coordinator saved there.
    let (first, loop_before) = match &opts.restart {
        Some(st) => {
            resume(c, st, &all)?;
            a = st.audit.clone();

            decoupled = st.decoupled.clone();
            for (u, d) in c.until.iter_mut().zip(&decoupled) {
                *u = d.as_ref().map(|d| d.0);
            }
            active.retain(|&i| c.nodes[i].finished.is_none());
            (st.window + 1, st.loop_s)
        }
        None => (1, 0.0),
    };
    let e0: f64 = c.nodes.iter().map(|n| n.initial_energy).sum();
    // A restart's guard reads the audited windows before its checkpoint again.
    c.guard.resume(
        a.rows
            .iter()
            .map(|r| (r.window, r.time, r.energy, r.external_work)),
        e0,
    );
    // The booking rule judges the impulse booked from here on.
    c.books
        .begin(first, c.nodes.iter().map(|n| &n.report.interface_impulse));
    let every = case.run.checkpoint_every;
    // A stop was requested: checkpoint the next window and stop there.
    let mut stop_after = false;
    c.progress = Progress::new(windows, case.run.end_time, opts.quiet);
    c.progress.resume_after(first - 1);
    let loop_start = Instant::now();
    c.in_windows = true;
    c.prof = Profile::default();
    c.prof.start();
    let lag0 = c.rec.lag_allocations;
    // Windows whose Advance is out and whose Done is not yet all in: (window, checkpoint).
    let mut in_flight: VecDeque<(u64, bool)> = VecDeque::with_capacity(MAX_AHEAD as usize + 1);
    let mut ahead = Ahead::new();
    let mut sent = first - 1;
    // Once no more than half of the windows allowed in flight are left after window
    // `completed`, the windows after the last one sent up to that count, while they may run
    // ahead (one batch: each node is woken once for it).
    macro_rules! top_up {
        ($completed:expr) => {
            let (done, n) = ($completed, ahead.count());
            if sent - done <= n / 2 {
                run_ahead(
                    c,
                    &order_idx,
                    &mut decoupled,
                    &mut active,
                    &mut in_flight,
                    &mut sent,
                    (done + n).min(windows),
                )?
            }
        };
    }
    for k in first..=windows {
        let (_, t1) = window_span(case, k, windows);
        c.window = k;
        if sent < k {
            let ck = send_window(
                c,
                &order_idx,
                &mut decoupled,
                &mut active,
                k,
                stop_after,
                false,
            )?;
            in_flight.push_back((k, ck));
            sent = k;
        }
        // Pipelining: the next windows' Advances go out now, so that the nodes go on while
        // this one is audited and recorded; only where nothing decided at this window's end
        // can change them (module doc).
        top_up!(k - 1);
        c.sim_t = c.sim_t.max(t1);
        if let Err(f) = c.wait_all(&active, "Done", None, |n| n.done.is_some_and(|d| d >= k)) {
            // A node about to send a non-finite value says so and leaves: the run diverged.
            let Some(mut d) = protocol::diverged::Divergence::parse(&f.reason) else {
                return Err(f);
            };
            // The quantity alone: the node's log is in the output folder.
            if let Some(at) = d.what.find(" (its log: ") {
                d.what.truncate(at);
            }
            let t = window_span(case, d.window.clamp(1, windows), windows).1;
            c.diverged = Some(c.guard.from_node(&f.node, d, t));
            break;
        }
        let checkpoint = in_flight.pop_front().is_some_and(|w| w.1);
        ahead.completed();
        // The window after the next goes out now, before this one's audit and records: the
        // driver finishes its next window while the responder computes, and then needs it
        // (the coordinator's own work per window would otherwise stand in its way). Not past
        // a checkpoint at this window: it is complete only once saved below.
        if ahead.count() > 1 && !checkpoint {
            top_up!(k);
        }
        let auditing = Instant::now();
        // Reports of later windows that came in meanwhile wait for their own audit.
        for (n, spare) in c.nodes.iter_mut().zip(&mut c.spare) {
            while n.ahead.front().is_some_and(|(w, _)| *w <= k) {
                if let Some((_, r)) = n.ahead.pop_front() {
                    spare.push(std::mem::replace(&mut n.report, r));
                }
            }
        }
        // Audit (docs/architecture.md): momentum against external impulse, energy against work.
        let mut p = [0.0; 3];
        let mut p0 = [0.0; 3];
        let mut jx = [0.0; 3];
        let mut ji = [0.0; 3];
        let (mut e, mut wext, mut wif, mut applied) = (0.0, 0.0, 0.0, 0.0);
        for n in &c.nodes {
            let r = &n.report;
            for d in 0..3 {
                p[d] += r.momentum[d];
                // the balance is against the start: a node may begin moving (an inflow, a
                // launched block)
                p0[d] += n.initial_momentum[d];
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
            .max(c.nodes.iter().map(|n| n.report.momentum_gross).sum());
        for n in &c.nodes {
            let r = &n.report;
            a.impulse_scale = a
                .impulse_scale
                .max(r.applied_impulse)
                .max(norm(r.external_impulse))
                .max(norm(r.interface_impulse));
        }
        // The booking rule: a node whose books and messages point opposite ways is stopped.
        let nodes = &c.nodes;
        if let Some((i, why)) = c.books.check(
            k,
            |i| {
                let n = &nodes[i];
                n.finished.is_none().then_some(&n.report.interface_impulse)
            },
            a.impulse_scale,
            |ci| decoupled[ci].is_some(),
        ) {
            return Err(fault(&c.nodes[i].name, why));
        }
        let reporting = c.prof.lap(Phase::Audit, auditing);
        let row = crate::checkpoint::BalanceRow {
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
        };
        let _ = c.rec.json_doc(
            "/cosim/balance",
            "cosim.Balance",
            t1,
            &row,
            &mut std::iter::empty(),
        );
        for n in c.nodes.iter().filter(|n| n.finished.is_none()) {
            let r = &n.report;
            let doc = NodeReportDoc {
                window: k,
                time: t1,
                r,
            };
            let _ = c.rec.json_doc(
                &n.report_topic,
                "cosim.NodeReport",
                t1,
                &doc,
                &mut r.scalars.iter().map(|(k, _)| k.as_str()),
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
        a.rows.push(row);
        let flushing = c.prof.lap(Phase::Reports, reporting);
        let nodes = c.nodes.iter().map(|n| crate::guard::NodeWindow {
            name: &n.name,
            report: &n.report,
            initial_energy: n.initial_energy,
        });
        if let Err(d) = c.guard.window(k, t1, nodes, e0, wext) {
            c.diverged = Some(d);
            c.completed = k;
            let _ = c.rec.window_end(Duration::from_millis(20));
            break;
        }
        c.progress.window(k, t1);
        c.completed = k;
        if checkpoint {
            let loop_s = loop_before + loop_start.elapsed().as_secs_f64();
            save_checkpoint(c, out, &a, &decoupled, k, t1, loop_s)?;
        }
        // Completed windows reach the disk (a killed cosim leaves them recoverable).
        let _ = c.rec.window_end(Duration::from_millis(20));
        c.prof.lap(Phase::Flush, flushing);
        // A stop signal ends the run here, at the window boundary; with checkpoints, after
        // one more window that checkpoints, so that a restart continues from where it stopped.
        if let Some(sig) = stop::requested() {
            if sent > k {
                continue; // windows already under way end first, each at its boundary
            }
            if every > 0 && !checkpoint && !stop_after {
                stop_after = true;
                continue;
            }
            c.interrupted = Some(sig);
            break;
        }
    }
    c.progress.finish();
    let loop_s = loop_before + loop_start.elapsed().as_secs_f64();
    c.prof.add_recorder_lag_allocs(c.rec.lag_allocations - lag0);
    c.prof.stop();
    let mut breakdown = c.prof.per_window(c.completed.saturating_sub(first - 1));
    breakdown["windows_in_flight"] = ahead.mean().into();
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
    let end_reason = match (&c.interrupted, &c.diverged) {
        (_, Some(d)) => format!("the run diverged: {d}"),
        (Some(sig), None) => format!(
            "interrupted by {} after window {}",
            stop::name(*sig),
            c.completed
        ),
        (None, None) => "end time reached".into(),
    };
    for i in active.clone() {
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
    let applied_final = a.rows.last().map_or(0.0, |r| r.applied_impulse);
    let mut nodes_json = BTreeMap::new();
    for (i, n) in c.nodes.iter().enumerate() {
        let cfg = &case.nodes[i];
        let of_loop = |x: f64| if loop_s > 0.0 { x / loop_s } else { 0.0 };
        nodes_json.insert(
            n.name.clone(),
            json!({
                "solver": cfg.solver, "model": cfg.model, "remote": cfg.remote,
                "stable_dt": n.stable_dt, "substeps": n.substeps,
                "compute_s": n.wall_s, "coupling_wait_s": n.wait_s, "idle_s": n.idle_s,
                // Shares of the window loop's wall time: computing (and sending), blocked on
                // a peer's input with a window in hand, waiting for the next window.
                "compute_fraction": of_loop(n.wall_s),
                "coupling_fraction": of_loop(n.wait_s),
                "idle_fraction": of_loop(n.idle_s),
                "finished_after_window": n.finished,
                "warnings": n.warnings,
                "final": {
                    "kinetic_energy": n.report.kinetic_energy, "internal_energy": n.report.internal_energy,
                    "external_work": n.report.external_work, "interface_work": n.report.interface_work,
                    "momentum": n.report.momentum,
                    "scalars": n.report.scalars.iter().cloned().collect::<HashMap<String, f64>>(),
                },
            }),
        );
    }
    let couplings: Vec<serde_json::Value> = case
        .couplings
        .iter()
        .zip(&decoupled)
        .map(|(cp, d)| {
            let mut v = json!({ "name": cp.name, "kind": cp.kind.as_str(),
                    "driver": format!("{}.{}", cp.driver.0, cp.driver.1),
                    "responder": format!("{}.{}", cp.responder.0, cp.responder.1) });
            if let Some((w, t, why)) = d {
                v["decoupled"] = json!({ "before_window": w, "time": t, "reason": why });
            }
            if cp.kind == CouplingKind::Lagrange {
                let by_side: BTreeMap<String, f64> = cp
                    .sides
                    .iter()
                    .filter_map(|s| {
                        let i = c.node_idx(&s.0)?;
                        Some((format!("{}.{}", s.0, s.1), c.nodes[i].report.interface_work))
                    })
                    .collect();
                let work: f64 = by_side.values().sum();
                v["sides"] = json!(
                    cp.sides
                        .iter()
                        .map(|s| format!("{}.{}", s.0, s.1))
                        .collect::<Vec<_>>()
                );
                v["method"] = json!(
                    format!(
                        "{:?}",
                        cp.method.unwrap_or(protocol::scheme::lagrange::Method::Gs4)
                    )
                    .to_lowercase()
                );
                // ΔE_Γ = −Σᵢ Wᵢ: ≥ 0 is energy the interface dissipated (J).
                v["interface_work_by_side"] = json!(by_side);
                v["interface_energy"] = json!(-work);
            }
            v
        })
        .collect();
    let reached_t = a.rows.last().map_or(0.0, |r| r.time);
    // Energy the methods created, short of the divergence bound: the mark of a slowly
    // growing instability (a window near the coupling's limit) that a user must see.
    let created = if a.energy_scale > 0.0 {
        a.worst_e_resid / a.energy_scale
    } else {
        0.0
    };
    let balance_warning = (created > crate::guard::CREATED_WARNING).then(|| {
        format!(
            "balance: the numerical methods created {:.1} % of the largest energy or work (energy residual {:+.4e} J); a healthy run creates almost none: the coupling or an integrator may be near its stability limit (try a smaller run.window)",
            created * 100.0,
            a.worst_e_resid
        )
    });
    Ok(json!({
        "run": c.run,
        "status": if c.diverged.is_some() { "diverged" } else if c.interrupted.is_some() { "interrupted" } else { "finished" },
        "divergence": c.diverged.as_ref().map(crate::guard::Diverged::to_json),
        "signal": c.interrupted.map(stop::name),
        "window_reached": c.completed,
        "time_reached": reached_t,
        "case": case.path.display().to_string(),
        "transport": case.run.transport.as_str(),
        "schedule": match case.run.schedule { config::Schedule::Serial => "serial", config::Schedule::Parallel => "parallel" },
        "end_time": case.run.end_time,
        "window": case.run.window,
        "windows": windows,
        "nodes": nodes_json,
        // Every node's warnings, "node: text" (also per node above, and in the log).
        "warnings": case
            .warnings
            .iter()
            .map(|w| format!("case: {w}"))
            .chain(balance_warning)
            .chain(
                c.nodes
                    .iter()
                    .flat_map(|n| n.warnings.iter().map(move |w| format!("{}: {w}", n.name))),
            )
            .collect::<Vec<_>>(),
        "couplings": couplings,
        // What the run costs beyond its slowest node's own work: the coupling overhead on
        // the critical path (exchange, waiting, coordination).
        "window_loop_s": loop_s,
        // The coordinator's side of a window (this process only: a restart's segment).
        "window_breakdown": breakdown,
        // Gaps in which the coordinator itself did not run (no node was blamed for them).
        "coordinator_stalls": { "count": c.own.count, "longest_s": c.own.longest },
        // Per node the booking rule applies to, the windows it judged (PROTOCOL.md 4.7).
        "booking_rule": c
            .books
            .judged_nodes()
            .map(|(i, n)| (c.nodes[i].name.clone(), serde_json::json!({ "judged_windows": n })))
            .collect::<serde_json::Map<_, _>>(),
        "coupling_overhead": if loop_s > 0.0 {
            1.0 - c.nodes.iter().map(|n| n.wall_s).fold(0.0, f64::max) / loop_s
        } else {
            0.0
        },
        "balance": {
            "applied_impulse": applied_final,
            "max_momentum_imbalance": a.worst_p,
            "max_momentum_imbalance_relative": if applied_final > 0.0 { a.worst_p / applied_final } else { 0.0 },
            "max_interface_impulse_sum": a.worst_iface_p,
            "impulse_scale": a.impulse_scale,
            "momentum_scale": a.momentum_scale,
            "max_momentum_residual": a.worst_resid,
            // Against the larger of the two scales: the largest impulse any node saw, and the
            // largest gross momentum of the run.
            "max_momentum_residual_relative": if a.impulse_scale.max(a.momentum_scale) > 0.0 {
                a.worst_resid / a.impulse_scale.max(a.momentum_scale)
            } else {
                0.0
            },
            // Signed: negative is energy the numerical methods (and couplings) dissipated,
            // positive energy they created.
            "max_energy_residual": a.worst_e_resid,
            "energy_scale": a.energy_scale,
            // The divergence guard's reading: the largest total energy over its budget
            // (initial energy plus the largest external work so far), against
            // run.energy_bound.
            "max_energy_over_budget": c.guard.worst_ratio(),
            "energy_bound": case.run.energy_bound,
            "max_energy_residual_relative": if a.energy_scale > 0.0 {
                a.worst_e_resid / a.energy_scale
            } else {
                0.0
            },
            "per_window": a.rows,
        },
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report() -> StepReport {
        StepReport {
            kinetic_energy: 1.5,
            internal_energy: 2.5,
            external_work: 3.0,
            interface_work: -0.25,
            momentum: [0.1, -0.2, 0.3],
            momentum_gross: 4.0,
            external_impulse: [1.0, 0.0, 0.0],
            interface_impulse: [0.0, 2.0, 0.0],
            substeps: 3,
            wall_s: 1e-5,
            coupling_wait_s: 2e-6,
            scalars: vec![
                ("tip_displacement".into(), 7e-4),
                ("internal_energy".into(), 9.0),
                ("probe".into(), f64::NAN),
            ],
            ..Default::default()
        }
    }

    /// `BUILTIN_KEYS` (what a dotted scalar name may not nest under) lists exactly the keys
    /// the serializer writes besides the scalars: a key added to one and not the other fails.
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

    #[test]
    fn builtin_keys_are_the_keys_of_a_report_without_scalars() {
        let r = StepReport::default();
        let doc = NodeReportDoc {
            window: 1,
            time: 0.0,
            r: &r,
        };
        let v = serde_json::to_value(&doc).expect("serialize");
        let mut got: Vec<&str> = v
            .as_object()
            .expect("an object")
            .keys()
            .map(String::as_str)
            .collect();
        let mut want = BUILTIN_KEYS.to_vec();
        got.sort_unstable();
        want.sort_unstable();
        assert_eq!(got, want);
    }

    /// The record written straight from the report is the document the coordinator built
    /// with `json!` before (written out here as it did: quantities, then the scalars set over
    /// them), and gives the same plot histories.
    #[test]
    fn node_report_doc_is_the_json_report() {
        let mut r = report();
        r.scalars.push(("point1.pressure".into(), 2e5));
        r.scalars.push(("point1.density".into(), 1.2));
        let mut old = json!({
            "window": 7, "time": 3.5e-6,
            "kinetic_energy": r.kinetic_energy, "internal_energy": r.internal_energy,
            "external_work": r.external_work, "interface_work": r.interface_work,
            "momentum": r.momentum, "momentum_gross": r.momentum_gross,
            "external_impulse": r.external_impulse,
            "interface_impulse": r.interface_impulse,
            "substeps": r.substeps, "wall_s": r.wall_s,
            "coupling_wait_s": r.coupling_wait_s,
        });
        for (name, val) in &r.scalars {
            old[name] = json!(val);
        }
        let doc = NodeReportDoc {
            window: 7,
            time: 3.5e-6,
            r: &r,
        };
        let bytes = serde_json::to_vec(&doc).expect("serialize");
        let new: serde_json::Value = serde_json::from_slice(&bytes).expect("parse");
        // the dotted names nested as Foxglove addresses them, the same document flattened
        assert_eq!(new["point1"], json!({ "pressure": 2e5, "density": 1.2 }));
        let flat = crate::nest::flatten(new.as_object().expect("an object"));
        assert_eq!(serde_json::Value::Object(flat), old);
        assert_eq!(new["internal_energy"], json!(9.0));
        assert!(new["probe"].is_null());
        let mut h_old = crate::plot::Histories::new();
        crate::plot::add_report(&mut h_old, "left", &old);
        let mut h_new = crate::plot::Histories::new();
        crate::plot::add_node_report(&mut h_new, "left", 3.5e-6, &r, 10);
        assert_eq!(h_new, h_old);
        // kinetic, internal (the scalar), external and interface work, gross momentum,
        // three momentum components, the tip displacement, the two point values; not the
        // NaN probe
        assert_eq!(h_new["left"].len(), 11, "{:?}", h_new["left"].keys());
    }
}
