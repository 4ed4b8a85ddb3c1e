//! The `mc-spg` model as a `protocol::Solver`: set-up (parameters → particles, supports,
//! mass scaling, coupling particles), the window loop with sub-cycling (coupling particles
//! moved along the driver's motion interpolated in time, seed 004 eq. 31–32), the constraint
//! loads at every synchronisation time (eq. 33), and output (VTK, joint force history CSV).
//!
//! **Coupling layout.** The interface is one point per coupling particle (its reference
//! position). The participant runtime builds `W` from the driver's shell mesh (bilinear shape
//! functions of the closest quad at each particle's projection, eq. 29 — once, on the
//! reference meshes) and hands this node, per particle, the interpolated shell motion
//! `position = W x_d` (the foot point on the mid-surface), `normal = W n_d`, `rotation`,
//! `velocity`; the loads it returns per particle are mapped back with `Wᵀ`, which is eq. 33:
//! `F_J = Σ_I N_J(ξ_I) f_I`, `M_J = Σ_I N_J(ξ_I) (a_I × f_I)` with `a_I` the lever arm from
//! the mid-surface to the particle. The reference offset `a_I⁰ = X_I − W X_d` is taken at
//! the first window from `position − displacement` (or `position − Δt·velocity`, the window's
//! mean velocity); its normal part `d_I = a_I⁰·n̄⁰` follows the current normal,
//! `x_I = W x_d + d_I n̄(t)` (eq. 31), the rest (non-zero only for particles outside the
//! shell's footprint) is carried along unrotated.

use crate::config::{Geometry, Params};
use crate::geometry;
use crate::model::{Kind, Model, ModelParams, RigidBody};
use crate::shape::{M3, Rows};
use crate::solid::Solid;
use mechanics::tensor::{self, Vector3, vec3};
use protocol::scheme::kinematic::{self, Follow};
use protocol::{
    Binding, Inbox, InterfaceInfo, InterfaceMesh, NodeDescription, Outbox, Solver, SolverError,
    SolverResult, StepReport, Window,
};
use std::path::Path;

/// Runtime state of the responder coupling (one entry per coupling particle).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
struct CouplingRt {
    interface: String,
    particles: Vec<u32>,
    /// Index of the region each particle belongs to, and the region names.
    region: Vec<u32>,
    region_names: Vec<String>,
    /// Reference offset along the normal (eq. 31) and the in-plane rest of it.
    depth: Vec<f64>,
    tang: Vec<[f64; 3]>,
    anchored: bool,
    /// Target positions at the last and the next synchronisation time, interpolated
    /// linearly in time through the window (eq. 31–32).
    follow: Follow,
    /// Lever arm `d n̄ + rest` at the last synchronisation time.
    arm: Vec<[f64; 3]>,
    ready: bool,
}

/// One history row: time, reaction force per velocity-BC group, force per coupling region.
pub type HistoryRow = (f64, Vec<[f64; 3]>, Vec<[f64; 3]>);

/// The MC-SPG joint solver.
pub struct SpgSolver {
    pub params: Params,
    pub model: Model,
    /// Mass added by mass scaling (kg) and the target step (s).
    pub added_mass: f64,
    pub mass_scaling_dt: Option<f64>,
    coupling: Option<CouplingRt>,
    /// (time, reaction force per velocity-BC group, force per coupling region).
    pub history: Vec<HistoryRow>,
    /// The joint report: one entry per joint (placement).
    pub joints: Vec<JointTrack>,
    /// Each joint's two plates, where it has a fastener (`bolted-plates`): what the
    /// fastener's force is summed over.
    plates: Vec<Option<Plates>>,
}

/// The two plates of one bolted joint: their particles, and their element nodes that are not
/// particles. The plates touch nothing but the fastener (parts never bond and only the
/// fastener has a bearing contact) and their coupled rings, so the internal forces summed
/// over a plate — its particles' and its own element nodes' — are the force the fastener
/// exerts on it (whatever the plate's inertia, which a sum over the coupled ring carries).
#[derive(Debug, Clone, Default)]
struct Plates {
    particles: [Vec<u32>; 2],
    nodes: [Vec<u32>; 2],
}

/// A joint has failed when its force, after its peak, falls below this fraction of the peak
/// while bonds of the joint are broken...
pub const FAILURE_FRACTION: f64 = 0.1;

/// ... unless it carries this fraction of its peak again later: then it had only been
/// unloaded (a crash tube's folds unload a joint and load it again), and the failure is
/// taken back.
pub const RECOVERY_FRACTION: f64 = 0.5;

/// One joint of the report (a placement, or the node's one joint without placements): its
/// force's peak and when, and when and how it failed. The joint's force is the force its
/// fastener carries (`SpgSolver::fastener_forces`); for a part without a fastener (a block)
/// the largest magnitude of its coupling regions' forces (each region one side of it), or of
/// the velocity-BC reactions without a coupling.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JointTrack {
    pub name: String,
    /// The coupling regions (indices of the region forces) of this joint.
    pub regions: Vec<usize>,
    /// Peak force magnitude (N) and its time (s).
    pub peak: f64,
    pub peak_time: f64,
    pub failure: Option<JointFailure>,
}

impl JointTrack {
    /// One window's force `force` at time `t`: the peak, and the failure (with the broken
    /// bonds `broken` counts then, as (within a plate, fastener–plate)) or its recovery.
    pub fn observe(&mut self, t: f64, force: f64, broken: impl FnOnce() -> (u64, u64)) {
        if force > self.peak {
            self.peak = force;
            self.peak_time = t;
        }
        match self.failure {
            Some(_) if force > RECOVERY_FRACTION * self.peak => self.failure = None,
            None if force < FAILURE_FRACTION * self.peak => {
                let (material_bonds, interface_bonds) = broken();
                if material_bonds + interface_bonds > 0 {
                    self.failure = Some(JointFailure {
                        time: t,
                        material_bonds,
                        interface_bonds,
                    });
                }
            }
            _ => {}
        }
    }
}

/// When a joint failed and which of its bonds were broken then.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JointFailure {
    pub time: f64,
    /// Broken bonds between particles of one plate (the plate tore) and between the
    /// fastener and a plate (the fastener came loose), each bond counted from both ends.
    pub material_bonds: u64,
    pub interface_bonds: u64,
}

impl JointFailure {
    /// `interfacial` when the fastener–plate bonds broke at least as often as the plates'
    /// own (the fastener came loose at its interface), else `pull-out` (the plate material
    /// around the fastener tore: the fastener pulls out of the sheet); `rupture` for a part
    /// without a fastener (a block: the material itself parted).
    pub fn mode(&self, fastened: bool) -> &'static str {
        if !fastened {
            "rupture"
        } else if self.interface_bonds > 0 && self.interface_bonds >= self.material_bonds {
            "interfacial"
        } else {
            "pull-out"
        }
    }
}

/// Broken bonds of placement `k` (parts `3k`, `3k + 1`, `3k + 2`): (within a plate, between
/// the fastener and a plate), each counted from both ends.
fn broken_bonds_of(m: &Model, k: usize) -> (u64, u64) {
    m.broken_by_part
        .iter()
        .skip(3 * k)
        .take(3)
        .fold((0, 0), |(a, b), n| (a + n[0], b + n[1]))
}

fn unit(a: Vector3<f64>) -> Vector3<f64> {
    let l = a.norm();
    if l > 0.0 { a / l } else { a }
}

/// A per-particle 3-vector field of the inbox, if present (checked length, finite values).
fn field3<'a>(
    inbox: &'a Inbox,
    itf: &str,
    name: &str,
    n: usize,
) -> SolverResult<Option<&'a [f64]>> {
    match inbox.get(itf, name) {
        None => Ok(None),
        Some(_) => {
            let v = inbox.require(itf, name, 3 * n)?;
            if let Some(p) = v.iter().position(|x| !x.is_finite()) {
                return Err(SolverError::interface(
                    itf,
                    format!("'{name}' value {p} is not finite"),
                ));
            }
            Ok(Some(v))
        }
    }
}

fn at(v: &[f64], k: usize) -> [f64; 3] {
    [v[3 * k], v[3 * k + 1], v[3 * k + 2]]
}

impl SpgSolver {
    pub fn new(params: Params) -> SolverResult<Self> {
        let h = params.spacing;
        // One particle set per placement (default: one, global frame), in its local frame
        // (`local`, where the coupling regions are evaluated) and placed (`set`).
        let placements: Vec<Option<&crate::config::Placement>> = if params.placements.is_empty() {
            vec![None]
        } else {
            params.placements.iter().map(Some).collect()
        };
        let mut set = geometry::ParticleSet::default();
        let mut local: Vec<[f64; 3]> = Vec::new();
        let mut instance: Vec<u32> = Vec::new();
        // With solid elements: their nodes (placed, and in the placement's frame), which
        // particle each is, the elements and their parts.
        let mut mesh = geometry::SolidSplit::default();
        let mut kernel_vol: Vec<f64> = Vec::new();
        let mut node_local: Vec<[f64; 3]> = Vec::new();
        for (k, pl) in placements.iter().enumerate() {
            let one = match params.geometry_for(*pl) {
                Geometry::Block { origin, size } => geometry::block(origin, size, h),
                Geometry::BoltedPlates {
                    thickness,
                    width,
                    length,
                    overlap,
                    bolt_radius,
                    head_radius,
                    head_height,
                } => geometry::bolted_plates(
                    thickness,
                    width,
                    length,
                    overlap,
                    bolt_radius,
                    head_radius,
                    head_height,
                    h,
                ),
            };
            let one = match &params.solid {
                None => one,
                Some(sp) => {
                    let split =
                        geometry::split_solid(&one, |x| sp.core.iter().any(|r| r.contains(x)));
                    let (p0, n0) = (set.x.len() as u32, mesh.nodes.len() as u32);
                    let frame = pl.and_then(|p| p.frame());
                    for (q, x) in split.nodes.iter().enumerate() {
                        node_local.push(*x);
                        mesh.nodes.push(match (pl, frame) {
                            (Some(p), Some(f)) => p.apply(&f, x),
                            _ => *x,
                        });
                        mesh.node_part.push(split.node_part[q] + 3 * k as u32);
                        let i = split.node_particle[q];
                        mesh.node_particle
                            .push(if i == crate::solid::NONE { i } else { i + p0 });
                    }
                    mesh.elements
                        .extend(split.elements.iter().map(|e| e.map(|n| n + n0)));
                    mesh.element_part
                        .extend(split.element_part.iter().map(|p| p + 3 * k as u32));
                    kernel_vol.extend(&split.kernel_vol);
                    split.particles
                }
            };
            // Parts of different placements never bond (3 parts per copy).
            let offset = 3 * k as u32;
            let frame = pl.and_then(|p| p.frame());
            for (q, x) in one.x.iter().enumerate() {
                local.push(*x);
                instance.push(k as u32);
                set.x.push(match (pl, frame) {
                    (Some(p), Some(f)) => p.apply(&f, x),
                    _ => *x,
                });
                set.vol.push(one.vol[q]);
                set.part.push(one.part[q] + offset);
            }
            set.rigid_parts
                .extend(one.rigid_parts.iter().map(|r| r + offset));
        }
        let mp = ModelParams {
            material: params.material(),
            blast: params.blast_solid()?,
            density: params.density,
            spacing: h,
            support: params.kernel_support,
            eps_crit: params.eps_crit,
            e_crit: params.e_crit,
            reanchor_every: params.reanchor_every,
            smoothing: params.smoothing,
            cfl: params.cfl,
            bearing: match params.fastener {
                crate::config::Fastener::Bonded => None,
                crate::config::Fastener::Bearing => Some(
                    params
                        .contact_stiffness
                        .unwrap_or(params.young * params.spacing),
                ),
            },
        };
        let mut solid_node_part: Vec<u32> = Vec::new();
        let solid = match &params.solid {
            None => None,
            Some(sp) => {
                if mesh.elements.is_empty() {
                    return Err(SolverError::config(
                        "solid.core",
                        "holds every cell of the geometry: no element is left outside it",
                    ));
                }
                if set.part.iter().all(|p| set.rigid_parts.contains(p)) {
                    return Err(SolverError::config(
                        "solid.core",
                        "holds no cell of the geometry: no SPG particle is left",
                    ));
                }
                solid_node_part = std::mem::take(&mut mesh.node_part);
                let hp = mechanics::hex8::HexParams {
                    material: params.material(),
                    density: params.density,
                    hourglass: sp.hourglass,
                };
                Some(
                    Solid::new(
                        mesh.nodes,
                        mesh.node_particle,
                        mesh.elements,
                        mesh.element_part,
                        hp,
                    )
                    .map_err(|e| SolverError::config("solid", e))?,
                )
            }
        };
        let kernel_vol = solid.as_ref().map(|_| kernel_vol);
        let mut model = Model::with_solid(
            mp,
            set.x,
            set.vol,
            set.part,
            &set.rigid_parts,
            solid,
            kernel_vol,
        )
        .map_err(|e| SolverError::config("kernel_support", e))?;
        model.separation_weight = params.separation_weight;
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
        // The placement of each reported coupling region (for the joint report).
        let mut region_placement: Vec<usize> = Vec::new();
        let coupling = match &params.coupling {
            None => None,
            Some(c) => {
                // Reported region names: `<region>` or `<placement>_<region>`; regions with
                // the same name add up (e.g. the four sides of a ring).
                let mut region_names: Vec<String> = Vec::new();
                let mut particles = Vec::new();
                let mut region = Vec::new();
                for i in 0..model.len() {
                    if model.kind[i] != Kind::Free {
                        continue;
                    }
                    if let Some(r) = c.regions.iter().position(|r| r.contains(&local[i])) {
                        let base = &c.regions[r].name;
                        let name = match placements[instance[i] as usize] {
                            Some(p) if !base.is_empty() => format!("{}_{base}", p.name),
                            _ => base.clone(),
                        };
                        let k = match region_names.iter().position(|n| *n == name) {
                            Some(k) => k,
                            None => {
                                region_names.push(name);
                                region_placement.push(instance[i] as usize);
                                region_names.len() - 1
                            }
                        };
                        particles.push(i as u32);
                        region.push(k as u32);
                    }
                }
                if particles.is_empty() {
                    return Err(SolverError::config(
                        "coupling.regions",
                        "the coupling surface holds no particle",
                    ));
                }
                if let Some(sd) = &model.solid
                    && let Some(k) = sd
                        .own_nodes()
                        .find(|&k| c.regions.iter().any(|r| r.contains(&node_local[k])))
                {
                    return Err(SolverError::config(
                        "coupling.regions",
                        format!(
                            "hold element nodes (one at {:?}): a kinematic coupling drives SPG particles only, so extend solid.core over the coupling regions",
                            sd.x0[k]
                        ),
                    ));
                }
                for &i in &particles {
                    model.kind[i as usize] = Kind::Coupled;
                }
                (model.coupled_p, model.coupled_ke) = model.coupled_sums();
                let n = particles.len();
                let mut follow = Follow::new(kinematic::Path::Linear, n, 3);
                for (q, &i) in particles.iter().enumerate() {
                    follow.set_start(q, &model.x0[i as usize]);
                }
                Some(CouplingRt {
                    interface: c.interface.clone(),
                    particles,
                    region,
                    region_names,
                    depth: vec![0.0; n],
                    tang: vec![[0.0; 3]; n],
                    anchored: false,
                    follow,
                    arm: vec![[0.0; 3]; n],
                    ready: false,
                })
            }
        };
        let added_mass = match params.mass_scaling_dt {
            Some(dt) => model.mass_scale(dt),
            None => 0.0,
        };
        let physical: f64 = model.mass.iter().sum::<f64>()
            + model
                .solid
                .as_ref()
                .map_or(0.0, |sd| sd.part.physical_mass());
        tracing::info!(
            particles = model.len(),
            bonds = model.rows.cols.len() - model.len(),
            stable_dt = model.stable_dt(),
            added_mass,
            added_mass_fraction = added_mass / physical,
            "mc-spg set up"
        );
        model.initial_forces();
        let names = coupling.as_ref().map_or(&[][..], |c| &c.region_names[..]);
        let joints = placements
            .iter()
            .enumerate()
            .map(|(k, pl)| JointTrack {
                name: pl.map_or_else(|| "joint".to_string(), |p| p.name.clone()),
                regions: (0..names.len())
                    .filter(|&r| region_placement[r] == k && !names[r].is_empty())
                    .collect(),
                peak: 0.0,
                peak_time: 0.0,
                failure: None,
            })
            .collect();
        // Plates A and B of placement k are parts 3k and 3k + 1 (the fastener 3k + 2).
        let mut plates: Vec<Option<Plates>> = placements
            .iter()
            .map(|pl| {
                matches!(params.geometry_for(*pl), Geometry::BoltedPlates { .. })
                    .then(Plates::default)
            })
            .collect();
        for (i, &part) in model.part.iter().enumerate() {
            if let Some(Some(p)) = plates.get_mut((part / 3) as usize)
                && part % 3 < 2
            {
                p.particles[(part % 3) as usize].push(i as u32);
            }
        }
        if let Some(sd) = &model.solid {
            for k in sd.own_nodes() {
                let part = solid_node_part[k];
                if let Some(Some(p)) = plates.get_mut((part / 3) as usize)
                    && part % 3 < 2
                {
                    p.nodes[(part % 3) as usize].push(k as u32);
                }
            }
        }
        Ok(SpgSolver {
            mass_scaling_dt: params.mass_scaling_dt,
            params,
            model,
            added_mass,
            coupling,
            history: Vec::new(),
            joints,
            plates,
        })
    }

    /// The joint report at time `t` from this window's fastener, reaction and region forces: each
    /// joint's peak, and its failure once its force has fallen below [`FAILURE_FRACTION`] of
    /// the peak with some of its bonds broken, unless it rises past [`RECOVERY_FRACTION`] of
    /// the peak again ([`JointTrack::observe`]).
    fn track_joints(
        &mut self,
        t: f64,
        reactions: &[[f64; 3]],
        regions: &[[f64; 3]],
        fasteners: &[Option<[f64; 3]>],
    ) {
        let norm = |f: &[f64; 3]| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
        for (k, j) in self.joints.iter_mut().enumerate() {
            let force = if let Some(Some(f)) = fasteners.get(k) {
                norm(f)
            } else if self.coupling.is_some() {
                j.regions
                    .iter()
                    .map(|&r| norm(&regions[r]))
                    .fold(0.0, f64::max)
            } else {
                reactions.iter().map(norm).fold(0.0, f64::max)
            };
            j.observe(t, force, || broken_bonds_of(&self.model, k));
        }
    }

    /// The joint report's columns.
    pub const JOINT_REPORT: [&str; 7] = [
        "joint",
        "peak_force_N",
        "peak_time_s",
        "failure_time_s",
        "failure_mode",
        "broken_bonds_material",
        "broken_bonds_interface",
    ];

    /// The joint report, one row per joint ([`Self::JOINT_REPORT`]): numbers as the shortest
    /// decimal that reads back exactly; a joint that has not failed has no failure time, mode
    /// `none` and its broken bonds so far.
    pub fn joint_report(&self) -> Vec<Vec<String>> {
        self.joints
            .iter()
            .enumerate()
            .map(|(k, j)| {
                let placement = self.params.placements.get(k);
                let fastened =
                    !matches!(self.params.geometry_for(placement), Geometry::Block { .. });
                let (time, mode, material, interface) = match &j.failure {
                    Some(f) => (
                        format!("{:e}", f.time),
                        f.mode(fastened),
                        f.material_bonds,
                        f.interface_bonds,
                    ),
                    None => {
                        let (m, i) = broken_bonds_of(&self.model, k);
                        (String::new(), "none", m, i)
                    }
                };
                vec![
                    j.name.clone(),
                    format!("{:e}", j.peak),
                    format!("{:e}", j.peak_time),
                    time,
                    mode.to_string(),
                    material.to_string(),
                    interface.to_string(),
                ]
            })
            .collect()
    }

    /// Physical mass of the particles (without mass scaling).
    pub fn physical_mass(&self) -> f64 {
        self.model.mass.iter().sum::<f64>()
            + self
                .model
                .solid
                .as_ref()
                .map_or(0.0, |sd| sd.part.physical_mass())
    }

    /// Number of coupling particles (the interface's points).
    pub fn coupling_points(&self) -> usize {
        self.coupling.as_ref().map_or(0, |c| c.particles.len())
    }

    /// Support reaction of each velocity-BC group at the current time: the force the support
    /// exerts on its particles, `Σ (m̂ a − f)`, with `a` the prescribed acceleration (nonzero
    /// while the velocity ramps up) — the same definition as the shell's support reaction.
    fn bc_reactions(&self) -> Vec<[f64; 3]> {
        let t = self.model.time;
        self.model
            .bcs
            .iter()
            .map(|g| {
                let a = if g.ramp > 0.0 && t < g.ramp {
                    g.velocity.map(|v| v / g.ramp)
                } else {
                    [0.0; 3]
                };
                let mut s = [0.0; 3];
                for &i in &g.particles {
                    let i = i as usize;
                    for d in 0..3 {
                        s[d] += self.model.mh[i] * a[d] - self.model.f[i][d];
                    }
                }
                if let Some(sd) = &self.model.solid {
                    for &k in &g.nodes {
                        let k = k as usize;
                        for d in 0..3 {
                            s[d] += sd.mass[k] * a[d] - sd.f[k][d];
                        }
                    }
                }
                s
            })
            .collect()
    }

    /// Mean displacement of each velocity-BC group.
    fn bc_displacements(&self) -> Vec<[f64; 3]> {
        self.model
            .bcs
            .iter()
            .map(|g| {
                let mut s = [0.0; 3];
                for &i in &g.particles {
                    for d in 0..3 {
                        s[d] += self.model.x[i as usize][d] - self.model.x0[i as usize][d];
                    }
                }
                if let Some(sd) = &self.model.solid {
                    for &k in &g.nodes {
                        for d in 0..3 {
                            s[d] += sd.x[k as usize][d] - sd.x0[k as usize][d];
                        }
                    }
                }
                s.map(|v| v / (g.particles.len() + g.nodes.len()).max(1) as f64)
            })
            .collect()
    }

    /// Force the body exerts on the coupling particles, summed per region (the joint force
    /// carried through each coupling surface; eq. 33 before the mapping).
    fn region_forces(&self) -> Vec<[f64; 3]> {
        let Some(c) = &self.coupling else {
            return Vec::new();
        };
        let mut s = vec![[0.0; 3]; c.region_names.len()];
        for (k, &i) in c.particles.iter().enumerate() {
            for d in 0..3 {
                s[c.region[k] as usize][d] += self.model.f[i as usize][d];
            }
        }
        s
    }

    /// The force each joint's fastener carries (None for a joint without one): the force
    /// it exerts on plate B less the force it exerts on plate A, halved — the force it
    /// passes from A to B, its own inertia split between the two — each the plate's internal
    /// forces summed ([`Plates`]).
    fn fastener_forces(&self) -> Vec<Option<[f64; 3]>> {
        let f = &self.model.f;
        let sd = self.model.solid.as_ref();
        self.plates
            .iter()
            .map(|p| {
                let p = p.as_ref()?;
                let mut side = [[0.0f64; 3]; 2];
                for (s, sum) in side.iter_mut().enumerate() {
                    for &i in &p.particles[s] {
                        for d in 0..3 {
                            sum[d] += f[i as usize][d];
                        }
                    }
                    if let Some(sd) = sd {
                        for &k in &p.nodes[s] {
                            for d in 0..3 {
                                sum[d] += sd.f[k as usize][d];
                            }
                        }
                    }
                }
                Some(std::array::from_fn(|d| 0.5 * (side[1][d] - side[0][d])))
            })
            .collect()
    }

    /// The constraint loads per coupling particle (eq. 33 before the `Wᵀ` mapping): the
    /// internal force `f_I` and the moment `a_I × f_I` about the mid-surface.
    fn write_loads(c: &CouplingRt, model: &Model, out: &mut Outbox) {
        let n = c.particles.len();
        {
            let f = out.put(&c.interface, "force", 3, n);
            for (k, &i) in c.particles.iter().enumerate() {
                f[3 * k..3 * k + 3].copy_from_slice(&model.f[i as usize]);
            }
        }
        let m = out.put(&c.interface, "moment", 3, n);
        for (k, &i) in c.particles.iter().enumerate() {
            let moment = vec3(&c.arm[k]).cross(&vec3(&model.f[i as usize]));
            m[3 * k..3 * k + 3].copy_from_slice(moment.as_slice());
        }
    }

    /// The driver's motion at the end of the window, per particle → target positions and
    /// lever arms (eq. 31). `span` is the window length (for the first-window reference).
    fn read_motion(
        c: &mut CouplingRt,
        model: &Model,
        inbox: &Inbox,
        span: f64,
    ) -> SolverResult<()> {
        let n = c.particles.len();
        let itf = c.interface.clone();
        let pos = field3(inbox, &itf, "position", n)?.ok_or_else(|| {
            SolverError::interface(&itf, "no 'position' received from the driver")
        })?;
        let normal = field3(inbox, &itf, "normal", n)?;
        let rotation = field3(inbox, &itf, "rotation", n)?;
        if !c.anchored {
            // Reference foot points W X_d: position − displacement, or position minus the
            // window's motion (the driver's velocity is its mean over the window).
            let disp = field3(inbox, &itf, "displacement", n)?;
            let vel = field3(inbox, &itf, "velocity", n)?;
            for (k, &i) in c.particles.iter().enumerate() {
                let p = at(pos, k);
                let foot0: [f64; 3] = match (disp, vel) {
                    (Some(u), _) => std::array::from_fn(|d| p[d] - u[3 * k + d]),
                    (None, Some(v)) => std::array::from_fn(|d| p[d] - span * v[3 * k + d]),
                    (None, None) => {
                        return Err(SolverError::interface(
                            &itf,
                            "the first window needs 'displacement' or 'velocity' to find the reference mid-surface",
                        ));
                    }
                };
                let x0 = model.x0[i as usize];
                let a0 = vec3(&x0) - vec3(&foot0);
                match normal {
                    Some(nv) => {
                        // Reference normal: the current one rotated back (exact for a
                        // uniform rotation; at the first window the rotation is ~0 anyway).
                        let nt = unit(at(nv, k).into());
                        let n0 = match rotation {
                            Some(r) => unit(tensor::rotate(&-vec3(&at(r, k)), &nt)),
                            None => nt,
                        };
                        let d = a0.dot(&n0);
                        c.depth[k] = d;
                        c.tang[k] = (a0 - n0 * d).into();
                    }
                    None => {
                        c.depth[k] = 0.0;
                        c.tang[k] = a0.into();
                    }
                }
            }
            c.anchored = true;
        }
        for k in 0..n {
            let nb = normal.map_or(Vector3::zeros(), |nv| unit(at(nv, k).into()));
            let p = at(pos, k);
            let arm: [f64; 3] = std::array::from_fn(|d| c.depth[k] * nb[d] + c.tang[k][d]);
            c.arm[k] = arm;
            c.follow
                .set_end(k, &std::array::from_fn::<f64, 3, _>(|d| p[d] + arm[d]));
        }
        Ok(())
    }
}

impl Solver for SpgSolver {
    fn describe(&self) -> NodeDescription {
        let interfaces = self
            .coupling
            .iter()
            .map(|c| InterfaceInfo {
                name: c.interface.clone(),
                points: c.particles.len(),
                provides: vec![
                    "mass".into(),
                    "stiffness".into(),
                    "force".into(),
                    "moment".into(),
                ],
                accepts: vec![
                    "position".into(),
                    "velocity".into(),
                    "displacement".into(),
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

    /// One point per coupling particle, at its reference position.
    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        match &self.coupling {
            Some(c) if c.interface == name => Ok(InterfaceMesh::points(
                c.particles
                    .iter()
                    .map(|&i| self.model.x0[i as usize])
                    .collect(),
            )),
            _ => Err(SolverError::interface(name, "no such interface")),
        }
    }

    /// Writes, per coupling particle, its lumped (scaled) mass, a stiffness bound
    /// `k = m̂ ω²` with `ω = 2c/h` the particle's frequency bound (its stable step is
    /// `cfl·h/c = cfl·2/ω`, so `ω = 2·cfl/Δt`; the driver applies its own safety factor), and the
    /// constraint force and moment at t0 (the moment is zero before the lever arms are known;
    /// so is the force of an unstressed start).
    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        let _ = inbox;
        let Some(c) = self.coupling.as_mut() else {
            if let Some(b) = bindings.first() {
                return Err(SolverError::interface(
                    &b.interface,
                    "this mc-spg node has no [coupling] table",
                ));
            }
            return Ok(());
        };
        if let Some(b) = bindings.iter().find(|b| b.interface != c.interface) {
            return Err(SolverError::interface(
                &b.interface,
                format!("no such interface (this node's is '{}')", c.interface),
            ));
        }
        let n = c.particles.len();
        let omega = 2.0 * self.model.p.cfl / self.model.stable_dt();
        {
            let mass = out.put(&c.interface, "mass", 1, n);
            for (k, &i) in c.particles.iter().enumerate() {
                mass[k] = self.model.mh[i as usize];
            }
        }
        {
            let stiff = out.put(&c.interface, "stiffness", 1, n);
            for (k, &i) in c.particles.iter().enumerate() {
                stiff[k] = self.model.mh[i as usize] * omega * omega;
            }
        }
        SpgSolver::write_loads(c, &self.model, out);
        c.ready = true;
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
            SpgSolver::read_motion(c, &self.model, inbox, span)?;
        }
        let dt_stable = self.model.stable_dt();
        let nsub = ((span / dt_stable * (1.0 - 1e-9)).ceil() as u64).max(1);
        let dt = span / nsub as f64;
        for k in 0..nsub {
            if let Some(c) = self.coupling.as_ref() {
                // Driver motion interpolated linearly in time between the synchronisation
                // times (eq. 31–32); the velocity lands each particle on its target.
                for (q, &i) in c.particles.iter().enumerate() {
                    let x = self.model.x[i as usize];
                    self.model.presc[i as usize] =
                        std::array::from_fn(|d| c.follow.velocity(q, d, x[d], k, nsub, dt));
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
            c.follow.next_window();
            SpgSolver::write_loads(c, &self.model, out);
        }
        let reactions = self.bc_reactions();
        let displacements = self.bc_displacements();
        let regions = self.region_forces();
        let fasteners = self.fastener_forces();
        self.track_joints(w.t1, &reactions, &regions, &fasteners);
        let every = self.params.history_every.max(1);
        if w.index.is_multiple_of(every) {
            self.history
                .push((w.t1, reactions.clone(), regions.clone()));
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
            (
                "max_eq_plastic_strain".to_string(),
                self.model.max_eps.max(
                    self.model
                        .solid
                        .as_ref()
                        .map_or(0.0, |sd| sd.max_plastic_strain()),
                ),
            ),
        ];
        for ((g, r), u) in self.model.bcs.iter().zip(&reactions).zip(&displacements) {
            scalars.push((format!("force_{}_x", g.name), r[0]));
            scalars.push((format!("displacement_{}_x", g.name), u[0]));
        }
        for (j, f) in self.joints.iter().zip(&fasteners) {
            let Some(f) = f else { continue };
            // `fastener_force_x` for the node's one joint, `fastener_force_<placement>_x` else
            let name = if self.params.placements.is_empty() {
                "fastener_force".to_string()
            } else {
                format!("fastener_force_{}", j.name)
            };
            for (d, axis) in ["x", "y", "z"].iter().enumerate() {
                scalars.push((format!("{name}_{axis}"), f[d]));
            }
            scalars.push((format!("{name}_magnitude"), vec3(f).norm()));
        }
        if let Some(c) = &self.coupling {
            for (name, f) in c.region_names.iter().zip(&regions) {
                if name.is_empty() {
                    continue;
                }
                for (d, axis) in ["x", "y", "z"].iter().enumerate() {
                    scalars.push((format!("force_{name}_{axis}"), f[d]));
                }
                scalars.push((format!("force_{name}_magnitude"), vec3(f).norm()));
            }
        }
        Ok(StepReport {
            kinetic_energy: ke,
            internal_energy: ie,
            external_work: self.model.bc_work,
            interface_work: self.model.coupling_work,
            momentum: self.model.momentum(),
            momentum_gross: self.model.momentum_gross(),
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

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        let m = &self.model;
        protocol::checkpoint::encode_state(&JointState {
            model: ModelState {
                xa: m.xa.clone(),
                x: m.x.clone(),
                xh: m.xh.clone(),
                u: m.u.clone(),
                vh: m.vh.clone(),
                v: m.v.clone(),
                f: m.f.clone(),
                acc: m.acc.clone(),
                mass: m.mass.clone(),
                mh: m.mh.clone(),
                ms: m.ms.clone(),
                rho: m.rho.clone(),
                vol: m.vol.clone(),
                vol_a: m.vol_a.clone(),
                fhat: m.fhat.clone(),
                ftot_a: m.ftot_a.clone(),
                finv_a: m.finv_a.clone(),
                mat: m.mat.clone(),
                bmat: m.bmat.clone(),
                eint: m.eint.clone(),
                kind: m.kind.clone(),
                presc: m.presc.clone(),
                rows: m.rows.clone(),
                dirty: m.dirty.clone(),
                rigid: m.rigid.clone(),
                steps: m.steps,
                time: m.time,
                broken_bonds: m.broken_bonds,
                detached: m.detached,
                damaged: m.damaged.clone(),
                bc_work: m.bc_work,
                bc_impulse: m.bc_impulse,
                coupling_work: m.coupling_work,
                coupling_impulse: m.coupling_impulse,
                coupled_p: m.coupled_p,
                coupled_ke: m.coupled_ke,
                max_eps: m.max_eps,
                contact_pairs: m.contact_pairs.clone(),
                contact_energy: m.contact_energy,
            },
            added_mass: self.added_mass,
            coupling: self.coupling.clone(),
            history: self.history.clone(),
            solid: m.solid.as_ref().map(|sd| sd.save()),
            joints: self.joints.clone(),
        })
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        use protocol::checkpoint::check_len;
        let JointState {
            model: s,
            added_mass,
            coupling,
            history,
            solid,
            joints,
        } = protocol::checkpoint::decode_state(bytes)?;
        let m = &mut self.model;
        check_len("particles", s.x.len(), m.x.len())?;
        check_len("bonds", s.rows.len(), m.rows.len())?;
        check_len("rigid bodies", s.rigid.len(), m.rigid.len())?;
        if coupling.as_ref().map(|c| (&c.interface, c.particles.len()))
            != self
                .coupling
                .as_ref()
                .map(|c| (&c.interface, c.particles.len()))
        {
            return Err(SolverError::Other(
                "load_state: the checkpoint's coupling is not this node's".into(),
            ));
        }
        match (m.solid.as_mut(), solid) {
            (None, None) => {}
            (Some(sd), Some(st)) => sd.load(st).map_err(SolverError::Other)?,
            _ => {
                return Err(SolverError::Other(
                    "load_state: the checkpoint's solid elements are not this node's".into(),
                ));
            }
        }
        m.xa = s.xa;
        m.x = s.x;
        m.xh = s.xh;
        m.u = s.u;
        m.vh = s.vh;
        m.v = s.v;
        m.f = s.f;
        m.acc = s.acc;
        m.mass = s.mass;
        m.mh = s.mh;
        m.ms = s.ms;
        m.rho = s.rho;
        m.vol = s.vol;
        m.vol_a = s.vol_a;
        m.fhat = s.fhat;
        m.ftot_a = s.ftot_a;
        m.finv_a = s.finv_a;
        m.mat = s.mat;
        m.bmat = s.bmat;
        m.eint = s.eint;
        m.kind = s.kind;
        m.presc = s.presc;
        m.rows.restore(s.rows);
        m.dirty = s.dirty;
        m.rigid = s.rigid;
        m.steps = s.steps;
        m.time = s.time;
        m.broken_bonds = s.broken_bonds;
        m.broken_by_part = m.count_broken_by_part();
        m.detached = s.detached;
        m.damaged = s.damaged;
        m.bc_work = s.bc_work;
        m.bc_impulse = s.bc_impulse;
        m.coupling_work = s.coupling_work;
        m.coupling_impulse = s.coupling_impulse;
        m.coupled_p = s.coupled_p;
        m.coupled_ke = s.coupled_ke;
        m.max_eps = s.max_eps;
        m.contact_pairs = s.contact_pairs;
        m.contact_energy = s.contact_energy;
        self.added_mass = added_mass;
        if joints
            .iter()
            .map(|j| (&j.name, &j.regions))
            .ne(self.joints.iter().map(|j| (&j.name, &j.regions)))
        {
            return Err(SolverError::Other(
                "load_state: the checkpoint's joints are not this node's".into(),
            ));
        }
        self.coupling = coupling;
        self.history = history;
        self.joints = joints;
        Ok(())
    }

    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        crate::output::write_vtu(&self.model, dir, window, t)?;
        let mut header = vec!["time".to_string()];
        let mut columns = |name: &str| {
            header.extend(["fx", "fy", "fz"].map(|c| format!("{name}_{c}")));
        };
        for g in &self.model.bcs {
            columns(&g.name);
        }
        if let Some(c) = &self.coupling {
            for (k, name) in c.region_names.iter().enumerate() {
                if name.is_empty() {
                    columns(&format!("region{k}"));
                } else {
                    columns(name);
                }
            }
        }
        let rows = self
            .history
            .iter()
            .map(|(t, r, c)| std::iter::once(*t).chain(r.iter().chain(c).flatten().copied()));
        node_kit::table::write_csv(&dir.join("joint_force.csv"), &header, rows)?;
        node_kit::table::write_text_csv(
            &dir.join("joint_report.csv"),
            &Self::JOINT_REPORT,
            &self.joint_report(),
        )?;
        Ok(())
    }
}

/// What the joint's `save_state` writes: every particle array `step` changes (motion,
/// deformation gradients, J2 states, kernel rows and bond states, rigid bodies, damage,
/// contact pairs), clocks and accumulators; the parameters and the set-up-only data are
/// rebuilt from the case.
#[derive(serde::Serialize, serde::Deserialize)]
struct JointState {
    model: ModelState,
    added_mass: f64,
    coupling: Option<CouplingRt>,
    history: Vec<HistoryRow>,
    solid: Option<crate::solid::SolidState>,
    joints: Vec<JointTrack>,
}

#[derive(serde::Serialize, serde::Deserialize)]
struct ModelState {
    xa: Vec<[f64; 3]>,
    x: Vec<[f64; 3]>,
    xh: Vec<[f64; 3]>,
    u: Vec<[f64; 3]>,
    vh: Vec<[f64; 3]>,
    v: Vec<[f64; 3]>,
    f: Vec<[f64; 3]>,
    acc: Vec<[f64; 3]>,
    mass: Vec<f64>,
    mh: Vec<f64>,
    ms: Vec<f64>,
    rho: Vec<f64>,
    vol: Vec<f64>,
    vol_a: Vec<f64>,
    fhat: Vec<M3>,
    ftot_a: Vec<M3>,
    finv_a: Vec<M3>,
    mat: Vec<crate::model::Point>,
    bmat: Vec<M3>,
    eint: Vec<f64>,
    kind: Vec<Kind>,
    presc: Vec<[f64; 3]>,
    rows: Rows,
    dirty: Vec<bool>,
    rigid: Vec<RigidBody>,
    steps: u64,
    time: f64,
    broken_bonds: usize,
    detached: usize,
    damaged: Vec<bool>,
    bc_work: f64,
    bc_impulse: [f64; 3],
    coupling_work: f64,
    coupling_impulse: [f64; 3],
    coupled_p: [f64; 3],
    coupled_ke: f64,
    max_eps: f64,
    contact_pairs: Vec<(u32, u32)>,
    contact_energy: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track() -> JointTrack {
        JointTrack {
            name: "j".into(),
            regions: vec![],
            peak: 0.0,
            peak_time: 0.0,
            failure: None,
        }
    }

    #[test]
    fn a_joint_unloaded_and_loaded_again_has_not_failed_a_torn_one_has() {
        let mut j = track();
        let bonds = || (5, 1);
        for (t, f) in [(1.0, 500.0), (2.0, 1000.0), (3.0, 80.0)] {
            j.observe(t, f, bonds);
        }
        // below a tenth of the peak with bonds broken: failed at 3
        assert_eq!(j.failure.as_ref().map(|f| f.time), Some(3.0));
        // a little load again (debris, contact): still failed
        j.observe(4.0, 300.0, bonds);
        assert_eq!(j.failure.as_ref().map(|f| f.time), Some(3.0));
        // half its peak again: it had only been unloaded
        j.observe(5.0, 600.0, bonds);
        assert!(j.failure.is_none());
        // a higher peak, then the tear: failed at 7, after its peak
        j.observe(6.0, 1200.0, bonds);
        j.observe(7.0, 100.0, bonds);
        assert_eq!((j.peak, j.peak_time), (1200.0, 6.0));
        let f = j.failure.as_ref().expect("failed");
        assert_eq!((f.time, f.material_bonds, f.interface_bonds), (7.0, 5, 1));
        // no broken bond: unloaded, not failed
        let mut k = track();
        k.observe(1.0, 1000.0, || (0, 0));
        k.observe(2.0, 0.0, || (0, 0));
        assert!(k.failure.is_none());
    }
}
