//! Participant runtime: runs any `Solver` as a node. Split in two so that the same logic serves
//! a node process and an in-process replay:
//!
//! * [`NodeEngine`]: couplings, the per-coupling input buffers (which window's data feeds which
//!   window, docs/architecture.md), interface mapping (`v_r = W v_d`, `f_d = Wᵀ f_r`) and the calls
//!   into the solver. No I/O.
//! * [`node_main`]: the process around it: command line, transport, handshake, heartbeat
//!   thread, the window loop, and clean failure (a `Failed` message, then a non-zero exit).

use crate::codec::{self, encode_into};
use crate::mapping::Mapping;
use crate::message::*;
use crate::scheme;
use crate::scheme::lagrange::node as lagrange;
use crate::solver::{
    BoxedFactory, BuildOptions, FieldSet, Solver, SolverError, SolverFactory, SolverResult, Window,
};
use crate::transport::{self, Publisher, Transport, TransportKind, TransportSpec};
use crate::{checkpoint, stop, watchdog};
use std::collections::VecDeque;
use std::ffi::OsString;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

pub use crate::error::EngineError;
pub use crate::scheme::{MOTION_FIELDS, is_motion};

/// One coupling of this node, with its input buffer and mapping.
pub(crate) struct Link {
    pub(crate) b: Binding,
    /// Peer fields not consumed yet, oldest first.
    pub(crate) pending: VecDeque<Fields>,
    /// Set for a responder whose interface differs from the driver's layout.
    map: Option<Mapping>,
    /// Number of points on the wire (the driver's layout).
    wire_points: usize,
    /// Decoupled: the first window the peer produces nothing for (seed 000 §4).
    until: Option<u64>,
}

/// Couplings, buffers and mapping around a solver; transport-free.
pub struct NodeEngine {
    pub solver: Box<dyn Solver>,
    pub(crate) links: Vec<Link>,
    inbox: FieldSet,
    pub(crate) outbox: FieldSet,
    scratch: Vec<f64>,
    /// Consumed peer messages, kept so that the next ones are read into their buffers.
    spare: Vec<Fields>,
}

/// Consumed peer messages kept for reuse (a few per coupling suffice: a window holds one).
const SPARE: usize = 8;

impl NodeEngine {
    pub fn new(solver: Box<dyn Solver>, bindings: &[Binding]) -> Self {
        let links = bindings
            .iter()
            .map(|b| Link {
                b: b.clone(),
                pending: VecDeque::new(),
                map: None,
                wire_points: 0,
                until: None,
            })
            .collect();
        NodeEngine {
            solver,
            links,
            inbox: FieldSet::new(),
            outbox: FieldSet::new(),
            scratch: Vec::new(),
            spare: Vec::new(),
        }
    }

    pub fn bindings(&self) -> impl Iterator<Item = &Binding> {
        self.links.iter().map(|l| &l.b)
    }

    /// The mesh this node puts on the wire for each coupling (its own interface).
    pub fn own_meshes(&self) -> Result<Vec<Mesh>, EngineError> {
        let mut v = Vec::new();
        for l in &self.links {
            v.push(Mesh {
                coupling: l.b.coupling.clone(),
                interface: l.b.interface.clone(),
                mesh: self.solver.interface(&l.b.interface)?,
            });
        }
        Ok(v)
    }

    /// Take the peer's interface mesh: a responder builds its mapping `W` from it.
    pub fn peer_mesh(&mut self, m: &Mesh) -> Result<(), EngineError> {
        let Some(i) = self.links.iter().position(|l| l.b.coupling == m.coupling) else {
            return Err(EngineError::Coupling {
                coupling: m.coupling.clone(),
                reason: "mesh for a coupling this node is not part of".into(),
            });
        };
        let own = self.solver.interface(&self.links[i].b.interface)?;
        let l = &mut self.links[i];
        match l.b.role {
            Role::Driver => l.wire_points = own.len(),
            Role::Responder => {
                l.wire_points = m.mesh.len();
                l.map = scheme::of(l.b.kind)
                    .responder_map(&m.mesh, &own)
                    .map_err(|reason| EngineError::Coupling {
                        coupling: m.coupling.clone(),
                        reason,
                    })?;
            }
        }
        Ok(())
    }

    /// Whether every coupling has its peer mesh.
    pub fn meshes_complete(&self) -> bool {
        self.links
            .iter()
            .all(|l| l.wire_points > 0 || !scheme::of(l.b.kind).needs_peer_mesh())
    }

    /// Buffer fields that arrived from a peer.
    pub fn receive(&mut self, f: Fields) -> Result<(), EngineError> {
        let Some(l) = self.links.iter_mut().find(|l| l.b.coupling == f.coupling) else {
            return Err(EngineError::Coupling {
                coupling: f.coupling,
                reason: "fields for a coupling this node is not part of".into(),
            });
        };
        if l.until.is_some_and(|u| f.window >= u) {
            return Ok(()); // produced after the decoupling: nobody consumes it
        }
        l.pending.push_back(f);
        Ok(())
    }

    /// [`Self::receive`] for fields read where they arrived (a shared-memory sample, checked
    /// by [`codec::decode_fields_view`]): their values are copied once, into the buffers of a
    /// message already consumed, so a window's input allocates nothing in steady state.
    pub fn receive_view(&mut self, v: &codec::FieldsView) -> Result<(), EngineError> {
        let Some(l) = self.links.iter_mut().find(|l| l.b.coupling == v.coupling) else {
            return Err(EngineError::Coupling {
                coupling: v.coupling.to_string(),
                reason: "fields for a coupling this node is not part of".into(),
            });
        };
        if l.until.is_some_and(|u| v.window >= u) {
            return Ok(()); // produced after the decoupling: nobody consumes it
        }
        let mut f = self.spare.pop().unwrap_or_else(|| Fields {
            coupling: String::new(),
            window: 0,
            time: 0.0,
            fields: Vec::new(),
        });
        f.coupling.clear();
        f.coupling.push_str(v.coupling);
        f.window = v.window;
        f.time = v.time;
        f.fields.truncate(v.fields.len());
        f.fields.resize_with(v.fields.len(), || Field {
            name: String::new(),
            components: 0,
            values: Vec::new(),
        });
        for (to, from) in f.fields.iter_mut().zip(&v.fields) {
            to.name.clear();
            to.name.push_str(from.name);
            to.components = from.components;
            to.values.clear();
            to.values.extend(from.values());
        }
        l.pending.push_back(f);
        Ok(())
    }

    /// Label of the peer output window `window` consumes on link `l` (None: nothing needed).
    fn needed(l: &Link, window: u64) -> Option<u64> {
        scheme::of(l.b.kind).input_window(l.b.role, l.b.input_lag, l.until, window)
    }

    /// End coupling `coupling` before window `window` (docs/architecture.md, seed 000 §4): the
    /// peer's outputs of earlier windows are still consumed (a lagged input in flight), later
    /// ones are neither expected nor sent, and the solver is told it goes on alone.
    pub fn decouple(&mut self, coupling: &str, window: u64) -> Result<(), EngineError> {
        let Some(l) = self.links.iter_mut().find(|l| l.b.coupling == coupling) else {
            return Err(EngineError::Coupling {
                coupling: coupling.to_string(),
                reason: "decoupling a coupling this node is not part of".into(),
            });
        };
        if window == 0 {
            return Err(EngineError::Coupling {
                coupling: coupling.to_string(),
                reason: "cannot decouple before the first window".into(),
            });
        }
        l.until = Some(l.until.map_or(window, |u| u.min(window)));
        l.pending.retain(|f| f.window < window);
        let interface = l.b.interface.clone();
        self.solver.decouple(&interface)?;
        Ok(())
    }

    /// Whether coupling `coupling` is still exchanging data in `window`.
    pub fn coupled(&self, coupling: &str, window: u64) -> bool {
        self.links
            .iter()
            .find(|l| l.b.coupling == coupling)
            .is_some_and(|l| l.until.is_none_or(|u| window < u))
    }

    /// True when the inputs of `window` (0 = set-up) are all buffered.
    pub fn ready(&self, window: u64) -> bool {
        self.links.iter().all(|l| match Self::needed(l, window) {
            None => true,
            Some(k) => l.pending.iter().any(|f| f.window == k),
        })
    }

    /// Couplings still missing an input for `window` (for error messages).
    pub fn missing(&self, window: u64) -> Vec<String> {
        self.links
            .iter()
            .filter(|l| match Self::needed(l, window) {
                None => false,
                Some(k) => !l.pending.iter().any(|f| f.window == k),
            })
            .map(|l| {
                format!(
                    "{} (window {})",
                    l.b.coupling,
                    Self::needed(l, window).unwrap_or(0)
                )
            })
            .collect()
    }

    /// Move the buffered inputs of `window` into the inbox, mapped into this solver's layout.
    fn fill_inbox(&mut self, window: u64) -> Result<(), EngineError> {
        // Decoupled links: their last inputs must not be used again (the inbox keeps its
        // buffers between windows).
        for l in &self.links {
            if l.until.is_some() && Self::needed(l, window).is_none() {
                self.inbox.remove_interface(&l.b.interface);
            }
        }
        for l in &mut self.links {
            let Some(k) = Self::needed(l, window) else {
                continue;
            };
            while l.pending.front().is_some_and(|f| f.window < k) {
                if let Some(f) = l.pending.pop_front()
                    && self.spare.len() < SPARE
                {
                    self.spare.push(f);
                }
            }
            let Some(f) = l.pending.iter().find(|f| f.window == k) else {
                return Err(EngineError::Coupling {
                    coupling: l.b.coupling.clone(),
                    reason: format!("input of window {k} missing"),
                });
            };
            let sch = scheme::of(l.b.kind);
            for field in &f.fields {
                sch.receive(
                    l.b.role,
                    l.map.as_ref(),
                    &l.b.interface,
                    field,
                    &mut self.inbox,
                )
                .map_err(|reason| EngineError::Coupling {
                    coupling: l.b.coupling.clone(),
                    reason,
                })?;
            }
        }
        Ok(())
    }

    /// Turn the outbox into one `Fields` message per coupling (in the driver's layout).
    fn drain_outbox(&mut self, window: u64, time: f64) -> Result<Vec<Fields>, EngineError> {
        let mut msgs = Vec::with_capacity(self.links.len());
        for l in &self.links {
            if l.until.is_some_and(|u| window >= u) {
                continue; // decoupled: the peer has gone on without us
            }
            let sch = scheme::of(l.b.kind);
            if !sch.sends_at_window_end(window) {
                continue;
            }
            let mut fields = Vec::new();
            let setup_only = sch.setup_sends(l.b.role);
            for f in self.outbox.fields_of(&l.b.interface) {
                // Set-up data (a kinematic responder's mass and stiffness) goes once, at
                // set-up, unless the binding asks for it every window.
                if window > 0
                    && setup_only.contains(&f.name.as_str())
                    && !l.b.sends.contains(&f.name)
                {
                    continue;
                }
                fields.push(
                    sch.send(l.b.role, l.map.as_ref(), f, &mut self.scratch)
                        .map_err(|reason| EngineError::Coupling {
                            coupling: l.b.coupling.clone(),
                            reason,
                        })?,
                );
            }
            let f = Fields {
                coupling: l.b.coupling.clone(),
                window,
                time,
                fields,
            };
            // The divergence rule: a non-finite value never leaves the node.
            crate::diverged::check_fields(&f)?;
            msgs.push(f);
        }
        Ok(msgs)
    }

    /// Set-up (window 0): returns the set-up fields to send.
    pub fn setup(&mut self) -> Result<Vec<Fields>, EngineError> {
        self.fill_inbox(0)?;
        let bindings: Vec<Binding> = self.links.iter().map(|l| l.b.clone()).collect();
        self.solver
            .setup(&bindings, &self.inbox, &mut self.outbox)?;
        for b in bindings
            .iter()
            .filter(|b| scheme::of(b.kind).coordinator_solved())
        {
            lagrange::setup(self.solver.as_mut(), b, &mut self.outbox)?;
        }
        self.drain_outbox(0, 0.0)
    }

    /// Advance one window; returns the report and the fields to send.
    pub fn advance(&mut self, w: &Window) -> Result<(StepReport, Vec<Fields>), EngineError> {
        self.fill_inbox(w.index)?;
        let report = match self.solver.advance(w, &self.inbox, &mut self.outbox) {
            // The solver saw its state become unphysical itself: the run diverged, as when a
            // non-finite value was about to leave.
            Err(SolverError::Diverged { time, reason }) => {
                return Err(crate::diverged::Divergence {
                    window: w.index,
                    what: format!("{reason} (t = {time:e} s)"),
                }
                .into());
            }
            r => r?,
        };
        crate::diverged::check_report(w.index, &report)?;
        let msgs = self.drain_outbox(w.index, w.t1)?;
        Ok((report, msgs))
    }

    /// The solver's state for a checkpoint: its `save_state`, and with a lagrange coupling
    /// the side's coupling state beside it.
    pub fn save_state(&mut self) -> SolverResult<Vec<u8>> {
        match self.lagrange_link() {
            None => self.solver.save_state(),
            Some(i) => lagrange::save_state(self.solver.as_mut(), &self.links[i].b),
        }
    }

    /// The inverse of [`Self::save_state`], after set-up.
    pub fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        match self.lagrange_link() {
            None => self.solver.load_state(bytes),
            Some(i) => lagrange::load_state(self.solver.as_mut(), &self.links[i].b, bytes),
        }
    }

    /// The lagrange coupling of this node (one at most): its link index.
    fn lagrange_link(&self) -> Option<usize> {
        self.links
            .iter()
            .position(|l| scheme::of(l.b.kind).coordinator_solved())
    }

    /// Coupling steps per window of this node's lagrange side (None: no lagrange coupling).
    pub fn lagrange_steps(&mut self) -> Option<usize> {
        let i = self.lagrange_link()?;
        lagrange::steps(self.solver.as_mut(), &self.links[i].b)
    }

    /// Applies the multipliers of `window` sent to node `me` once they are here (window 0:
    /// the initial ones, else the end of the side's current coupling step); false while
    /// they have not arrived.
    pub fn lagrange_correct(&mut self, me: &str, window: u64) -> Result<bool, EngineError> {
        let Some(i) = self.lagrange_link() else {
            return Ok(false);
        };
        let Some(lambda) = lagrange::take(&mut self.links[i].pending, me, window) else {
            return Ok(false);
        };
        lagrange::correct(self.solver.as_mut(), &self.links[i].b, window, &lambda)?;
        Ok(true)
    }

    /// The free coupling step `c` of `window` on the lagrange side: the message with its
    /// interface velocities at the step's start and end, sent at time `time`.
    pub fn lagrange_free_step(
        &mut self,
        c: usize,
        window: u64,
        time: f64,
    ) -> Result<Fields, EngineError> {
        let Some(i) = self.lagrange_link() else {
            return Err(EngineError::coupling("", "no lagrange coupling"));
        };
        lagrange::free_step(self.solver.as_mut(), &self.links[i].b, c, window, time)
    }
}

/// Command line of every node binary.
#[derive(Debug, clap::Parser)]
#[command(
    about = "A cosim node: launched by `cosim run`, joining a run from another host, or describing itself (--describe)"
)]
pub struct NodeArgs {
    /// Run id to join (printed by `cosim run` for remote nodes).
    #[arg(
        long,
        alias = "join",
        required_unless_present_any = ["describe", "schema"],
        default_value = "",
        hide_default_value = true
    )]
    pub run: String,
    /// This node's name in the case file (with --describe: only names it in messages).
    #[arg(
        long,
        required_unless_present_any = ["describe", "schema"],
        default_value = "",
        hide_default_value = true
    )]
    pub node: String,
    /// Describe the node instead of running it: read its params, print its description (or
    /// the bad parameter's key and why) as JSON on stdout; exit 0, or 2 for a bad parameter.
    /// Opens no device and no transport.
    #[arg(long, requires = "model")]
    pub describe: bool,
    /// Print the JSON Schema of a model's parameters (with --model), or the models this
    /// node offers (without), instead of running (what `cosim params` reads).
    #[arg(long, conflicts_with = "describe")]
    pub schema: bool,
    /// The model to describe (with --describe or --schema).
    #[arg(long)]
    pub model: Option<String>,
    /// Params file (TOML) to describe with; `-` or none: standard input.
    #[arg(long, requires = "describe")]
    pub params: Option<PathBuf>,
    /// shm | zenoh
    #[arg(long, default_value = "shm")]
    pub transport: String,
    /// zenoh endpoint of the coordinator, e.g. tcp/10.0.0.1:7447.
    #[arg(long)]
    pub connect: Option<String>,
    /// Token printed by `cosim run` for remote nodes.
    #[arg(long, default_value = "")]
    pub token: String,
    /// A node joining from another host: the run directory on this host, where it writes its
    /// output (`DIR/<node>`) and its checkpoints (`DIR/checkpoints/...`), instead of the
    /// coordinator's path. Rejoin a restarted run with the same DIR: the node restores from it.
    #[arg(long)]
    pub output: Option<PathBuf>,
}

struct Wire {
    t: Box<dyn Transport>,
    up: Box<dyn Publisher>,
    data: Vec<(String, Box<dyn Publisher>)>,
    run: String,
    me: String,
    buf: Vec<u8>,
    seq: Arc<AtomicU64>,
    cmd_topic: usize,
    /// See [`node_main_withholding`]; None for every real node.
    withhold: Option<WithholdFields>,
}

/// Whether a node withholds a `Fields` it is about to send (true: it never goes out).
pub type WithholdFields = Box<dyn FnMut(&Fields) -> bool + Send>;

impl Wire {
    fn send_up(&mut self, m: &Message) -> anyhow::Result<()> {
        self.send_up_ringing(m, true)
    }

    /// [`Wire::send_up`], waking the coordinator only if `ring` ([`Publisher::send_quiet`]).
    fn send_up_ringing(&mut self, m: &Message, ring: bool) -> anyhow::Result<()> {
        let seq = self.seq.fetch_add(1, Ordering::Relaxed);
        encode_into(&mut self.buf, &self.run, &self.me, seq, m)?;
        if ring {
            self.up.send(&self.buf)?;
        } else {
            self.up.send_quiet(&self.buf)?;
        }
        Ok(())
    }

    /// Coupling data: encoded straight into the transport's buffer where it has one (a
    /// shared-memory sample), so a large field is copied once on this side.
    fn send_data(&mut self, coupling: &str, m: &Message) -> anyhow::Result<()> {
        if let (Some(withhold), Message::Fields(f)) = (self.withhold.as_mut(), m)
            && withhold(f)
        {
            tracing::warn!(
                "withholding the Fields of window {} on coupling '{coupling}'",
                f.window
            );
            return Ok(());
        }
        let seq = self.seq.fetch_add(1, Ordering::Relaxed);
        let p = self
            .data
            .iter_mut()
            .find(|(c, _)| c == coupling)
            .ok_or_else(|| anyhow::anyhow!("no publisher for coupling {coupling}"))?;
        p.1.send_message(&self.run, &self.me, seq, m, &mut self.buf)?;
        Ok(())
    }
}

/// What arrived: a command from the coordinator or data from a peer.
enum Incoming {
    Cmd(Message),
    Data(Message),
    /// A peer's `Fields`, already in the engine's input buffers.
    Taken,
    Bad(String),
}

/// Wait up to `timeout` for the next message, in slices of at most 100 ms so that a stop
/// raised by the watchdog (a stop signal, a dead coordinator) is seen promptly. With an
/// engine, a peer's `Fields` goes into it straight from the received bytes
/// ([`NodeEngine::receive_view`]) and comes back as [`Incoming::Taken`].
fn recv_one(
    w: &mut Wire,
    mut engine: Option<&mut NodeEngine>,
    timeout: Duration,
) -> anyhow::Result<Option<Incoming>> {
    let deadline = Instant::now() + timeout;
    let cmd = w.cmd_topic;
    loop {
        if let Some(s) = watchdog::stop() {
            anyhow::bail!("{}", s.reason());
        }
        let slice = deadline
            .saturating_duration_since(Instant::now())
            .min(Duration::from_millis(100));
        let mut got = None;
        let mut refused = None;
        w.t.recv(slice, &mut |topic, bytes| {
            if topic != cmd
                && let Some(e) = engine.as_deref_mut()
                && codec::header(bytes).is_ok_and(|h| h.kind == codec::FIELDS_KIND)
            {
                got = Some(match codec::decode_fields_view(bytes) {
                    Ok(v) => {
                        refused = e.receive_view(&v).err();
                        Incoming::Taken
                    }
                    Err(e) => Incoming::Bad(e.to_string()),
                });
                return;
            }
            got = Some(match codec::decode(bytes) {
                Ok(env) if topic == cmd => Incoming::Cmd(env.message),
                Ok(env) => Incoming::Data(env.message),
                Err(e) => Incoming::Bad(e.to_string()),
            });
        })?;
        if let Some(e) = refused {
            return Err(e.into());
        }
        if got.is_some() || Instant::now() >= deadline {
            return Ok(got);
        }
    }
}

/// Entry point of every node binary; returns the process exit code
/// (0 finished, 1 failed or its coordinator gone, 2 bad invocation or, with `--describe`, a
/// bad parameter, 3 aborted by the coordinator, 128 + N stopped by signal N).
pub fn node_main(binary: &str, factory: SolverFactory) -> i32 {
    node_main_with(binary, std::env::args_os(), Box::new(factory))
}

/// [`node_main`] for a node that breaks the protocol on purpose, to test what the coordinator
/// makes of it: every `Fields` for which `withhold` says true is dropped instead of sent, as
/// if it were lost (the node goes on as if it had sent it). Only test nodes use this.
pub fn node_main_withholding(
    binary: &str,
    factory: SolverFactory,
    withhold: WithholdFields,
) -> i32 {
    node_main_inner(
        binary,
        std::env::args_os(),
        Box::new(factory),
        Some(withhold),
    )
}

/// [`node_main`] for a node that is not a Rust binary of its own: the command line comes as
/// `args` (program name first, like `argv`), the solver from a boxed factory.
pub fn node_main_with(
    binary: &str,
    args: impl IntoIterator<Item = impl Into<OsString> + Clone>,
    factory: BoxedFactory,
) -> i32 {
    node_main_inner(binary, args, factory, None)
}

fn node_main_inner(
    binary: &str,
    args: impl IntoIterator<Item = impl Into<OsString> + Clone>,
    factory: BoxedFactory,
    withhold: Option<WithholdFields>,
) -> i32 {
    use clap::Parser;
    let args = match NodeArgs::try_parse_from(args) {
        Ok(a) => a,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return code;
        }
    };
    if args.schema {
        return crate::params::schema_main(binary, args.model.as_deref());
    }
    init_logging();
    if args.describe {
        let model = args.model.as_deref().unwrap_or_default();
        let node = (!args.node.is_empty()).then_some(args.node.as_str());
        return crate::describe::describe_main(
            binary,
            factory,
            model,
            args.params.as_deref(),
            node,
        );
    }
    tune_allocator();
    // Launched by cosim: die with it. Started by hand: watch it through the transport.
    let parent = match watchdog::arm_parent_death() {
        Ok(p) => p,
        Err(e) => {
            crate::log_line!("{binary} {}: {e}", args.node);
            return 1;
        }
    };
    // SIGTERM (and, when started by hand, Ctrl-C) stops the node cleanly; under cosim,
    // Ctrl-C is the coordinator's to act on (the terminal sends it to both).
    let signals = if parent.is_some() {
        if let Err(e) = stop::ignore(libc::SIGINT) {
            tracing::warn!("cannot ignore SIGINT: {e}");
        }
        &[libc::SIGTERM][..]
    } else {
        &[libc::SIGINT, libc::SIGTERM][..]
    };
    if let Err(e) = stop::install(signals) {
        tracing::warn!("cannot handle stop signals: {e}");
    }
    let code = match run_node(binary, factory, &args, parent, withhold) {
        Ok(code) => code,
        Err(e) => {
            crate::log_line!("{binary} {}: {e:#}", args.node);
            watchdog::stop().map_or(1, |s| s.exit_code())
        }
    };
    // The transport is closed: if this may be the run's last process (its coordinator died,
    // or it was started by hand), sweep what the run left in shared memory. A coordinator that
    // still runs sweeps once all its nodes have exited; the sweep here would only wait its
    // second for the coordinator to be listed gone, and leave the files to it anyway.
    if !watchdog::parent_alive(parent)
        && let Ok(kind) = args.transport.parse::<TransportKind>()
    {
        transport::cleanup(kind, &args.run);
    }
    watchdog::finished();
    code
}

/// Keep freed message buffers in the heap: coupling messages of the same size come every
/// window, and glibc would otherwise return each large buffer to the kernel and take page
/// faults on fresh pages at the next one (measured: a third of an 8 MiB round trip).
pub fn tune_allocator() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes allocator thresholds; called before any thread starts.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 256 << 20);
    }
}

/// Logs to stderr (the coordinator keeps each node's stderr in `<out>/<node>.log`), filtered by
/// `COSIM_LOG`, else `RUST_LOG` (tracing's `EnvFilter` syntax), else `info`.
pub fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_env("COSIM_LOG")
        .or_else(|_| tracing_subscriber::EnvFilter::try_from_default_env())
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=warn,iceoryx2=warn"));
    use std::io::IsTerminal;
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .try_init();
}

fn run_node(
    binary: &str,
    factory: BoxedFactory,
    args: &NodeArgs,
    parent: Option<u32>,
    withhold: Option<WithholdFields>,
) -> anyhow::Result<i32> {
    let kind: TransportKind = args
        .transport
        .parse()
        .map_err(|e: String| anyhow::anyhow!(e))?;
    let spec = TransportSpec {
        kind,
        run: args.run.clone(),
        endpoint: args.node.clone(),
        listen: vec![],
        connect: args.connect.iter().cloned().collect(),
    };
    let mut t = transport::open(&spec)?;
    t.declare_alive()?;
    let peer = if parent.is_none() {
        t.watch("coordinator")?
    } else {
        None
    };
    watchdog::start(parent, peer);
    let cmd_topic = t.subscribe(&topic::down(&args.run, &args.node))?;
    let up_topic = topic::up(&args.run, &args.node);
    let coordinator = vec!["coordinator".to_string()];
    let up = t.publisher(&up_topic, &coordinator)?;
    // The coordinator subscribes before it launches us; wait for it where the transport
    // can tell (shared memory drops messages sent before a reader connects).
    let start = Instant::now();
    while t.readers(&up_topic) == Some(0) {
        if start.elapsed() > Duration::from_secs(30) {
            anyhow::bail!("no coordinator is listening on {up_topic}");
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    let mut w = Wire {
        t,
        up,
        data: Vec::new(),
        run: args.run.clone(),
        me: args.node.clone(),
        buf: Vec::new(),
        seq: Arc::new(AtomicU64::new(0)),
        cmd_topic,
        withhold,
    };
    w.send_up(&Message::Hello(Hello {
        protocol_version: codec::PROTOCOL_VERSION,
        node: args.node.clone(),
        model: String::new(),
        pid: std::process::id(),
        capabilities: vec![binary.to_string()],
        token: args.token.clone(),
    }))?;
    // Welcome: as long as the coordinator lives (it may wait minutes for remote nodes to
    // join); the watchdog ends the wait if it dies.
    let mut welcome = loop {
        match recv_one(&mut w, None, Duration::from_secs(60))? {
            Some(Incoming::Cmd(Message::Welcome(wl))) => break wl,
            Some(Incoming::Cmd(Message::Reject(r))) => {
                crate::log_line!("{binary} {}: rejected: {}", args.node, r.reason);
                return Ok(2);
            }
            Some(Incoming::Cmd(Message::Abort(a))) => {
                tracing::info!("aborted before start: {}", a.reason);
                return Ok(3);
            }
            Some(_) | None => continue,
        }
    };
    if let Some(dir) = &args.output {
        welcome.output_dir = dir.join(&args.node).display().to_string();
    }
    let fail = |w: &mut Wire, reason: String| -> anyhow::Result<i32> {
        tracing::error!("{reason}");
        match watchdog::stop() {
            // Nobody to tell.
            Some(s @ watchdog::Stop::CoordinatorGone(_)) => Ok(s.exit_code()),
            s => {
                w.send_up(&Message::Failed(Failed { reason }))?;
                Ok(s.map_or(1, |s| s.exit_code()))
            }
        }
    };
    // Heartbeats from a thread, from now on: building the solver (a GPU node compiles its
    // shaders) or a long window must not look like a hang.
    let alive = Arc::new(AtomicBool::new(true));
    let progress = Arc::new(Progress::default());
    let hb = {
        let mut p = w.t.publisher(&up_topic, &coordinator)?;
        let alive = alive.clone();
        let progress = progress.clone();
        let (run, me, seq) = (w.run.clone(), w.me.clone(), w.seq.clone());
        let period = Duration::from_millis(welcome.heartbeat_ms.max(10));
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            let mut last = Instant::now();
            while alive.load(Ordering::Relaxed) {
                // Asleep until the next beat is due (woken early when the node leaves), not
                // polling: a wake-up costs the node's cores a context switch.
                let due = period.saturating_sub(last.elapsed());
                if !due.is_zero() {
                    std::thread::park_timeout(due);
                    continue;
                }
                last = Instant::now();
                if watchdog::stop().is_some() {
                    continue; // leaving: the coordinator may be gone
                }
                let s = seq.fetch_add(1, Ordering::Relaxed);
                let m = Message::Heartbeat(Heartbeat {
                    window: progress.window.load(Ordering::Relaxed),
                    substeps: progress.substeps.load(Ordering::Relaxed),
                    waiting: progress.waiting.load(Ordering::Relaxed),
                });
                if encode_into(&mut buf, &run, &me, s, &m).is_ok() {
                    let _ = p.send(&buf);
                }
            }
        })
    };
    // A panic in the solver (or in the runtime under it) is a failure like any other: the
    // coordinator gets its message and place instead of a bare exit status.
    record_panics();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        build_and_run(&mut w, factory, &welcome, args, &progress)
    }))
    .unwrap_or_else(|_| Err(last_panic()));
    alive.store(false, Ordering::Relaxed);
    hb.thread().unpark();
    let _ = hb.join();
    match result {
        Ok(Ok(code)) => Ok(code),
        Ok(Err(reason)) | Err(reason) => fail(&mut w, reason),
    }
}

/// The message and place of the last panic in this process, as [`record_panics`] kept it.
static LAST_PANIC: std::sync::Mutex<Option<String>> = std::sync::Mutex::new(None);

/// Keep each panic's message and place for the failure report (the default hook still
/// prints it to stderr, i.e. to the node's log).
fn record_panics() {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info.payload_as_str().unwrap_or("(no message)");
        let place = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        let thread = std::thread::current()
            .name()
            .map(|n| format!(" (thread '{n}')"))
            .unwrap_or_default();
        if let Ok(mut last) = LAST_PANIC.lock() {
            *last = Some(format!("panicked{thread}: {message}{place}"));
        }
        previous(info);
    }));
}

/// The failure reason of a caught panic.
fn last_panic() -> String {
    LAST_PANIC
        .lock()
        .ok()
        .and_then(|mut l| l.take())
        .unwrap_or_else(|| "panicked (no message)".into())
}

/// Build the solver from the Welcome, wire its couplings and run the window loop. `Ok(Err)`
/// is a refused set-up (a bad parameter), `Err` a failure while running: both are reported
/// to the coordinator by the caller.
fn build_and_run(
    w: &mut Wire,
    factory: BoxedFactory,
    welcome: &Welcome,
    args: &NodeArgs,
    progress: &Progress,
) -> Result<Result<i32, String>, String> {
    let params: toml::Table = match toml::from_str(&welcome.params_toml) {
        Ok(p) => p,
        Err(e) => return Ok(Err(format!("params: {}", e.message()))),
    };
    let solver = match factory(&welcome.model, &params, &BuildOptions::RUN) {
        Ok(s) => s,
        Err(SolverError::Config { key, reason }) => {
            let key = crate::describe::node_key(&key);
            return Ok(Err(format!("nodes.{}.{key}: {reason}", args.node)));
        }
        Err(e) => return Ok(Err(e.to_string())),
    };
    let mut engine = NodeEngine::new(solver, &welcome.bindings);
    let wire = |w: &mut Wire| -> anyhow::Result<()> {
        for b in &welcome.bindings {
            w.t.subscribe(&topic::data(&welcome.run, &b.coupling, &b.peer))?;
            // Only the peer is woken by coupling data. The coordinator subscribes to record it
            // (or, on a lagrange coupling, is the peer), but it needs no wake-up of its own:
            // the window's `Done`, which always follows its `Fields`, wakes it, and it takes
            // everything queued then. One notification and one wake-up less per message.
            let p = w.t.publisher(
                &topic::data(&welcome.run, &b.coupling, &args.node),
                std::slice::from_ref(&b.peer),
            )?;
            w.data.push((b.coupling.clone(), p));
        }
        Ok(())
    };
    wire(w).map_err(|e| format!("{e:#}"))?;
    node_loop(w, &mut engine, welcome, &args.node, progress)
        .map(Ok)
        .map_err(|e| format!("{e:#}"))
}

/// A restore command: an `Advance` of zero length with `checkpoint` set, for a window after
/// set-up (PROTOCOL.md §7). No window to run is ever empty.
fn is_restore(a: &Advance) -> bool {
    a.window > 0 && a.checkpoint && a.t0 == a.t1
}

/// The run directory: the parent of the node's output directory (`<run>/<node>`).
fn run_dir(welcome: &Welcome) -> PathBuf {
    PathBuf::from(&welcome.output_dir)
        .parent()
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// Write the solver's state at the end of window `a.window` into its container; the `Done`
/// that follows acknowledges it.
fn save_checkpoint(
    engine: &mut NodeEngine,
    welcome: &Welcome,
    me: &str,
    a: &Advance,
    sent: Vec<Fields>,
) -> anyhow::Result<()> {
    let payload = engine
        .save_state()
        .map_err(|e| anyhow::anyhow!("checkpoint of window {}: {e}", a.window))?;
    let c = checkpoint::Checkpoint {
        node: me.to_string(),
        model: welcome.model.clone(),
        window: a.window,
        time: a.t1,
        params_hash: checkpoint::params_hash(&welcome.params_toml),
        sent,
        payload,
    };
    c.write(&checkpoint::file(&run_dir(welcome), a.window, me))?;
    Ok(())
}

/// Load this node's checkpoint of window `a.window` into the solver, after checking that it is
/// this node's, of this model and parameters, at this time; returns what to send again.
fn restore(
    engine: &mut NodeEngine,
    welcome: &Welcome,
    me: &str,
    a: &Advance,
) -> anyhow::Result<Vec<Fields>> {
    let path = checkpoint::file(&run_dir(welcome), a.window, me);
    let c = checkpoint::Checkpoint::read(&path)?;
    let p = path.display();
    if c.node != me || c.model != welcome.model {
        anyhow::bail!(
            "{p}: checkpoint of node '{}' ({}), this is '{me}' ({})",
            c.node,
            c.model,
            welcome.model
        );
    }
    if c.window != a.window || c.time.to_bits() != a.t1.to_bits() {
        anyhow::bail!(
            "{p}: checkpoint of window {} at t = {:e}, asked for window {} at t = {:e}",
            c.window,
            c.time,
            a.window,
            a.t1
        );
    }
    if c.params_hash != checkpoint::params_hash(&welcome.params_toml) {
        anyhow::bail!("{p}: written with other parameters than this node's");
    }
    engine
        .load_state(&c.payload)
        .map_err(|e| anyhow::anyhow!("{p}: {e}"))?;
    Ok(c.sent)
}

/// What the heartbeat thread reports of the main loop.
#[derive(Default)]
struct Progress {
    window: AtomicU64,
    substeps: AtomicU64,
    waiting: AtomicBool,
}

fn node_loop(
    w: &mut Wire,
    engine: &mut NodeEngine,
    welcome: &Welcome,
    me: &str,
    progress: &Progress,
) -> anyhow::Result<i32> {
    let desc = engine.solver.describe();
    let describe = Message::Describe(Describe {
        model: desc.model.clone(),
        interfaces: desc
            .interfaces
            .iter()
            .map(|i| InterfaceDescription {
                name: i.name.clone(),
                points: i.points as u64,
                provides: i.provides.clone(),
                accepts: i.accepts.clone(),
            })
            .collect(),
        stable_dt: engine.solver.stable_dt(),
        units: desc.units,
        warnings: engine.solver.warnings(),
    });
    w.send_up(&describe)?;
    // Set-up starts when the coordinator says so (window 0): by then every node has
    // subscribed to its inputs, so nothing we publish is lost.
    let mut pending_cmd: VecDeque<Message> = VecDeque::new();
    loop {
        match recv_one(w, Some(engine), Duration::from_secs(60))? {
            Some(Incoming::Cmd(Message::Advance(a))) if a.window == 0 => break,
            Some(Incoming::Cmd(Message::Abort(a))) => {
                tracing::info!("aborted: {}", a.reason);
                return Ok(3);
            }
            Some(Incoming::Cmd(Message::Finish(_))) => return Ok(0),
            Some(Incoming::Cmd(m)) => pending_cmd.push_back(m),
            Some(Incoming::Data(Message::Mesh(m))) => engine.peer_mesh(&m)?,
            Some(Incoming::Data(Message::Fields(f))) => engine.receive(f)?,
            Some(Incoming::Data(_)) | Some(Incoming::Taken) => {}
            Some(Incoming::Bad(e)) => anyhow::bail!("malformed message received: {e}"),
            None => anyhow::bail!("no set-up command from the coordinator within 60 s"),
        }
    }
    // Shared memory can tell when every reader is connected: wait for it.
    let start = Instant::now();
    for b in &welcome.bindings {
        let tp = topic::data(&welcome.run, &b.coupling, me);
        // A lagrange side's only reader is the coordinator.
        let want = if scheme::of(b.kind).coordinator_solved() {
            1
        } else {
            2
        };
        while w.t.readers(&tp).is_some_and(|n| n < want) {
            if start.elapsed() > Duration::from_secs(60) {
                anyhow::bail!("peer '{}' never subscribed to {tp}", b.peer);
            }
            if let Some(Incoming::Cmd(Message::Abort(a))) =
                recv_one(w, Some(engine), Duration::from_millis(2))?
            {
                tracing::info!("aborted: {}", a.reason);
                return Ok(3);
            }
        }
    }
    for m in engine.own_meshes()? {
        let c = m.coupling.clone();
        w.send_data(&c, &Message::Mesh(m))?;
    }
    let mut window: u64 = 0;
    let mut set_up = false;
    let mut wait_s = 0.0;
    let mut idle_s = 0.0;
    let mut substeps = 0u64;
    // End time of the last window and whether its output was written (a node finished early,
    // e.g. the fluid after a decoupling, writes its final state on `Finish`).
    let mut last_t1 = 0.0;
    let mut written = true;
    loop {
        // Act on what can be done now.
        if !set_up && engine.meshes_complete() && engine.ready(0) {
            let t0 = Instant::now();
            let msgs = engine.setup()?;
            for f in msgs {
                let c = f.coupling.clone();
                w.send_data(&c, &Message::Fields(f))?;
            }
            if engine.lagrange_steps().is_some()
                && let Some(code) = lagrange_wait(w, engine, me, 0, &mut pending_cmd, progress)?
            {
                return Ok(code);
            }
            set_up = true;
            let mut report = engine.solver.initial_report()?;
            crate::diverged::check_report(0, &report)?;
            report.wall_s = t0.elapsed().as_secs_f64();
            let describe_after = Message::Describe(Describe {
                model: engine.solver.describe().model,
                interfaces: vec![],
                stable_dt: engine.solver.stable_dt(),
                units: String::new(),
                warnings: engine.solver.warnings(),
            });
            w.send_up(&describe_after)?;
            w.send_up(&Message::Done(Done { window: 0, report }))?;
        }
        if set_up
            && let Some(Message::Advance(a)) = pending_cmd.front()
            && is_restore(a)
        {
            // Restart (PROTOCOL.md §7): the state at the end of window `a.window` comes from
            // its checkpoint; what the node sent then goes out again for peers that use it in
            // the next window.
            let a = *a;
            pending_cmd.pop_front();
            for f in restore(engine, welcome, me, &a)? {
                let c = f.coupling.clone();
                w.send_data(&c, &Message::Fields(f))?;
            }
            tracing::info!("restored the checkpoint of window {}", a.window);
            (window, last_t1, written) = (a.window, a.t1, true);
            progress.window.store(window, Ordering::Relaxed);
            w.send_up(&Message::Done(Done {
                window,
                report: StepReport::default(),
            }))?;
            continue;
        }
        if set_up && let Some(Message::Advance(a)) = pending_cmd.front() {
            let a = *a;
            if engine.ready(a.window) {
                pending_cmd.pop_front();
                if a.window == 1 {
                    // The series opens with the state after set-up (window 0, t0); a restart
                    // never runs window 1, so its series keeps the frame of the first run.
                    let dir = PathBuf::from(&welcome.output_dir);
                    engine.solver.write_output(a.t0, 0, &dir)?;
                }
                let started = Instant::now();
                let win = Window {
                    index: a.window,
                    t0: a.t0,
                    t1: a.t1,
                    write_output: a.write_output,
                };
                if let Some(steps) = engine.lagrange_steps() {
                    // seed 003 §4: each coupling step is a free step, the multipliers from
                    // the coordinator, and the correction.
                    for c in 0..steps {
                        let t = a.t0 + (a.t1 - a.t0) * (c + 1) as f64 / steps as f64;
                        let f = engine.lagrange_free_step(c, a.window, t)?;
                        let coupling = f.coupling.clone();
                        w.send_data(&coupling, &Message::Fields(f))?;
                        if let Some(code) =
                            lagrange_wait(w, engine, me, a.window, &mut pending_cmd, progress)?
                        {
                            return Ok(code);
                        }
                    }
                }
                let (mut report, msgs) = engine.advance(&win)?;
                let sent = a.checkpoint.then(|| msgs.clone());
                for f in msgs {
                    let c = f.coupling.clone();
                    w.send_data(&c, &Message::Fields(f))?;
                }
                if a.write_output {
                    let dir = PathBuf::from(&welcome.output_dir);
                    engine.solver.write_output(a.t1, a.window, &dir)?;
                }
                if let Some(sent) = sent {
                    save_checkpoint(engine, welcome, me, &a, sent)?;
                }
                written = a.write_output;
                last_t1 = a.t1;
                report.wall_s = started.elapsed().as_secs_f64();
                report.coupling_wait_s = wait_s;
                report.idle_s = idle_s;
                wait_s = 0.0;
                idle_s = 0.0;
                window = a.window;
                substeps += report.substeps;
                progress.window.store(window, Ordering::Relaxed);
                progress.substeps.store(substeps, Ordering::Relaxed);
                // The coordinator is woken by every second Done, and by any Done after which
                // this node holds fewer than two further windows: then the coordinator must
                // act soon (send the next windows, checkpoint, decouple). In between it reads
                // this Done with the next one: one wake-up of the coordinator less per window
                // (its data topics queue `SUBSCRIBER_BUFFER` windows, so it still reads them
                // in time).
                let held = pending_cmd
                    .iter()
                    .filter(|m| matches!(m, Message::Advance(_)))
                    .count();
                let ring = window.is_multiple_of(2) || held < 2;
                w.send_up_ringing(&Message::Done(Done { window, report }), ring)?;
                continue;
            }
        }
        // Otherwise wait for something to arrive: a peer's input when a window is in hand (or
        // set-up is pending), else the next command.
        let on_input = !set_up || matches!(pending_cmd.front(), Some(Message::Advance(_)));
        progress.waiting.store(on_input, Ordering::Relaxed);
        let waited = Instant::now();
        let got = recv_one(w, Some(engine), Duration::from_millis(500))?;
        progress.waiting.store(false, Ordering::Relaxed);
        if set_up {
            let dt = waited.elapsed().as_secs_f64();
            if on_input {
                wait_s += dt;
            } else {
                idle_s += dt;
            }
        }
        match got {
            None | Some(Incoming::Taken) => {}
            Some(Incoming::Bad(e)) => anyhow::bail!("malformed message received: {e}"),
            Some(Incoming::Cmd(Message::Advance(a))) => pending_cmd.push_back(Message::Advance(a)),
            Some(Incoming::Cmd(Message::Finish(f))) => {
                if !written && window > 0 {
                    let dir = PathBuf::from(&welcome.output_dir);
                    engine.solver.write_output(last_t1, window, &dir)?;
                }
                tracing::info!("finished after window {window}: {}", f.reason);
                return Ok(0);
            }
            Some(Incoming::Cmd(Message::Decouple(d))) => {
                tracing::info!(
                    "coupling {} ends before window {}: {}",
                    d.coupling,
                    d.window,
                    d.reason
                );
                engine.decouple(&d.coupling, d.window)?;
            }
            Some(Incoming::Cmd(Message::Abort(a))) => {
                tracing::info!("aborted by the coordinator: {}", a.reason);
                return Ok(3);
            }
            Some(Incoming::Cmd(other)) => {
                tracing::warn!("ignored command {}", other.type_name());
            }
            Some(Incoming::Data(Message::Mesh(m)))
                if engine.bindings().any(|b| b.coupling == m.coupling) =>
            {
                engine.peer_mesh(&m)?;
            }
            Some(Incoming::Data(Message::Fields(f))) => engine.receive(f)?,
            Some(Incoming::Data(other)) => {
                anyhow::bail!("unexpected {} on a data topic", other.type_name());
            }
        }
    }
}

/// Waits for the multipliers of `window` sent to node `me` and applies them; commands and
/// other data arriving meanwhile are kept for the main loop. `Some(code)`: aborted.
fn lagrange_wait(
    w: &mut Wire,
    engine: &mut NodeEngine,
    me: &str,
    window: u64,
    pending_cmd: &mut VecDeque<Message>,
    progress: &Progress,
) -> anyhow::Result<Option<i32>> {
    let start = Instant::now();
    while !engine.lagrange_correct(me, window)? {
        progress.waiting.store(true, Ordering::Relaxed);
        let got = recv_one(w, Some(engine), Duration::from_millis(500))?;
        progress.waiting.store(false, Ordering::Relaxed);
        match got {
            None if start.elapsed() > Duration::from_secs(3600) => {
                anyhow::bail!("no lagrange multipliers for window {window} within an hour")
            }
            None | Some(Incoming::Taken) => {}
            Some(Incoming::Bad(e)) => anyhow::bail!("malformed message received: {e}"),
            Some(Incoming::Cmd(Message::Abort(a))) => {
                tracing::info!("aborted by the coordinator: {}", a.reason);
                return Ok(Some(3));
            }
            // The run ended while this side waited (a diverged peer): no multipliers follow.
            Some(Incoming::Cmd(Message::Finish(f))) => {
                tracing::info!("finished while waiting for multipliers: {}", f.reason);
                return Ok(Some(0));
            }
            Some(Incoming::Cmd(m)) => pending_cmd.push_back(m),
            Some(Incoming::Data(Message::Fields(f))) => engine.receive(f)?,
            Some(Incoming::Data(Message::Mesh(m))) => engine.peer_mesh(&m)?,
            Some(Incoming::Data(other)) => {
                anyhow::bail!("unexpected {} on a data topic", other.type_name());
            }
        }
    }
    Ok(None)
}
