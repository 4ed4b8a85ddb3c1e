//! The `Solver` implementation of the macro-shell node (model "blt-shell"): it only
//! orchestrates — set-up of the kinematic couplings it drives, sub-cycling each window to land
//! exactly on t1, the window report, and output (seed 004 Fig. 4, driver side).

use crate::coupling::{self, ACCEPTS, Interface, SENDS, SETUP};
use crate::element;
use crate::model::Model;
use crate::output::{self, History};
use crate::setup::{self, ShellConfig};
use crate::step;
use mechanics::tensor::vec3;
use protocol::scheme;
use protocol::{
    Binding, Inbox, InterfaceInfo, InterfaceMesh, NodeDescription, Outbox, Solver, SolverError,
    SolverResult, StepReport, Window,
};
use std::path::Path;
use std::time::Instant;

/// The model name this solver registers under.
pub const MODEL: &str = "blt-shell";

pub struct ShellSolver {
    pub model: Model,
    pub interfaces: Vec<Interface>,
    pub history: History,
    scaled: bool,
    last_span: f64,
    last_substeps: u64,
}

impl ShellSolver {
    pub fn from_config(cfg: &ShellConfig) -> SolverResult<Self> {
        let mut model = setup::build(cfg)?;
        step::initialise(&mut model)?;
        let interfaces = coupling::interfaces_of(&cfg.interfaces, &model);
        let history = History::new(&model);
        Ok(ShellSolver {
            model,
            interfaces,
            history,
            scaled: false,
            last_span: 0.0,
            last_substeps: 0,
        })
    }

    pub fn from_params(params: &toml::Table) -> SolverResult<Self> {
        Self::from_config(&setup::parse(params)?)
    }

    pub fn from_toml_str(text: &str) -> SolverResult<Self> {
        Self::from_config(&setup::parse_str(text)?)
    }

    /// Mass scaling (once, after the coupling mass and stiffness are in).
    fn finish_setup(&mut self) {
        if self.scaled {
            return;
        }
        self.scaled = true;
        let mut coupled: Vec<u32> = self
            .interfaces
            .iter()
            .filter(|i| i.active)
            .flat_map(|i| i.nodes.iter().copied())
            .collect();
        coupled.sort_unstable();
        coupled.dedup();
        self.model.coupled_nodes = coupled;
        if let Some(t) = self.model.mass_scaling_dt {
            let physical = self.model.total_mass();
            let added = step::apply_mass_scaling(&mut self.model, t);
            // Also in every window's report (scalars `added_mass`, `added_mass_fraction`).
            tracing::info!(
                target_dt = t,
                added_mass_kg = added,
                fraction = added / physical,
                added_inertia = self.model.added_inertia,
                "mass scaling to the target step"
            );
        }
    }

    /// Coupling loads on the nodes: the held loads of this window (interfaces add up).
    fn set_coupling_loads(&mut self) {
        let m = &mut self.model;
        for &i in &m.coupled_nodes {
            m.f_c[i as usize] = [0.0; 3];
            m.m_c[i as usize] = [0.0; 3];
        }
        for itf in self.interfaces.iter().filter(|i| i.active) {
            itf.apply(m);
        }
    }

    fn find(&self, name: &str) -> SolverResult<usize> {
        self.interfaces
            .iter()
            .position(|i| i.name == name)
            .ok_or_else(|| SolverError::interface(name, "no such interface on this shell"))
    }

    fn report(&self, substeps: u64, wall: f64) -> StepReport {
        let m = &self.model;
        let (ke, ie) = (m.kinetic_energy(), m.internal_energy());
        let mut scalars = vec![
            ("dt".into(), m.dt_prev),
            ("added_mass".into(), m.added_mass),
            (
                "added_mass_fraction".into(),
                m.added_mass / (m.total_mass() - m.added_mass),
            ),
            (
                "max_plastic_strain".into(),
                match m.material {
                    crate::element::Material::J2(_) => {
                        (0..m.num_elements()).map(|e| m.eqps(e)).fold(0.0, f64::max)
                    }
                    _ => 0.0,
                },
            ),
            (
                "kinetic_over_internal".into(),
                if ie > 0.0 { ke / ie } else { 0.0 },
            ),
        ];
        if let Some(c) = &m.contact {
            scalars.push(("contact_nodes".into(), c.active as f64));
            scalars.push(("contact_energy".into(), c.energy));
        }
        // Reaction force (support on the structure, last step) and mean displacement of
        // every reaction set, e.g. the pulled edge of a tension test.
        for set in &m.reaction_sets {
            let r = output::reaction_sum(m, &set.nodes);
            let mut u = [0.0; 3];
            for &n in &set.nodes {
                for d in 0..3 {
                    u[d] += m.x[n as usize][d] - m.x0[n as usize][d];
                }
            }
            let k = set.nodes.len().max(1) as f64;
            for (d, axis) in ["x", "y", "z"].iter().enumerate() {
                scalars.push((format!("force_{}_{axis}", set.name), r[d]));
            }
            for (d, axis) in ["x", "y", "z"].iter().enumerate() {
                scalars.push((format!("displacement_{}_{axis}", set.name), u[d] / k));
            }
        }
        StepReport {
            kinetic_energy: ke,
            internal_energy: ie,
            external_work: m.external_work + m.support_work + m.pressure_work(),
            interface_work: m.interface_work,
            momentum: m.momentum(),
            momentum_gross: m.momentum_gross(),
            external_impulse: m.external_impulse,
            interface_impulse: m.interface_impulse,
            applied_impulse: vec3(&m.load_impulse).norm(),
            substeps,
            wall_s: wall,
            coupling_wait_s: 0.0,
            idle_s: 0.0,
            scalars,
        }
    }
}

impl Solver for ShellSolver {
    fn describe(&self) -> NodeDescription {
        NodeDescription {
            model: MODEL.into(),
            interfaces: self
                .interfaces
                .iter()
                .map(|i| InterfaceInfo {
                    name: i.name.clone(),
                    points: i.len(),
                    provides: SENDS.iter().map(|s| s.to_string()).collect(),
                    accepts: ACCEPTS.iter().map(|s| s.to_string()).collect(),
                })
                .collect(),
            units: "SI (m, kg, s, N, Pa)".into(),
        }
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        let k = self.find(name)?;
        Ok(self.interfaces[k].mesh(&self.model))
    }

    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        for b in bindings {
            let k = self.find(&b.interface)?;
            // The shell's side sends its motion and takes its peer's loads, with the peer's
            // coupling mass and stiffness at set-up: a sync-force driver.
            let sch = scheme::of(b.kind);
            let takes_loads = !sch.coordinator_solved() && !sch.follows(b.role);
            if !(takes_loads && SETUP.iter().all(|f| sch.setup_receives(b.role).contains(f))) {
                return Err(SolverError::interface(
                    &b.interface,
                    format!(
                        "the shell drives kinematic couplings only (got {} as {:?})",
                        b.kind.as_str(),
                        b.role
                    ),
                ));
            }
            let itf = &mut self.interfaces[k];
            itf.take_setup(&mut self.model, inbox)?;
        }
        self.finish_setup();
        for itf in self.interfaces.iter().filter(|i| i.active) {
            itf.send(&self.model, 0.0, out);
        }
        Ok(())
    }

    fn initial_report(&mut self) -> SolverResult<StepReport> {
        let m = &self.model;
        Ok(StepReport {
            kinetic_energy: m.kinetic_energy(),
            internal_energy: m.internal_energy(),
            momentum: m.momentum(),
            momentum_gross: m.momentum_gross(),
            ..Default::default()
        })
    }

    fn stable_dt(&self) -> f64 {
        step::stable_dt(&self.model)
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        let t_start = Instant::now();
        self.finish_setup();
        if !w.t0.is_finite() || !w.t1.is_finite() || w.t1 <= w.t0 {
            return Err(SolverError::Other(format!(
                "window {}: bad interval [{}, {}]",
                w.index, w.t0, w.t1
            )));
        }
        let m = &mut self.model;
        if m.steps == 0 {
            m.time = w.t0;
        } else if (m.time - w.t0).abs() > 1e-9 * (w.t1 - w.t0).max(w.t0.abs() * 1e-6) {
            return Err(SolverError::Other(format!(
                "window {} starts at {} but the shell is at {}",
                w.index, w.t0, m.time
            )));
        }
        m.time = w.t0;
        // Sub-steps: as few as the stable step allows, but not fewer than in the previous
        // window of the same length, so the step size (and with it the central-difference
        // weight of each window's constraint force) stays constant through a run.
        let span = w.t1 - w.t0;
        let (mut n, _) = step::plan(m, span)?;
        if (span - self.last_span).abs() <= 1e-12 * span {
            n = n.max(self.last_substeps);
        }
        self.last_span = span;
        self.last_substeps = n;
        let dt = span / n as f64;
        for itf in self.interfaces.iter_mut().filter(|i| i.active) {
            // Window 1 may run on the set-up force at t0 when nothing newer arrived.
            itf.take_loads(inbox, w.index <= 1)?;
            itf.mark_start(&self.model);
        }
        self.set_coupling_loads();
        step::run_steps(&mut self.model, w.t0, n, dt)?;
        self.model.time = w.t1;
        for itf in self.interfaces.iter().filter(|i| i.active) {
            itf.send(&self.model, w.t1 - w.t0, out);
        }
        self.history.record(&self.model);
        Ok(self.report(n, t_start.elapsed().as_secs_f64()))
    }

    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        output::write_vtu(&self.model, dir, "shell", window, t)?;
        if !self.history.rows.is_empty() {
            self.history.write_csv(&dir.join("reactions.csv"))?;
        }
        Ok(())
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        let m = &self.model;
        protocol::checkpoint::encode_state(&ShellState {
            x: m.x.clone(),
            v: m.v.clone(),
            w: m.w.clone(),
            q: m.q.clone(),
            mass: m.mass.clone(),
            inertia: m.inertia.clone(),
            f_c: m.f_c.clone(),
            m_c: m.m_c.clone(),
            reaction: m.reaction.clone(),
            stress: m.stress.clone(),
            plastic: m.plastic.clone(),
            res: m.res.clone(),
            fe: m.fe.clone(),
            pressure: m.pressure.clone(),
            clocks: (m.time, m.dt_prev, m.steps),
            work: [m.external_work, m.support_work, m.interface_work],
            impulses: [
                m.external_impulse,
                m.interface_impulse,
                m.load_impulse,
                m.interface_angular_impulse,
            ],
            added: [m.added_mass, m.added_inertia],
            interfaces: self
                .interfaces
                .iter()
                .map(|i| (i.force.clone(), i.moment.clone(), i.x_start.clone()))
                .collect(),
            history: self.history.rows.clone(),
            last: (self.last_span, self.last_substeps),
        })
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        use protocol::checkpoint::check_len;
        let s: ShellState = protocol::checkpoint::decode_state(bytes)?;
        let m = &mut self.model;
        check_len("nodes", s.x.len(), m.x.len())?;
        check_len("stresses", s.stress.len(), m.stress.len())?;
        check_len("interfaces", s.interfaces.len(), self.interfaces.len())?;
        for (itf, (f, mo, xs)) in self.interfaces.iter_mut().zip(s.interfaces) {
            check_len(
                &format!("interface {} force", itf.name),
                f.len(),
                itf.force.len(),
            )?;
            (itf.force, itf.moment, itf.x_start) = (f, mo, xs);
        }
        (m.x, m.v, m.w, m.q) = (s.x, s.v, s.w, s.q);
        (m.mass, m.inertia, m.f_c, m.m_c) = (s.mass, s.inertia, s.f_c, s.m_c);
        (m.reaction, m.stress, m.plastic) = (s.reaction, s.stress, s.plastic);
        (m.res, m.fe, m.pressure) = (s.res, s.fe, s.pressure);
        (m.time, m.dt_prev, m.steps) = s.clocks;
        [m.external_work, m.support_work, m.interface_work] = s.work;
        [
            m.external_impulse,
            m.interface_impulse,
            m.load_impulse,
            m.interface_angular_impulse,
        ] = s.impulses;
        [m.added_mass, m.added_inertia] = s.added;
        self.history.rows = s.history;
        (self.last_span, self.last_substeps) = s.last;
        // The contact forces are those of the positions.
        m.update_contact();
        Ok(())
    }
}

/// What the shell's `save_state` writes: the nodal motion, the element stresses and plastic
/// state, the coupling loads held over the window, clocks, accumulators, the reaction history
/// and the sub-step plan (everything `advance` reads that changes during a run).
#[derive(serde::Serialize, serde::Deserialize)]
struct ShellState {
    x: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
    w: Vec<[f64; 3]>,
    q: Vec<[f64; 4]>,
    mass: Vec<f64>,
    inertia: Vec<f64>,
    f_c: Vec<[f64; 3]>,
    m_c: Vec<[f64; 3]>,
    reaction: Vec<[f64; 6]>,
    stress: Vec<f64>,
    plastic: Vec<f64>,
    res: Vec<[f64; element::RES]>,
    fe: Vec<[[f64; 6]; 4]>,
    pressure: Vec<f64>,
    clocks: (f64, f64, u64),
    work: [f64; 3],
    impulses: [[f64; 3]; 4],
    added: [f64; 2],
    /// Per interface: force, moment, window-start positions.
    interfaces: Vec<InterfaceState>,
    history: Vec<Vec<f64>>,
    last: (f64, u64),
}

type InterfaceState = (Vec<f64>, Vec<f64>, Vec<[f64; 3]>);
