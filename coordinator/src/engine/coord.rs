//! The coordinator's state during a run ([`Coord`]): its transport, topics, nodes,
//! recorder, audit helpers and lagrange hubs, and what it sends; opened before the nodes
//! start and closed whatever happened.

use crate::case::Case;
use crate::contract::Contract;
use crate::profile::Profile;
use crate::progress::Progress;
use crate::record::RecorderThread;
use protocol::codec::{self, encode_into};
use protocol::scheme::lagrange;
use protocol::stop;
use protocol::transport::{Publisher, Transport};
use protocol::*;
use std::collections::VecDeque;
use std::path::PathBuf;
use std::process::Child;
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

pub(super) enum Topic {
    Up(usize),
    Data(usize),
}

pub(super) struct NodeRt {
    pub(super) name: String,
    pub(super) child: Option<Child>,
    pub(super) down: Box<dyn Publisher>,
    pub(super) last_seen: Instant,
    /// Since when the node's heartbeats say it is blocked on a peer's input.
    pub(super) waiting_since: Option<Instant>,
    pub(super) idle_s: f64,
    pub(super) hello: bool,
    pub(super) described: u32,
    pub(super) stable_dt: f64,
    pub(super) done: Option<u64>,
    pub(super) report: StepReport,
    /// Energy and momentum after set-up: the audit balances against them.
    pub(super) initial_energy: f64,
    pub(super) initial_momentum: [f64; 3],
    pub(super) substeps: u64,
    pub(super) wall_s: f64,
    pub(super) wait_s: f64,
    pub(super) exited: Option<String>,
    /// Where its stdout and stderr go (launched nodes).
    pub(super) log: Option<PathBuf>,
    /// Finished before the end (its couplings ended, seed 000 §4): the window after which.
    pub(super) finished: Option<u64>,
    /// What the node warned of in its descriptions (each once).
    pub(super) warnings: Vec<String>,
    /// Reports of windows after the one being audited (pipelining), oldest first.
    pub(super) ahead: VecDeque<(u64, StepReport)>,
    /// The recording's channel of its per-window reports: `/cosim/node/<name>`.
    pub(super) report_topic: String,
    /// How its report's scalars are recorded there (kept while their names stay).
    pub(super) record_plan: super::report::RecordPlan,
    /// The topic of what the coordinator sends it (its recording channel).
    pub(super) down_topic: String,
}

pub(crate) struct Coord<'a> {
    pub(super) case: &'a Case,
    pub(super) run: String,
    pub(super) token: String,
    pub(super) t: Box<dyn Transport>,
    pub(super) topics: Vec<(String, Topic)>,
    /// Per topic (as `topics`), what its node's `Fields` must hold on a data topic that is
    /// not a lagrange side's.
    pub(super) contracts: Vec<Option<Contract>>,
    /// The booking rule's check: the `force` that crossed the interfaces against the nodes'
    /// booked interface impulse.
    pub(super) books: crate::books::Books,
    /// Per topic (as `topics`), the coupling and side whose data it carries (None: a node's
    /// up topic), and the last window of `Fields` seen on it.
    pub(super) sides: Vec<Option<(usize, String)>>,
    pub(super) last_fields: Vec<Option<u64>>,
    /// Per coupling, the window before which it ended (decoupled), for the deadlock message.
    pub(super) until: Vec<Option<u64>>,
    /// In [`Coord::culprit`]: reading what is queued behind a `Failed`.
    pub(super) draining: bool,
    pub(super) nodes: Vec<NodeRt>,
    /// The recorder, on its own thread: recording never holds the window loop up.
    pub(super) rec: RecorderThread,
    pub(super) buf: Vec<u8>,
    pub(super) seq: u64,
    pub(super) sim_t: f64,
    pub(super) window: u64,
    pub(super) faults: Vec<Fault>,
    /// Every node's reported quantities per window, for the plots written at the end.
    pub(super) history: crate::plot::Histories,
    /// The last window completed by every node.
    pub(super) completed: u64,
    /// In the window loop: a first stop signal waits for the window boundary there.
    pub(super) in_windows: bool,
    /// The stop signal that ends the run, once acted on.
    pub(super) interrupted: Option<i32>,
    /// The divergence guard, and why it stopped the run.
    pub(super) guard: crate::guard::Guard,
    pub(super) diverged: Option<crate::guard::Diverged>,
    /// The bar or progress lines of the window loop; messages go through it.
    pub(super) progress: Progress,
    /// The lagrange couplings (the interface problems solved here) and their publishers.
    pub(super) hubs: Vec<(lagrange::Hub, Box<dyn Publisher>)>,
    /// Where the window loop's time goes (`summary.json`: `window_breakdown`).
    pub(super) prof: Profile,
    /// The last receive's time blocked and recording (ns), for [`Coord::pump_one`].
    pub(super) last_recv_ns: (u64, u64),
    /// [`Coord::wait_all`]'s list of the nodes still awaited.
    pub(super) pending: Vec<usize>,
    /// When [`Coord::check_health`] last ran, and the coordinator's own stalls seen
    /// (`summary.json`: `coordinator_stalls`).
    pub(super) own: crate::clock::OwnClock,
    /// Per node, the report of its `Done` being received, read in place
    /// (`codec::decode_done_into`), then swapped with the node's: once the node's scalar
    /// names have been seen, the window loop allocates nothing for it.
    pub(super) inbox: Vec<StepReport>,
    /// Per node, its reports returned from `NodeRt::ahead` once audited, reused for the next
    /// ones.
    pub(super) spare: Vec<Vec<StepReport>>,
}

/// The most windows in flight: the control topics queue them
/// (`transport::shm::CONTROL_BUFFER`), and a stop request lets them end first.
pub const MAX_AHEAD: u64 = 8;

/// How often [`Coord::wait_all`] checks the nodes' health while messages keep arriving.
pub(super) const HEALTH_EVERY: Duration = Duration::from_millis(2);

/// At most this many queued messages are read before a node is judged silent.
pub(super) const QUEUED_MAX: usize = 4096;

/// A message as [`Coord::pump_one`] received it.
pub(super) enum Got {
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
pub(super) enum LagIn {
    Mesh(Mesh),
    Fields(Fields),
}

/// The coordinator's side of the run's topics: one up topic per node, then per coupling the
/// data topic of each member (with the contract it keeps, where the scheme has one), and a
/// hub with its publisher for each scheme the coordinator solves.
struct Wiring {
    topics: Vec<(String, Topic)>,
    contracts: Vec<Option<Contract>>,
    /// Per topic, the coupling and side whose data it carries (the booking rule's feeds).
    sides: Vec<Option<(usize, String)>>,
    hubs: Vec<(lagrange::Hub, Box<dyn Publisher>)>,
}

impl Wiring {
    fn of(case: &Case, run_id: &str, t: &mut dyn Transport) -> anyhow::Result<Wiring> {
        let mut w = Wiring {
            topics: Vec::new(),
            contracts: Vec::new(),
            sides: Vec::new(),
            hubs: Vec::new(),
        };
        let idx = |n: &str| case.nodes.iter().position(|x| x.name == n).unwrap_or(0);
        for (i, n) in case.nodes.iter().enumerate() {
            let tp = topic::up(run_id, &n.name);
            t.subscribe(&tp)?;
            w.topics.push((tp, Topic::Up(i)));
            w.contracts.push(None);
            w.sides.push(None);
        }
        for (ci, c) in case.couplings.iter().enumerate() {
            let solved = protocol::scheme::of(c.kind).coordinator_solved();
            // A scheme the coordinator solves has a hub here (the lagrange interface problem).
            if solved {
                let readers: Vec<String> = c.sides.iter().map(|s| s.0.clone()).collect();
                let p = t.publisher(
                    &topic::data(run_id, &c.name, lagrange::wire::PEER),
                    &readers,
                )?;
                let method = c.method.unwrap_or(lagrange::Method::Gs4);
                let hub = lagrange::Hub::new(&c.name, method, &readers, case.run.window);
                w.hubs.push((hub, p));
            }
            for (k, (side, _)) in c.members().into_iter().enumerate() {
                let tp = topic::data(run_id, &c.name, side);
                t.subscribe(&tp)?;
                w.topics.push((tp, Topic::Data(idx(side))));
                w.sides.push(Some((ci, side.to_string())));
                // Members are the driver, then the responder, where there is a contract.
                let role = if k == 0 {
                    Role::Driver
                } else {
                    Role::Responder
                };
                w.contracts
                    .push((!solved).then(|| Contract::in_case(case, c, role)));
            }
        }
        Ok(w)
    }
}

/// The run's token, which a remote node presents in its `Hello`: the clock and this
/// process's id, mixed.
fn run_token() -> String {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    format!(
        "{:016x}",
        (t as u64) ^ ((std::process::id() as u64) << 32) ^ 0x9e37_79b9_7f4a_7c15
    )
}

impl NodeRt {
    /// Node `name` before its process starts: nothing heard from it yet.
    fn new(run_id: &str, name: &str, down: Box<dyn Publisher>) -> NodeRt {
        NodeRt {
            name: name.to_string(),
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
            report_topic: format!("/cosim/node/{name}"),
            record_plan: Default::default(),
            down_topic: topic::down(run_id, name),
        }
    }
}

impl<'a> Coord<'a> {
    /// The last window of `Fields` seen from `sender` on coupling `coupling` (None: none).
    pub(super) fn fields_seen(&self, coupling: &str, sender: &str) -> Option<u64> {
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

    pub(super) fn node_idx(&self, name: &str) -> Option<usize> {
        self.nodes.iter().position(|n| n.name == name)
    }

    /// Stop now on a stop signal received during set-up (there is no window boundary to wait
    /// for) or on the second one (a second Ctrl-C); the cleanup still runs.
    pub(super) fn stop_now(&mut self) -> Result<(), Fault> {
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

    pub(super) fn send(&mut self, i: usize, m: &Message) -> Result<(), Fault> {
        self.send_ringing(i, m, true)
    }

    /// [`Coord::send`], waking the node only if `ring` (a batch of `Advance`s goes quietly and
    /// rings once, [`Coord::ring`]).
    pub(super) fn send_ringing(&mut self, i: usize, m: &Message, ring: bool) -> Result<(), Fault> {
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
    pub(super) fn ring(&mut self, i: usize) -> Result<(), Fault> {
        let a0 = crate::profile::allocations_now();
        let r = self.nodes[i].down.ring();
        self.prof
            .add_transport_allocs(crate::profile::allocations_now() - a0);
        r.map_err(|e| Fault {
            node: self.nodes[i].name.clone(),
            reason: format!("waking the node failed: {e}"),
        })
    }

    pub(super) fn abort_all(&mut self, reason: &str) {
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

impl<'a> Coord<'a> {
    /// The coordinator of run `run` of `case` on transport `t`, recording with `rec`: every
    /// node's up topic and every coupling member's data topic subscribed, each with the field
    /// contract it must keep, a lagrange hub per coupling the coordinator solves, and a down
    /// topic per node.
    pub(crate) fn new(
        case: &'a Case,
        run_id: String,
        mut t: Box<dyn Transport>,
        rec: RecorderThread,
    ) -> anyhow::Result<Coord<'a>> {
        let Wiring {
            topics,
            contracts,
            sides,
            hubs,
        } = Wiring::of(case, &run_id, t.as_mut())?;
        let mut nodes = Vec::new();
        for n in &case.nodes {
            let down = t.publisher(
                &topic::down(&run_id, &n.name),
                std::slice::from_ref(&n.name),
            )?;
            nodes.push(NodeRt::new(&run_id, &n.name, down));
        }
        Ok(Coord {
            case,
            run: run_id.clone(),
            token: run_token(),
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
        })
    }

    /// Close what the run opened, whatever happened: the nodes' processes, the recording
    /// and this process's ports (the caller then sweeps the run's shared memory). A recording
    /// that cannot be finished (a full disk) fails a run that had not failed.
    pub(crate) fn close(mut self, outcome: Result<serde_json::Value, Fault>) -> Closed {
        let outcome = match outcome {
            Ok(summary) => Ok(summary),
            Err(f) => {
                self.abort_all(&f.to_string());
                self.faults.push(Fault {
                    node: f.node.clone(),
                    reason: f.reason.clone(),
                });
                Err(f)
            }
        };
        for n in &mut self.nodes {
            if let Some(ch) = n.child.as_mut() {
                let _ = ch.kill();
                let _ = ch.wait();
            }
        }
        let (interrupted, completed) = (self.interrupted, self.completed);
        let diverged = self.diverged.clone();
        let Coord {
            rec,
            t,
            nodes,
            history,
            hubs,
            ..
        } = self;
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
        Closed {
            outcome,
            interrupted,
            completed,
            diverged,
            history,
            messages,
            bytes,
        }
    }
}

/// What is left of a run once [`Coord::close`] closed it.
pub(crate) struct Closed {
    /// The summary of a run that ended its window loop, or the fault that ended it.
    pub outcome: Result<serde_json::Value, Fault>,
    /// The stop signal that ended it.
    pub interrupted: Option<i32>,
    /// The last window every node completed.
    pub completed: u64,
    pub diverged: Option<crate::guard::Diverged>,
    /// Every node's reports, for the plots.
    pub history: crate::plot::Histories,
    /// Messages and bytes recorded.
    pub messages: u64,
    pub bytes: u64,
}

/// A fault of node `node`.
pub(super) fn fault(node: &str, reason: String) -> Fault {
    Fault {
        node: node.to_string(),
        reason,
    }
}
