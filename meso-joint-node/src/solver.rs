//! The `mc-spg` model as a `protocol::Solver`: set-up (parameters → particles, supports,
//! mass scaling, coupling projection), the window loop with sub-cycling (coupling particles
//! moved along the driver's motion interpolated in time, eq. 31–32), and output (VTK, joint
//! force history CSV).

use crate::config::{Geometry, Params};
use crate::coupling::{self, Projection};
use crate::geometry;
use crate::model::{Kind, Model, ModelParams};
use protocol::{
    Binding, Inbox, InterfaceInfo, InterfaceMesh, NodeDescription, Outbox, Solver, SolverError,
    SolverResult, StepReport, Window,
};
use std::io::Write;
use std::path::Path;

/// Runtime state of the responder coupling.
#[derive(Debug, Clone, Default)]
struct CouplingRt {
    interface: String,
    particles: Vec<u32>,
    proj: Vec<Projection>,
    nodes: usize,
    quads: Vec<[u32; 4]>,
    n_ref: Vec<[f64; 3]>,
    x_prev: Vec<[f64; 3]>,
    n_prev: Vec<[f64; 3]>,
    x_next: Vec<[f64; 3]>,
    n_next: Vec<[f64; 3]>,
    xs: Vec<[f64; 3]>,
    ns: Vec<[f64; 3]>,
    f: Vec<[f64; 3]>,
    arm: Vec<[f64; 3]>,
    ready: bool,
}

/// One history row: time, reaction force per velocity-BC group, total coupling force.
pub type HistoryRow = (f64, Vec<[f64; 3]>, [f64; 3]);

/// The MC-SPG joint solver.
pub struct SpgSolver {
    pub params: Params,
    pub model: Model,
    /// Mass added by mass scaling (kg) and the target step (s).
    pub added_mass: f64,
    pub mass_scaling_dt: Option<f64>,
    coupling: Option<CouplingRt>,
    /// (time, reaction force per velocity-BC group, total coupling force).
    pub history: Vec<HistoryRow>,
}

fn to_vec3(v: &[f64]) -> Vec<[f64; 3]> {
    v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

impl SpgSolver {
    pub fn new(params: Params) -> SolverResult<Self> {
        let h = params.spacing;
        let set = match &params.geometry {
            Geometry::Block { origin, size } => geometry::block(*origin, *size, h),
            Geometry::BoltedPlates {
                thickness,
                width,
                length,
                overlap,
                bolt_radius,
                head_radius,
                head_height,
            } => geometry::bolted_plates(
                *thickness,
                *width,
                *length,
                *overlap,
                *bolt_radius,
                *head_radius,
                *head_height,
                h,
            ),
        };
        let mp = ModelParams {
            material: params.material(),
            density: params.density,
            spacing: h,
            support: params.kernel_support,
            eps_crit: params.eps_crit,
            e_crit: params.e_crit,
            reanchor_every: params.reanchor_every,
            smoothing: params.smoothing,
            cfl: params.cfl,
        };
        let mut model = Model::new(mp, set.x, set.vol, set.part, &set.rigid_parts)
            .map_err(|e| SolverError::config("kernel_support", e))?;
        for (k, bc) in params.velocity_bc.iter().enumerate() {
            let r = bc.region;
            let n = model.add_velocity_bc(&bc.name, bc.velocity, bc.ramp, |x| r.contains(x));
            if n == 0 {
                return Err(SolverError::config(
                    format!("velocity_bc[{k}].region"),
                    "holds no particle",
                ));
            }
        }
        let coupling = match &params.coupling {
            None => None,
            Some(c) => {
                let particles: Vec<u32> = (0..model.len())
                    .filter(|&i| {
                        model.kind[i] == Kind::Free
                            && c.regions.iter().any(|r| r.contains(&model.x0[i]))
                    })
                    .map(|i| i as u32)
                    .collect();
                if particles.is_empty() {
                    return Err(SolverError::config(
                        "coupling.regions",
                        "the coupling surface holds no particle",
                    ));
                }
                for &i in &particles {
                    model.kind[i as usize] = Kind::Coupled;
                }
                Some(CouplingRt {
                    interface: c.interface.clone(),
                    particles,
                    quads: c.cells.clone(),
                    ..Default::default()
                })
            }
        };
        let added_mass = match params.mass_scaling_dt {
            Some(dt) => model.mass_scale(dt),
            None => 0.0,
        };
        let physical: f64 = model.mass.iter().sum();
        tracing::info!(
            particles = model.len(),
            bonds = model.rows.cols.len() - model.len(),
            stable_dt = model.stable_dt(),
            added_mass,
            added_mass_fraction = added_mass / physical,
            "mc-spg set up"
        );
        model.initial_forces();
        Ok(SpgSolver {
            mass_scaling_dt: params.mass_scaling_dt,
            params,
            model,
            added_mass,
            coupling,
            history: Vec::new(),
        })
    }

    /// Physical mass of the particles (without mass scaling).
    pub fn physical_mass(&self) -> f64 {
        self.model.mass.iter().sum()
    }

    fn bc_reactions(&self) -> Vec<[f64; 3]> {
        self.model
            .bcs
            .iter()
            .map(|g| {
                let mut s = [0.0; 3];
                for &i in &g.particles {
                    for d in 0..3 {
                        s[d] -= self.model.f[i as usize][d];
                    }
                }
                s
            })
            .collect()
    }

    fn write_loads(c: &mut CouplingRt, model: &Model, out: &mut Outbox) {
        for (k, &i) in c.particles.iter().enumerate() {
            c.f[k] = model.f[i as usize];
            let (_, arm) = coupling::follow(&c.proj[k], &c.x_prev, &c.n_prev);
            c.arm[k] = arm;
        }
        let nodes = c.nodes;
        let mut force = vec![0.0; 3 * nodes];
        let mut moment = vec![0.0; 3 * nodes];
        coupling::constraint_loads(&c.proj, &c.f, &c.arm, &mut force, &mut moment);
        out.put(&c.interface, "force", 3, nodes)
            .copy_from_slice(&force);
        out.put(&c.interface, "moment", 3, nodes)
            .copy_from_slice(&moment);
    }

    #[allow(clippy::type_complexity)]
    fn read_motion(c: &CouplingRt, inbox: &Inbox) -> SolverResult<(Vec<[f64; 3]>, Vec<[f64; 3]>)> {
        let n = c.nodes;
        let x = to_vec3(inbox.require(&c.interface, "position", 3 * n)?);
        let normals = if let Some(f) = inbox.get(&c.interface, "normal") {
            if f.values.len() != 3 * n {
                return Err(SolverError::interface(
                    &c.interface,
                    format!("'normal' has {} values, expected {}", f.values.len(), 3 * n),
                ));
            }
            to_vec3(&f.values)
        } else if let Some(f) = inbox.get(&c.interface, "rotation") {
            if f.values.len() != 3 * n {
                return Err(SolverError::interface(
                    &c.interface,
                    format!(
                        "'rotation' has {} values, expected {}",
                        f.values.len(),
                        3 * n
                    ),
                ));
            }
            let r = to_vec3(&f.values);
            (0..n)
                .map(|k| coupling::rotate(&r[k], &c.n_ref[k]))
                .collect()
        } else {
            coupling::node_normals(&x, &c.quads)
        };
        if x.iter().flatten().any(|v| !v.is_finite()) {
            return Err(SolverError::interface(
                &c.interface,
                "non-finite 'position'",
            ));
        }
        Ok((x, normals))
    }
}

impl Solver for SpgSolver {
    fn describe(&self) -> NodeDescription {
        let interfaces = self
            .coupling
            .iter()
            .map(|c| InterfaceInfo {
                name: c.interface.clone(),
                points: c.nodes,
                provides: vec![
                    "mass".into(),
                    "stiffness".into(),
                    "force".into(),
                    "moment".into(),
                ],
                accepts: vec![
                    "position".into(),
                    "velocity".into(),
                    "normal".into(),
                    "rotation".into(),
                ],
            })
            .collect();
        NodeDescription {
            model: "mc-spg".into(),
            interfaces,
            units: "SI (m, kg, s, N, Pa)".into(),
        }
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        match &self.coupling {
            Some(c) if c.interface == name => Ok(InterfaceMesh::points(
                c.particles
                    .iter()
                    .map(|&i| self.model.x[i as usize])
                    .collect(),
            )),
            _ => Err(SolverError::interface(name, "no such interface")),
        }
    }

    /// The set-up inbox carries the driver's interface mesh in its layout: `position` (3 per
    /// shell node), optionally `normal` (3) and `cells` (4 node indices per quad, as f64),
    /// else the cells come from `coupling.cells`. Writes `mass`, `stiffness`, `force`,
    /// `moment` per shell node.
    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        let _ = bindings;
        let Some(c) = self.coupling.as_mut() else {
            return Ok(());
        };
        let pos = inbox.get(&c.interface, "position").ok_or_else(|| {
            SolverError::interface(&c.interface, "no 'position' of the driver mesh at set-up")
        })?;
        if pos.values.len() % 3 != 0 || pos.values.is_empty() {
            return Err(SolverError::interface(
                &c.interface,
                "'position' must hold 3 values per node",
            ));
        }
        c.nodes = pos.values.len() / 3;
        let x = to_vec3(&pos.values);
        if let Some(cells) = inbox.get(&c.interface, "cells") {
            if cells.values.len() % 4 != 0 {
                return Err(SolverError::interface(
                    &c.interface,
                    "'cells' must hold 4 node indices per quad",
                ));
            }
            c.quads = cells
                .values
                .chunks_exact(4)
                .map(|q| std::array::from_fn(|k| q[k] as u32))
                .collect();
        }
        if c.quads.is_empty() {
            return Err(SolverError::config(
                "coupling.cells",
                "no quad cells for the driver mesh (params or 'cells' field)",
            ));
        }
        if c.quads.iter().flatten().any(|&k| k as usize >= c.nodes) {
            return Err(SolverError::interface(
                &c.interface,
                "a cell refers to a node beyond 'position'",
            ));
        }
        let normals = match inbox.get(&c.interface, "normal") {
            Some(f) if f.values.len() == 3 * c.nodes => to_vec3(&f.values)
                .into_iter()
                .map(|n| {
                    let l = crate::shape::norm(&n);
                    n.map(|v| v / l)
                })
                .collect(),
            _ => coupling::node_normals(&x, &c.quads),
        };
        let px: Vec<[f64; 3]> = c
            .particles
            .iter()
            .map(|&i| self.model.x0[i as usize])
            .collect();
        c.proj = coupling::project(&px, &x, &normals, &c.quads);
        c.n_ref = normals.clone();
        c.x_prev = x.clone();
        c.n_prev = normals.clone();
        c.xs = x;
        c.ns = normals;
        c.f = vec![[0.0; 3]; c.particles.len()];
        c.arm = vec![[0.0; 3]; c.particles.len()];
        c.ready = true;
        // Lumped mass and a stiffness bound k = m (2/Δt)² per particle, mapped with Wᵀ.
        let dt = self.model.stable_dt();
        let mut mass = vec![0.0; c.nodes];
        let mut stiff = vec![0.0; c.nodes];
        for (k, &i) in c.particles.iter().enumerate() {
            let m = self.model.mh[i as usize];
            for a in 0..4 {
                let j = c.proj[k].nodes[a] as usize;
                mass[j] += c.proj[k].weights[a] * m;
                stiff[j] += c.proj[k].weights[a] * m * (2.0 / dt).powi(2);
            }
        }
        out.put(&c.interface, "mass", 1, c.nodes)
            .copy_from_slice(&mass);
        out.put(&c.interface, "stiffness", 1, c.nodes)
            .copy_from_slice(&stiff);
        SpgSolver::write_loads(c, &self.model, out);
        Ok(())
    }

    fn stable_dt(&self) -> f64 {
        self.model.stable_dt()
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        let start = std::time::Instant::now();
        let span = w.t1 - w.t0;
        if !(span > 0.0) {
            return Err(SolverError::Other(format!(
                "empty window [{}, {}]",
                w.t0, w.t1
            )));
        }
        if let Some(c) = self.coupling.as_mut() {
            if !c.ready {
                return Err(SolverError::interface(
                    &c.interface,
                    "advance before set-up",
                ));
            }
            let (x, n) = SpgSolver::read_motion(c, inbox)?;
            c.x_next = x;
            c.n_next = n;
        }
        let dt_stable = self.model.stable_dt();
        let nsub = ((span / dt_stable).ceil() as u64).max(1);
        let dt = span / nsub as f64;
        for k in 0..nsub {
            if let Some(c) = self.coupling.as_mut() {
                // Driver motion interpolated in time (eq. 31–32): positions linearly, normals
                // linearly then normalised.
                let s = (k + 1) as f64 / nsub as f64;
                for j in 0..c.nodes {
                    for d in 0..3 {
                        c.xs[j][d] = (1.0 - s) * c.x_prev[j][d] + s * c.x_next[j][d];
                        c.ns[j][d] = (1.0 - s) * c.n_prev[j][d] + s * c.n_next[j][d];
                    }
                }
                for (q, &i) in c.particles.iter().enumerate() {
                    let (target, _) = coupling::follow(&c.proj[q], &c.xs, &c.ns);
                    let x = self.model.x[i as usize];
                    self.model.presc[i as usize] = std::array::from_fn(|d| (target[d] - x[d]) / dt);
                }
            }
            self.model.velocity_phase(dt);
            self.model
                .position_phase(dt)
                .map_err(|e| SolverError::Diverged {
                    time: self.model.time,
                    reason: e,
                })?;
        }
        if let Some(c) = self.coupling.as_mut() {
            std::mem::swap(&mut c.x_prev, &mut c.x_next);
            std::mem::swap(&mut c.n_prev, &mut c.n_next);
            SpgSolver::write_loads(c, &self.model, out);
        }
        let reactions = self.bc_reactions();
        let mut ctot = [0.0; 3];
        if let Some(c) = &self.coupling {
            for &i in &c.particles {
                for d in 0..3 {
                    ctot[d] += self.model.f[i as usize][d];
                }
            }
        }
        let every = self.params.history_every.max(1);
        if w.index.is_multiple_of(every) {
            self.history.push((w.t1, reactions.clone(), ctot));
        }
        let ke = self.model.kinetic_energy();
        let ie = self.model.internal_energy();
        let mut scalars = vec![
            ("added_mass".to_string(), self.added_mass),
            (
                "mass_scaling_dt".to_string(),
                self.mass_scaling_dt.unwrap_or(0.0),
            ),
            (
                "kinetic_over_internal".to_string(),
                if ie > 0.0 { ke / ie } else { 0.0 },
            ),
            ("broken_bonds".to_string(), self.model.broken_bonds as f64),
            ("max_eq_plastic_strain".to_string(), self.model.max_eps),
        ];
        for (g, r) in self.model.bcs.iter().zip(&reactions) {
            scalars.push((format!("force_{}_x", g.name), r[0]));
        }
        Ok(StepReport {
            kinetic_energy: ke,
            internal_energy: ie,
            external_work: self.model.bc_work,
            interface_work: self.model.coupling_work,
            momentum: self.model.momentum(),
            external_impulse: self.model.bc_impulse,
            interface_impulse: self.model.coupling_impulse,
            substeps: nsub,
            wall_s: start.elapsed().as_secs_f64(),
            coupling_wait_s: 0.0,
            idle_s: 0.0,
            scalars,
            // No prescribed loads (only supports and the coupling): other fields default.
            ..Default::default()
        })
    }

    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        std::fs::create_dir_all(dir)?;
        crate::output::write_vtu(&self.model, &dir.join(format!("joint_{window:06}.vtu")), t)?;
        let mut csv = std::fs::File::create(dir.join("joint_force.csv"))?;
        write!(csv, "time")?;
        for g in &self.model.bcs {
            write!(csv, ",{0}_fx,{0}_fy,{0}_fz", g.name)?;
        }
        writeln!(csv, ",coupling_fx,coupling_fy,coupling_fz")?;
        for (t, r, c) in &self.history {
            write!(csv, "{t:e}")?;
            for f in r {
                write!(csv, ",{:e},{:e},{:e}", f[0], f[1], f[2])?;
            }
            writeln!(csv, ",{:e},{:e},{:e}", c[0], c[1], c[2])?;
        }
        Ok(())
    }
}
