//! `cosim conformance -- NODE_COMMAND [ARGS…]`: one node executable, in any language, driven
//! through a whole short run against a peer that `cosim` plays itself, and held to the rules
//! of PROTOCOL.md one by one (its section 9 lists them). The node is launched, welcomed and
//! fed as `cosim replay` does it (`replay::Session`), with a scripted peer instead of a
//! recorded one: the peer's mesh is the node's own interface, its motion a small constant
//! velocity, its loads zero. Each rule ends PASS, FAIL (with the reason) or not reached
//! (an earlier failure ended the drive).

use crate::case::{self, CouplingConfig, NodeConfig};
use crate::contract::Contract;
use crate::launch::pick_run_id;
use crate::replay::{Gone, Session};
use protocol::scheme;
use protocol::*;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

mod lagrange;

/// What `cosim conformance` is asked to check.
#[derive(Debug, Clone)]
pub struct Options {
    /// The node's command: an executable (a path, or a name beside `cosim`) and its own
    /// arguments (e.g. `python3 bar.py`).
    pub command: Vec<String>,
    pub model: String,
    /// The node's parameter table (`[nodes.NAME.params]` of a case).
    pub params: toml::Table,
    /// The interface to couple (default: the first the node describes).
    pub interface: Option<String>,
    pub kind: CouplingKind,
    /// The node's role; `cosim` plays the other.
    pub role: Role,
    pub windows: u64,
    /// The window (s); default: the node's stable step, or 1 µs if it states none.
    pub window: Option<f64>,
    /// Where the node's log, output and checkpoint go.
    pub output: PathBuf,
}

/// How a rule ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    Pass,
    Fail,
    /// An earlier failure ended the drive before the rule could be checked.
    NotReached,
}

/// One rule of PROTOCOL.md and how the node fared.
#[derive(Debug, Clone)]
pub struct Verdict {
    /// The section of PROTOCOL.md that states it.
    pub section: &'static str,
    pub rule: &'static str,
    pub outcome: Outcome,
    pub reason: String,
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let tag = match self.outcome {
            Outcome::Pass => "PASS",
            Outcome::Fail => "FAIL",
            Outcome::NotReached => "----",
        };
        write!(
            f,
            "{tag}  {:<16} {}: {}",
            self.section, self.rule, self.reason
        )
    }
}

/// The rules, in the order a run meets them: (name, section).
const RULES: [(&str, &str); 13] = [
    ("describe", "§2 --describe"),
    ("hello", "§4.2 item 2"),
    ("welcome-describe", "§4.2 item 4"),
    ("mesh", "§4.2 item 6"),
    ("set-up", "§4.2 item 6"),
    ("fields-match-binding", "§5.3 Fields"),
    ("finite-values", "§4.4 Divergence"),
    ("books-match-fields", "§4.7 Booking"),
    ("windows-in-order", "§4.2 items 7-8"),
    ("heartbeat", "§4.4 Heartbeat"),
    ("checkpoint", "§4.5"),
    ("finish", "§4.2 item 9"),
    ("cleanup", "§3 Cleanup"),
];

/// The heartbeat period the node is given (ms), and the longest gap tolerated between two
/// beats: ten periods (a loaded machine delays a thread; a node that stops beating is found
/// by the heartbeat timeout of 3 s, as `cosim run` finds it).
const HEARTBEAT_MS: u64 = 100;
const LONGEST_GAP: Duration = Duration::from_millis(10 * HEARTBEAT_MS);
/// How long the peer idles after each window: heartbeats must go on while the node waits.
const IDLE: Duration = Duration::from_millis(250);
/// The peer's constant velocity along x (m/s): small, so any solid follows it.
const PEER_VELOCITY: [f64; 3] = [1e-3, 0.0, 0.0];

/// The verdicts being gathered.
struct Sheet(Vec<Verdict>);

impl Sheet {
    fn new(rules: &[(&'static str, &'static str)]) -> Sheet {
        Sheet(
            rules
                .iter()
                .map(|&(rule, section)| Verdict {
                    section,
                    rule,
                    outcome: Outcome::NotReached,
                    reason: "not reached".into(),
                })
                .collect(),
        )
    }

    fn set(&mut self, rule: &str, outcome: Outcome, reason: impl Into<String>) {
        if let Some(v) = self.0.iter_mut().find(|v| v.rule == rule) {
            // A rule broken once stays broken.
            if v.outcome != Outcome::Fail {
                v.outcome = outcome;
                v.reason = reason.into();
            }
        }
    }

    fn pass(&mut self, rule: &str, reason: impl Into<String>) {
        self.set(rule, Outcome::Pass, reason);
    }

    fn fail(&mut self, rule: &str, reason: impl Into<String>) {
        self.set(rule, Outcome::Fail, reason);
    }

    fn outcome(&self, rule: &str) -> Outcome {
        self.0
            .iter()
            .find(|v| v.rule == rule)
            .map_or(Outcome::NotReached, |v| v.outcome)
    }
}

/// Whether every rule passed.
pub fn all_pass(verdicts: &[Verdict]) -> bool {
    verdicts.iter().all(|v| v.outcome == Outcome::Pass)
}

/// Drive the node of `o` through a short run and check it; one verdict per rule of
/// [`RULES`] (of `lagrange::RULES` for a lagrange side). An error is `cosim`'s own trouble
/// (no transport), not the node's.
pub fn check(o: &Options) -> anyhow::Result<Vec<Verdict>> {
    if scheme::of(o.kind).coordinator_solved() {
        return lagrange::check(o);
    }
    check_with(o, &RULES, |coupling, iface, window| {
        // The booking rule over the node's own force (a responder's): node 0, the peer 1.
        let responder = match o.role {
            Role::Responder => "node",
            Role::Driver => "peer",
        };
        let books = crate::books::Books::new(
            &["node", "peer"],
            std::slice::from_ref(&coupling),
            window,
            &[Some((0, responder.to_string()))],
        );
        Drive {
            books: std::cell::RefCell::new(books),
            o,
            binding: binding_of(o, &coupling),
            contract: Contract::of(&coupling, o.role, true, Some(iface.points), &iface.provides),
            described: iface,
            window,
            checkpoint_at: o.windows.saturating_sub(1).max(1),
        }
    })
}

/// A drive of the node through one coupling kind's short run.
trait Driven {
    /// The node's one binding.
    fn binding(&self) -> &Binding;
    /// Handshake, set-up and windows, the rules judged on the way.
    fn run(&self, s: &mut Session, sheet: &mut Sheet) -> anyhow::Result<()>;
}

impl Driven for Drive<'_> {
    fn binding(&self) -> &Binding {
        &self.binding
    }
    fn run(&self, s: &mut Session, sheet: &mut Sheet) -> anyhow::Result<()> {
        Drive::run(self, s, sheet)
    }
}

/// Check the node of `o` against `rules`: its description ("describe"), then the drive that
/// `make` builds from the coupling it is checked in, its interface and the window, launched
/// on a fresh run, run, and ended ("finish", "cleanup").
fn check_with<D: Driven>(
    o: &Options,
    rules: &[(&'static str, &'static str)],
    make: impl FnOnce(CouplingConfig, InterfaceDescription, f64) -> D,
) -> anyhow::Result<Vec<Verdict>> {
    let mut sheet = Sheet::new(rules);
    let Some((program, args)) = o.command.split_first() else {
        anyhow::bail!("no node command given");
    };
    let exe = crate::launch::resolve_exe(program, Path::new(".")).unwrap_or_else(|| program.into());
    std::fs::create_dir_all(&o.output)?;
    let Some((d, iface)) = described(o, program, &exe, args, &mut sheet) else {
        return Ok(sheet.0);
    };
    let coupling = coupling_of(o, &iface.name);
    let window = o.window.or(d.stable_dt).unwrap_or(1e-6);
    let drive = make(coupling, iface, window);
    let run = pick_run_id("conformance");
    let mut s = Session::launch(
        &exe,
        args,
        &run,
        "node",
        std::slice::from_ref(drive.binding()),
        o.output.join("node.log"),
        (Duration::from_secs(3), Duration::from_secs(30)),
    )?;
    let went = drive.run(&mut s, &mut sheet);
    let ended = s.stop(went.is_ok());
    judge_ending(&mut sheet, went, ended, s.gone);
    let finished = sheet.outcome("finish") == Outcome::Pass;
    drop(s);
    judge_cleanup(&mut sheet, &run, finished);
    Ok(sheet.0)
}

/// The "describe" rule: the node's description with `o`'s parameters and the interface it
/// is checked on, which must carry the fields its role needs; None (the rule failed) if not.
fn described(
    o: &Options,
    program: &str,
    exe: &Path,
    args: &[String],
    sheet: &mut Sheet,
) -> Option<(describe::NodeDescriptionJson, InterfaceDescription)> {
    let node = NodeConfig {
        name: "node".into(),
        solver: program.to_string(),
        exe: Some(exe.to_path_buf()),
        model: o.model.clone(),
        params: o.params.clone(),
        remote: false,
        interfaces: None,
        fields: Vec::new(),
        points: Vec::new(),
        window_limits: Vec::new(),
        positions: Default::default(),
    };
    let timeout = crate::case::describe::DESCRIBE_TIMEOUT;
    let d = match crate::case::describe::describe_one(exe, args, &node, timeout) {
        Ok(d) => d,
        Err(e) => {
            sheet.fail("describe", format!("{}: {}", e.key, e.reason));
            return None;
        }
    };
    let chosen = |i: &&InterfaceDescription| o.interface.as_ref().is_none_or(|n| *n == i.name);
    let Some(iface) = d.interfaces.iter().find(chosen).cloned() else {
        let which = o.interface.as_deref().unwrap_or("at all");
        sheet.fail(
            "describe",
            format!("no interface {which} among those described"),
        );
        return None;
    };
    let lacking = lacking_fields(&coupling_of(o, &iface.name), &iface);
    if !lacking.is_empty() {
        sheet.fail(
            "describe",
            format!(
                "interface '{}' as the {} {}: {}",
                iface.name,
                o.kind.as_str(),
                role_name(o.role),
                lacking.join(", ")
            ),
        );
        return None;
    }
    let stable = d
        .stable_dt
        .map_or_else(|| "none".to_string(), |s| format!("{s:e} s"));
    sheet.pass(
        "describe",
        format!(
            "model '{}', interface '{}' of {} points, stable step {stable}",
            d.model, iface.name, iface.points
        ),
    );
    Some((d, iface))
}

/// What the node's interface lacks of the fields the coupling needs it to provide or accept.
fn lacking_fields(coupling: &CouplingConfig, iface: &InterfaceDescription) -> Vec<String> {
    case::required_fields(coupling)
        .iter()
        .filter(|n| n.member.0 == "node")
        .flat_map(|n| {
            let (have, verb) = if n.provide {
                (&iface.provides, "provide")
            } else {
                (&iface.accepts, "accept")
            };
            n.fields
                .iter()
                .filter(|f| !have.contains(f))
                .map(move |f| format!("does not {verb} '{f}'"))
        })
        .collect()
}

/// The "finish" rule (or the rule the run broke off in): how the drive `went` and how the
/// node `ended` once asked to finish, and whether it went silent or exited first (`gone`).
fn judge_ending(
    sheet: &mut Sheet,
    went: anyhow::Result<()>,
    ended: Option<String>,
    gone: Option<Gone>,
) {
    match (went, ended) {
        (Ok(()), Some(how)) if how == "exited with status 0" => {
            sheet.pass("finish", "Finish answered by exit status 0");
        }
        (Ok(()), how) => sheet.fail(
            "finish",
            format!(
                "after Finish the node {}",
                how.as_deref().unwrap_or("was gone")
            ),
        ),
        (Err(e), _) => {
            let e = format!("{e:#}");
            match gone {
                Some(Gone::Silent) => sheet.fail("heartbeat", e),
                Some(Gone::Exited) => sheet.fail("finish", format!("ended before Finish: {e}")),
                None => {
                    let at = sheet
                        .0
                        .iter()
                        .map(|v| v.rule)
                        .find(|r| sheet.outcome(r) == Outcome::NotReached)
                        .unwrap_or("finish");
                    sheet.fail(at, e);
                }
            }
        }
    }
}

/// The "cleanup" rule, for a node that finished: nothing of run `run` left in shared memory.
/// Only what the node left is left: cosim's own ports went with the session. iceoryx2's
/// management file of the run's configuration is no process's: the sweep after every run
/// removes it.
fn judge_cleanup(sheet: &mut Sheet, run: &str, finished: bool) {
    let left: Vec<PathBuf> = protocol::transport::shm::shm_files(run)
        .into_iter()
        .filter(|p| !p.to_string_lossy().ends_with(".global_mgmt"))
        .collect();
    protocol::transport::cleanup(protocol::transport::TransportKind::Shm, run);
    if !finished {
        return;
    }
    if left.is_empty() {
        sheet.pass("cleanup", "nothing of the run left in /dev/shm");
    } else {
        let names: Vec<String> = left.iter().map(|p| p.display().to_string()).collect();
        sheet.fail(
            "cleanup",
            format!("left after its exit: {}", names.join(", ")),
        );
    }
}

/// The coupling the node is checked in: its interface on the side of its role, `cosim`'s
/// peer (named `peer`, on an interface of the same name) on the other, the scheme's fields.
fn coupling_of(o: &Options, iface: &str) -> CouplingConfig {
    let me = ("node".to_string(), iface.to_string());
    let peer = ("peer".to_string(), iface.to_string());
    let (driver, responder) = match o.role {
        Role::Driver => (me, peer),
        Role::Responder => (peer, me),
    };
    let (driver_fields, responder_fields) = case::default_fields(o.kind);
    // A coupling the coordinator solves has sides: the node and cosim's rigid side.
    let (sides, method) = if scheme::of(o.kind).coordinator_solved() {
        let rigid = (lagrange::SIDE.to_string(), iface.to_string());
        (
            vec![driver.clone(), rigid],
            Some(scheme::lagrange::Method::Gs4),
        )
    } else {
        (Vec::new(), None)
    };
    CouplingConfig {
        name: "conformance".into(),
        kind: o.kind,
        driver,
        responder,
        driver_fields,
        responder_fields,
        decouple: Default::default(),
        sides,
        method,
        point_tolerance: case::DEFAULT_POINT_TOLERANCE,
    }
}

/// The node's binding in `c`, as `cosim run` would give it (serial schedule).
fn binding_of(o: &Options, c: &CouplingConfig) -> Binding {
    let (me, peer, sends, receives) = match o.role {
        Role::Driver => (
            &c.driver,
            &c.responder,
            &c.driver_fields,
            &c.responder_fields,
        ),
        Role::Responder => (
            &c.responder,
            &c.driver,
            &c.responder_fields,
            &c.driver_fields,
        ),
    };
    // A side of a coupling the coordinator solves exchanges with the coordinator.
    let (peer, peer_interface) = if scheme::of(c.kind).coordinator_solved() {
        (scheme::lagrange::wire::PEER.to_string(), String::new())
    } else {
        (peer.0.clone(), peer.1.clone())
    };
    Binding {
        coupling: c.name.clone(),
        kind: c.kind,
        interface: me.1.clone(),
        role: o.role,
        peer,
        peer_interface,
        sends: sends.clone(),
        receives: receives.clone(),
        input_lag: scheme::of(c.kind).input_lag(o.role, true),
    }
}

fn role_name(r: Role) -> &'static str {
    match r {
        Role::Driver => "driver",
        Role::Responder => "responder",
    }
}

/// One drive of the node through handshake, set-up, windows, a checkpoint and `Finish`.
struct Drive<'a> {
    o: &'a Options,
    binding: Binding,
    contract: Contract,
    /// The interface as `--describe` gave it.
    described: InterfaceDescription,
    window: f64,
    checkpoint_at: u64,
    /// The booking rule's check: the node's `force` against its booked interface impulse.
    books: std::cell::RefCell<crate::books::Books>,
}

impl Drive<'_> {
    fn run(&self, s: &mut Session, sheet: &mut Sheet) -> anyhow::Result<()> {
        let mut sent = vec![false; self.o.windows as usize + 1];
        let mesh = self.set_up(s, sheet, &mut sent)?;
        self.windows(s, sheet, &mesh, &mut sent)?;
        judge_order(s, sheet, &sent, self.o.windows);
        judge_heartbeat(s, sheet);
        self.judge_unbroken(sheet);
        Ok(())
    }

    /// Hello, Welcome and set-up up to the node's `Done` of window 0, with the "hello",
    /// "describe" (its second description), "mesh" and "set-up" rules; returns the node's
    /// interface mesh, which the peer mirrors.
    fn set_up(
        &self,
        s: &mut Session,
        sheet: &mut Sheet,
        sent: &mut [bool],
    ) -> anyhow::Result<InterfaceMesh> {
        greet(s, sheet, self.o, &self.binding, &self.described)?;
        s.set_up()?;
        let mesh = take_mesh(s, sheet, &self.binding, self.described.points)?;
        let b = &self.binding;
        s.send_peer(
            0,
            &b.peer,
            &Message::Mesh(Mesh {
                coupling: b.coupling.clone(),
                interface: b.peer_interface.clone(),
                mesh: mesh.clone(),
            }),
        )?;
        let sch = scheme::of(b.kind);
        let reads_setup = [0, 1]
            .iter()
            .any(|&w| sch.input_window(b.role, b.input_lag, None, w) == Some(0));
        if reads_setup {
            let f = self.peer_fields(&mesh, 0, 0.0);
            s.send_peer(0, &b.peer, &Message::Fields(f))?;
        }
        s.wait("Done of the set-up", Some(Duration::from_secs(60)), |s| {
            s.done.as_ref().is_some_and(|d| d.0 == 0)
        })?;
        let zero = [0.0; 3];
        let booked0 = s.done.as_ref().map_or(zero, |d| d.1.interface_impulse);
        self.books.borrow_mut().begin(1, [booked0, zero].iter());
        self.idle(s, sheet, sent)?;
        judge_set_up(s, sheet, sent);
        Ok(mesh)
    }

    /// Windows 1 to `o.windows`: Advance, the peer's constant-velocity `Fields`, the node's
    /// `Done`, a checkpoint asked in one, and the booking rule judged on each.
    fn windows(
        &self,
        s: &mut Session,
        sheet: &mut Sheet,
        mesh: &InterfaceMesh,
        sent: &mut [bool],
    ) -> anyhow::Result<()> {
        let (o, b) = (self.o, &self.binding);
        // The impulse scale the booking rule judges against: the node's own interface impulse
        // (the peer applies no load; the node's own loads may dwarf what a 1 mm/s push gives).
        let mut scale = 0.0f64;
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        for k in 1..=o.windows {
            let t1 = advance(s, k, self.window, k == self.checkpoint_at)?;
            let f = self.peer_fields(mesh, k, t1);
            s.send_peer(0, &b.peer, &Message::Fields(f))?;
            await_done(s, sheet, &self.o.output, k, t1, k == self.checkpoint_at)?;
            self.idle(s, sheet, sent)?;
            if let Some((_, r)) = &s.done {
                scale = scale.max(norm(r.interface_impulse));
                let booked = [r.interface_impulse];
                let broken = self
                    .books
                    .borrow_mut()
                    .check(k, |i| booked.get(i), scale, |_| false);
                if let Some((_, why)) = broken {
                    sheet.fail("books-match-fields", why);
                }
            }
        }
        Ok(())
    }

    /// The rules nothing broke pass: fields as bound, finite values, the booking rule.
    fn judge_unbroken(&self, sheet: &mut Sheet) {
        if sheet.outcome("fields-match-binding") == Outcome::NotReached {
            sheet.pass(
                "fields-match-binding",
                format!(
                    "every Fields holds what its binding says ({} points)",
                    self.described.points
                ),
            );
        }
        if sheet.outcome("finite-values") == Outcome::NotReached {
            sheet.pass("finite-values", "every value sent is finite");
        }
        if sheet.outcome("books-match-fields") == Outcome::NotReached {
            let judged = self.books.borrow().judged(0);
            sheet.pass(
                "books-match-fields",
                if judged > 0 {
                    format!(
                        "over {judged} window(s) its booked interface impulse and the force it sent agree in sign"
                    )
                } else {
                    "nothing to judge: no interface impulse above round-off (the peer applies no load)".to_string()
                },
            );
        }
    }

    /// Let the node idle a moment (its heartbeats go on), then check the `Fields` that came
    /// meanwhile; `sent[k]` marks the windows whose `Fields` arrived.
    fn idle(&self, s: &mut Session, sheet: &mut Sheet, sent: &mut [bool]) -> anyhow::Result<()> {
        let until = Instant::now() + IDLE;
        while Instant::now() < until {
            s.pump(Duration::from_millis(10))?;
        }
        for f in std::mem::take(&mut s.arrived) {
            if let Some(x) = sent.get_mut(f.window as usize) {
                *x = true;
            }
            self.check_fields(&f, sheet);
            if self.binding.role == Role::Responder {
                let force = crate::books::force_of(&f.fields);
                self.books.borrow_mut().force(0, f.window, force);
            }
        }
        Ok(())
    }

    fn check_fields(&self, f: &Fields, sheet: &mut Sheet) {
        let mut check = self.contract.check();
        for x in &f.fields {
            check.field(&x.name, x.components, x.values.len());
        }
        if let Err(e) = check.finish(f.window) {
            sheet.fail("fields-match-binding", e);
        }
        if let Err(e) = protocol::diverged::check_fields(f) {
            sheet.fail("finite-values", e.to_string());
        }
    }

    /// What `cosim`'s peer sends for window `k` (0: set-up, with its set-up fields): per
    /// point of the node's mesh, the peer's motion (its position moving at
    /// [`PEER_VELOCITY`] from the mesh, that velocity), zero loads, zero mass and stiffness,
    /// and any other field as zeros.
    fn peer_fields(&self, mesh: &InterfaceMesh, k: u64, t: f64) -> Fields {
        let b = &self.binding;
        let sch = scheme::of(b.kind);
        let peer = match b.role {
            Role::Driver => Role::Responder,
            Role::Responder => Role::Driver,
        };
        let mut names: Vec<&str> = b.receives.iter().map(String::as_str).collect();
        if k == 0 {
            names.extend(sch.setup_sends(peer));
        }
        let fields = names
            .into_iter()
            .map(|name| {
                let c = scheme::components_of(name).unwrap_or(1);
                let values = match name {
                    "position" => mesh
                        .positions
                        .iter()
                        .flat_map(|p| (0..3).map(move |d| p[d] + PEER_VELOCITY[d] * t))
                        .collect(),
                    "velocity" => mesh.positions.iter().flat_map(|_| PEER_VELOCITY).collect(),
                    _ => vec![0.0; mesh.len() * c as usize],
                };
                Field {
                    name: name.to_string(),
                    components: c,
                    values,
                }
            })
            .collect();
        Fields {
            coupling: b.coupling.clone(),
            window: k,
            time: t,
            fields,
        }
    }
}

/// The handshake: the node's `Hello` ("hello"), `Welcome` with `binding`, its `Describe`
/// ("welcome-describe", against `described`).
fn greet(
    s: &mut Session,
    sheet: &mut Sheet,
    o: &Options,
    binding: &Binding,
    described: &InterfaceDescription,
) -> anyhow::Result<()> {
    let started = Instant::now();
    s.wait("Hello", Some(Duration::from_secs(60)), |s| s.hello)?;
    sheet.pass(
        "hello",
        format!(
            "Hello after {:.2} s, protocol {}",
            started.elapsed().as_secs_f64(),
            codec::PROTOCOL_VERSION
        ),
    );
    s.welcome(&Welcome {
        run: s.run.clone(),
        model: o.model.clone(),
        params_toml: toml::to_string(&o.params)?,
        bindings: vec![binding.clone()],
        output_dir: o.output.join("node").display().to_string(),
        heartbeat_ms: HEARTBEAT_MS,
    })?;
    check_describe(described, &s.describes[0], sheet);
    Ok(())
}

/// The node's `Mesh` after `Advance{0}` (waiting for it), judged by the "mesh" rule: of
/// `binding`'s coupling and interface, with the `points` described.
fn take_mesh(
    s: &mut Session,
    sheet: &mut Sheet,
    b: &Binding,
    points: u64,
) -> anyhow::Result<InterfaceMesh> {
    s.wait("Mesh", Some(Duration::from_secs(60)), |s| {
        !s.meshes.is_empty()
    })?;
    let m = &s.meshes[0];
    let n = m.mesh.len() as u64;
    if m.coupling == b.coupling && m.interface == b.interface && n == points {
        sheet.pass("mesh", format!("interface '{}', {n} points", m.interface));
    } else {
        sheet.fail(
            "mesh",
            format!(
                "Mesh of coupling '{}', interface '{}', {n} points; expected '{}', '{}', {points} points",
                m.coupling, m.interface, b.coupling, b.interface
            ),
        );
    }
    Ok(m.mesh.clone())
}

/// Wait for the node's `Done` of window `k` (ending at `t1`), then judge the "checkpoint"
/// rule on the window that asked for one.
fn await_done(
    s: &mut Session,
    sheet: &mut Sheet,
    output: &Path,
    k: u64,
    t1: f64,
    checkpoint: bool,
) -> anyhow::Result<()> {
    s.wait(
        &format!("Done of window {k}"),
        Some(Duration::from_secs(60)),
        |s| s.done.as_ref().is_some_and(|d| d.0 == k),
    )?;
    if checkpoint {
        check_checkpoint(output, k, t1, sheet);
    }
    Ok(())
}

/// Send `Advance` of window `k` (windows of `window` s from t = 0), a checkpoint asked or
/// not; returns the window's end time.
fn advance(s: &mut Session, k: u64, window: f64, checkpoint: bool) -> anyhow::Result<f64> {
    let (t0, t1) = ((k - 1) as f64 * window, k as f64 * window);
    s.window = k;
    s.send_down(&Message::Advance(Advance {
        window: k,
        t0,
        t1,
        write_output: false,
        checkpoint,
    }))?;
    Ok(t1)
}

/// The "welcome-describe" rule: the interface of the node's `Describe` is `want`, as
/// `--describe` gave it.
fn check_describe(want: &InterfaceDescription, d: &Describe, sheet: &mut Sheet) {
    match d.interfaces.iter().find(|i| i.name == want.name) {
        Some(i) if i == want => sheet.pass(
            "welcome-describe",
            format!("interface '{}' as --describe gave it", i.name),
        ),
        Some(i) => sheet.fail(
            "welcome-describe",
            format!("interface differs from --describe's: {i:?} against {want:?}"),
        ),
        None => sheet.fail(
            "welcome-describe",
            format!("no interface '{}' in its Describe", want.name),
        ),
    }
}

/// The "checkpoint" rule: the node's checkpoint of window `k` (ending at `t1`) in `output`
/// reads back as its own.
fn check_checkpoint(output: &Path, k: u64, t1: f64, sheet: &mut Sheet) {
    let file = protocol::checkpoint::file(output, k, "node");
    match protocol::checkpoint::Checkpoint::read(&file) {
        Ok(c) if c.node == "node" && c.window == k && c.time == t1 => sheet.pass(
            "checkpoint",
            format!(
                "window {k} saved before its Done ({} bytes of state)",
                c.payload.len()
            ),
        ),
        Ok(c) => sheet.fail(
            "checkpoint",
            format!(
                "{} is of node '{}', window {} at t = {:e} s; expected 'node', {k}, {t1:e} s",
                file.display(),
                c.node,
                c.window,
                c.time
            ),
        ),
        Err(e) => sheet.fail(
            "checkpoint",
            format!("Done of window {k} came, but {}: {e}", file.display()),
        ),
    }
}

/// The "windows-in-order" rule: a `Done` of every window 0 to `windows` in order, and a
/// `Fields` of each (`sent`).
fn judge_order(s: &Session, sheet: &mut Sheet, sent: &[bool], windows: u64) {
    let expected: Vec<u64> = (0..=windows).collect();
    let missing: Vec<String> = sent
        .iter()
        .enumerate()
        .filter(|(_, s)| !**s)
        .map(|(k, _)| k.to_string())
        .collect();
    if s.dones == expected && missing.is_empty() {
        sheet.pass(
            "windows-in-order",
            format!("Fields and Done for windows 0 to {windows}"),
        );
    } else {
        sheet.fail(
            "windows-in-order",
            format!(
                "Done windows {:?} (expected {expected:?}){}",
                s.dones,
                if missing.is_empty() {
                    String::new()
                } else {
                    format!("; no Fields of window(s) {}", missing.join(", "))
                }
            ),
        );
    }
}

/// The "heartbeat" rule: at least two heartbeats, never further apart than tolerated.
fn judge_heartbeat(s: &Session, sheet: &mut Sheet) {
    let gap = s.longest_gap;
    if s.beats >= 2 && gap <= LONGEST_GAP {
        sheet.pass(
            "heartbeat",
            format!(
                "{} heartbeats, at most {:.0} ms apart (period {HEARTBEAT_MS} ms)",
                s.beats,
                gap.as_secs_f64() * 1e3
            ),
        );
    } else {
        sheet.fail(
                "heartbeat",
                format!(
                    "{} heartbeats, up to {:.0} ms apart: the period is {HEARTBEAT_MS} ms, {:.0} ms at most tolerated",
                    s.beats,
                    gap.as_secs_f64() * 1e3,
                    LONGEST_GAP.as_secs_f64() * 1e3
                ),
            );
    }
}
/// The set-up's verdict: the node answered with its window-0 fields (`sent[0]`) and a second
/// `Describe`.
fn judge_set_up(s: &Session, sheet: &mut Sheet, sent: &[bool]) {
    if sent[0] && s.describes.len() >= 2 {
        sheet.pass("set-up", "Fields{0}, a second Describe, Done{0}");
        return;
    }
    let fields = if sent[0] { "" } else { "no Fields{0}; " };
    let describes = if s.describes.len() >= 2 {
        String::new()
    } else {
        format!("{} Describe(s), 2 expected", s.describes.len())
    };
    sheet.fail("set-up", format!("{fields}{describes}"));
}
