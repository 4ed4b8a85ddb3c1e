//! Benchmark helper: a node whose solver only passes data through (model `echo`), the Rust
//! baseline of the participant window benchmark (`cosim bench --only window`). Interface `port` has `points` points (param,
//! default 128); a responder answers each window's `signal` with the same values as
//! `echo`, a driver sends `signal` (its window index) and takes `echo`. With one value per
//! point, 128 points are 1 KiB each way. The names are no physical quantity's (whose
//! component counts the protocol fixes), and the benchmark couples them as an immersed
//! coupling, which asks for no set-up data. `panic_at_window = N` makes it panic in window N
//! (the failure tests' panicking node).

use protocol::{
    Binding, Inbox, InterfaceInfo, InterfaceMesh, NodeDescription, Outbox, Role, Solver,
    SolverError, SolverResult, StepReport, Window,
};

const PORT: &str = "port";

struct Echo {
    points: usize,
    role: Option<Role>,
    panic_at: Option<u64>,
}

fn factory(
    model: &str,
    params: &toml::Table,
    _: &protocol::BuildOptions,
) -> SolverResult<Box<dyn Solver>> {
    if model != "echo" {
        return Err(SolverError::config(
            "model",
            format!("only \"echo\", got \"{model}\""),
        ));
    }
    let mut points = 128;
    let mut panic_at = None;
    for (k, v) in params {
        match (k.as_str(), v.as_integer()) {
            ("points", Some(n)) if n > 0 => points = n as usize,
            ("points", _) => return Err(SolverError::config("points", "must be an integer > 0")),
            ("panic_at_window", Some(n)) if n > 0 => panic_at = Some(n as u64),
            ("panic_at_window", _) => {
                return Err(SolverError::config(
                    "panic_at_window",
                    "must be an integer > 0",
                ));
            }
            _ => {
                return Err(SolverError::config(
                    k,
                    "unknown parameter (echo reads: points, panic_at_window)",
                ));
            }
        }
    }
    Ok(Box::new(Echo {
        points,
        role: None,
        panic_at,
    }))
}

impl Solver for Echo {
    fn describe(&self) -> NodeDescription {
        let f = vec!["signal".to_string(), "echo".to_string()];
        NodeDescription {
            model: "echo".into(),
            interfaces: vec![InterfaceInfo {
                name: PORT.into(),
                points: self.points,
                provides: f.clone(),
                accepts: f,
            }],
            units: "SI".into(),
        }
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        if name != PORT {
            return Err(SolverError::interface(
                name,
                "echo has one interface, 'port'",
            ));
        }
        Ok(InterfaceMesh::points(
            (0..self.points).map(|i| [i as f64, 0.0, 0.0]).collect(),
        ))
    }

    fn setup(
        &mut self,
        bindings: &[Binding],
        _inbox: &Inbox,
        _out: &mut Outbox,
    ) -> SolverResult<()> {
        self.role = bindings.first().map(|b| b.role);
        Ok(())
    }

    fn stable_dt(&self) -> f64 {
        1.0
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        if self.panic_at == Some(w.index) {
            let empty: Vec<f64> = Vec::new();
            // An out-of-bounds index: the kind of bug a solver has.
            let _ = empty[w.index as usize];
        }
        match self.role {
            Some(Role::Responder) => {
                let v = inbox.require(PORT, "signal", self.points)?;
                let f = out.put(PORT, "echo", 1, self.points);
                f.copy_from_slice(v);
            }
            Some(Role::Driver) => {
                out.put(PORT, "signal", 1, self.points).fill(w.index as f64);
            }
            None => {}
        }
        Ok(StepReport {
            substeps: 1,
            ..Default::default()
        })
    }
}

fn main() {
    std::process::exit(protocol::participant::node_main("cosim-echo-node", factory));
}
