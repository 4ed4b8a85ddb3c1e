//! The `Solver` implementation of the peridynamic node: set-up (config → validated body and
//! model), the window loop with sub-cycling at the stable step, boundary conditions, and
//! the coupling sides (docs/architecture.md): immersed provider (send position, velocity, volume;
//! apply the received window-averaged force over the next window), kinematic driver and
//! responder (seed 004 eq. 29–33, seed 001 §5.1: boundary-layer particles moved by a driver),
//! and the overlap responder (a patch whose boundary layer follows a mesh, carries the mesh's
//! mass and sends the patch's pull on it: `Layer`).
//! With `device = "gpu"` the body's time stepping runs on the device
//! ([`DeviceBody`]); what the device kernels do not implement is refused at set-up.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use super::correspondence::CorrHistory;
use super::family::{Bonds, full_family, surface_particles};
use super::geometry::{Shape, lattice, lattice_count};
use super::gpu::DeviceBody;
use super::integrate::Body;
use super::lagrange::ExplicitSide;
use super::model::Dim;
use super::models::{ModelInput, PdModelDef};
pub use super::params::*;
use crate::fem2d::load_ramp;
use mechanics::damage::{
    BrittleVonMises, CriticalStretch, DamageModel, DuctilePlasticStrain, FailureIndicator, NoDamage,
};
use mechanics::j2::{J2Material, von_mises};
use mechanics::time::LoadRamp;
use mechanics::xfem::Crack;
use node_kit::device::Device;
use node_kit::vtk::{self, Arrays, Frame};
use protocol::checkpoint::{check_len, decode_state, encode_state};
use protocol::scheme::lagrange::{LagrangeSide, Method, wire as lwire};
use protocol::scheme::{self, kinematic};
use protocol::{
    Binding, CouplingKind, InterfaceInfo, InterfaceMesh, NodeDescription, Role, Solver,
    SolverError, SolverResult, StepReport, Window,
};
use protocol::{BuildOptions, Inbox, LimitApplies, LimitKind, Outbox, WindowLimit};
use std::borrow::Cow;
use std::path::Path;

/// Damage index φ (seed 000 App. C: the volume fraction of a particle's family whose bonds
/// are broken) at or above which a particle counts in the `damaged_particles` report scalar:
/// half of its family cut off, as for a particle on a crack through its family's centre.
pub const DAMAGED_INDEX: f64 = 0.5;

/// Where and when damage first appeared ("cracks start from the re-entrant
/// corners"): reference position of the most damaged particle of the first window with any
/// φ > 0, how many particles were damaged then, and the distances of all of them to the
/// nearest inner corner of a hollow-square body / from the axis of a hollow-cylinder body
/// (negative when the body has no such shape).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FirstDamage {
    pub time: f64,
    pub position: [f64; 3],
    pub count: usize,
    /// Largest distance (m) of a first-damaged particle to its nearest inner corner.
    pub corner_distance: f64,
    /// Smallest and largest radius (m) of the first-damaged particles.
    pub radius: [f64; 2],
}

/// One coupling as this node plays it: its scheme's side (`role`).
#[derive(Debug, Clone)]
struct Coupled {
    interface: String,
    kind: CouplingKind,
    role: Role,
    /// Decoupled (seed 000 §4): a force still in flight is applied, nothing more is sent.
    ended: bool,
}

/// The peridynamic solver node.
pub struct PdSolver {
    pub model_name: String,
    pub params: PdParams,
    pub body: Body,
    interfaces: Vec<(String, Vec<usize>)>,
    coupled: Vec<Coupled>,
    /// External force per particle from couplings, held over a window (N).
    fcouple: Vec<[f64; 3]>,
    /// The particles that follow a driver's motion, in coupling order, and their path
    /// through the window (sync-force responder side).
    follow_pts: Vec<usize>,
    follow: kinematic::Follow,
    /// Pressure particles and their outward area vectors (m²).
    pressure_area: Vec<(usize, [f64; 3])>,
    /// Particles with prescribed velocity from the config.
    bc_particles: Vec<usize>,
    /// The held particles' internal force at the start of the step being taken (the
    /// supports' impulse is the step's mean force: see `advance`).
    held_force: Vec<[f64; 3]>,
    external_impulse: [f64; 3],
    applied_impulse: f64,
    interface_impulse: [f64; 3],
    interface_work: f64,
    external_work: f64,
    /// The walls' impulse over the window so far (N s).
    wall_impulse: [f64; 3],
    first_damage: Option<FirstDamage>,
    /// (Σ damage, component of every particle, component sizes) of the last count: bonds
    /// never heal, so an unchanged damage sum means no bond broke and the components need no
    /// recount.
    fragment_cache: Option<(f64, Vec<u32>, Vec<usize>)>,
    /// The cracks there from the start (`cracks`); the first one is followed.
    cracks: Vec<Crack>,
    /// (Σ damage, the followed crack's front) of the last measurement.
    crack_cache: Option<(f64, super::fracture::CrackFront)>,
    /// The device copy of the body when `device = "gpu"`: it owns the time stepping; `body`
    /// is brought up to date at every window end.
    device: Option<DeviceBody>,
    /// Loads: particle, force at full load (N), and history of each load.
    loads: Vec<(usize, [f64; 3], LoadRamp)>,
    /// Reported points: scalar names (x, y[, z]) and particle.
    points: Vec<(Vec<String>, usize)>,
    /// The body as one side of a lagrange coupling (then the side steps it).
    pub(super) lagrange: Option<(String, ExplicitSide)>,
    /// The boundary layer of an overlap coupling this body responds to.
    layer: Option<Layer>,
}

/// An overlap coupling's boundary layer: particles outside the patch that follow the
/// driver's mesh and carry its mass, not ours. What they send is the patch's pull on them.
#[derive(Debug, Clone)]
struct Layer {
    interface: String,
    pts: Vec<usize>,
    /// 1 for the patch's own particles (every particle but the layer's).
    own: Vec<u8>,
    /// The patch's pull on each layer particle (N): at the last force evaluation and the
    /// one before it, at the window's start (after the particles landed on the driver's
    /// positions), and its impulse over the window so far (N s, trapezoidal over the steps,
    /// as velocity Verlet gives the patch its reaction).
    last: Vec<[f64; 3]>,
    before: Vec<[f64; 3]>,
    start: Vec<[f64; 3]>,
    impulse: Vec<[f64; 3]>,
    /// The force sent at the last window's end (N).
    sent: Vec<[f64; 3]>,
}

/// The patch's pull on each layer particle `pts` at the body's last force evaluation (N),
/// from the particles `own` marks; false where the model cannot split its force by bond.
fn pull(b: &Body, pts: &[usize], own: &[u8], out: &mut [[f64; 3]]) -> bool {
    let k = b.kinematics();
    for (o, &i) in out.iter_mut().zip(pts) {
        match b.model.partial_force(&k, &b.bonds, i, own) {
            Some(f) => *o = f.map(|x| x * b.vol[i]),
            None => return false,
        }
    }
    true
}

/// Most lattice points a body's bounding box may hold (the largest runs here are ~10⁷).
pub const MAX_LATTICE_POINTS: f64 = 2e8;

/// The fewest bytes of memory a bond takes (of the models: 57 to 216).
const BOND_BYTES_MIN: u64 = 57;

/// Refuses a body whose bonds would exceed `max_bonds`, or the memory available on this host
/// at [`BOND_BYTES_MIN`] each, before anything is allocated: `particles` × the full family of
/// the horizon (capped at the other particles), an upper estimate (surface particles have
/// smaller families). The key named is `horizon` when the family is far past the usual few
/// spacings (δ > 6 Δx), else `spacing`.
fn bond_budget(p: &PdParams, particles: usize, three_d: bool) -> SolverResult<()> {
    let family = full_family(p.horizon, p.spacing, three_d).min((particles - 1) as f64);
    let bonds = particles as f64 * family;
    let ratio = p.horizon / p.spacing;
    let key = if ratio > 6.0 { "horizon" } else { "spacing" };
    if bonds <= p.max_bonds as f64 {
        // Within the budget, but maybe not within this host's memory: the cheapest model's
        // bytes a bond, before the bonds are built.
        return protocol::memory::check_fits(
            key,
            (bonds * BOND_BYTES_MIN as f64) as u128,
            &format!(
                "about {bonds:.3e} bonds of {particles} particles at spacing {} and horizon {}, at least {BOND_BYTES_MIN} bytes each",
                p.spacing, p.horizon
            ),
        );
    }
    cfg(
        key,
        format!(
            "the bodies' {particles} particles at spacing {} with up to {family:.0} neighbours each (horizon {} = {ratio:.3} spacings) make about {bonds:.3e} bonds, more than max_bonds = {} (each takes 57 to 216 bytes of memory, by model, and set-up time): coarsen the spacing, shorten the horizon, or raise max_bonds where the host has the memory",
            p.spacing, p.horizon, p.max_bonds
        ),
    )
}

/// What a checkpoint holds of the body and the node's sums (`Solver::save_state`; read back
/// with `protocol::checkpoint::decode_state`); the model's history rides along in the
/// model's own form (`PdModel::save_state`).
#[derive(serde::Serialize, serde::Deserialize)]
pub struct BodyState<'a> {
    pub particles: usize,
    pub bonds: usize,
    pub time: f64,
    pub steps: u64,
    pub disp: Cow<'a, [[f64; 3]]>,
    pub vel: Cow<'a, [[f64; 3]]>,
    pub force: Cow<'a, [[f64; 3]]>,
    pub vpres: Cow<'a, [[f64; 3]]>,
    pub prescribed: Cow<'a, [u8]>,
    pub intact: Cow<'a, [f64]>,
    pub external_impulse: [f64; 3],
    pub interface_impulse: [f64; 3],
    pub applied_impulse: f64,
    pub interface_work: f64,
    pub external_work: f64,
    pub first_damage: Option<FirstDamage>,
    pub model: Vec<u8>,
    /// An overlap patch's boundary layer at the window's end (empty without one): the pull
    /// the next window's impulse starts from and the force last sent.
    pub layer_start: Cow<'a, [[f64; 3]]>,
    pub layer_sent: Cow<'a, [[f64; 3]]>,
}

fn cfg<T>(key: &str, reason: impl Into<String>) -> SolverResult<T> {
    Err(SolverError::config(key, reason))
}

impl PdSolver {
    /// Builds the solver for `model` ("pd-bond" or "pd-correspondence") from its table.
    pub fn from_table(model: &str, table: &toml::Table) -> SolverResult<Self> {
        Self::new(model, protocol::params::decode(table)?)
    }

    pub fn new(model: &str, p: PdParams) -> SolverResult<Self> {
        Self::build(model, p, &BuildOptions::RUN)
    }

    /// As `new`, as `opts` asks: describe-only checks `device = "gpu"` against the device
    /// kernels but opens no GPU (the body stays on the host).
    pub fn build(model: &str, p: PdParams, opts: &BuildOptions) -> SolverResult<Self> {
        let Some(def) = super::models::by_name(model) else {
            return cfg("model", format!("unknown peridynamic model '{model}'"));
        };
        Self::build_model(def, p, opts)
    }

    /// The solver of model `def` from its parameters `p`: the parameters checked, the
    /// particles laid out and bonded, the model built, then what the parameters place on
    /// the body (initial and prescribed velocities, a pressure pulse, interfaces, loads,
    /// probe points) and, with `device = "gpu"`, its device copy.
    pub fn build_model(def: &PdModelDef, p: PdParams, opts: &BuildOptions) -> SolverResult<Self> {
        let dim = dimension(&p)?;
        let three_d = dim.three_d();
        let target = Device::parse(p.device.as_deref(), p.precision.as_deref())?;
        let on_gpu = target.is_gpu();
        if on_gpu {
            gpu_supports(def, dim, &p).map_err(|r| SolverError::config("device", r))?;
        }
        let material = check_params(&p, three_d)?;
        let x0 = lattice(&p.bodies, &p.holes, p.spacing, three_d);
        let v = if three_d {
            p.spacing.powi(3)
        } else {
            p.spacing * p.spacing * p.thickness
        };
        let vol = vec![v; x0.len()];
        let cracks = p
            .cracks
            .iter()
            .enumerate()
            .map(|(k, c)| Crack::new(&format!("cracks[{k}]"), c.clone()))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|mechanics::fem2d::Fem2dError::Config { key, reason }| {
                SolverError::config(key, reason)
            })?;
        let bonds = Bonds::build(&x0, p.horizon);
        // A crack there from the start: the bonds across it do not exist.
        let crosses = |c: &Crack, i: usize, j: usize| {
            !c.crossings([x0[i][0], x0[i][1]], [x0[j][0], x0[j][1]])
                .is_empty()
        };
        for (k, c) in cracks.iter().enumerate() {
            let cut = (0..x0.len()).any(|i| {
                (bonds.offsets[i]..bonds.offsets[i + 1])
                    .any(|b| crosses(c, i, bonds.nbr[b] as usize))
            });
            if !cut {
                return Err(SolverError::config(
                    format!("cracks[{k}]"),
                    "crosses no bond of the body (is it inside it?)",
                ));
            }
        }
        let mut bonds = if cracks.is_empty() {
            bonds
        } else {
            bonds.without(|i, j| cracks.iter().any(|c| crosses(c, i, j)))
        };
        bonds.no_fail = no_fail_of(&x0, &p, three_d)?;
        let model = at_rest(&x0, &vol, |k| {
            (def.build)(&ModelInput {
                dim,
                p: &p,
                material,
                k,
                bonds: &bonds,
            })
        })?;
        let mut body = Body::new(dim, p.spacing, p.horizon, p.density, x0, vol, bonds, model);
        if let Some(m) = p.mott().or_else(|(k, r)| cfg(&k, r))? {
            let f: Vec<f64> = (0..body.len()).map(|i| m.factor(i as u64)).collect();
            body.model.set_failure_factors(&f);
        }
        set_initial_velocity(&mut body, &p)?;
        set_walls(&mut body, &p)?;
        let bc_particles = prescribe_velocity(&mut body, &p)?;
        let pressure_area = pressure_faces(&body, &p)?;
        let interfaces = interfaces_of(&body, &p)?;
        let points = probe_points(&body, &p)?;
        let device = if on_gpu && !opts.describe_only {
            // the supports' and the reported points' particles come back every window too
            let watched: Vec<usize> = bc_particles
                .iter()
                .copied()
                .chain(points.iter().map(|(_, i)| *i))
                .collect();
            open_device(
                def,
                &target,
                (dim, &p, material),
                &body,
                &interfaces,
                &watched,
            )?
        } else {
            None
        };
        let loads = loads_of(&body, &p)?;
        if on_gpu && !p.loads.is_empty() {
            return cfg(
                "device",
                "\"gpu\" does not support loads: use device = \"cpu\"",
            );
        }
        if p.substeps == Some(0) {
            return cfg("substeps", "must be ≥ 1, got 0");
        }
        let n = body.len();
        Ok(PdSolver {
            model_name: def.name.to_string(),
            params: p,
            body,
            interfaces,
            coupled: Vec::new(),
            fcouple: vec![[0.0; 3]; n],
            follow_pts: Vec::new(),
            follow: kinematic::Follow::default(),
            pressure_area,
            held_force: vec![[0.0; 3]; bc_particles.len()],
            bc_particles,
            external_impulse: [0.0; 3],
            applied_impulse: 0.0,
            interface_impulse: [0.0; 3],
            interface_work: 0.0,
            external_work: 0.0,
            wall_impulse: [0.0; 3],
            first_damage: None,
            fragment_cache: None,
            layer: None,
            cracks,
            crack_cache: None,
            device,
            loads,
            points,
            lagrange: None,
        })
    }

    fn points_of(&self, name: &str) -> SolverResult<&[usize]> {
        self.interfaces
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, p)| p.as_slice())
            .ok_or_else(|| {
                SolverError::interface(name, "no such interface (see params.interfaces)")
            })
    }

    /// Write the fields `fields` of interface `iface` (particles `pts`), in that order: what
    /// its scheme's side sends (its window fields, and the scheme's set-up fields).
    fn send_fields(
        &self,
        iface: &str,
        pts: &[usize],
        fields: &[&str],
        out: &mut Outbox,
    ) -> SolverResult<()> {
        let n = pts.len();
        for &f in fields {
            match f {
                "position" => {
                    let x = out.put(iface, "position", 3, n);
                    for (k, &i) in pts.iter().enumerate() {
                        x[3 * k..3 * k + 3].copy_from_slice(&self.body.pos[i]);
                    }
                }
                "velocity" => {
                    let v = out.put(iface, "velocity", 3, n);
                    for (k, &i) in pts.iter().enumerate() {
                        v[3 * k..3 * k + 3].copy_from_slice(&self.body.vel[i]);
                    }
                }
                "volume" => {
                    let w = out.put(iface, "volume", 1, n);
                    for (k, &i) in pts.iter().enumerate() {
                        w[k] = self.body.vol[i];
                    }
                }
                "force" => {
                    let f = out.put(iface, "force", 3, n);
                    match self.layer.as_ref().filter(|l| l.interface == iface) {
                        Some(l) => {
                            // the impulse-conserving force (`layer_window_end`)
                            for (k, s) in l.sent.iter().enumerate() {
                                f[3 * k..3 * k + 3].copy_from_slice(s);
                            }
                        }
                        None => {
                            for (k, &i) in pts.iter().enumerate() {
                                f[3 * k..3 * k + 3].copy_from_slice(&self.internal_force(i));
                            }
                        }
                    }
                }
                "mass" => {
                    let m = out.put(iface, "mass", 1, n);
                    for (k, &i) in pts.iter().enumerate() {
                        m[k] = self.body.density * self.body.vol[i];
                    }
                }
                "stiffness" => {
                    let kin = self.body.kinematics();
                    let st = out.put(iface, "stiffness", 1, n);
                    for (k, &i) in pts.iter().enumerate() {
                        st[k] = self.body.model.stiffness_bound(&kin, &self.body.bonds, i);
                    }
                }
                other => {
                    return Err(SolverError::interface(
                        iface,
                        format!("a peridynamic body cannot send '{other}'"),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Makes `pts` the boundary layer of an overlap coupling on `iface` (one per body; the
    /// model must split its force by bond).
    fn setup_layer(&mut self, iface: &str, pts: &[usize]) -> SolverResult<()> {
        if self.layer.is_some() {
            return Err(SolverError::interface(
                iface,
                "a second overlap coupling: a patch has one boundary layer",
            ));
        }
        let mut own = vec![1u8; self.body.len()];
        for &i in pts {
            own[i] = 0;
        }
        if !own.contains(&1) {
            return Err(SolverError::interface(
                iface,
                "the boundary layer holds every particle: the patch has none of its own",
            ));
        }
        let mut l = Layer {
            interface: iface.to_string(),
            pts: pts.to_vec(),
            own,
            last: vec![[0.0; 3]; pts.len()],
            before: vec![[0.0; 3]; pts.len()],
            start: vec![[0.0; 3]; pts.len()],
            impulse: vec![[0.0; 3]; pts.len()],
            sent: vec![[0.0; 3]; pts.len()],
        };
        if !pull(&self.body, &l.pts, &l.own, &mut l.last) {
            return Err(SolverError::config(
                "model",
                format!(
                    "{} cannot be an overlap patch (its force does not split by bond): use \
                     pd-correspondence",
                    self.model_name
                ),
            ));
        }
        l.start.clone_from(&l.last);
        l.sent.clone_from(&l.last);
        self.layer = Some(l);
        Ok(())
    }

    /// After a step of `dt`: the pull's trapezoidal impulse over it, booked as the patch's
    /// interface impulse (the patch took minus it), and its work on the layer's motion.
    fn layer_step(&mut self, dt: f64) {
        let Some(l) = self.layer.as_mut() else {
            return;
        };
        std::mem::swap(&mut l.last, &mut l.before);
        pull(&self.body, &l.pts, &l.own, &mut l.last);
        for (k, &i) in l.pts.iter().enumerate() {
            let v = self.body.vel[i];
            for d in 0..3 {
                let j = 0.5 * dt * (l.before[k][d] + l.last[k][d]);
                l.impulse[k][d] += j;
                self.interface_impulse[d] -= j;
                self.interface_work -= j * v[d];
            }
        }
    }

    /// At the window's end (the layer on the driver's positions, the forces evaluated
    /// there): the force to send is the window's impulse over its length `span` plus half the
    /// pull's change over the window, so that what the driver holds over its windows adds up
    /// to the impulse the patch took (half the pull at the end in flight), and a pull that
    /// changes smoothly arrives as its value at the window's end.
    fn layer_window_end(&mut self, span: f64) {
        let Some(l) = self.layer.as_mut() else {
            return;
        };
        pull(&self.body, &l.pts, &l.own, &mut l.last);
        for k in 0..l.pts.len() {
            for d in 0..3 {
                l.sent[k][d] = l.impulse[k][d] / span + 0.5 * (l.last[k][d] - l.start[k][d]);
            }
        }
        l.start.clone_from(&l.last);
        for j in l.impulse.iter_mut() {
            *j = [0.0; 3];
        }
    }

    /// Internal force (N) on particle i: force density × volume.
    fn internal_force(&self, i: usize) -> [f64; 3] {
        let f = self.body.force[i];
        let v = self.body.vol[i];
        [f[0] * v, f[1] * v, f[2] * v]
    }

    /// Fragments: sizes of the connected components (over unbroken bonds) with at least
    /// `min_size` particles, largest first, and the number of particles in smaller ones.
    pub fn fragments(&mut self, min_size: usize) -> (Vec<usize>, usize) {
        let b = &mut self.body;
        b.model.fragment_links(&b.pos, &mut b.bonds);
        let (_, sizes) = super::fracture::components(&b.bonds, &b.bonds.intact);
        let mut big: Vec<usize> = sizes.iter().copied().filter(|&s| s >= min_size).collect();
        big.sort_unstable_by(|a, b| b.cmp(a));
        let debris = sizes.iter().filter(|&&s| s < min_size).sum();
        (big, debris)
    }

    /// The axis fragments are measured about (`fragment_axis`); none: principal extents.
    fn fragment_axis(&self) -> Option<[f64; 2]> {
        self.params.fragment_axis.as_ref().map(|a| [a[0], a[1]])
    }

    /// The fragments (components of ≥ `fragment_min_size` particles) of the body with its
    /// bonds as `bonds`, measured now, and each particle's fragment index.
    fn measured_fragments(
        &self,
        label: &[u32],
        sizes: &[usize],
        vel: &[[f64; 3]],
    ) -> (Vec<super::fracture::Fragment>, Vec<u32>) {
        let b = &self.body;
        let mass: Vec<f64> = b.vol.iter().map(|v| v * b.density).collect();
        super::fracture::measure_fragments(
            label,
            sizes,
            self.params.fragment_min_size,
            &b.pos,
            vel,
            &mass,
            self.fragment_axis(),
            b.spacing,
        )
    }

    /// The window's fracture and stress scalars: with a damage model,
    /// `damaged_particles` (φ ≥ [`DAMAGED_INDEX`]), `cracked_particles` (φ > 0), `fragments`
    /// (components of ≥ `fragment_min_size` particles) and `debris_particles`, and from the
    /// first window with damage on, where it first appeared ([`FirstDamage`]); with a stress,
    /// `max_von_mises` (Pa); with plasticity, `max_plastic_strain`.
    fn fracture_scalars(&mut self, t1: f64, damage: &[f64]) -> Vec<(String, f64)> {
        let mut v: Vec<(String, f64)> = Vec::new();
        if let Some(st) = self.body.model.stress() {
            let vm = st.iter().map(von_mises).fold(0.0, f64::max);
            v.push(("max_von_mises".into(), vm));
        }
        if self.params.yield_stress.is_some()
            && let Some(ep) = self.body.model.plastic_strain()
        {
            let m = ep.iter().cloned().fold(0.0, f64::max);
            v.push(("max_plastic_strain".into(), m));
        }
        // the stress law's own point scalars (temperature, failure indicator)
        for (name, values) in self.body.model.point_scalars() {
            let m = values.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            v.push((format!("max_{name}"), m));
        }
        let no_damage = matches!(self.params.damage, None | Some(DamageParams::None {}));
        if let Some(crack) = self.cracks.first() {
            let dsum: f64 = damage.iter().sum();
            if !matches!(&self.crack_cache, Some((d, _)) if *d == dsum) {
                if !no_damage {
                    self.body.model.sync_bonds(&mut self.body.bonds);
                }
                let front = super::fracture::crack_front(
                    &self.body.x0,
                    &self.body.bonds,
                    crack,
                    self.body.horizon,
                );
                self.crack_cache = Some((dsum, front));
            }
            if let Some((_, front)) = &self.crack_cache {
                v.push(("crack_tip_x".into(), front.tip[0]));
                v.push(("crack_tip_y".into(), front.tip[1]));
                v.push(("crack_length".into(), front.length));
            }
        }
        if no_damage {
            return v;
        }
        let damaged = damage.iter().filter(|&&d| d >= DAMAGED_INDEX).count();
        let cracked = damage.iter().filter(|&&d| d > 0.0).count();
        v.push(("damaged_particles".into(), damaged as f64));
        v.push(("cracked_particles".into(), cracked as f64));
        for (name, x) in self.body.model.damage_scalars() {
            v.push((name.into(), x));
        }
        // keyed by the damage and the links (a model's links can also part with distance)
        let b = &mut self.body;
        b.model.fragment_links(&b.pos, &mut b.bonds);
        let key = damage.iter().sum::<f64>() + b.bonds.intact.iter().sum::<f64>();
        if !matches!(&self.fragment_cache, Some((d, ..)) if *d == key) {
            let (label, sizes) = super::fracture::components(&b.bonds, &b.bonds.intact);
            self.fragment_cache = Some((key, label, sizes));
        }
        let Some((_, label, sizes)) = &self.fragment_cache else {
            unreachable!("the fragment cache was filled above")
        };
        let min = self.params.fragment_min_size;
        let debris: usize = sizes.iter().filter(|&&s| s < min).sum();
        let (frags, _) = self.measured_fragments(label, sizes, &self.body.vel);
        let [width, thickness, speed] = super::fracture::fragment_summary(&frags);
        v.push(("fragments".into(), frags.len() as f64));
        v.push(("debris_particles".into(), debris as f64));
        v.push(("fragment_mean_width".into(), width));
        v.push(("fragment_mean_thickness".into(), thickness));
        v.push(("fragment_max_speed".into(), speed));
        if self.first_damage.is_none() && cracked > 0 {
            self.first_damage = Some(first_damage_of(
                &self.params.bodies,
                &self.body.x0,
                damage,
                t1,
            ));
        }
        if let Some(f) = &self.first_damage {
            v.push(("first_damage_time".into(), f.time));
            v.push(("first_damage_x".into(), f.position[0]));
            v.push(("first_damage_y".into(), f.position[1]));
            if self.body.dim.three_d() {
                v.push(("first_damage_z".into(), f.position[2]));
            }
            v.push(("first_damage_particles".into(), f.count as f64));
            if f.corner_distance >= 0.0 {
                v.push(("first_damage_corner_distance".into(), f.corner_distance));
            }
            if f.radius[0] >= 0.0 {
                v.push(("first_damage_radius_min".into(), f.radius[0]));
                v.push(("first_damage_radius_max".into(), f.radius[1]));
            }
        }
        v
    }

    /// Where and when damage first appeared, once it has.
    pub fn first_damage(&self) -> Option<FirstDamage> {
        self.first_damage
    }

    fn pressure_at(&self, t: f64) -> f64 {
        self.params
            .pressure_pulse
            .as_ref()
            .map_or(0.0, |pp| pp.at(t))
    }

    /// The body's energies now (J): elastic strain energy of the force state, plastic work
    /// and energy released by broken bonds since the start (the last two dissipated; the
    /// coordinator's balance counts all three, see `wire::DISSIPATED_SCALARS`).
    /// On the device path the host body is not up to date between windows (only the
    /// interface and support particles come back): the strain energy, plastic work and the
    /// energy released by broken bonds (pd-bond with a critical stretch, booked on the
    /// device in the step a bond breaks) are reduced on the device with the window report
    /// (gpu.rs `energy` and `report`).
    pub fn energies(&mut self) -> (f64, f64, f64) {
        if let Some(dev) = &self.device {
            let r = dev.last_report();
            return (r.strain_energy, r.plastic_work, r.released);
        }
        let b = &mut self.body;
        let k = super::model::Kinematics {
            x0: &b.x0,
            pos: &b.pos,
            disp: &b.disp,
            vel: &b.vel,
            vol: &b.vol,
        };
        let mut strain = b.model.strain_energy(&k, &b.bonds);
        if let (Some(l), Some(e)) = (&self.layer, b.model.point_energies()) {
            // the layer's material is the driver's
            strain -= l.pts.iter().map(|&i| e[i]).sum::<f64>();
        }
        (
            strain,
            b.model.plastic_work(&b.vol),
            b.model.fracture_energy(),
        )
    }

    /// The window's report at `w.t1`, after `nsub` particle steps (the state of the body and
    /// the running sums of this solver).
    fn window_report(
        &mut self,
        w: &Window,
        nsub: u64,
        wall: std::time::Instant,
    ) -> SolverResult<StepReport> {
        self.body.time = w.t1;
        let dev_report = self.device.as_ref().map(|d| d.last_report().clone());
        let diverged = match &dev_report {
            // the device path: the kinetic energy reduced over every particle
            Some(r) => !r.kinetic_energy.is_finite(),
            None => self
                .body
                .vel
                .iter()
                .any(|v| !(v[0].is_finite() && v[1].is_finite() && v[2].is_finite())),
        };
        if diverged {
            return Err(SolverError::Diverged {
                time: w.t1,
                reason: "non-finite particle velocity".into(),
            });
        }
        let damage = self.body.damage();
        let broken = damage.iter().filter(|&&d| d >= 1.0 - 1e-12).count();
        let maxd = damage.iter().cloned().fold(0.0, f64::max);
        let mut fracture = self.fracture_scalars(w.t1, &damage);
        if let Some(r) = &dev_report {
            // the host model's stresses stay at their start values on the device path
            for (name, v) in fracture.iter_mut() {
                match name.as_str() {
                    "max_von_mises" => *v = r.max_von_mises,
                    "max_plastic_strain" => *v = r.max_plastic_strain,
                    _ => {}
                }
            }
        }
        let (strain, plastic, released) = self.energies();
        Ok(StepReport {
            kinetic_energy: match &dev_report {
                Some(r) => r.kinetic_energy,
                None => self.body.kinetic_energy(),
            },
            internal_energy: strain,
            external_work: self.external_work,
            interface_work: self.interface_work,
            momentum: match &dev_report {
                Some(r) => r.momentum,
                None => self.body.momentum(),
            },
            momentum_gross: match &dev_report {
                Some(r) => r.momentum_gross,
                None => self.body.momentum_gross(),
            },
            external_impulse: self.external_impulse,
            applied_impulse: self.applied_impulse,
            interface_impulse: self.interface_impulse,
            substeps: nsub,
            wall_s: wall.elapsed().as_secs_f64(),
            coupling_wait_s: 0.0,
            idle_s: 0.0,
            scalars: {
                let mut v = vec![
                    ("max_damage".into(), maxd),
                    ("free_particles".into(), broken as f64),
                ];
                // Displacement of the centre of mass (seed 000 Fig. 4a plots its x part).
                let b = &self.body;
                let m: f64 = b.vol.iter().sum();
                for (d, axis) in ["x", "y", "z"].iter().enumerate() {
                    let u: f64 = match &dev_report {
                        Some(r) => r.vol_disp[d],
                        None => (0..b.len()).map(|i| b.vol[i] * b.disp[i][d]).sum(),
                    };
                    v.push((
                        format!("com_displacement_{axis}"),
                        u / m.max(f64::MIN_POSITIVE),
                    ));
                }
                v.extend(fracture);
                v.push(("plastic_work".into(), plastic));
                v.push(("fracture_energy".into(), released));
                for (names, i) in &self.points {
                    for (d, name) in names.iter().enumerate() {
                        v.push((name.clone(), b.disp[*i][d]));
                    }
                }
                let dims = if b.dim.three_d() { 3 } else { 2 };
                let axes = ["x", "y", "z"];
                if !b.walls.is_empty() {
                    let span = w.t1 - w.t0;
                    for d in 0..dims {
                        v.push((
                            format!("wall_force_{}", axes[d]),
                            self.wall_impulse[d] / span,
                        ));
                    }
                }
                if self.params.report_extent {
                    for d in 0..dims {
                        let (lo, hi) = b.pos.iter().fold((f64::MAX, f64::MIN), |(lo, hi), x| {
                            (lo.min(x[d]), hi.max(x[d]))
                        });
                        v.push((format!("extent_{}", axes[d]), hi - lo + b.spacing));
                    }
                    if dims == 3 {
                        v.push(("extent_radial".into(), radial_extent(&b.pos, b.spacing)));
                    }
                }
                if let Some(dev) = &self.device {
                    // precision of the device arithmetic (64, or 32 with a warning in the log)
                    let bits = if dev.warning().is_some() { 32.0 } else { 64.0 };
                    v.push(("gpu_precision_bits".into(), bits));
                }
                v
            },
        })
    }

    /// The particles of interface `name` (empty when there is none).
    pub fn interface_points(&self, name: &str) -> Vec<usize> {
        self.points_of(name)
            .map(<[usize]>::to_vec)
            .unwrap_or_default()
    }

    /// The force of the loads on particle `i` at full load (N).
    pub fn load_on(&self, i: usize) -> [f64; 3] {
        let mut f = [0.0; 3];
        for (_, g, _) in self.loads.iter().filter(|(j, _, _)| *j == i) {
            for d in 0..3 {
                f[d] += g[d];
            }
        }
        f
    }

    /// Stable step with the safety factor.
    pub fn dt(&self) -> f64 {
        self.params.cfl * self.body.stable_dt()
    }

    /// Makes the body one side of a lagrange coupling on `interface` (seed 003 §4, §5.4;
    /// `pd::lagrange`) for the system step `window`: every component of every interface
    /// particle tied, local multipliers `first_lambda` + … with sign `sign` in B (through
    /// `cosim run`: 0 and +1, the coordinator assigns them). The particle step is `window` /
    /// `substeps` (default: as the stable step needs); gs4 and ph take one per window.
    pub fn lagrange_side_for(
        &mut self,
        interface: &str,
        method: Method,
        window: f64,
        (first_lambda, sign): (usize, f64),
    ) -> SolverResult<()> {
        if self.lagrange.is_some() {
            return Err(SolverError::interface(
                interface,
                "a peridynamic body is one side of one lagrange coupling",
            ));
        }
        if self.device.is_some() {
            return cfg(
                "device",
                "a lagrange side runs on the cpu: use device = \"cpu\"",
            );
        }
        if !self.bc_particles.is_empty() {
            return cfg(
                "prescribed_velocity",
                "a lagrange side takes no prescribed velocity (hold the supports on another \
                 subdomain)",
            );
        }
        if self.params.pressure_pulse.is_some() {
            return cfg("pressure_pulse", "a lagrange side takes loads only");
        }
        if !self.params.walls.is_empty() {
            return cfg("walls", "a lagrange side takes loads only");
        }
        let pts = self.points_of(interface)?.to_vec();
        let substeps = match self.params.substeps {
            Some(m) => m,
            None => (window / self.dt() - 1e-9).ceil().max(1.0) as usize,
        };
        let dt = window / substeps as f64;
        let limit = self.body.stable_dt();
        if !(dt <= limit * (1.0 + 1e-12)) {
            return cfg(
                "substeps",
                format!(
                    "{substeps} steps per window of {window:e} s take {dt:e} s, beyond the \
                     particles' stable step {limit:e} s"
                ),
            );
        }
        let gc = method == Method::Gc;
        if !gc && substeps != 1 {
            return cfg(
                "substeps",
                format!(
                    "{method:?} takes one particle step per system step (an explicit side's \
                     condensed operator over {substeps} substeps would need its stiffness): set \
                     run.window ≤ {:e} s, or method = \"gc\"",
                    self.dt()
                ),
            );
        }
        let mut history = LoadRamp::STEP;
        for (k, l) in self.params.loads.iter().enumerate() {
            let h = load_ramp("", l.ramp, l.ramp_time)?;
            if k > 0 && h != history {
                return cfg(
                    &format!("loads[{k}].ramp"),
                    "a lagrange side takes loads of one ramp",
                );
            }
            history = h;
        }
        let loads = self.loads.iter().map(|&(i, f, _)| (i, f)).collect();
        let comps = if self.body.dim.three_d() { 3 } else { 2 };
        let steps = if gc { substeps } else { 1 };
        let side = ExplicitSide::new(
            &self.body,
            &pts,
            comps,
            (first_lambda, sign),
            (dt, steps, gc),
            loads,
            history,
        );
        self.lagrange = Some((interface.to_string(), side));
        Ok(())
    }
}

/// The body's lagrange side (the solver's, so that the side steps the body it owns);
/// without one, an empty side.
impl LagrangeSide for PdSolver {
    fn multiplier_ids(&self) -> &[usize] {
        self.lagrange
            .as_ref()
            .map_or(&[], |(_, s)| s.multiplier_ids())
    }
    fn coupling_steps(&self) -> usize {
        self.lagrange
            .as_ref()
            .map_or(1, |(_, s)| s.coupling_steps())
    }
    fn operator(&self) -> &[f64] {
        self.lagrange.as_ref().map_or(&[], |(_, s)| s.operator())
    }
    fn initial(&mut self, free: &mut [f64], op: &mut [f64]) {
        if let Some((_, s)) = self.lagrange.as_mut() {
            s.initial(&self.body, free, op);
        }
    }
    fn set_initial(&mut self, lambda0: &[f64]) {
        if let Some((_, s)) = self.lagrange.as_mut() {
            s.set_initial(&self.body, lambda0);
        }
    }
    fn free_step(&mut self, v_start: &mut [f64], v_free: &mut [f64]) {
        if let Some((_, s)) = self.lagrange.as_mut() {
            s.free_step(&mut self.body, v_start, v_free);
        }
    }
    fn correct(&mut self, lambda: &[f64]) {
        if let Some((_, s)) = self.lagrange.as_mut() {
            s.correct(&mut self.body, lambda);
        }
    }
    fn interface_work(&self) -> f64 {
        self.lagrange
            .as_ref()
            .map_or(0.0, |(_, s)| s.interface_work)
    }
    fn save_state(&self) -> Result<Vec<u8>, String> {
        match self.lagrange.as_ref() {
            Some((_, s)) => s.save_state().map_err(|e| e.to_string()),
            None => Err("this peridynamic body is no lagrange side".into()),
        }
    }
    fn load_state(&mut self, bytes: &[u8]) -> Result<(), String> {
        match self.lagrange.as_mut() {
            Some((_, s)) => s.load_state(bytes).map_err(|e| e.to_string()),
            None => Err("this peridynamic body is no lagrange side".into()),
        }
    }
}

/// The particle model's dimension, from `dimension`.
fn dimension(p: &PdParams) -> SolverResult<Dim> {
    Ok(match p.dimension.as_str() {
        "3d" => Dim::Three,
        "plane_stress" => Dim::PlaneStress,
        "plane_strain" => Dim::PlaneStrain,
        other => {
            return cfg(
                "dimension",
                format!("must be \"3d\", \"plane_stress\" or \"plane_strain\", got \"{other}\""),
            );
        }
    })
}

/// The parameters every model takes, checked (spacing, horizon, density, thickness, step
/// factor, stabilization, material, bodies, damage), and the bodies' size against what a
/// node holds; returns the J2 material they give.
fn check_params(p: &PdParams, three_d: bool) -> SolverResult<J2Material> {
    if !(p.spacing.is_finite() && p.spacing > 0.0) {
        return cfg("spacing", format!("must be > 0, got {}", p.spacing));
    }
    if !(p.horizon.is_finite() && p.horizon > p.spacing) {
        return cfg(
            "horizon",
            format!("must exceed the spacing {} (got {})", p.spacing, p.horizon),
        );
    }
    if !(p.density.is_finite() && p.density > 0.0) {
        return cfg("density", format!("must be > 0, got {}", p.density));
    }
    let thickness_ok = p.thickness.is_finite() && p.thickness > 0.0;
    if !three_d && !thickness_ok {
        return cfg("thickness", format!("must be > 0, got {}", p.thickness));
    }
    if !(p.cfl > 0.0 && p.cfl <= 1.0) {
        return cfg("cfl", format!("must be in (0, 1], got {}", p.cfl));
    }
    if let Some(a) = &p.fragment_axis
        && !((a.len() == 2 || a.len() == 3) && a.iter().all(|x| x.is_finite()))
    {
        return cfg(
            "fragment_axis",
            format!("must be a point [x, y] (or [x, y, z]) of finite numbers, got {a:?}"),
        );
    }
    if !(p.stabilization.is_finite() && p.stabilization >= 0.0) {
        return cfg(
            "stabilization",
            format!("must be >= 0, got {}", p.stabilization),
        );
    }
    let material = J2Material {
        young: p.young,
        poisson: p.poisson,
        yield_stress: p.yield_stress.unwrap_or(f64::MAX),
        iso_hardening: p.iso_hardening,
        kin_hardening: p.kin_hardening,
    };
    if let Err((k, r)) = material.validate() {
        return cfg(&k, r);
    }
    if p.bodies.is_empty() {
        return cfg("bodies", "no body given: the particle set would be empty");
    }
    for (n, s) in p.bodies.iter().enumerate() {
        if let Err(r) = s.check(three_d) {
            return cfg(&format!("bodies[{n}]"), r);
        }
    }
    let damage: Box<dyn DamageModel> = match &p.damage {
        None | Some(DamageParams::None {}) => Box::new(NoDamage),
        Some(DamageParams::CriticalStretch { critical_stretch }) => Box::new(CriticalStretch {
            critical_stretch: *critical_stretch,
        }),
        Some(DamageParams::VonMises { critical_stress }) => Box::new(BrittleVonMises {
            critical_stress: *critical_stress,
        }),
        Some(DamageParams::PlasticStrain {
            eps_threshold,
            eps_critical,
        }) => Box::new(DuctilePlasticStrain {
            threshold: *eps_threshold,
            critical: *eps_critical,
        }),
        Some(DamageParams::JohnsonCook { .. }) => {
            if p.johnson_cook.is_none() {
                return cfg(
                    "damage.kind",
                    "\"johnson_cook\" needs the johnson_cook strength table (its failure indicator grows with that law's plastic strain, rate and temperature)",
                );
            }
            Box::new(FailureIndicator)
        }
    };
    if let Err((k, r)) = damage.validate() {
        return cfg(&format!("damage.{k}"), r);
    }
    // the lattice points each body's bounding box holds: refuse a body that would not
    // fit in memory before generating it (an input must not exhaust the host)
    for (n, s) in p.bodies.iter().enumerate() {
        let (lo, hi) = s.bounds();
        let dims = if three_d { 3 } else { 2 };
        let points: f64 = (0..dims)
            .map(|d| ((hi[d] - lo[d]) / p.spacing).floor() + 1.0)
            .product();
        if !(points <= MAX_LATTICE_POINTS) {
            return cfg(
                &format!("bodies[{n}]"),
                format!(
                    "holds about {points:.3e} lattice points at spacing {}: more than the {MAX_LATTICE_POINTS:.0e} a node takes",
                    p.spacing
                ),
            );
        }
    }
    let particles = lattice_count(&p.bodies, &p.holes, p.spacing, three_d);
    if particles == 0 {
        return cfg("bodies", "the bodies hold no lattice point at this spacing");
    }
    bond_budget(p, particles, three_d)?;
    Ok(material)
}

/// Calls `f` with the kinematics of particles at reference positions `x0` (volumes `vol`)
/// at rest, as a model is built.
fn at_rest<R>(x0: &[[f64; 3]], vol: &[f64], f: impl FnOnce(&super::model::Kinematics) -> R) -> R {
    let rest = vec![[0.0; 3]; x0.len()];
    f(&super::model::Kinematics {
        x0,
        pos: x0,
        disp: &rest,
        vel: &rest,
        vol,
    })
}

/// `initial_velocity`: each region's velocity on the particles in it.
fn set_initial_velocity(body: &mut Body, p: &PdParams) -> SolverResult<()> {
    let three_d = body.dim.three_d();
    for (n, r) in p.initial_velocity.iter().enumerate() {
        if let Err(e) = r.region.check(three_d) {
            return cfg(&format!("initial_velocity[{n}].region"), e);
        }
        for i in 0..body.len() {
            if r.region.contains(&body.x0[i], three_d) {
                body.vel[i] = r.velocity;
            }
        }
    }
    Ok(())
}

/// Twice the largest distance of a particle from the vertical (z) axis through the particles'
/// mean x–y position, plus one spacing: a bar's largest diameter about its axis, whichever
/// way the lattice's diagonals spread it (the extents along x and y see only the lattice's
/// axes).
fn radial_extent(pos: &[[f64; 3]], spacing: f64) -> f64 {
    let n = pos.len().max(1) as f64;
    let (cx, cy) = pos
        .iter()
        .fold((0.0, 0.0), |(a, b), x| (a + x[0] / n, b + x[1] / n));
    let r2 = pos
        .iter()
        .map(|x| (x[0] - cx).powi(2) + (x[1] - cy).powi(2))
        .fold(0.0, f64::max);
    2.0 * r2.sqrt() + spacing
}

/// `walls`: each plane with its normal made unit; every particle must start on the body's
/// side, touching at most (its centre half a spacing or more from the plane).
fn set_walls(body: &mut Body, p: &PdParams) -> SolverResult<()> {
    let three_d = body.dim.three_d();
    for (k, w) in p.walls.iter().enumerate() {
        let key = |f: &str| format!("walls[{k}].{f}");
        if w.point.iter().chain(&w.normal).any(|a| !a.is_finite()) {
            return cfg(&key("point"), "the point and the normal must be finite");
        }
        if !three_d && w.normal[2] != 0.0 {
            return cfg(&key("normal"), "must lie in the plane (z = 0) in 2-D");
        }
        let len = w.normal.iter().map(|a| a * a).sum::<f64>().sqrt();
        if !(len > 0.0) {
            return cfg(&key("normal"), "must not be zero");
        }
        let normal = w.normal.map(|a| a / len);
        let half = 0.5 * body.spacing;
        let behind = (0..body.len()).find(|&i| {
            let gap: f64 = (0..3)
                .map(|d| (body.x0[i][d] - w.point[d]) * normal[d])
                .sum();
            gap < half * (1.0 - 1e-9)
        });
        if let Some(i) = behind {
            let x = body.x0[i];
            return cfg(
                &key("point"),
                format!(
                    "the particle at ({:e}, {:e}, {:e}) starts closer than half a spacing to the \
                     wall or behind it (the normal points toward the body)",
                    x[0], x[1], x[2]
                ),
            );
        }
        body.walls.push(super::integrate::Wall {
            point: w.point,
            normal,
        });
    }
    Ok(())
}

/// `no_fail`: per particle, whether it lies in one of the zones (empty when there are none).
/// A zone that holds no particle is refused: it would protect nothing, and is most likely
/// misplaced.
fn no_fail_of(x0: &[[f64; 3]], p: &PdParams, three_d: bool) -> SolverResult<Vec<bool>> {
    if p.no_fail.is_empty() {
        return Ok(Vec::new());
    }
    let mut flag = vec![false; x0.len()];
    for (n, z) in p.no_fail.iter().enumerate() {
        if let Err(e) = z.check(three_d) {
            return cfg(&format!("no_fail[{n}]"), e);
        }
        let mut any = false;
        for (f, x) in flag.iter_mut().zip(x0) {
            if z.contains(x, three_d) {
                *f = true;
                any = true;
            }
        }
        if !any {
            return cfg(&format!("no_fail[{n}]"), "holds no particle of the body");
        }
    }
    Ok(flag)
}

/// `prescribed_velocity`: each region's particles held at its velocity; returns them, sorted.
fn prescribe_velocity(body: &mut Body, p: &PdParams) -> SolverResult<Vec<usize>> {
    let three_d = body.dim.three_d();
    let mut bc_particles = Vec::new();
    for (n, r) in p.prescribed_velocity.iter().enumerate() {
        if let Err(e) = r.region.check(three_d) {
            return cfg(&format!("prescribed_velocity[{n}].region"), e);
        }
        let mask = match held_mask(r.components.as_deref(), three_d) {
            Ok(m) => m,
            Err(e) => return cfg(&format!("prescribed_velocity[{n}].components"), e),
        };
        for i in 0..body.len() {
            if r.region.contains(&body.x0[i], three_d) {
                let was = body.held_components(i);
                let now = was | mask;
                if now == 0b111 {
                    body.prescribed[i] = 1;
                } else {
                    body.prescribed[i] = 3;
                    body.held[i] = now;
                }
                for d in (0..3).filter(|d| mask & (1 << d) != 0) {
                    body.vpres[i][d] = r.velocity[d];
                    body.vel[i][d] = r.velocity[d];
                }
                bc_particles.push(i);
            }
        }
    }
    bc_particles.sort_unstable();
    bc_particles.dedup();
    Ok(bc_particles)
}

/// The components a support's `components` holds, as bits (bit d for component d; all when
/// absent). A plane body has no z to hold, so z counts as held there.
fn held_mask(components: Option<&str>, three_d: bool) -> Result<u8, String> {
    let Some(c) = components else {
        return Ok(0b111);
    };
    let mut m = 0u8;
    for ch in c.chars() {
        let d = match ch {
            'x' => 0,
            'y' => 1,
            'z' => 2,
            _ => {
                return Err(format!(
                    "must be letters of \"xyz\" (\"y\", \"xz\"), got \"{c}\""
                ));
            }
        };
        m |= 1 << d;
    }
    if m == 0 {
        return Err("holds no component: leave the region out instead".into());
    }
    Ok(if three_d { m } else { m | 0b100 })
}

/// `pressure_pulse`: the particles of the first layer outside the inner face, each with the
/// area vector of the face it carries.
fn pressure_faces(body: &Body, p: &PdParams) -> SolverResult<Vec<(usize, [f64; 3])>> {
    let three_d = body.dim.three_d();
    let mut pressure_area = Vec::new();
    if let Some(pp) = &p.pressure_pulse {
        if pp.surface != "inner" {
            return cfg(
                "pressure_pulse.surface",
                format!("only \"inner\" is offered, got \"{}\"", pp.surface),
            );
        }
        if !(pp.inner_radius > 0.0 && pp.inner_radius.is_finite()) {
            return cfg(
                "pressure_pulse.inner_radius",
                format!("must be > 0, got {}", pp.inner_radius),
            );
        }
        if !(pp.peak.is_finite()) {
            return cfg("pressure_pulse.peak", "must be finite");
        }
        if !(pp.duration > 0.0 && pp.duration.is_finite()) {
            return cfg(
                "pressure_pulse.duration",
                format!("must be > 0, got {}", pp.duration),
            );
        }
        if !(pp.rise >= 0.0 && pp.rise < pp.duration) {
            return cfg(
                "pressure_pulse.rise",
                format!("must be in [0, duration), got {}", pp.rise),
            );
        }
        // Particles of the first layer outside the inner face; each carries Δx·h (2-D)
        // or Δx² (3-D) of the face.
        let a = if three_d {
            p.spacing * p.spacing
        } else {
            p.spacing * p.thickness
        };
        for i in 0..body.len() {
            let dx = body.x0[i][0] - pp.center[0];
            let dy = body.x0[i][1] - pp.center[1];
            let r = (dx * dx + dy * dy).sqrt();
            if r >= pp.inner_radius && r < pp.inner_radius + p.spacing {
                pressure_area.push((i, [a * dx / r, a * dy / r, 0.0]));
            }
        }
        if pressure_area.is_empty() {
            return cfg(
                "pressure_pulse.inner_radius",
                "no particle lies on this face",
            );
        }
    }
    Ok(pressure_area)
}

/// `interfaces`: each interface's name and particles (all or the surface ones, within its
/// regions).
fn interfaces_of(body: &Body, p: &PdParams) -> SolverResult<Vec<(String, Vec<usize>)>> {
    let three_d = body.dim.three_d();
    let surf = surface_particles(&body.x0, &body.bonds, p.spacing, three_d);
    let mut interfaces = Vec::new();
    for (n, ip) in p.interfaces.iter().enumerate() {
        let base: Vec<usize> = match ip.select.as_str() {
            "all" => (0..body.len()).collect(),
            "surface" => surf.clone(),
            other => {
                return cfg(
                    &format!("interfaces[{n}].select"),
                    format!("must be \"all\" or \"surface\", got \"{other}\""),
                );
            }
        };
        for (k, r) in ip.region.iter().chain(&ip.regions).enumerate() {
            if let Err(e) = r.check(three_d) {
                let key = match ip.region {
                    Some(_) if k == 0 => format!("interfaces[{n}].region"),
                    Some(_) => format!("interfaces[{n}].regions[{}]", k - 1),
                    None => format!("interfaces[{n}].regions[{k}]"),
                };
                return cfg(&key, e);
            }
        }
        let pts: Vec<usize> = if ip.region.is_none() && ip.regions.is_empty() {
            base
        } else {
            base.into_iter()
                .filter(|&i| {
                    ip.region
                        .iter()
                        .chain(&ip.regions)
                        .any(|r| r.contains(&body.x0[i], three_d))
                })
                .collect()
        };
        if pts.is_empty() {
            return cfg(&format!("interfaces[{n}]"), "selects no particle");
        }
        interfaces.push((ip.name.clone(), pts));
    }
    Ok(interfaces)
}

/// The device copy of `body` for model `def` (built from `dim`, the parameters and the
/// material), gathering the interfaces' particles and `watched` (the supports' and the
/// reported points') to the host every window; None where `target` opens no device.
fn open_device(
    def: &PdModelDef,
    target: &Device,
    (dim, p, material): (Dim, &PdParams, J2Material),
    body: &Body,
    interfaces: &[(String, Vec<usize>)],
    watched: &[usize],
) -> SolverResult<Option<DeviceBody>> {
    let name = def.name;
    let bad = |e: String| SolverError::config("device", format!("device = \"gpu\": {e}"));
    let Some(dd) = &def.device else {
        return Err(bad(format!("no device kernels for {name}")));
    };
    let mut gather: Vec<usize> = interfaces
        .iter()
        .flat_map(|(_, pts)| pts.iter().copied())
        .chain(watched.iter().copied())
        .collect();
    gather.sort_unstable();
    gather.dedup();
    let Some(ctx) = target.open(&format!("{name} body"))? else {
        return Ok(None);
    };
    let dev = at_rest(&body.x0, &body.vol, |k| {
        let input = ModelInput {
            dim,
            p,
            material,
            k,
            bonds: &body.bonds,
        };
        (dd.open)(ctx, &input, body, &gather)
    })
    .map_err(|e| bad(e.to_string()))?;
    let (now, before) = dev.window_bytes();
    tracing::info!(
        "{name} on the GPU: {now} bytes read back per window ({} particles, {} gathered; the full state would be {before} bytes)",
        body.len(),
        gather.len()
    );
    Ok(Some(dev))
}

/// `loads`: each load's force shared among the particles of its region, with its history.
fn loads_of(body: &Body, p: &PdParams) -> SolverResult<Vec<(usize, [f64; 3], LoadRamp)>> {
    let three_d = body.dim.three_d();
    let mut loads = Vec::new();
    for (n, l) in p.loads.iter().enumerate() {
        let key = format!("loads[{n}].");
        if let Err(e) = l.region.check(three_d) {
            return cfg(&format!("{key}region"), e);
        }
        if !l.force.iter().all(|f| f.is_finite()) {
            return cfg(&format!("{key}force"), "must be finite");
        }
        let history = load_ramp(&key, l.ramp, l.ramp_time)?;
        let pts: Vec<usize> = (0..body.len())
            .filter(|&i| l.region.contains(&body.x0[i], three_d))
            .collect();
        if pts.is_empty() {
            return cfg(&format!("{key}region"), "holds no particle");
        }
        let share = 1.0 / pts.len() as f64;
        loads.extend(
            pts.into_iter()
                .map(|i| (i, l.force.map(|f| f * share), history)),
        );
    }
    Ok(loads)
}

/// `points`: each probe point's particle (within half a spacing) and its displacement
/// series' names.
fn probe_points(body: &Body, p: &PdParams) -> SolverResult<Vec<(Vec<String>, usize)>> {
    let three_d = body.dim.three_d();
    let axes: &[&str] = if three_d {
        &["x", "y", "z"]
    } else {
        &["x", "y"]
    };
    let mut points = Vec::with_capacity(p.points.len());
    for (name, at) in &p.points {
        let key = format!("points.{name}");
        if at.len() != axes.len() || !at.iter().all(|x| x.is_finite()) {
            return cfg(
                &key,
                format!("must be {} finite coordinates, got {at:?}", axes.len()),
            );
        }
        let dist = |i: usize| -> f64 {
            at.iter()
                .enumerate()
                .map(|(d, x)| (body.x0[i][d] - x).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let near = (0..body.len()).min_by(|&a, &b| dist(a).total_cmp(&dist(b)));
        match near {
            Some(i) if dist(i) <= 0.5 * p.spacing => {
                points.push((axes.iter().map(|a| format!("{name}_u{a}")).collect(), i))
            }
            _ => {
                return cfg(&key, format!("no particle within half a spacing of {at:?}"));
            }
        }
    }
    Ok(points)
}

/// What `device = "gpu"` cannot run of model `def` with parameters `p`, as the reason.
fn gpu_supports(def: &PdModelDef, dim: Dim, p: &PdParams) -> Result<(), String> {
    let cpu = "use device = \"cpu\"";
    let Some(dd) = &def.device else {
        let with: Vec<&str> = super::models::ALL
            .iter()
            .filter(|d| d.device.is_some())
            .map(|d| d.name)
            .collect();
        return Err(format!(
            "\"gpu\" is offered for {}, not {} (no device kernels): {cpu}",
            with.join(" and "),
            def.name
        ));
    };
    let kind = match &p.damage {
        None | Some(DamageParams::None {}) => None,
        Some(DamageParams::CriticalStretch { .. }) if dd.critical_stretch => None,
        Some(DamageParams::CriticalStretch { .. }) => Some("critical_stretch"),
        Some(DamageParams::VonMises { .. }) => Some("von_mises"),
        Some(DamageParams::PlasticStrain { .. }) => Some("plastic_strain"),
        Some(DamageParams::JohnsonCook { .. }) => Some("johnson_cook"),
    };
    if let Some(kind) = kind {
        let breaking: Vec<&str> = super::models::ALL
            .iter()
            .filter(|d| d.device.as_ref().is_some_and(|d| d.critical_stretch))
            .map(|d| d.name)
            .collect();
        return Err(format!(
            "\"gpu\" does not support bond damage (damage.kind = \"{kind}\") for {}: the device kernels break bonds only at a critical stretch (damage.kind = \"critical_stretch\"), and only for {}; {cpu}",
            def.name,
            breaking.join(" and ")
        ));
    }
    if let Some(why) = (dd.refuses)(dim, p) {
        return Err(why);
    }
    if p.prescribed_velocity
        .iter()
        .any(|r| held_mask(r.components.as_deref(), dim.three_d()).is_ok_and(|m| m != 0b111))
    {
        return Err(format!(
            "\"gpu\" does not support a support that holds some components only \
             (prescribed_velocity[].components): {cpu}"
        ));
    }
    if !p.walls.is_empty() {
        return Err(format!("\"gpu\" does not support walls: {cpu}"));
    }
    if !p.no_fail.is_empty() {
        return Err(format!(
            "\"gpu\" does not support no-fail zones (no_fail): the device kernels break \
             every bond past the critical stretch; {cpu}"
        ));
    }
    if p.pressure_pulse.is_some() {
        return Err(format!(
            "\"gpu\" does not support pressure_pulse (it changes the external force every substep; the device path holds the external force over a window): {cpu}"
        ));
    }
    Ok(())
}

fn gpu_err(e: mechanics::gpu::GpuError) -> SolverError {
    SolverError::Other(e.to_string())
}

/// [`FirstDamage`] from the damage indices `damage` at time `t1` of the first window with any
/// φ > 0, over the reference positions `x0`; the corners and axes are those of the
/// `hollow_square` / `hollow_cylinder` shapes among `bodies`.
pub fn first_damage_of(bodies: &[Shape], x0: &[[f64; 3]], damage: &[f64], t1: f64) -> FirstDamage {
    let mut corners: Vec<[f64; 2]> = Vec::new();
    let mut axes: Vec<[f64; 2]> = Vec::new();
    for b in bodies {
        match b {
            Shape::HollowSquare {
                center, inner_half, ..
            } => {
                for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
                    corners.push([center[0] + sx * inner_half, center[1] + sy * inner_half]);
                }
            }
            Shape::HollowCylinder { center, .. } => axes.push([center[0], center[1]]),
            _ => {}
        }
    }
    let nearest = |p: &[f64; 3], set: &[[f64; 2]]| {
        set.iter()
            .map(|c| (p[0] - c[0]).hypot(p[1] - c[1]))
            .fold(f64::MAX, f64::min)
    };
    let mut worst = 0usize;
    let (mut count, mut corner, mut rmin, mut rmax) = (0, 0.0f64, f64::MAX, 0.0f64);
    for i in 0..damage.len() {
        if damage[i] <= 0.0 {
            continue;
        }
        count += 1;
        if damage[i] > damage[worst] || damage[worst] <= 0.0 {
            worst = i;
        }
        if !corners.is_empty() {
            corner = corner.max(nearest(&x0[i], &corners));
        }
        if !axes.is_empty() {
            let r = nearest(&x0[i], &axes);
            rmin = rmin.min(r);
            rmax = rmax.max(r);
        }
    }
    FirstDamage {
        time: t1,
        position: x0[worst],
        count,
        corner_distance: if corners.is_empty() { -1.0 } else { corner },
        radius: if axes.is_empty() {
            [-1.0, -1.0]
        } else {
            [rmin, rmax]
        },
    }
}

impl Solver for PdSolver {
    fn warnings(&self) -> Vec<String> {
        let Some(dev) = &self.device else {
            return Vec::new();
        };
        dev.warning().map(|w| w.to_string()).into_iter().collect()
    }

    fn describe(&self) -> NodeDescription {
        NodeDescription {
            model: self.model_name.clone(),
            interfaces: self
                .interfaces
                .iter()
                .map(|(n, p)| InterfaceInfo {
                    name: n.clone(),
                    points: p.len(),
                    provides: [
                        "position",
                        "velocity",
                        "volume",
                        "force",
                        "mass",
                        "stiffness",
                        "lagrange_operator",
                    ]
                    .iter()
                    .map(|s| s.to_string())
                    .collect(),
                    accepts: ["force", "position", "velocity", "mass", "stiffness"]
                        .iter()
                        .map(|s| s.to_string())
                        .collect(),
                })
                .collect(),
            units: "SI".into(),
        }
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        let pts = self.points_of(name)?;
        let mut m = InterfaceMesh::points(pts.iter().map(|&i| self.body.pos[i]).collect());
        m.weights = pts.iter().map(|&i| self.body.vol[i]).collect();
        Ok(m)
    }

    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        self.coupled.clear();
        self.follow_pts.clear();
        self.lagrange = None;
        self.layer = None;
        if bindings.len() > 1
            && let Some(b) = bindings
                .iter()
                .find(|b| scheme::of(b.kind).coordinator_solved())
        {
            return Err(SolverError::interface(
                &b.interface,
                "a peridynamic lagrange side takes no other coupling: join its edges in one \
                 interface (params.interfaces[].regions) and list every subdomain in that \
                 coupling's sides",
            ));
        }
        for b in bindings {
            let pts = self.points_of(&b.interface)?.to_vec();
            let sch = scheme::of(b.kind);
            if sch.coordinator_solved() {
                let (method, window) = lwire::request(inbox, &b.interface)?;
                self.lagrange_side_for(&b.interface, method, window, (0, 1.0))?;
            } else if sch.follows(b.role) {
                if self.device.is_some() {
                    return Err(SolverError::config(
                        "device",
                        format!(
                            "\"gpu\" does not support a kinematic responder coupling (interface '{}'): it moves particles along the driver's path every substep, which the device path does not; use device = \"cpu\"",
                            b.interface
                        ),
                    ));
                }
                let flag = if sch.boundary_layer() {
                    self.setup_layer(&b.interface, &pts)?;
                    2
                } else {
                    1
                };
                for &i in &pts {
                    self.body.prescribed[i] = flag;
                }
                self.follow_pts.extend_from_slice(&pts);
            } else {
                // A set-up mass from the peer (a sync-force responder's, with its stiffness
                // bound): checked; its mass is small against the body's for a boundary layer,
                // so we keep our own step (the runtime's stable-step report carries the bound).
                if let Some(m) = inbox.get(&b.interface, "mass")
                    && m.values.iter().any(|v| !(v.is_finite() && *v >= 0.0))
                {
                    return Err(SolverError::interface(&b.interface, "bad set-up mass"));
                }
            }
            if !sch.coordinator_solved() {
                self.send_fields(&b.interface, &pts, sch.setup_sends(b.role), out)?;
                self.send_fields(&b.interface, &pts, sch.sends(b.role), out)?;
            }
            self.coupled.push(Coupled {
                interface: b.interface.clone(),
                kind: b.kind,
                role: b.role,
                ended: false,
            });
        }
        self.follow = kinematic::Follow::new(kinematic::Path::Held, self.follow_pts.len(), 3);
        Ok(())
    }

    fn stable_dt(&self) -> f64 {
        self.dt()
    }

    fn window_limits(&self) -> Vec<WindowLimit> {
        // As a lagrange side (`lagrange_side_for`): `substeps` steps of at most the stable
        // step, or, without them, one step per window of at most `cfl` of it under gs4 and
        // ph (gc then takes as many as it needs).
        // With `substeps`, the sub-cycling resonance of central differences too.
        let integrator = "central differences (velocity Verlet)".to_string();
        match self.params.substeps {
            Some(n) => {
                let critical = self.body.stable_dt();
                let resonance = crate::lagrange::resonance_limit(
                    &mechanics::time::Gs4::central_difference(),
                    &integrator,
                    n,
                    critical,
                );
                std::iter::once(WindowLimit {
                    applies: LimitApplies::LagrangeSide,
                    integrator,
                    substeps: n as u64,
                    max_step: critical,
                    key: Some("params.substeps".into()),
                    kind: LimitKind::Stability,
                })
                .chain(resonance)
                .collect()
            }
            None => vec![WindowLimit {
                applies: LimitApplies::LagrangeSideGs4OrPh,
                integrator,
                substeps: 1,
                max_step: self.dt(),
                key: None,
                kind: LimitKind::Stability,
            }],
        }
    }

    fn lagrange_side(&mut self, interface: &str) -> Option<&mut dyn LagrangeSide> {
        match &self.lagrange {
            Some((name, _)) if name == interface => Some(self),
            _ => None,
        }
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        let wall = std::time::Instant::now();
        let span = w.t1 - w.t0;
        if !(span > 0.0) {
            return Err(SolverError::Other(format!(
                "empty window [{}, {}]",
                w.t0, w.t1
            )));
        }
        if let Some((_, side)) = &self.lagrange {
            // The runtime stepped the body through the side: its sums are the window's.
            let nsub = (span / side.dt()).round().max(1.0) as u64;
            let (g, total) = (side.load_integral, side.load_total());
            self.external_work = side.external_work;
            self.external_impulse = total.map(|f| f * g);
            self.applied_impulse = g.abs()
                * self
                    .loads
                    .iter()
                    .map(|(_, f, _)| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt())
                    .sum::<f64>();
            self.interface_impulse = side.interface_impulse;
            self.interface_work = side.interface_work;
            return self.window_report(w, nsub, wall);
        }
        let nsub = (span / self.dt() - 1e-9).ceil().max(1.0) as u64;
        let dt = span / nsub as f64;
        self.wall_impulse = [0.0; 3];
        // Inputs of this window.
        for f in self.fcouple.iter_mut() {
            *f = [0.0; 3];
        }
        // Followed motion: each particle's displacement at t0 and the driver's velocity,
        // held over the window. Loads (an immersed fluid's window-averaged force, a
        // sync-force responder's constraint force): held over the window.
        let mut q = 0;
        let coupled = self.coupled.clone();
        for c in &coupled {
            let sch = scheme::of(c.kind);
            if sch.coordinator_solved() {
                continue;
            }
            let pts = self.points_of(&c.interface)?.to_vec();
            let n = pts.len();
            if sch.follows(c.role) {
                let x = inbox.require(&c.interface, "position", 3 * n)?;
                let v = inbox.require(&c.interface, "velocity", 3 * n)?;
                if x.iter().chain(v).any(|a| !a.is_finite()) {
                    return Err(SolverError::interface(
                        &c.interface,
                        "non-finite motion received",
                    ));
                }
                let flag = if sch.boundary_layer() { 2 } else { 1 };
                for (k, &i) in pts.iter().enumerate() {
                    self.body.prescribed[i] = flag;
                    self.follow.set_start(q, &self.body.disp[i]);
                    self.follow.set_end(q, &v[3 * k..3 * k + 3]);
                    let x = self.body.pos[i];
                    self.body.vpres[i] =
                        std::array::from_fn(|d| self.follow.velocity(q, d, x[d], 0, nsub, dt));
                    q += 1;
                }
                continue;
            }
            if sch.loads_may_be_absent() && inbox.get(&c.interface, "force").is_none() {
                continue;
            }
            let f = inbox.require(&c.interface, "force", 3 * n)?;
            if f.iter().any(|a| !a.is_finite()) {
                return Err(SolverError::interface(
                    &c.interface,
                    "non-finite force received",
                ));
            }
            for (k, &i) in pts.iter().enumerate() {
                for d in 0..3 {
                    self.fcouple[i][d] += f[3 * k + d];
                }
            }
        }
        let coupled_pts: Vec<usize> = (0..self.body.len())
            .filter(|&i| self.fcouple[i] != [0.0; 3])
            .collect();
        if let Some(dev) = self.device.as_mut() {
            // The body on the device (kinematic responders and pressure pulses were refused
            // at set-up, so nothing follows a driver and the external force is `fcouple` for the
            // whole window). Only the window report comes back, at the window end.
            dev.advance(&self.fcouple, nsub, dt).map_err(gpu_err)?;
            dev.finish(&mut self.body, w.t1).map_err(gpu_err)?;
            // The held force's impulse, summed in the CPU path's order.
            for _ in 0..nsub {
                for &i in &coupled_pts {
                    for d in 0..3 {
                        self.interface_impulse[d] += self.fcouple[i][d] * dt;
                    }
                }
            }
            for &i in &coupled_pts {
                self.interface_work += dev.work(i);
            }
            for &i in &self.bc_particles {
                let imp = dev.impulse(i);
                for d in 0..3 {
                    self.external_impulse[d] -= imp[d];
                    self.external_work -= imp[d] * self.body.vpres[i][d];
                }
            }
            // and against the held coupling force on them, step by step as on the CPU path
            for _ in 0..nsub {
                for &i in &self.bc_particles {
                    for d in 0..3 {
                        self.external_impulse[d] -= self.fcouple[i][d] * dt;
                        self.external_work -= self.fcouple[i][d] * dt * self.body.vpres[i][d];
                    }
                }
            }
        } else {
            for step in 0..nsub {
                let t = w.t0 + step as f64 * dt;
                let pr = self.pressure_at(t + 0.5 * dt);
                self.body.fext.copy_from_slice(&self.fcouple);
                for &(i, f, h) in &self.loads {
                    let g = h.at(t + 0.5 * dt);
                    for d in 0..3 {
                        self.body.fext[i][d] += g * f[d];
                        self.external_impulse[d] += g * f[d] * dt;
                    }
                    self.applied_impulse +=
                        g.abs() * (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt() * dt;
                }
                for &(i, a) in &self.pressure_area {
                    for d in 0..3 {
                        self.body.fext[i][d] += pr * a[d];
                    }
                    for d in 0..3 {
                        self.external_impulse[d] += pr * a[d] * dt;
                    }
                    self.applied_impulse +=
                        pr * (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt() * dt;
                }
                // the supports' internal force at the step's start (velocity Verlet kicks the
                // free particles with the mean of the start and end forces)
                for (k, &i) in self.bc_particles.iter().enumerate() {
                    self.held_force[k] = self.internal_force(i);
                }
                self.body.step(dt);
                if !self.body.walls.is_empty() {
                    let ws = self.body.wall_step;
                    for d in 0..3 {
                        self.external_impulse[d] += ws.impulse[d];
                        self.wall_impulse[d] += ws.impulse[d];
                    }
                    self.applied_impulse += ws.impulse_magnitude;
                    self.external_work += ws.work;
                }
                for &i in &coupled_pts {
                    for d in 0..3 {
                        self.interface_impulse[d] += self.fcouple[i][d] * dt;
                        self.interface_work += self.fcouple[i][d] * dt * self.body.vel[i][d];
                    }
                }
                for &(i, f, h) in &self.loads {
                    let g = h.at(t + 0.5 * dt);
                    for d in 0..3 {
                        self.external_work += g * f[d] * dt * self.body.vel[i][d];
                    }
                }
                // Supports: the impulse that holds prescribed particles on their path. The
                // free particles' momentum changes by the mean of the internal force at the
                // step's start and end (velocity Verlet), whose sum over the body is minus the
                // held particles' (internal forces are pairwise); every external force on a
                // held particle (a coupling's force too) goes into the support.
                for (k, &i) in self.bc_particles.iter().enumerate() {
                    let (f0, f) = (self.held_force[k], self.internal_force(i));
                    let fe = self.body.fext[i];
                    let held = self.body.held_components(i);
                    for d in (0..3).filter(|d| held & (1 << d) != 0) {
                        let j = -(0.5 * dt * (f0[d] + f[d]) + fe[d] * dt);
                        self.external_impulse[d] += j;
                        // a driven grip works on the body (a fixed support does not)
                        self.external_work += j * self.body.vpres[i][d];
                    }
                }
                for (q, &i) in self.follow_pts.iter().enumerate() {
                    // seed 004 eq. (31): along the driver's motion.
                    let u = std::array::from_fn(|d| self.follow.position(q, d, step, nsub, dt));
                    self.body.set_disp(i, u);
                    if self.body.prescribed[i] == 2 {
                        continue;
                    }
                    let f = self.internal_force(i);
                    for d in 0..3 {
                        self.interface_impulse[d] -= f[d] * dt;
                    }
                }
                self.layer_step(dt);
            }
        }
        // Land exactly on the driver's positions at t1.
        for c in coupled
            .iter()
            .filter(|c| scheme::of(c.kind).follows(c.role))
        {
            let pts = self.points_of(&c.interface)?.to_vec();
            let x = inbox.require(&c.interface, "position", 3 * pts.len())?;
            for (k, &i) in pts.iter().enumerate() {
                let x = [x[3 * k], x[3 * k + 1], x[3 * k + 2]];
                let x0 = self.body.x0[i];
                self.body.set_disp(i, std::array::from_fn(|d| x[d] - x0[d]));
                self.body.pos[i] = x;
            }
        }
        if !self.follow.is_empty() {
            self.body.eval_forces(0.0);
        }
        self.layer_window_end(span);
        // Outputs at t1.
        for c in &coupled {
            if c.ended || scheme::of(c.kind).coordinator_solved() {
                continue;
            }
            let pts = self.points_of(&c.interface)?.to_vec();
            let fields = scheme::of(c.kind).sends(c.role);
            self.send_fields(&c.interface, &pts, fields, out)?;
        }
        self.window_report(w, nsub, wall)
    }

    /// The body at set-up: its particles may start moving (a launched block); it starts
    /// in its reference configuration, unstressed, so its strain energy is zero (computed,
    /// not assumed).
    fn initial_report(&mut self) -> SolverResult<StepReport> {
        let (strain, plastic, fracture) = self.energies();
        Ok(StepReport {
            kinetic_energy: self.body.kinetic_energy(),
            internal_energy: strain,
            momentum: self.body.momentum(),
            momentum_gross: self.body.momentum_gross(),
            scalars: vec![
                ("plastic_work".into(), plastic),
                ("fracture_energy".into(), fracture),
            ],
            ..Default::default()
        })
    }

    /// Seed 000 §4 decoupling: an immersed coupling ends and the body goes on alone. The
    /// force the gas sent before the end (in flight across the one-window lag) is still
    /// applied when it arrives; nothing more is sent there. A kinematic coupling holds
    /// particles on a driver's path and cannot simply end.
    fn decouple(&mut self, interface: &str) -> SolverResult<()> {
        for c in self.coupled.iter_mut().filter(|c| c.interface == interface) {
            if !scheme::of(c.kind).decouples() {
                return Err(SolverError::interface(
                    interface,
                    "only an immersed coupling can be decoupled",
                ));
            }
            c.ended = true;
        }
        Ok(())
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        // A lagrange side's coupling state goes beside this (`LagrangeSide::save_state`, the
        // runtime pairs them).
        let b = &self.body;
        // the device path keeps the state on the device: read it in full here
        let snap = match &self.device {
            Some(dev) => Some(dev.snapshot().map_err(gpu_err)?),
            None => None,
        };
        let (disp, vel, force) = match &snap {
            Some(s) => (&s.disp, &s.vel, &s.force),
            None => (&b.disp, &b.vel, &b.force),
        };
        let model = match snap
            .as_ref()
            .and_then(|s| s.states.as_ref().zip(s.plastic_work.as_ref()))
        {
            // pd-correspondence on the device: its J2 states, plastic work and released bond
            // energy (none: no damage on the device), in the model's own form
            Some((states, plastic_work)) => encode_state(&CorrHistory {
                state: Cow::Borrowed(states),
                plastic_work: Cow::Borrowed(plastic_work),
                released: Cow::Owned(vec![0.0; states.len()]),
            })?,
            None => b.model.save_state()?,
        };
        encode_state(&BodyState {
            particles: b.len(),
            bonds: b.bonds.len(),
            time: b.time,
            steps: b.steps,
            disp: Cow::Borrowed(disp),
            vel: Cow::Borrowed(vel),
            force: Cow::Borrowed(force),
            vpres: Cow::Borrowed(&b.vpres),
            prescribed: Cow::Borrowed(&b.prescribed),
            intact: Cow::Borrowed(&b.bonds.intact),
            external_impulse: self.external_impulse,
            interface_impulse: self.interface_impulse,
            applied_impulse: self.applied_impulse,
            interface_work: self.interface_work,
            external_work: self.external_work,
            first_damage: self.first_damage,
            model,
            layer_start: Cow::Borrowed(self.layer.as_ref().map_or(&[], |l| &l.start)),
            layer_sent: Cow::Borrowed(self.layer.as_ref().map_or(&[], |l| &l.sent)),
        })
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        self.fragment_cache = None;
        let s: BodyState = decode_state(bytes)?;
        let b = &mut self.body;
        let (n, nb) = (b.len(), b.bonds.len());
        if s.particles != n || s.bonds != nb {
            return Err(SolverError::Other(format!(
                "load_state: a state of {} particles / {} bonds, this body has {n} / {nb}",
                s.particles, s.bonds
            )));
        }
        for (what, got) in [
            ("displacements", s.disp.len()),
            ("velocities", s.vel.len()),
            ("forces", s.force.len()),
            ("prescribed velocities", s.vpres.len()),
            ("prescribed flags", s.prescribed.len()),
        ] {
            check_len(what, got, n)?;
        }
        check_len("bond damage", s.intact.len(), nb)?;
        let layer = self.layer.as_ref().map_or(0, |l| l.pts.len());
        check_len("boundary layer pulls", s.layer_start.len(), layer)?;
        check_len("boundary layer forces", s.layer_sent.len(), layer)?;
        // the model first: nothing changes unless the whole state reads
        b.model.load_state(&s.model)?;
        b.time = s.time;
        b.steps = s.steps;
        b.disp = s.disp.into_owned();
        b.sync_positions();
        b.vel = s.vel.into_owned();
        b.force = s.force.into_owned();
        b.vpres = s.vpres.into_owned();
        b.prescribed = s.prescribed.into_owned();
        b.bonds.intact = s.intact.into_owned();
        self.external_impulse = s.external_impulse;
        self.interface_impulse = s.interface_impulse;
        self.applied_impulse = s.applied_impulse;
        self.interface_work = s.interface_work;
        self.external_work = s.external_work;
        self.first_damage = s.first_damage;
        if let Some(dev) = self.device.as_mut() {
            dev.rebuild(&self.body).map_err(gpu_err)?;
        }
        if let Some(l) = self.layer.as_mut() {
            // the pull the window starts from and the force sent, as the run before the stop
            // had them
            l.start.copy_from_slice(&s.layer_start);
            l.last.copy_from_slice(&s.layer_start);
            l.sent.copy_from_slice(&s.layer_sent);
            l.impulse.fill([0.0; 3]);
        }
        Ok(())
    }

    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        let b = &self.body;
        let n = b.len();
        // the device path keeps the state on the device: read it in full for the frame
        let snap = match &self.device {
            Some(dev) => Some(dev.snapshot().map_err(gpu_err)?),
            None => None,
        };
        let (disp_s, vel_s) = match &snap {
            Some(s) => (&s.disp, &s.vel),
            None => (&b.disp, &b.vel),
        };
        let pos: Vec<[f64; 3]> = (0..n)
            .map(|i| std::array::from_fn(|d| b.x0[i][d] + disp_s[i][d]))
            .collect();
        let flat = |a: &[[f64; 3]]| {
            a.iter()
                .flat_map(|v| v.iter().copied())
                .collect::<Vec<f64>>()
        };
        let mut data: Arrays = vec![
            ("displacement", 3, flat(disp_s)),
            ("velocity", 3, flat(vel_s)),
        ];
        let (stress, plastic) = match snap.as_ref().and_then(|s| s.states.as_ref()) {
            Some(st) => (
                Some(st.iter().map(|s| s.stress).collect::<Vec<_>>()),
                Some(st.iter().map(|s| s.eq_plastic_strain).collect::<Vec<_>>()),
            ),
            None => (b.model.stress(), b.model.plastic_strain()),
        };
        if let Some(s) = stress {
            let full: Vec<f64> = s
                .iter()
                .flat_map(|s| [s[0], s[5], s[4], s[5], s[1], s[3], s[4], s[3], s[2]])
                .collect();
            data.push(("stress", 9, full));
        }
        if let Some(p) = plastic {
            data.push(("plastic_strain", 1, p));
        }
        for (name, values) in b.model.point_scalars() {
            data.push((name, 1, values));
        }
        let mut bonds = b.bonds.clone();
        b.model.sync_bonds(&mut bonds);
        let mut d = vec![0.0; n];
        bonds.damage(&b.vol, &mut d);
        data.push(("damage", 1, d));
        if !matches!(self.params.damage, None | Some(DamageParams::None {})) {
            // the fragment table of this frame and each particle's fragment (−1: debris)
            b.model.fragment_links(&pos, &mut bonds);
            let (label, sizes) = super::fracture::components(&bonds, &bonds.intact);
            let (frags, of) = self.measured_fragments(&label, &sizes, vel_s);
            write_fragments(&dir.join("fragments.csv"), t, &frags)?;
            let ids = of
                .iter()
                .map(|&k| if k == u32::MAX { -1.0 } else { k as f64 })
                .collect();
            data.push(("fragment", 1, ids));
        }
        let frame = Frame {
            dir,
            stem: "pd",
            window,
            time: t,
        };
        vtk::write_vtu(&frame, vtk::point_cloud(&pos, data))?;
        Ok(())
    }
}

/// `fragments.csv`: one row per fragment of the frame at time `t`, heaviest first — index,
/// particles, mass (kg), centre of mass (m), its velocity and speed (m/s), width and
/// thickness (m).
fn write_fragments(path: &Path, t: f64, frags: &[super::fracture::Fragment]) -> SolverResult<()> {
    let header: Vec<String> = [
        "time",
        "fragment",
        "particles",
        "mass",
        "x",
        "y",
        "z",
        "vx",
        "vy",
        "vz",
        "speed",
        "width",
        "thickness",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let rows = frags.iter().enumerate().map(|(k, f)| {
        [t, k as f64, f.particles as f64, f.mass]
            .into_iter()
            .chain(f.centroid)
            .chain(f.velocity)
            .chain([f.speed(), f.width, f.thickness])
    });
    node_kit::table::write_csv(path, &header, rows).map_err(SolverError::from)
}
