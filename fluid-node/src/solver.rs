//! The `Solver` implementation of the fluid node (docs/architecture.md): sub-cycles the
//! CFL-limited SSP-RK3 step to the window end, answers the immersed coupling as responder
//! (inputs `position`, `velocity`, `volume`; output window-averaged `force`), reports
//! energies, momentum and impulses, writes VTK and probe histories.

use crate::gpu::{GpuEuler, GpuSetupError};
use crate::immersed::Immersed;
use crate::model::Fluid;
use crate::{diagnostics, output, setup, step};
use node_kit::device::Device;
use protocol::message::{InterfaceMesh, StepReport};
use protocol::{
    BuildOptions, Inbox, InterfaceInfo, NodeDescription, Outbox, Solver, SolverError, SolverResult,
    Window,
};
use std::path::Path;
use std::time::Instant;

pub struct EulerSolver {
    pub fluid: Fluid,
    /// Probe history: (time, per probe [ρ, p, u, v, w]).
    pub probe_history: Vec<(f64, Vec<[f64; 5]>)>,
    /// Edge history: (time, per edge line [first, last]), from t = 0.
    pub edge_history: Vec<(f64, Vec<[f64; 2]>)>,
    /// Work received through the immersed interface so far (J): minus the work of the
    /// impulse given to the particles at the particle velocities of that window.
    pub interface_work: f64,
    /// The device copy of the state when `device = "gpu"`: it owns the state during the
    /// run; `fluid` is brought up to date only for output and checkpoints.
    pub gpu: Option<GpuEuler>,
}

impl EulerSolver {
    pub fn new(params: &toml::Table) -> SolverResult<Self> {
        Self::build(params, &BuildOptions::RUN)
    }

    /// As `new`, as `opts` asks: describe-only checks `device = "gpu"` against what the
    /// device kernels support but opens no GPU (the state stays on the host).
    pub fn build(params: &toml::Table, opts: &BuildOptions) -> SolverResult<Self> {
        let p = setup::parse(params)?;
        let fluid = setup::build(&p)?;
        let device = Device::parse(p.device.as_deref(), p.precision.as_deref())?;
        // What the device kernels cannot run is refused before any adapter is asked for;
        // describe-only stops there (the state stays on the host).
        if device.is_gpu() {
            crate::gpu::supports(&fluid)
                .map_err(|s| SolverError::from(GpuSetupError::Unsupported(s)))?;
        }
        let gpu = match opts.describe_only {
            true => None,
            false => match device.open("fluid step")? {
                Some(ctx) => Some(GpuEuler::with_context(ctx, &fluid)?),
                None => None,
            },
        };
        Ok(EulerSolver {
            edge_history: first_edges(&fluid),
            fluid,
            probe_history: Vec::new(),
            interface_work: 0.0,
            gpu,
        })
    }

    pub fn from_fluid(fluid: Fluid) -> Self {
        EulerSolver {
            edge_history: first_edges(&fluid),
            fluid,
            probe_history: Vec::new(),
            interface_work: 0.0,
            gpu: None,
        }
    }

    /// The state as the host sees it: the device's copy when on the GPU.
    fn host_state(&self) -> SolverResult<std::borrow::Cow<'_, Fluid>> {
        match &self.gpu {
            None => Ok(std::borrow::Cow::Borrowed(&self.fluid)),
            Some(g) => {
                let mut f = self.fluid.clone();
                g.download(&mut f)?;
                Ok(std::borrow::Cow::Owned(f))
            }
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
            match self.gpu.as_mut() {
                // the state is on the device: only the cells the interface touches cross
                Some(g) => g.set_particles(&mut im, &mut self.fluid, pos, vel, vol)?,
                None => im.set_particles(&mut self.fluid, pos, vel, vol),
            }
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
    fn warnings(&self) -> Vec<String> {
        let w = self.gpu.as_ref().and_then(|g| g.warning());
        w.map(|w| vec![w.to_string()]).unwrap_or_default()
    }

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
        match &self.gpu {
            Some(g) => g.stable_dt().unwrap_or(0.0),
            None => step::stable_dt_of(&self.fluid).unwrap_or(0.0),
        }
    }

    fn initial_report(&mut self) -> SolverResult<StepReport> {
        let d = diagnostics::totals(&mut self.fluid)?;
        Ok(StepReport {
            kinetic_energy: d.kinetic,
            internal_energy: d.internal,
            momentum: d.momentum,
            momentum_gross: d.momentum_gross,
            ..Default::default()
        })
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
            let t = Instant::now();
            self.read_particles(inbox)?;
            self.fluid.timing.immersed_window_s += t.elapsed().as_secs_f64();
        }
        if let Some(g) = self.gpu.as_mut() {
            let mut report = Self::advance_gpu(
                g,
                &mut self.fluid,
                &mut self.probe_history,
                &mut self.edge_history,
                w,
                start,
            )?;
            if let Some(im) = self.fluid.immersed.as_mut() {
                g.read_impulses(im)?;
                let nd = self.fluid.grid.nd;
                self.interface_work -= crate::gpu::immersed_outputs(im, nd, w, out, &mut report);
                report.interface_work = self.interface_work;
                report.wall_s = start.elapsed().as_secs_f64();
            }
            return Ok(report);
        }
        // the window's steps run inside the thread pool: their parallel loops (about seven
        // per RK stage) then start on a pool thread instead of each waking one from outside
        let substeps = rayon::scope(|_| self.advance_to(w.t1))?;
        let t_forces = Instant::now();
        if let Some(im) = &self.fluid.immersed {
            let n = im.n;
            let buf = out.put(&im.interface.clone(), "force", 3, n);
            im.forces(w.t1 - w.t0, buf);
            self.interface_work -= im
                .impulse
                .iter()
                .zip(&im.velocities)
                .map(|(j, v)| j[0] * v[0] + j[1] * v[1] + j[2] * v[2])
                .sum::<f64>();
            self.fluid.timing.immersed_window_s += t_forces.elapsed().as_secs_f64();
        }
        self.record_probes();
        self.record_edges();
        let d = diagnostics::totals(&mut self.fluid)?;
        let mut report = StepReport {
            kinetic_energy: d.kinetic,
            internal_energy: d.internal,
            momentum: d.momentum,
            momentum_gross: d.momentum_gross,
            external_impulse: self.fluid.boundary_impulse,
            external_work: self.fluid.boundary_work,
            interface_work: self.interface_work,
            substeps,
            wall_s: start.elapsed().as_secs_f64(),
            ..Default::default()
        };
        if let Some(im) = &self.fluid.immersed {
            for c in 0..3 {
                report.interface_impulse[c] = -im.total_impulse[c];
                // Cells that change class (gas ↔ solid) create or remove gas momentum that
                // does not cross to the particles: a source of the gas like its walls, so the
                // coordinator's audit counts it with the external impulse.
                report.external_impulse[c] += im.reclass_momentum[c] - im.held_momentum[c];
            }
            // and the energy of the gas those cells add or remove, with the external work;
            // with a conservative refill also the energy the walls carried into solid cells
            // (out; it comes back with the refills)
            report.external_work += im.reclass_energy - im.held_energy;
            report
                .scalars
                .push(("reclassification_energy".into(), im.reclass_energy));
            for (c, axis) in ["x", "y", "z"].iter().enumerate().take(self.fluid.grid.nd) {
                report.scalars.push((
                    format!("reclassification_momentum_{axis}"),
                    im.reclass_momentum[c],
                ));
            }
        }
        report.scalars.push(("mass".into(), d.mass));
        report.scalars.push(("max_pressure".into(), d.max_pressure));
        report.scalars.push(("min_pressure".into(), d.min_pressure));
        report.scalars.push(("min_density".into(), d.min_density));
        edge_scalars(&self.fluid.edges, &self.edge_history, &mut report.scalars);
        timing_scalars(&self.fluid, &mut report.scalars);
        if let Some((_, last)) = self.probe_history.last() {
            for (p, s) in self.fluid.probes.iter().zip(last) {
                report.scalars.push((format!("{}.pressure", p.name), s[1]));
                report.scalars.push((format!("{}.density", p.name), s[0]));
            }
        }
        Ok(report)
    }

    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        let f = self.host_state()?;
        output::write_vtk(&f, t, window, dir)?;
        output::write_probes(&f, &self.probe_history, dir)?;
        output::write_edges(&f, &self.edge_history, dir)
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        let f = self.host_state()?;
        // the device path keeps the window's particle impulses on the device: read them
        let im = match (&self.gpu, &f.immersed) {
            (Some(g), Some(im)) => {
                let mut im = im.clone();
                g.read_impulses(&mut im)?;
                Some(std::borrow::Cow::Owned(im))
            }
            (_, im) => im.as_ref().map(std::borrow::Cow::Borrowed),
        };
        protocol::checkpoint::encode_state(&FluidStateRef {
            time: f.time,
            steps: f.steps,
            cons: &f.cons,
            boundary_impulse: f.boundary_impulse,
            boundary_work: f.boundary_work,
            interface_work: self.interface_work,
            probe_history: &self.probe_history,
            edge_history: &self.edge_history,
            immersed: im.as_deref(),
        })
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        use protocol::checkpoint::check_len;
        let s: FluidState = protocol::checkpoint::decode_state(bytes)?;
        check_len("cons", s.cons.len(), self.fluid.cons.len())?;
        for (_, e) in &s.edge_history {
            check_len("edge lines", e.len(), self.fluid.edges.len())?;
        }
        match (&self.fluid.immersed, &s.immersed) {
            (None, None) => {}
            (Some(a), Some(b)) if a.interface == b.interface && a.kind.len() == b.kind.len() => {}
            _ => {
                return Err(SolverError::Other(
                    "load_state: the checkpoint's immersed interface is not this node's".into(),
                ));
            }
        }
        let f = &mut self.fluid;
        f.time = s.time;
        f.steps = s.steps;
        f.cons = s.cons;
        f.boundary_impulse = s.boundary_impulse;
        f.boundary_work = s.boundary_work;
        f.immersed = s.immersed;
        f.prim_valid = false;
        self.interface_work = s.interface_work;
        self.probe_history = s.probe_history;
        self.edge_history = s.edge_history;
        if let Some(g) = self.gpu.as_mut() {
            g.upload(&self.fluid)?;
        }
        Ok(())
    }
}

/// `NAME.first`, `NAME.last` and their speeds of every edge line, from the history.
fn edge_scalars(
    edges: &[crate::edges::EdgeLine],
    history: &[(f64, Vec<[f64; 2]>)],
    out: &mut Vec<(String, f64)>,
) {
    let Some((_, now)) = history.last() else {
        return;
    };
    for (e, (line, pos)) in edges.iter().zip(now).enumerate() {
        for (side, which) in ["first", "last"].iter().enumerate() {
            out.push((format!("{}.{which}", line.name), pos[side]));
            let v = crate::edges::speed(history, e, side, line.moved);
            out.push((format!("{}.{which}_speed", line.name), v));
        }
    }
}

/// The edge lines' positions now.
fn edges_now(f: &Fluid) -> Vec<[f64; 2]> {
    f.edges.iter().map(|e| e.positions(f)).collect()
}

/// The edge history's first entry, at the model's time (none without edge lines).
fn first_edges(f: &Fluid) -> Vec<(f64, Vec<[f64; 2]>)> {
    if f.edges.is_empty() {
        Vec::new()
    } else {
        vec![(f.time, edges_now(f))]
    }
}

/// Where the fluid's time went since the node started (s; a restart starts the clocks
/// again): its steps, split into the fluid kernels, the immersed work inside the steps and
/// the ghost fills; the immersed work once per window (classification, refills, forces); and
/// the steps' throughput (interior cells × steps per second of step).
fn timing_scalars(f: &Fluid, out: &mut Vec<(String, f64)>) {
    let t = &f.timing;
    let rate = if t.steps_s > 0.0 {
        t.cell_updates / t.steps_s
    } else {
        0.0
    };
    for (name, v) in [
        ("time_steps_s", t.steps_s),
        ("time_fluid_kernels_s", t.kernels_s),
        ("time_immersed_s", t.immersed_s),
        ("time_ghost_fills_s", t.ghosts_s),
        ("time_immersed_window_s", t.immersed_window_s),
        ("cell_updates_per_s", rate),
    ] {
        out.push((name.into(), v));
    }
}

/// What `save_state` writes: everything `advance` depends on (conserved state, clocks, the
/// boundary and interface accumulators, the immersed classification and totals, the probe
/// history the output files list).
#[derive(serde::Serialize)]
struct FluidStateRef<'a> {
    time: f64,
    steps: u64,
    cons: &'a [f64],
    boundary_impulse: [f64; 3],
    boundary_work: f64,
    interface_work: f64,
    probe_history: &'a [(f64, Vec<[f64; 5]>)],
    edge_history: &'a [(f64, Vec<[f64; 2]>)],
    immersed: Option<&'a Immersed>,
}

/// [`FluidStateRef`] read back (the same bincode layout, owned).
#[derive(serde::Deserialize)]
struct FluidState {
    time: f64,
    steps: u64,
    cons: Vec<f64>,
    boundary_impulse: [f64; 3],
    boundary_work: f64,
    interface_work: f64,
    probe_history: Vec<(f64, Vec<[f64; 5]>)>,
    edge_history: Vec<(f64, Vec<[f64; 2]>)>,
    immersed: Option<Immersed>,
}

impl EulerSolver {
    /// One window on the device: only totals and probe cells come back to the host.
    fn advance_gpu(
        g: &mut GpuEuler,
        fluid: &mut Fluid,
        probe_history: &mut Vec<(f64, Vec<[f64; 5]>)>,
        edge_history: &mut Vec<(f64, Vec<[f64; 2]>)>,
        w: &Window,
        start: Instant,
    ) -> SolverResult<StepReport> {
        let substeps = g.advance_to(w.t1)?;
        fluid.time = g.time();
        fluid.steps = g.steps();
        let d = g.totals()?;
        let mut report = StepReport {
            kinetic_energy: d.kinetic,
            internal_energy: d.internal,
            momentum: d.momentum,
            momentum_gross: d.momentum_gross,
            external_impulse: g.boundary_impulse(),
            external_work: g.boundary_work(),
            substeps,
            ..Default::default()
        };
        report.scalars.push(("mass".into(), d.mass));
        report.scalars.push(("max_pressure".into(), d.max_pressure));
        report.scalars.push(("min_pressure".into(), d.min_pressure));
        report.scalars.push(("min_density".into(), d.min_density));
        // Precision of the device arithmetic (64, or 32 with a warning in the log).
        let bits = if g.warning().is_some() { 32.0 } else { 64.0 };
        report.scalars.push(("gpu_precision_bits".into(), bits));
        if !fluid.probes.is_empty() {
            let cells: Vec<(usize, usize)> = fluid.probes.iter().map(|p| (p.row, p.i)).collect();
            let vals = g.cell_states(&cells)?;
            for (p, s) in fluid.probes.iter().zip(&vals) {
                report.scalars.push((format!("{}.pressure", p.name), s[1]));
                report.scalars.push((format!("{}.density", p.name), s[0]));
            }
            probe_history.push((fluid.time, vals));
        }
        if !fluid.edges.is_empty() {
            let mut now = Vec::with_capacity(fluid.edges.len());
            for e in &fluid.edges {
                let cells: Vec<(usize, usize)> = e.cells.iter().map(|c| (c.0, c.1)).collect();
                now.push(e.positions_of(&g.volume_fractions(&cells, e.material)?));
            }
            edge_history.push((fluid.time, now));
            edge_scalars(&fluid.edges, edge_history, &mut report.scalars);
        }
        report.wall_s = start.elapsed().as_secs_f64();
        Ok(report)
    }

    /// Appends the edge lines' positions now to their history.
    fn record_edges(&mut self) {
        if !self.fluid.edges.is_empty() {
            let now = edges_now(&self.fluid);
            self.edge_history.push((self.fluid.time, now));
        }
    }

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
