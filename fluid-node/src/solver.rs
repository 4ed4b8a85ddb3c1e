//! The `Solver` implementation of the fluid node (ARCHITECTURE §3): sub-cycles the
//! CFL-limited SSP-RK3 step to the window end, answers the immersed coupling as responder
//! (inputs `position`, `velocity`, `volume`; output window-averaged `force`), reports
//! energies, momentum and impulses, writes VTK and probe histories.

use crate::immersed::Immersed;
use crate::model::Fluid;
use crate::{diagnostics, output, setup, step};
use protocol::message::{InterfaceMesh, StepReport};
use protocol::{
    Inbox, InterfaceInfo, NodeDescription, Outbox, Solver, SolverError, SolverResult, Window,
};
use std::path::Path;
use std::time::Instant;

pub struct EulerSolver {
    pub fluid: Fluid,
    /// Probe history: (time, per probe [ρ, p, u, v, w]).
    pub probe_history: Vec<(f64, Vec<[f64; 5]>)>,
}

impl EulerSolver {
    pub fn new(params: &toml::Table) -> SolverResult<Self> {
        let p = setup::parse(params)?;
        Ok(EulerSolver {
            fluid: setup::build(&p)?,
            probe_history: Vec::new(),
        })
    }

    pub fn from_fluid(fluid: Fluid) -> Self {
        EulerSolver {
            fluid,
            probe_history: Vec::new(),
        }
    }

    fn read_particles(&mut self, inbox: &Inbox) -> SolverResult<()> {
        let Some(mut im) = self.fluid.immersed.take() else {
            return Ok(());
        };
        let name = im.interface.clone();
        let res = (|| {
            let n = match (im.n, inbox.get(&name, "volume")) {
                (0, Some(v)) => v.values.len(),
                (n, _) => n,
            };
            if n == 0 {
                return Err(SolverError::interface(
                    &name,
                    "no 'volume' field received and no particle count in params",
                ));
            }
            let pos = inbox.require(&name, "position", 3 * n)?;
            let vel = inbox.require(&name, "velocity", 3 * n)?;
            let vol = inbox.require(&name, "volume", n)?;
            if pos.iter().chain(vel).chain(vol).any(|x| !x.is_finite()) {
                return Err(SolverError::interface(&name, "non-finite particle data"));
            }
            im.set_particles(&mut self.fluid, pos, vel, vol);
            Ok(())
        })();
        self.fluid.immersed = Some(im);
        res
    }

    /// Advance to `t1` by CFL steps, the last one shortened to land on t1 exactly.
    pub fn advance_to(&mut self, t1: f64) -> SolverResult<u64> {
        let mut n = 0;
        while self.fluid.time < t1 {
            let remaining = t1 - self.fluid.time;
            step::step(&mut self.fluid, remaining)?;
            if t1 - self.fluid.time <= 1e-12 * t1.abs().max(f64::MIN_POSITIVE) {
                self.fluid.time = t1;
            }
            n += 1;
            if n > self.fluid.max_steps_per_window {
                return Err(SolverError::Diverged {
                    time: self.fluid.time,
                    reason: format!(
                        "more than {} steps in one window (max_steps_per_window)",
                        self.fluid.max_steps_per_window
                    ),
                });
            }
        }
        Ok(n)
    }
}

impl Solver for EulerSolver {
    fn describe(&self) -> NodeDescription {
        let interfaces = self
            .fluid
            .immersed
            .iter()
            .map(|im| InterfaceInfo {
                name: im.interface.clone(),
                points: im.n,
                provides: vec!["force".into()],
                accepts: vec!["position".into(), "velocity".into(), "volume".into()],
            })
            .collect();
        NodeDescription {
            model: "euler".into(),
            interfaces,
            units: "SI".into(),
        }
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        match &self.fluid.immersed {
            Some(im) if im.interface == name => Ok(InterfaceMesh::points(im.positions.clone())),
            _ => Err(SolverError::interface(
                name,
                "no such interface on this fluid node",
            )),
        }
    }

    fn setup(
        &mut self,
        _bindings: &[protocol::message::Binding],
        inbox: &Inbox,
        _out: &mut Outbox,
    ) -> SolverResult<()> {
        if let Some(im) = &self.fluid.immersed
            && inbox.get(&im.interface, "position").is_some()
        {
            self.read_particles(inbox)?;
        }
        Ok(())
    }

    fn stable_dt(&self) -> f64 {
        let mut f = self.fluid.clone();
        step::stable_dt(&mut f).unwrap_or(0.0)
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        let start = Instant::now();
        if (self.fluid.time - w.t0).abs() > 1e-9 * w.t1.abs().max(1e-300) {
            return Err(SolverError::Other(format!(
                "window {} starts at {:e} but the fluid is at {:e}",
                w.index, w.t0, self.fluid.time
            )));
        }
        self.fluid.time = w.t0;
        if self.fluid.immersed.is_some() {
            self.read_particles(inbox)?;
        }
        let substeps = self.advance_to(w.t1)?;
        if let Some(im) = &self.fluid.immersed {
            let n = im.n;
            let buf = out.put(&im.interface.clone(), "force", 3, n);
            im.forces(w.t1 - w.t0, buf);
        }
        self.record_probes();
        let d = diagnostics::totals(&mut self.fluid)?;
        let mut report = StepReport {
            kinetic_energy: d.kinetic,
            internal_energy: d.internal,
            momentum: d.momentum,
            external_impulse: self.fluid.boundary_impulse,
            substeps,
            wall_s: start.elapsed().as_secs_f64(),
            ..Default::default()
        };
        if let Some(im) = &self.fluid.immersed {
            for c in 0..3 {
                report.interface_impulse[c] = -im.total_impulse[c];
            }
            report
                .scalars
                .push(("reclassification_momentum_x".into(), im.reclass_momentum[0]));
        }
        report.scalars.push(("mass".into(), d.mass));
        report.scalars.push(("max_pressure".into(), d.max_pressure));
        if let Some((_, last)) = self.probe_history.last() {
            for (p, s) in self.fluid.probes.iter().zip(last) {
                report.scalars.push((format!("{}.pressure", p.name), s[1]));
                report.scalars.push((format!("{}.density", p.name), s[0]));
            }
        }
        Ok(report)
    }

    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        output::write_vtk(&self.fluid, t, window, dir)?;
        output::write_probes(&self.fluid, &self.probe_history, dir)
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        let mut b = Vec::with_capacity(8 * (self.fluid.cons.len() + 2));
        b.extend_from_slice(&self.fluid.time.to_le_bytes());
        b.extend_from_slice(&(self.fluid.cons.len() as u64).to_le_bytes());
        for x in &self.fluid.cons {
            b.extend_from_slice(&x.to_le_bytes());
        }
        Ok(b)
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        let n = self.fluid.cons.len();
        if bytes.len() != 8 * (n + 2) {
            return Err(SolverError::Other(format!(
                "checkpoint has {} bytes, expected {}",
                bytes.len(),
                8 * (n + 2)
            )));
        }
        let word = |i: usize| {
            let mut w = [0u8; 8];
            w.copy_from_slice(&bytes[8 * i..8 * i + 8]);
            w
        };
        if u64::from_le_bytes(word(1)) as usize != n {
            return Err(SolverError::Other("checkpoint is for another grid".into()));
        }
        self.fluid.time = f64::from_le_bytes(word(0));
        for (i, x) in self.fluid.cons.iter_mut().enumerate() {
            *x = f64::from_le_bytes(word(i + 2));
        }
        self.fluid.prim_valid = false;
        Ok(())
    }
}

impl EulerSolver {
    fn record_probes(&mut self) {
        if self.fluid.probes.is_empty() {
            return;
        }
        let f = &self.fluid;
        let vals = f
            .probes
            .iter()
            .map(|p| diagnostics::cell_state(f, p.row, p.i))
            .collect();
        self.probe_history.push((f.time, vals));
    }

    /// Access to the immersed state (tests, examples).
    pub fn immersed(&self) -> Option<&Immersed> {
        self.fluid.immersed.as_ref()
    }
}
