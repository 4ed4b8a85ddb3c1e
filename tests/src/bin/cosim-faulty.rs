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
//! * `"early_exit"`: exits with status 0 at the start of window `at`, before any `Finish`.

use protocol::*;
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Fault {
    None,
    Components,
    Misnamed,
    NoSetupForce,
    Reversed,
    Silent,
    EarlyExit,
}

struct Faulty {
    bar: Box<dyn Solver>,
    fault: Fault,
    at: u64,
    /// What the bar writes, passed on to the runtime's outbox with the fault applied.
    own: Outbox,
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
        Some(other) => {
            return Err(SolverError::config(
                "fault",
                format!(
                    "unknown fault {other:?} (none, components, misnamed, no_setup_force, reversed, silent, early_exit)"
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
    Ok(Box::new(Faulty {
        bar: solid_node::build(model, &params, opts)?,
        fault,
        at,
        own: Outbox::new(),
    }))
}

fn main() {
    std::process::exit(protocol::participant::node_main("cosim-faulty", build));
}
