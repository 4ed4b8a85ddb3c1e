//! Test node: the built-in `bar-1d` of solid-node with one protocol fault, chosen by the key
//! `fault` of its parameters (the rest are the bar's), for the tests of the coordinator's
//! binding check and of `cosim conformance`:
//!
//! * `"none"`: the bar as it is;
//! * `"components"`: sends its `force` with 1 component per point instead of 3;
//! * `"misnamed"`: sends its `force` as `forse`;
//! * `"no_setup_force"`: leaves the `force` out of its set-up `Fields`;
//! * `"reversed"`: sends its `force` with the sign reversed, booking its interface impulse as
//!   the bar does (the booking rule of PROTOCOL.md 4.7 is broken);
//! * `"silent"`: stops (SIGSTOP, every thread: no heartbeat either) at the start of window
//!   `at` (default 2);
//! * `"early_exit"`: exits with status 0 at the start of window `at`, before any `Finish`;
//! * `"operator"`: as a lagrange side, states an operator twice the bar's (it claims its
//!   interface answers a force twice as fast as it does) and corrects as the bar does;
//! * `"withhold"`: never sends its `Fields` of window `at` (the runtime drops them as if
//!   lost) and goes on as if it had, heartbeats and all.

use protocol::scheme::lagrange;
use protocol::*;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// The window whose `Fields` the `withhold` fault drops (none: `u64::MAX`).
static WITHHELD: AtomicU64 = AtomicU64::new(u64::MAX);

#[derive(Debug, Clone, Copy, PartialEq)]
enum Fault {
    None,
    Components,
    Misnamed,
    NoSetupForce,
    Reversed,
    Silent,
    EarlyExit,
    Operator,
    Withhold,
}

struct Faulty {
    bar: Box<dyn Solver>,
    fault: Fault,
    at: u64,
    /// What the bar writes, passed on to the runtime's outbox with the fault applied.
    own: Outbox,
    /// The lagrange interface, and what the lying side states of it: the bar's multiplier
    /// ids, coupling steps and operator (doubled), read when the runtime asks for the side.
    iface: String,
    ids: Vec<usize>,
    steps: usize,
    operator: Vec<f64>,
    /// The bar's side's coupling state when the runtime last asked for the side (it asks
    /// just before it saves the state).
    saved: Result<Vec<u8>, String>,
}

impl Faulty {
    /// The bar's own lagrange side.
    fn inner(&mut self) -> &mut dyn lagrange::LagrangeSide {
        let iface = self.iface.clone();
        match self.bar.lagrange_side(&iface) {
            Some(s) => s,
            None => panic!("the bar's lagrange side on '{iface}' is gone"),
        }
    }
}

/// The `operator` fault: the bar's side, but with its operator doubled.
impl lagrange::LagrangeSide for Faulty {
    fn multiplier_ids(&self) -> &[usize] {
        &self.ids
    }
    fn coupling_steps(&self) -> usize {
        self.steps
    }
    fn operator(&self) -> &[f64] {
        &self.operator
    }
    fn initial(&mut self, free: &mut [f64], op: &mut [f64]) {
        self.inner().initial(free, op)
    }
    fn set_initial(&mut self, lambda0: &[f64]) {
        self.inner().set_initial(lambda0)
    }
    fn free_step(&mut self, v_start: &mut [f64], v_free: &mut [f64]) {
        self.inner().free_step(v_start, v_free)
    }
    fn correct(&mut self, lambda: &[f64]) {
        self.inner().correct(lambda)
    }
    fn interface_work(&self) -> f64 {
        0.0
    }
    fn save_state(&self) -> Result<Vec<u8>, String> {
        self.saved.clone()
    }
    fn load_state(&mut self, bytes: &[u8]) -> Result<(), String> {
        self.inner().load_state(bytes)
    }
}

impl Faulty {
    fn pass_on(&mut self, window: u64, out: &mut Outbox) {
        for (iface, f) in self.own.iter() {
            let mut f = f.clone();
            if f.name == "force" {
                match self.fault {
                    Fault::Components => {
                        f.values = f.values.iter().step_by(3).copied().collect();
                        f.components = 1;
                    }
                    Fault::Misnamed => f.name = "forse".into(),
                    Fault::NoSetupForce if window == 0 => continue,
                    Fault::Reversed => f.values.iter_mut().for_each(|x| *x = -*x),
                    _ => {}
                }
            }
            out.insert(iface, f);
        }
    }
}

impl Solver for Faulty {
    fn describe(&self) -> NodeDescription {
        self.bar.describe()
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        self.bar.interface(name)
    }

    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        self.bar.setup(bindings, inbox, &mut self.own)?;
        self.pass_on(0, out);
        Ok(())
    }

    fn stable_dt(&self) -> f64 {
        self.bar.stable_dt()
    }

    fn initial_report(&mut self) -> SolverResult<StepReport> {
        self.bar.initial_report()
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        if w.index == self.at {
            match self.fault {
                // SAFETY: raise only sends a signal to this process.
                Fault::Silent => unsafe {
                    libc::raise(libc::SIGSTOP);
                },
                Fault::EarlyExit => std::process::exit(0),
                _ => {}
            }
        }
        let r = self.bar.advance(w, inbox, &mut self.own)?;
        self.pass_on(w.index, out);
        Ok(r)
    }

    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        self.bar.write_output(t, window, dir)
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        self.bar.save_state()
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        self.bar.load_state(bytes)
    }

    fn window_limits(&self) -> Vec<WindowLimit> {
        self.bar.window_limits()
    }

    fn lagrange_side(&mut self, interface: &str) -> Option<&mut dyn lagrange::LagrangeSide> {
        if self.fault != Fault::Operator {
            return self.bar.lagrange_side(interface);
        }
        let side = self.bar.lagrange_side(interface)?;
        let (ids, steps) = (side.multiplier_ids().to_vec(), side.coupling_steps());
        let operator = side.operator().iter().map(|x| 2.0 * x).collect();
        self.saved = side.save_state();
        self.iface = interface.to_string();
        (self.ids, self.steps, self.operator) = (ids, steps, operator);
        Some(self)
    }
}

fn build(model: &str, params: &toml::Table, opts: &BuildOptions) -> SolverResult<Box<dyn Solver>> {
    let mut params = params.clone();
    let fault = match params.remove("fault").as_ref().map(|v| v.as_str()) {
        None | Some(Some("none")) => Fault::None,
        Some(Some("components")) => Fault::Components,
        Some(Some("misnamed")) => Fault::Misnamed,
        Some(Some("no_setup_force")) => Fault::NoSetupForce,
        Some(Some("reversed")) => Fault::Reversed,
        Some(Some("silent")) => Fault::Silent,
        Some(Some("early_exit")) => Fault::EarlyExit,
        Some(Some("operator")) => Fault::Operator,
        Some(Some("withhold")) => Fault::Withhold,
        Some(other) => {
            return Err(SolverError::config(
                "fault",
                format!(
                    "unknown fault {other:?} (none, components, misnamed, no_setup_force, reversed, silent, early_exit, operator, withhold)"
                ),
            ));
        }
    };
    let at = match params.remove("at") {
        None => 2,
        Some(v) => v
            .as_integer()
            .and_then(|i| u64::try_from(i).ok())
            .ok_or_else(|| SolverError::config("at", "must be a window number"))?,
    };
    if fault == Fault::Withhold {
        WITHHELD.store(at, Ordering::Relaxed);
    }
    Ok(Box::new(Faulty {
        bar: solid_node::build(model, &params, opts)?,
        fault,
        at,
        own: Outbox::new(),
        iface: String::new(),
        ids: Vec::new(),
        steps: 1,
        operator: Vec::new(),
        saved: Ok(Vec::new()),
    }))
}

fn main() {
    std::process::exit(protocol::participant::node_main_withholding(
        "cosim-faulty",
        build,
        Box::new(|f| f.window == WITHHELD.load(Ordering::Relaxed)),
    ));
}
