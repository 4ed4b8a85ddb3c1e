//! Test node: a solver that blows up on purpose, for the divergence guard's tests. Model
//! `grow`: a body of kinetic energy `energy` (J) after set-up that multiplies it by `growth`
//! every window, and, from window `nan_at` on (0: never), reports it as NaN. Its stable step
//! is `stable_dt` (s), stated as a lagrange side's limit in `substeps` steps when those are
//! given, so that validation can be tested against a known limit. Its momentum (along x) is
//! `momentum` after set-up and grows by `drift` every window with no impulse booked: a
//! booking fault of known size, for the balance warnings' tests.

use protocol::*;

#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    #[serde(default = "one")]
    energy: f64,
    #[serde(default = "one")]
    growth: f64,
    #[serde(default)]
    nan_at: u64,
    #[serde(default = "one")]
    stable_dt: f64,
    #[serde(default)]
    substeps: Option<u64>,
    #[serde(default)]
    momentum: f64,
    #[serde(default)]
    drift: f64,
}

fn one() -> f64 {
    1.0
}

struct Grow {
    p: Params,
    energy: f64,
    momentum: f64,
}

impl Solver for Grow {
    fn describe(&self) -> NodeDescription {
        NodeDescription {
            model: "grow".into(),
            interfaces: vec![],
            units: "SI".into(),
        }
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        Err(SolverError::interface(
            name,
            "the grow model has no interfaces",
        ))
    }

    fn stable_dt(&self) -> f64 {
        self.p.stable_dt
    }

    fn window_limits(&self) -> Vec<WindowLimit> {
        self.p
            .substeps
            .map(|n| WindowLimit {
                applies: LimitApplies::LagrangeSide,
                integrator: "central differences".into(),
                substeps: n,
                max_step: self.p.stable_dt,
                key: Some("params.substeps".into()),
                kind: protocol::LimitKind::Stability,
            })
            .into_iter()
            .collect()
    }

    fn initial_report(&mut self) -> SolverResult<StepReport> {
        Ok(StepReport {
            kinetic_energy: self.energy,
            momentum: [self.momentum, 0.0, 0.0],
            momentum_gross: self.momentum.abs(),
            ..Default::default()
        })
    }

    fn advance(&mut self, w: &Window, _: &Inbox, _: &mut Outbox) -> SolverResult<StepReport> {
        self.energy *= self.p.growth;
        self.momentum += self.p.drift;
        let reported = if self.p.nan_at > 0 && w.index >= self.p.nan_at {
            f64::NAN
        } else {
            self.energy
        };
        Ok(StepReport {
            kinetic_energy: reported,
            momentum: [self.momentum, 0.0, 0.0],
            momentum_gross: self.momentum.abs(),
            substeps: 1,
            ..Default::default()
        })
    }
}

fn build(model: &str, params: &toml::Table, _: &BuildOptions) -> SolverResult<Box<dyn Solver>> {
    if model != "grow" {
        return Err(SolverError::config(
            "model",
            format!("unknown model '{model}' (this node offers: grow)"),
        ));
    }
    let p: Params = protocol::params::decode(params)?;
    Ok(Box::new(Grow {
        energy: p.energy,
        momentum: p.momentum,
        p,
    }))
}

fn main() {
    std::process::exit(protocol::participant::node_main("cosim-grow", build));
}
