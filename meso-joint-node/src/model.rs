//! The MC-SPG particle model and its explicit time step (seed 004 §2): state in structs of
//! arrays, kernels as free functions over slices, the `Model` only orchestrating.
//!
//! One step (central difference, forces `f^n` known at `x^n`):
//! 1. smoothed acceleration `a_J = f_J / m_J` and the scatter update of the unsmoothed
//!    velocity `v̂_I += Δt Σ_J φ_J(X_I) a_J` (eq. 10–11);
//! 2. gather smoothing `v_I = Σ_J m̂_J φ_I(X_J) v̂_J / m_I`, `m_I = Σ_J m̂_J φ_I(X_J)`
//!    (eq. 2–6); rigid bodies and prescribed particles then set their velocities;
//! 3. `x += Δt v` (eq. 7); incremental deformation gradient `F̂ = I + Σ_J (u_J − u_I) ⊗
//!    ∇φ_J(X_I)` from the anchor (eq. 12–14), velocity gradient, continuity density (eq. 8–9),
//!    Jaumann-rotated J2 update (shared `mechanics::j2`);
//! 4. bond failure (eq. 15–17) and, every `reanchor_every` steps, re-anchoring of the
//!    adaptive anisotropic Lagrangian kernel;
//! 5. direct-nodal-integration internal force `f_K = −Σ_I V_I σ_I F̂_I⁻ᵀ ∇φ_K(X_I)` (eq. 28),
//!    gathered through the mirror entries.
//!
//! Linear momentum `Σ_I m_I v_I = Σ_J m̂_J v̂_J` is conserved exactly by the pair (1)+(2)
//! because `m_K = Σ_J m̂_J φ_K(X_J)` (eq. 5) and `Σ_K f_K = 0` (`Σ_K ∇φ_K = 0`).
//!
//! **Why the smoothing kernel must reproduce linear fields (angular momentum).** Write the
//! pair as one matrix `A_JK = m̂_J φ_K(X_J) / m_K = ψ_K(X_J)`: the gather is `v = Aᵀ v̂`
//! (eq. 2, 6) and the scatter `m̂ Δv̂ = Δt A f` (eq. 10–11). This is exactly the central
//! difference of the Lagrangian `½ Σ m̂_J |v̂_J|² − W(x)`, `x = X̂ + Aᵀ û` with `û̇ = v̂`: the
//! momentum conjugate to the unsmoothed positions `y = X̂ + û` is `m̂ v̂`. It is conserved by
//! translation because `Σ_J A_JK = 1`. Rotation `û → Qû + (Q − I) X̂` maps `x → Q x` (so
//! `W` is invariant) only if `Σ_J A_JK X̂_J = X̂_K`, i.e. the gather weights `ψ_K(X_J)` also
//! reproduce linear fields. Then `L = Σ_J y_J × m̂_J v̂_J` obeys, in the discrete step,
//! `Lⁿ⁺½ − Lⁿ⁻½ = Δt Σ_K (Aᵀyⁿ)_K × f_K = Δt Σ_K x_K × f_K = 0` (the DNI force is torque
//! free, `σ` symmetric): angular momentum to round-off. Eq. 3 with the RK `φ_I(X_J)` of
//! row J reproduces constants only (`Smoothing::Shepard`, which drifts); the default
//! `Smoothing::Consistent` uses for `φ_I^a` the kernel of particle I with the mass-weighted
//! first-order correction (`shape::Rows::compute_psi`), normalised so that `m_I = m̂_I`.
//! Re-anchoring changes `A` and resets `y ← x`; the resulting change of `L` (the part of the
//! unsmoothed displacement filtered out by the old smoothing) is restored by the
//! mass-weighted least-change rigid rotation of `v̂` of the free particles. Bond breakage
//! (eq. 16) also changes `A`; it is not corrected (an open, dissipative event).

use crate::config::Smoothing;
use crate::profile::{Phase, PhaseClock};
use crate::shape::{M3, Rows};
use crate::solid::{NONE, Solid};
use mechanics::blast_solid::{BlastPoint, BlastSolid};
use mechanics::j2::{J2Material, J2State, Sym, jaumann_rotate};
use mechanics::stress_law::StressLaw;
use mechanics::tensor::{self, IDENTITY, Matrix3, Vector3, vec3};
use rayon::prelude::*;

/// Momentum and kinetic energy of a set of particles, summed.
#[derive(Default)]
struct Motion {
    p: [f64; 3],
    e: f64,
}

impl Motion {
    fn add(&mut self, m: f64, v: &[f64; 3]) {
        for d in 0..3 {
            self.p[d] += m * v[d];
        }
        self.e += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    }
}

/// What drives a particle's velocity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[repr(u8)]
pub enum Kind {
    Free = 0,
    /// Velocity boundary condition (group index in `Model::bcs`).
    Prescribed = 1,
    /// Member of a rigid body.
    Rigid = 2,
    /// Moved by the driver of a kinematic coupling.
    Coupled = 3,
}

/// A rigid body (bolt, screw) made of particles (seed 004 §4.2).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct RigidBody {
    pub particles: Vec<u32>,
    pub mass: f64,
    pub com: [f64; 3],
    pub vel: [f64; 3],
    pub omega: [f64; 3],
}

/// One velocity boundary condition group.
#[derive(Debug, Clone)]
pub struct BcGroup {
    pub name: String,
    pub particles: Vec<u32>,
    /// Element nodes (of no particle) under the condition.
    pub nodes: Vec<u32>,
    pub velocity: [f64; 3],
    pub ramp: f64,
}

/// Static model parameters.
#[derive(Debug, Clone)]
pub struct ModelParams {
    /// The elastic constants (the stable step) and, without `blast`, J2 plasticity.
    pub material: J2Material,
    /// Johnson–Cook strength (with an optional Mie–Grüneisen pressure) in place of the J2
    /// hardening of `material`, whose elastic constants it shares.
    pub blast: Option<BlastSolid>,
    pub density: f64,
    pub spacing: f64,
    pub support: f64,
    pub eps_crit: f64,
    pub e_crit: f64,
    pub reanchor_every: u64,
    pub smoothing: Smoothing,
    pub cfl: f64,
    /// `Some(k)`: rigid fasteners bear on the plates through a penalty contact of
    /// stiffness k (N/m) instead of sharing kernel rows with them (a bolt in a hole);
    /// `None`: rigid bodies are bonded to the material around them (a thread-formed screw).
    pub bearing: Option<f64>,
}

/// Steps between refreshes of the bearing-contact candidate pairs (2 h apart or less):
/// a pair cannot close the gap h in this many steps at the speeds of a joint test.
const CONTACT_REFRESH: u64 = 10;

/// Buffers of the bearing-contact candidate search: the particles within 2 h of the rigid
/// bodies' bounding box, their positions and a cell list over them.
#[derive(Debug, Clone, Default)]
pub struct ContactSearch {
    near: Vec<u32>,
    xs: Vec<[f64; 3]>,
    grid: mechanics::neighbour::CellGrid,
}

/// The particle state (structure of arrays).
#[derive(Debug, Clone)]
pub struct Model {
    pub p: ModelParams,
    /// Initial, anchor and current positions.
    pub x0: Vec<[f64; 3]>,
    pub xa: Vec<[f64; 3]>,
    pub x: Vec<[f64; 3]>,
    /// Unsmoothed positions `y = X̂ + û` (moved by v̂; `Smoothing::Consistent`).
    pub xh: Vec<[f64; 3]>,
    /// Displacement since the anchor `u = x − X̂` (scratch of the kinematics, eq. 14).
    pub u: Vec<[f64; 3]>,
    /// Unsmoothed (v̂) and smoothed (v) velocities.
    pub vh: Vec<[f64; 3]>,
    pub v: Vec<[f64; 3]>,
    /// Internal force at the current positions.
    pub f: Vec<[f64; 3]>,
    pub acc: Vec<[f64; 3]>,
    /// Physical mass, inertial (possibly mass-scaled) lumped mass m̂, smoothed mass m (eq. 5).
    pub mass: Vec<f64>,
    pub mh: Vec<f64>,
    pub ms: Vec<f64>,
    pub rho: Vec<f64>,
    pub vol: Vec<f64>,
    pub vol0: Vec<f64>,
    /// The shape functions' quadrature weights at the anchor: the volumes there, scaled by
    /// `kernel_scale`.
    pub vol_a: Vec<f64>,
    /// A particle's kernel weight over its volume: 1, but a particle on the boundary of an
    /// SPG core among solid elements weighs as a whole cell in its neighbours' shape
    /// functions while it integrates only the core's share of the cells it touches (with
    /// its partial volume as weight, a uniform stretch left forces of 0.13 σ h² inside the
    /// core, measured; with the whole cell, 6e-8 σ h² at a stretch of 1e-8).
    pub kernel_scale: Vec<f64>,
    /// Incremental deformation gradient since the anchor, total F at the anchor and its inverse.
    pub fhat: Vec<M3>,
    pub ftot_a: Vec<M3>,
    pub finv_a: Vec<M3>,
    pub mat: Vec<Point>,
    /// `V σ F̂⁻ᵀ` per particle (the DNI stress factor).
    pub bmat: Vec<M3>,
    /// Internal (stress) work per particle.
    pub eint: Vec<f64>,
    pub part: Vec<u32>,
    pub kind: Vec<Kind>,
    /// Velocity imposed on non-free particles for the current step.
    pub presc: Vec<[f64; 3]>,
    pub rows: Rows,
    pub dirty: Vec<bool>,
    pub rigid: Vec<RigidBody>,
    pub bcs: Vec<BcGroup>,
    pub steps: u64,
    pub time: f64,
    pub broken_bonds: usize,
    /// Broken bonds by the part of the particle whose row holds them: [within the material,
    /// with a rigid body], each bond counted from both ends (kept as they break; recounted
    /// from the bonds on loading a checkpoint, [`Model::count_broken_by_part`]).
    pub broken_by_part: Vec<[u64; 2]>,
    /// Row rebuilds that found a particle cut loose by broken bonds (detached rows).
    pub detached: usize,
    /// The damage zone: particles that have lost a bond, and their support neighbours.
    pub damaged: Vec<bool>,
    /// A particle keeping less than this share of its kernel weight after bond failure is
    /// separated (0, the default: only when its moment matrix is singular).
    pub separation_weight: f64,
    /// Work of the prescribed-velocity supports and of the coupling (reaction power).
    pub bc_work: f64,
    pub bc_impulse: [f64; 3],
    pub coupling_work: f64,
    pub coupling_impulse: [f64; 3],
    /// The coupled particles' momentum and kinetic energy when last booked (in the mass and
    /// velocity of the `momentum` sums): what they exchange with the free particles between
    /// two bookings (the smoothing) crossed the interface too.
    pub coupled_p: [f64; 3],
    pub coupled_ke: f64,
    pub max_eps: f64,
    /// Candidate (rigid, other) particle pairs of the bearing contact, refreshed every
    /// `CONTACT_REFRESH` steps from a 2-spacing neighbour search.
    pub contact_pairs: Vec<(u32, u32)>,
    /// Scratch of the candidate search (kept between refreshes).
    pub contact_search: ContactSearch,
    /// Elastic energy stored in the bearing contact now (J).
    pub contact_energy: f64,
    /// Time per phase of the step (off unless enabled; `profile`).
    pub clock: PhaseClock,
    /// Hexahedra around the particles (`solid`), sharing the particles on their boundary.
    pub solid: Option<Solid>,
}

/// Why a step failed.
pub type StepResult = Result<(), String>;

impl Model {
    /// A model of free particles at `x` with lattice volumes `vol`, parts `part` (bonds only
    /// within one part, or with a rigid body), kernel supports from `find_neighbours`.
    pub fn new(
        p: ModelParams,
        x: Vec<[f64; 3]>,
        vol: Vec<f64>,
        part: Vec<u32>,
        rigid_parts: &[u32],
    ) -> Result<Self, String> {
        Self::with_solid(p, x, vol, part, rigid_parts, None, None)
    }

    /// As [`Model::new`], with hexahedra whose boundary nodes are particles: their lumped
    /// mass joins those particles' before the shapes (and the smoothing weights, which
    /// depend on the masses) are computed. `kernel_vol`: each particle's weight in the
    /// shape functions (default: its volume; `kernel_scale`).
    pub fn with_solid(
        p: ModelParams,
        x: Vec<[f64; 3]>,
        vol: Vec<f64>,
        part: Vec<u32>,
        rigid_parts: &[u32],
        solid: Option<Solid>,
        kernel_vol: Option<Vec<f64>>,
    ) -> Result<Self, String> {
        let n = x.len();
        if let Some(k) = &kernel_vol
            && k.len() != n
        {
            return Err(format!("{} kernel weights for {n} particles", k.len()));
        }
        let fam = mechanics::neighbour::find_neighbours(&x, p.support);
        let is_rigid = |k: usize| rigid_parts.contains(&part[k]);
        // Pairs at the support distance or beyond have zero kernel weight for good (the
        // window is evaluated at the material distance, shape.rs): leave them out of the rows.
        // The 1e-9 margin drops lattice pairs at exactly the support that round-off puts a hair
        // inside (weight ~1e-27 of the centre value, far below round-off).
        let reach = p.support * (1.0 - 1e-9);
        let bonded_to_rigid = p.bearing.is_none();
        let rows = Rows::build(&fam, &x, |i, j| {
            let rigid_pair = if bonded_to_rigid {
                is_rigid(i) || is_rigid(j)
            } else {
                is_rigid(i) && is_rigid(j)
            };
            (part[i] == part[j] || rigid_pair) && (vec3(&x[i]) - vec3(&x[j])).norm() < reach
        });
        let mass: Vec<f64> = vol.iter().map(|v| v * p.density).collect();
        // A particle shared with elements moves their mass too (its inertial mass m̂); its
        // physical mass stays its own cells' share, which its density and volume follow.
        let mut mh = mass.clone();
        if let Some(sd) = &solid {
            for (k, &i) in sd.node_particle.iter().enumerate() {
                if i != NONE {
                    mh[i as usize] += sd.mass[k];
                }
            }
        }
        let mut m = Model {
            x0: x.clone(),
            xa: x.clone(),
            xh: x.clone(),
            u: vec![[0.0; 3]; n],
            vh: vec![[0.0; 3]; n],
            v: vec![[0.0; 3]; n],
            f: vec![[0.0; 3]; n],
            acc: vec![[0.0; 3]; n],
            ms: mh.clone(),
            mh,
            mass,
            rho: vec![p.density; n],
            vol0: vol.clone(),
            kernel_scale: match &kernel_vol {
                Some(k) => k.iter().zip(&vol).map(|(k, v)| k / v).collect(),
                None => vec![1.0; n],
            },
            vol_a: kernel_vol.unwrap_or_else(|| vol.clone()),
            vol,
            fhat: vec![IDENTITY; n],
            ftot_a: vec![IDENTITY; n],
            finv_a: vec![IDENTITY; n],
            mat: vec![Point::initial(p.blast.as_ref()); n],
            bmat: vec![[[0.0; 3]; 3]; n],
            eint: vec![0.0; n],
            kind: vec![Kind::Free; n],
            presc: vec![[0.0; 3]; n],
            dirty: vec![false; n],
            rows,
            part,
            rigid: Vec::new(),
            bcs: Vec::new(),
            steps: 0,
            time: 0.0,
            broken_bonds: 0,
            broken_by_part: Vec::new(),
            detached: 0,
            damaged: vec![false; n],
            separation_weight: 0.0,
            bc_work: 0.0,
            bc_impulse: [0.0; 3],
            coupling_work: 0.0,
            coupling_impulse: [0.0; 3],
            coupled_p: [0.0; 3],
            coupled_ke: 0.0,
            max_eps: 0.0,
            contact_pairs: Vec::new(),
            contact_search: ContactSearch::default(),
            contact_energy: 0.0,
            clock: PhaseClock::default(),
            solid,
            x,
            p,
        };
        for (k, rp) in rigid_parts.iter().enumerate() {
            let particles: Vec<u32> = (0..n)
                .filter(|&i| m.part[i] == *rp)
                .map(|i| i as u32)
                .collect();
            for &i in &particles {
                m.kind[i as usize] = Kind::Rigid;
            }
            let _ = k;
            m.rigid.push(RigidBody {
                particles,
                ..Default::default()
            });
        }
        m.rebuild_shapes(None)?;
        m.update_rigid_mass();
        m.broken_by_part = m.count_broken_by_part();
        Ok(m)
    }

    pub fn len(&self) -> usize {
        self.x.len()
    }
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Recompute shape functions (all rows or the flagged ones) and the smoothed masses.
    /// At set-up (`self.steps == 0`) a singular row is an error (the support is too small
    /// for the lattice); during the run it is a particle that broken bonds (eq. 16) have cut
    /// loose, and it is detached (`Rows::compute_detaching`; counted in `detached`).
    pub fn rebuild_shapes(&mut self, which: Option<&[bool]>) -> Result<(), String> {
        let singular = |i: usize| {
            format!(
                "particle {i}: singular moment matrix (kernel support holds too few intact neighbours)"
            )
        };
        if self.steps == 0 {
            self.rows
                .compute(&self.xa, &self.vol_a, self.p.support, which)
                .map_err(singular)?;
            if self.p.smoothing == Smoothing::Consistent {
                self.rows
                    .compute_psi(&self.mh, self.p.support, which)
                    .map_err(singular)?;
            }
        } else {
            let keep = self.separation_weight;
            self.detached +=
                self.rows
                    .compute_detaching(&self.xa, &self.vol_a, self.p.support, which, keep);
            if self.p.smoothing == Smoothing::Consistent {
                self.rows
                    .compute_psi_detaching(&self.mh, self.p.support, which, keep);
            }
        }
        self.rows.refresh_transposed();
        self.update_smoothed_mass();
        // Re-gather v with the new rows (acc is scratch here: it is recomputed at the start of
        // the next step).
        match self.p.smoothing {
            Smoothing::Consistent => gather_consistent(&self.rows, &self.vh, &mut self.acc),
            Smoothing::Shepard => {
                gather_smooth(&self.rows, &self.mh, &self.ms, &self.vh, &mut self.acc)
            }
            _ => return Ok(()),
        }
        let (kind, acc) = (&self.kind, &self.acc);
        self.v.par_iter_mut().enumerate().for_each(|(i, v)| {
            if kind[i] == Kind::Free {
                *v = acc[i];
            }
        });
        Ok(())
    }

    /// Smoothed mass `m_I = Σ_J m̂_J φ_I(X_J)` (eq. 5); `m̂_I` with the consistent kernel,
    /// whose normalisation is chosen so (module doc).
    pub fn update_smoothed_mass(&mut self) {
        let rows = &self.rows;
        let mh = &self.mh;
        match self.p.smoothing {
            Smoothing::Shepard => self.ms.par_iter_mut().enumerate().for_each(|(i, m)| {
                let mut s = 0.0;
                for p in rows.range(i) {
                    s += mh[rows.cols[p] as usize] * rows.phi[rows.mirror[p] as usize];
                }
                *m = s;
            }),
            _ => self.ms.copy_from_slice(mh),
        }
    }

    fn update_rigid_mass(&mut self) {
        for b in &mut self.rigid {
            b.mass = b.particles.iter().map(|&i| self.mh[i as usize]).sum();
            let mut c = [0.0; 3];
            for &i in &b.particles {
                for d in 0..3 {
                    c[d] += self.mh[i as usize] * self.x[i as usize][d];
                }
            }
            b.com = c.map(|v| v / b.mass.max(f64::MIN_POSITIVE));
        }
    }

    /// Register a velocity boundary condition on the particles for which `sel` is true.
    pub fn add_velocity_bc(
        &mut self,
        name: &str,
        velocity: [f64; 3],
        ramp: f64,
        sel: impl Fn(&[f64; 3]) -> bool,
    ) -> usize {
        let particles: Vec<u32> = (0..self.len())
            .filter(|&i| self.kind[i] == Kind::Free && sel(&self.x0[i]))
            .map(|i| i as u32)
            .collect();
        for &i in &particles {
            self.kind[i as usize] = Kind::Prescribed;
        }
        let mut nodes = Vec::new();
        if let Some(sd) = self.solid.as_mut() {
            for k in 0..sd.len() {
                if sd.own(k) && !sd.held[k] && sel(&sd.x0[k]) {
                    sd.held[k] = true;
                    nodes.push(k as u32);
                }
            }
        }
        let n = particles.len() + nodes.len();
        self.bcs.push(BcGroup {
            name: name.to_string(),
            particles,
            nodes,
            velocity,
            ramp,
        });
        n
    }

    /// Dilatational wave speed bound and stable step `cfl · h / c` (h from the current volume).
    pub fn stable_dt(&self) -> f64 {
        let e = &self.p.material;
        let modulus = e.bulk_modulus() + 4.0 / 3.0 * e.shear_modulus();
        let mut dt = f64::INFINITY;
        for i in 0..self.len() {
            let h = self.p.spacing * (self.vol[i] / self.vol0[i]).cbrt();
            let rho_eff = self.mh[i] / self.vol[i];
            dt = dt.min(self.p.cfl * h * (rho_eff / modulus).sqrt());
        }
        if let Some(sd) = &self.solid {
            dt = dt.min(sd.stable_dt());
        }
        dt
    }

    /// Mass scaling (seed 004 §4 implies it): raise m̂ so every particle's stable step is at
    /// least `target`. Returns the added mass.
    pub fn mass_scale(&mut self, target: f64) -> f64 {
        let e = &self.p.material;
        let modulus = e.bulk_modulus() + 4.0 / 3.0 * e.shear_modulus();
        let mut added = 0.0;
        if let Some(sd) = self.solid.as_mut() {
            // the elements first: a shared node's particle moves their added mass too
            let add = sd.mass_scale(target);
            added += add.iter().sum::<f64>();
            for (k, a) in add.iter().enumerate() {
                let i = sd.node_particle[k];
                if i != NONE {
                    self.mh[i as usize] += a;
                }
            }
        }
        for i in 0..self.len() {
            let h = self.p.spacing * (self.vol[i] / self.vol0[i]).cbrt();
            let dt_i = self.p.cfl * h * (self.mh[i] / self.vol[i] / modulus).sqrt();
            if dt_i < target {
                let m_new = self.mh[i] * (target / dt_i).powi(2);
                added += m_new - self.mh[i];
                self.mh[i] = m_new;
            }
        }
        if self.p.smoothing == Smoothing::Consistent {
            // ψ depends on m̂ (eq. 3): recompute with the scaled masses.
            if let Err(i) = self.rows.compute_psi(&self.mh, self.p.support, None) {
                tracing::warn!("mass scaling: particle {i} has a singular smoothing row");
            }
            self.rows.refresh_transposed();
        }
        self.update_smoothed_mass();
        self.update_rigid_mass();
        added
    }

    /// Phase 1–2: velocity update and smoothing (eq. 2–6, 10–11), then rigid bodies and
    /// velocity boundary conditions. Coupled particles keep `presc` (set by the caller).
    pub fn velocity_phase(&mut self, dt: f64) {
        self.clock.begin();
        let rows = &self.rows;
        match self.p.smoothing {
            Smoothing::Consistent => {
                // Kinematic particles (supports, rigid bodies, coupling) do not scatter their
                // reaction forces: their motion is imposed (masked inside the scatter).
                scatter_consistent(rows, &self.f, &self.kind, &self.mh, dt, &mut self.vh);
                self.clock.lap(Phase::Scatter);
                gather_consistent(rows, &self.vh, &mut self.v);
            }
            Smoothing::Shepard => {
                // Kinematic particles (supports, rigid bodies, coupling) do not scatter their
                // reaction forces into their neighbours' velocities: their acceleration is
                // imposed, and taken as zero over the step.
                let (f, ms, kind) = (&self.f, &self.ms, &self.kind);
                self.acc.par_iter_mut().enumerate().for_each(|(k, a)| {
                    let im = if kind[k] == Kind::Free {
                        1.0 / ms[k]
                    } else {
                        0.0
                    };
                    *a = [f[k][0] * im, f[k][1] * im, f[k][2] * im];
                });
                scatter_update(rows, &self.acc, dt, &mut self.vh);
                gather_smooth(rows, &self.mh, &self.ms, &self.vh, &mut self.v);
            }
            Smoothing::Average => {
                let (f, mh) = (&self.f, &self.mh);
                self.vh.par_iter_mut().enumerate().for_each(|(k, vh)| {
                    for d in 0..3 {
                        vh[d] += dt * f[k][d] / mh[k];
                    }
                });
                average_smooth(rows, &self.vh, &mut self.v);
            }
            Smoothing::None => {
                let (f, mh) = (&self.f, &self.mh);
                self.vh.par_iter_mut().enumerate().for_each(|(k, vh)| {
                    for d in 0..3 {
                        vh[d] += dt * f[k][d] / mh[k];
                    }
                });
                self.v.copy_from_slice(&self.vh);
            }
        }
        self.clock.lap(Phase::Gather);
        // Rigid bodies: Newton–Euler on the sum of the particle forces. With the consistent
        // scatter, free neighbours also push momentum into the body's particles (their rows
        // reach them): that momentum, m (v̂ − v_rigid), joins the body's force and torque
        // instead of being overwritten, so the body conserves what it receives.
        let consistent = self.p.smoothing == Smoothing::Consistent;
        for b in &mut self.rigid {
            let mut force = [0.0; 3];
            let mut torque = [0.0; 3];
            let mut inertia = [[0.0; 3]; 3];
            for &i in &b.particles {
                let i = i as usize;
                let r = vec3(&self.x[i]) - vec3(&b.com);
                let mut fi = vec3(&self.f[i]);
                if consistent && dt > 0.0 {
                    let w = vec3(&b.omega).cross(&r);
                    for d in 0..3 {
                        let v_rigid = b.vel[d] + w[d];
                        fi[d] += self.mh[i] * (self.vh[i][d] - v_rigid) / dt;
                    }
                }
                let t = r.cross(&fi);
                let r2 = r.norm_squared();
                for a in 0..3 {
                    force[a] += fi[a];
                    torque[a] += t[a];
                    for c in 0..3 {
                        inertia[a][c] += self.mh[i] * (if a == c { r2 } else { 0.0 } - r[a] * r[c]);
                    }
                }
            }
            let inertia = tensor::mat(&inertia);
            let omega = vec3(&b.omega);
            let rhs = vec3(&torque) - omega.cross(&(inertia * omega));
            let dw = tensor::inverse(&inertia, 1e-300)
                .map(|ii| ii * rhs)
                .unwrap_or_else(Vector3::zeros);
            for a in 0..3 {
                b.vel[a] += dt * force[a] / b.mass;
                b.omega[a] += dt * dw[a];
            }
            for &i in &b.particles {
                let i = i as usize;
                let r = vec3(&self.x[i]) - vec3(&b.com);
                let vi = (vec3(&b.vel) + vec3(&b.omega).cross(&r)).into();
                self.v[i] = vi;
                self.vh[i] = vi;
            }
        }
        if let Some(sd) = self.solid.as_mut() {
            sd.velocity_update(dt);
        }
        // Velocity boundary conditions (ramped), with their reaction power and impulse.
        let t_mid = self.time + 0.5 * dt;
        for g in &self.bcs {
            let s = if g.ramp > 0.0 {
                (t_mid / g.ramp).min(1.0)
            } else {
                1.0
            };
            let vel = g.velocity.map(|c| c * s);
            for &i in &g.particles {
                let i = i as usize;
                // The support's impulse: its particle's own force, which the update left
                // out (−f dt), plus what it takes to set the velocity the update gave it to
                // the prescribed one, in the momentum the node reports (`momentum`).
                let j = self.overwrite_impulse(i, &vel);
                self.v[i] = vel;
                self.vh[i] = vel;
                for d in 0..3 {
                    self.bc_work -= dt * self.f[i][d] * vel[d];
                    self.bc_impulse[d] += j[d] - dt * self.f[i][d];
                }
            }
            if let Some(sd) = self.solid.as_mut() {
                // an element node: what it takes to move it from its last velocity to the
                // prescribed one is the support's impulse (its own force included)
                for &k in &g.nodes {
                    let k = k as usize;
                    for d in 0..3 {
                        self.bc_work -= dt * sd.f[k][d] * vel[d];
                        self.bc_impulse[d] += sd.mass[k] * (vel[d] - sd.v[k][d]) - dt * sd.f[k][d];
                    }
                    sd.v[k] = vel;
                }
            }
        }
        // A coupled particle's mass is its driver's (the shell adds it to its node at set-up
        // and counts it in its momentum and kinetic energy), so the joint leaves the particle
        // out of its sums and books what crossed to its free particles: the force its body
        // exerts on the particle (−f dt, −f·v dt; PROTOCOL.md 4.7, the kinematic responder's
        // booking), and what the particles gave the free ones since the last booking through
        // the smoothing of the velocities (their momentum and energy before this overwrite,
        // against those after the last one).
        let (mut before, mut after) = (Motion::default(), Motion::default());
        for i in 0..self.len() {
            if self.kind[i] == Kind::Coupled {
                let vel = self.presc[i];
                let (m, v) = self.moving(i);
                before.add(m, &v);
                after.add(m, &vel);
                self.v[i] = vel;
                self.vh[i] = vel;
                for d in 0..3 {
                    self.coupling_work -= dt * self.f[i][d] * vel[d];
                    self.coupling_impulse[d] -= dt * self.f[i][d];
                }
            }
        }
        for d in 0..3 {
            self.coupling_impulse[d] -= before.p[d] - self.coupled_p[d];
        }
        self.coupling_work -= before.e - self.coupled_ke;
        (self.coupled_p, self.coupled_ke) = (after.p, after.e);
        self.clock.lap(Phase::Kinematic);
    }

    /// Phases 3–5: positions, kinematics and stress, bond failure, re-anchoring, forces.
    pub fn position_phase(&mut self, dt: f64) -> StepResult {
        self.clock.begin();
        self.x
            .par_iter_mut()
            .zip(self.v.par_iter())
            .zip(self.xh.par_iter_mut())
            .zip(self.vh.par_iter())
            .zip(self.u.par_iter_mut())
            .zip(self.xa.par_iter())
            .for_each(|(((((x, v), xh), vh), u), xa)| {
                for d in 0..3 {
                    x[d] += dt * v[d];
                    xh[d] += dt * vh[d];
                }
                *u = (vec3(x) - vec3(xa)).into();
            });
        for b in &mut self.rigid {
            for d in 0..3 {
                b.com[d] += dt * b.vel[d];
            }
        }
        if let Some(sd) = self.solid.as_mut() {
            sd.position_update(dt);
        }
        self.time += dt;
        self.steps += 1;
        self.clock.lap(Phase::Positions);
        kinematics_and_stress(self, dt)?;
        self.clock.lap(Phase::Stress);
        self.bond_failure()?;
        self.clock.lap(Phase::Bonds);
        if self.steps.is_multiple_of(self.p.reanchor_every) {
            self.reanchor()?;
        }
        self.clock.lap(Phase::Reanchor);
        internal_force(&self.rows, &self.bmat, &mut self.f);
        if let Some(sd) = self.solid.as_mut() {
            sd.forces(dt, &self.x, &self.v, &mut self.f)?;
        }
        self.clock.lap(Phase::Force);
        self.bearing_contact();
        self.clock.lap(Phase::Contact);
        Ok(())
    }

    /// A whole step with only boundary conditions and rigid bodies (no coupling input).
    pub fn step(&mut self, dt: f64) -> StepResult {
        self.velocity_phase(dt);
        self.position_phase(dt)
    }

    /// Bearing contact of rigid fasteners (`ModelParams::bearing`): a rigid particle and a
    /// particle of the material closer than d0 (one spacing h, or their reference distance
    /// if smaller) push each other apart with k (d0 − d) along the line between them, equal and opposite, so the pair adds no
    /// momentum; the rigid body takes its share through the sum of its particle forces. The
    /// bolt carries load by bearing on the hole wall and under its heads, not by bonds.
    fn bearing_contact(&mut self) {
        let Some(k) = self.p.bearing else {
            return;
        };
        let h = self.p.spacing;
        if self.contact_pairs.is_empty() || self.steps.is_multiple_of(CONTACT_REFRESH) {
            // Search only around the rigid bodies (debris may fly far: a neighbour grid
            // over the whole cloud would grow with it).
            let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for b in &self.rigid {
                for &i in &b.particles {
                    for a in 0..3 {
                        lo[a] = lo[a].min(self.x[i as usize][a] - 2.0 * h);
                        hi[a] = hi[a].max(self.x[i as usize][a] + 2.0 * h);
                    }
                }
            }
            // The search reuses its buffers (`ContactSearch`): no allocation once they have
            // grown to the neighbourhood's size.
            let cs = &mut self.contact_search;
            cs.near.clear();
            cs.xs.clear();
            for (i, x) in self.x.iter().enumerate() {
                if (0..3).all(|a| (lo[a]..=hi[a]).contains(&x[a])) {
                    cs.near.push(i as u32);
                    cs.xs.push(*x);
                }
            }
            cs.grid.rebuild(&cs.xs, 2.0 * h);
            let r2 = mechanics::neighbour::radius_squared(2.0 * h);
            self.contact_pairs.clear();
            for (k, &i) in cs.near.iter().enumerate() {
                if self.kind[i as usize] != Kind::Rigid {
                    continue;
                }
                let row = self.contact_pairs.len();
                let (near, kind, pairs) = (&cs.near, &self.kind, &mut self.contact_pairs);
                cs.grid.for_each_within(&cs.xs, &cs.xs[k], r2, |q| {
                    let j = near[q as usize];
                    if kind[j as usize] != Kind::Rigid {
                        pairs.push((i, j));
                    }
                });
                // each rigid particle's partners ascending, as a compressed-row family
                self.contact_pairs[row..].sort_unstable();
            }
        }
        let mut energy = 0.0;
        for &(i, j) in &self.contact_pairs {
            let (i, j) = (i as usize, j as usize);
            let r = vec3(&self.x[j]) - vec3(&self.x[i]);
            let d = r.norm();
            // Contact distance: one spacing, or the pair's distance in the reference state
            // if that is closer (the lattices of bolt and plate need not mesh), so the
            // contact is at rest in the reference state.
            let d0 = h.min((vec3(&self.x0[j]) - vec3(&self.x0[i])).norm());
            if d >= d0 || d <= 0.0 {
                continue;
            }
            let pen = d0 - d;
            let c = k * pen / d;
            for a in 0..3 {
                self.f[j][a] += c * r[a];
                self.f[i][a] -= c * r[a];
            }
            energy += 0.5 * k * pen * pen;
        }
        self.contact_energy = energy;
    }

    /// Compute stresses and forces at the current state (after set-up or a restart).
    pub fn initial_forces(&mut self) {
        let n = self.len();
        for i in 0..n {
            let fi = inverse(&self.fhat[i]).unwrap_or_else(Matrix3::identity);
            self.bmat[i] = stress_factor(self.mat[i].stress(), self.vol[i], &fi);
        }
        internal_force(&self.rows, &self.bmat, &mut self.f);
        if let Some(sd) = self.solid.as_mut()
            && let Err(e) = sd.forces(0.0, &self.x, &self.v, &mut self.f)
        {
            // a folded element: the next step fails on it, with this message
            tracing::error!("{e}");
        }
        self.bearing_contact();
    }

    /// Bond failure (eq. 15–17): a bond breaks, for good, when the pair-averaged effective
    /// plastic strain reaches ε_crit *and* the stretch ratio exceeds e_crit (so never under
    /// compression). Broken bonds drop out of the kernel (χ = 0) and the rows are rebuilt.
    /// `max_eps` is that of the current states (`kinematics_and_stress` reduces it).
    fn bond_failure(&mut self) -> StepResult {
        if self.max_eps < self.p.eps_crit {
            return Ok(());
        }
        let rows = &self.rows;
        let (mat, x) = (&self.mat, &self.x);
        let (ec, sc) = (self.p.eps_crit, self.p.e_crit);
        let newly: Vec<bool> = (0..rows.cols.len())
            .into_par_iter()
            .map(|p| {
                let i = rows.row_of[p] as usize;
                let j = rows.cols[p] as usize;
                if i == j || !rows.alive[p] {
                    return false;
                }
                let eps = 0.5 * (mat[i].eq_plastic_strain() + mat[j].eq_plastic_strain());
                let stretch = (vec3(&x[i]) - vec3(&x[j])).norm() / rows.len0[p];
                eps >= ec && stretch > sc
            })
            .collect();
        let mut any = false;
        self.dirty.iter_mut().for_each(|d| *d = false);
        for (p, &b) in newly.iter().enumerate() {
            if b {
                self.rows.alive[p] = false;
                let (i, j) = (self.rows.row_of[p] as usize, self.rows.cols[p] as usize);
                self.dirty[i] = true;
                self.broken_bonds += 1;
                let with_rigid = self.kind[i] == Kind::Rigid || self.kind[j] == Kind::Rigid;
                self.broken_by_part[self.part[i] as usize][with_rigid as usize] += 1;
                any = true;
            }
        }
        if any {
            // The damage zone: particles that lost a bond and their support neighbours.
            for i in 0..self.len() {
                if self.dirty[i] {
                    for p in self.rows.range(i) {
                        self.damaged[self.rows.cols[p] as usize] = true;
                    }
                }
            }
            let dirty = std::mem::take(&mut self.dirty);
            let r = self.rebuild_shapes(Some(&dirty));
            self.dirty = dirty;
            r?;
            // Keep F̂ consistent with the new gradients so the next increment has no jump.
            let rows = &self.rows;
            let (x, xa, dirty, mat, vol) = (&self.x, &self.xa, &self.dirty, &self.mat, &self.vol);
            self.fhat
                .par_iter_mut()
                .zip(self.bmat.par_iter_mut())
                .enumerate()
                .for_each(|(i, (fh, bm))| {
                    if dirty[i] {
                        *fh = incremental_f(rows, x, xa, i);
                        if let Some(fi) = inverse(fh) {
                            *bm = stress_factor(mat[i].stress(), vol[i], &fi);
                        }
                    }
                });
        }
        Ok(())
    }

    /// Broken bonds by the part of the particle whose row holds them, [within the material,
    /// with a rigid body], counted from the bonds (what [`Model::broken_by_part`] keeps).
    pub fn count_broken_by_part(&self) -> Vec<[u64; 2]> {
        let parts = self.part.iter().max().map_or(0, |&p| p as usize + 1);
        let mut n = vec![[0u64; 2]; parts];
        for (p, &alive) in self.rows.alive.iter().enumerate() {
            let (i, j) = (self.rows.row_of[p] as usize, self.rows.cols[p] as usize);
            if alive || i == j {
                continue;
            }
            let with_rigid = self.kind[i] == Kind::Rigid || self.kind[j] == Kind::Rigid;
            n[self.part[i] as usize][with_rigid as usize] += 1;
        }
        n
    }

    /// Re-anchor the adaptive anisotropic Lagrangian kernel at the current configuration
    /// (eq. 12–14): `F_tot ← F̂ F_tot`, `X̂ ← x`, `F̂ ← I`, shapes rebuilt with the kernel of
    /// each particle stretched by its `F_tot`.
    pub fn reanchor(&mut self) -> StepResult {
        if self.p.smoothing == Smoothing::Consistent {
            self.restore_angular_momentum();
        }
        self.xh.copy_from_slice(&self.x);
        let singular = self
            .ftot_a
            .par_iter_mut()
            .zip(self.finv_a.par_iter_mut())
            .zip(self.fhat.par_iter_mut())
            .enumerate()
            .filter_map(|(i, ((ft, fi), fh))| {
                let f = tensor::mat(fh) * tensor::mat(ft);
                *ft = tensor::rows(&f);
                *fh = IDENTITY;
                match tensor::inverse(&f, 1e-300) {
                    Some(m) => {
                        *fi = tensor::rows(&m);
                        None
                    }
                    None => Some(i),
                }
            })
            .min();
        if let Some(i) = singular {
            return Err(format!("particle {i}: singular deformation gradient"));
        }
        self.xa.copy_from_slice(&self.x);
        for ((a, v), s) in self.vol_a.iter_mut().zip(&self.vol).zip(&self.kernel_scale) {
            *a = v * s;
        }
        let (mat, vol) = (&self.mat, &self.vol);
        self.bmat.par_iter_mut().enumerate().for_each(|(i, b)| {
            *b = stress_factor(mat[i].stress(), vol[i], &Matrix3::identity());
        });
        self.rebuild_shapes(None)
    }

    /// Before re-anchoring (`y ← x`): add to `v̂` of the free particles the rigid rotation
    /// `ω × (x − c)` (mass-weighted least change; `c` their centre of mass, so linear
    /// momentum is untouched) that keeps `L = Σ y × m̂ v̂` across the reset (module doc).
    fn restore_angular_momentum(&mut self) {
        let (mut msum, mut c) = (0.0, [0.0; 3]);
        for i in 0..self.len() {
            if self.kind[i] == Kind::Free {
                msum += self.mh[i];
                for d in 0..3 {
                    c[d] += self.mh[i] * self.x[i][d];
                }
            }
        }
        if !(msum > 0.0) {
            return;
        }
        let c = c.map(|v| v / msum);
        let mut dl = [0.0; 3];
        let mut inertia = [[0.0; 3]; 3];
        for i in 0..self.len() {
            if self.kind[i] != Kind::Free {
                continue;
            }
            let m = self.mh[i];
            let dy = vec3(&self.xh[i]) - vec3(&self.x[i]);
            let t = dy.cross(&vec3(&self.vh[i]));
            let r = vec3(&self.x[i]) - vec3(&c);
            let r2 = r.norm_squared();
            for a in 0..3 {
                dl[a] += m * t[a];
                for b in 0..3 {
                    inertia[a][b] += m * (if a == b { r2 } else { 0.0 } - r[a] * r[b]);
                }
            }
        }
        let Some(ii) = tensor::inverse(&tensor::mat(&inertia), 1e-300) else {
            return;
        };
        let w = ii * vec3(&dl);
        for i in 0..self.len() {
            if self.kind[i] == Kind::Free {
                let dv = w.cross(&(vec3(&self.x[i]) - vec3(&c)));
                for d in 0..3 {
                    self.vh[i][d] += dv[d];
                }
            }
        }
    }

    /// The coupled particles' momentum and kinetic energy, in the mass and velocity of the
    /// `momentum` sums; the baseline of their booking once they are marked.
    pub fn coupled_sums(&self) -> ([f64; 3], f64) {
        let mut s = Motion::default();
        for i in (0..self.len()).filter(|&i| self.kind[i] == Kind::Coupled) {
            let (m, v) = self.moving(i);
            s.add(m, &v);
        }
        (s.p, s.e)
    }

    /// Particle `i`'s mass and velocity in the `momentum` sums.
    fn moving(&self, i: usize) -> (f64, [f64; 3]) {
        match self.p.smoothing {
            Smoothing::Consistent => (self.mh[i], self.vh[i]),
            _ => (self.ms[i], self.v[i]),
        }
    }

    /// The particles whose mass is the joint's in its sums: all but those moved by a
    /// kinematic coupling's driver (whose mass the driver carries).
    fn counted(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).filter(|&i| self.kind[i] != Kind::Coupled)
    }

    /// Kinetic energy: `½ Σ m̂ |v̂|²` with the consistent pair (the kinetic energy of the
    /// discrete Lagrangian, module doc), else with the masses the particles move with; the
    /// coupled particles left out (their mass is the driver's).
    pub fn kinetic_energy(&self) -> f64 {
        let (m, vel) = match self.p.smoothing {
            Smoothing::Consistent => (&self.mh, &self.vh),
            _ => (&self.ms, &self.v),
        };
        let mut e = self.solid.as_ref().map_or(0.0, |sd| sd.motion().0);
        for i in self.counted() {
            let v = &vel[i];
            e += 0.5 * m[i] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        }
        e
    }
    /// Internal energy: the stress work stored in the particles plus the elastic energy of
    /// the bearing contact's penalty springs (½ k (d0 − d)² per pair in contact).
    pub fn internal_energy(&self) -> f64 {
        self.eint.iter().sum::<f64>()
            + self.contact_energy
            + self.solid.as_ref().map_or(0.0, |sd| sd.internal_energy())
    }
    /// Momentum change of particle `i` when its velocity is set to `vel`, in the mass and
    /// velocity `momentum` sums.
    fn overwrite_impulse(&self, i: usize, vel: &[f64; 3]) -> [f64; 3] {
        let (m, v) = self.moving(i);
        [
            m * (vel[0] - v[0]),
            m * (vel[1] - v[1]),
            m * (vel[2] - v[2]),
        ]
    }

    /// Gross momentum Σ m|v| (in the mass and velocity `momentum` sums).
    pub fn momentum_gross(&self) -> f64 {
        let (m, vel) = match self.p.smoothing {
            Smoothing::Consistent => (&self.mh, &self.vh),
            _ => (&self.ms, &self.v),
        };
        let nodes: f64 = self.solid.as_ref().map_or(0.0, |sd| {
            sd.own_nodes()
                .map(|k| sd.mass[k] * vec3(&sd.v[k]).norm())
                .sum()
        });
        self.counted()
            .map(|i| {
                m[i] * (vel[i][0] * vel[i][0] + vel[i][1] * vel[i][1] + vel[i][2] * vel[i][2])
                    .sqrt()
            })
            .sum::<f64>()
            + nodes
    }

    /// Linear momentum: `Σ m̂_J v̂_J` with the consistent pair (the conjugate momentum,
    /// module doc), `Σ m_I v_I` otherwise (the two agree for `Shepard`); the coupled
    /// particles left out (their mass is the driver's).
    pub fn momentum(&self) -> [f64; 3] {
        let (m, vel) = match self.p.smoothing {
            Smoothing::Consistent => (&self.mh, &self.vh),
            _ => (&self.ms, &self.v),
        };
        let mut p = self.solid.as_ref().map_or([0.0; 3], |sd| sd.motion().1);
        for i in self.counted() {
            for d in 0..3 {
                p[d] += m[i] * vel[i][d];
            }
        }
        p
    }
    /// Angular momentum about the origin: `Σ y_J × m̂_J v̂_J` with the consistent pair
    /// (module doc), `Σ x_I × m_I v_I` otherwise.
    pub fn angular_momentum(&self) -> [f64; 3] {
        let (x, m, vel) = match self.p.smoothing {
            Smoothing::Consistent => (&self.xh, &self.mh, &self.vh),
            _ => (&self.x, &self.ms, &self.v),
        };
        let mut l = self.solid.as_ref().map_or([0.0; 3], |sd| sd.motion().2);
        for i in self.counted() {
            let mv = vec3(&vel[i]) * m[i];
            let c = vec3(&x[i]).cross(&mv);
            for d in 0..3 {
                l[d] += c[d];
            }
        }
        l
    }
    /// `Σ x_I × m̂_I v_I` with the smoothed positions and velocities (for comparison: not
    /// the conserved quantity of the consistent pair, it differs by the filtered part).
    pub fn smoothed_angular_momentum(&self) -> [f64; 3] {
        let mut l = [0.0; 3];
        for i in 0..self.len() {
            let mv = vec3(&self.v[i]) * self.mh[i];
            let c = vec3(&self.x[i]).cross(&mv);
            for d in 0..3 {
                l[d] += c[d];
            }
        }
        l
    }
    /// Fraction of the initial bonds of each particle that are broken.
    pub fn broken_fraction(&self) -> Vec<f64> {
        (0..self.len())
            .map(|i| {
                let r = self.rows.range(i);
                let total = r.len().saturating_sub(1);
                if total == 0 {
                    return 0.0;
                }
                let broken = r.filter(|&p| !self.rows.alive[p]).count();
                broken as f64 / total as f64
            })
            .collect()
    }
}

/// Scatter-type update of the unsmoothed velocity (eq. 10–11) with the consistent kernel:
/// `v̂_J += Δt/m̂_J Σ_K ψ_K(X_J) f_K` (`= Δt Σ_K φ_K(X_J) a_K` with `m_K = m̂_K`), the exact
/// transpose of [`gather_consistent`]; `ψ_K(X_J)` is the row-ordered `psi_t`. Only free
/// particles' forces are scattered: a kinematic one's counts as zero (the same sums as a
/// masked copy of the forces, without the pass that made it).
pub fn scatter_consistent(
    rows: &Rows,
    f: &[[f64; 3]],
    kind: &[Kind],
    mh: &[f64],
    dt: f64,
    vh: &mut [[f64; 3]],
) {
    let (offsets, cols, psi_t) = (&rows.offsets, &rows.cols, &rows.psi_t);
    vh.par_iter_mut().enumerate().for_each(|(j, v)| {
        let mut s = [0.0; 3];
        let r = offsets[j]..offsets[j + 1];
        for (&c, &w) in cols[r.clone()].iter().zip(&psi_t[r]) {
            let c = c as usize;
            let a = &if kind[c] == Kind::Free {
                f[c]
            } else {
                [0.0; 3]
            };
            s[0] += w * a[0];
            s[1] += w * a[1];
            s[2] += w * a[2];
        }
        let c = dt / mh[j];
        for d in 0..3 {
            v[d] += c * s[d];
        }
    });
}

/// Gather smoothing with the consistent kernel (eq. 2, 6): `v_I = Σ_J ψ_I(X_J) v̂_J`.
pub fn gather_consistent(rows: &Rows, vh: &[[f64; 3]], v: &mut [[f64; 3]]) {
    let (offsets, cols, psi) = (&rows.offsets, &rows.cols, &rows.psi);
    v.par_iter_mut().enumerate().for_each(|(i, vi)| {
        let mut s = [0.0; 3];
        let r = offsets[i]..offsets[i + 1];
        for (&c, &w) in cols[r.clone()].iter().zip(&psi[r]) {
            let u = &vh[c as usize];
            s[0] += w * u[0];
            s[1] += w * u[1];
            s[2] += w * u[2];
        }
        *vi = s;
    });
}

/// Scatter-type update of the unsmoothed velocity (eq. 10–11):
/// `v̂_I += Δt Σ_J φ_J(X_I) a_J` (row I, entries as stored).
pub fn scatter_update(rows: &Rows, acc: &[[f64; 3]], dt: f64, vh: &mut [[f64; 3]]) {
    vh.par_iter_mut().enumerate().for_each(|(i, v)| {
        let mut s = [0.0; 3];
        for p in rows.range(i) {
            let a = &acc[rows.cols[p] as usize];
            let w = rows.phi[p];
            s[0] += w * a[0];
            s[1] += w * a[1];
            s[2] += w * a[2];
        }
        for d in 0..3 {
            v[d] += dt * s[d];
        }
    });
}

/// Gather-type smoothing (eq. 2–6): `v_I = Σ_J m̂_J φ_I(X_J) v̂_J / m_I` with `φ_I(X_J)`
/// read from the mirror entry.
pub fn gather_smooth(rows: &Rows, mh: &[f64], ms: &[f64], vh: &[[f64; 3]], v: &mut [[f64; 3]]) {
    v.par_iter_mut().enumerate().for_each(|(i, vi)| {
        let mut s = [0.0; 3];
        for p in rows.range(i) {
            let j = rows.cols[p] as usize;
            let w = mh[j] * rows.phi[rows.mirror[p] as usize];
            s[0] += w * vh[j][0];
            s[1] += w * vh[j][1];
            s[2] += w * vh[j][2];
        }
        let im = 1.0 / ms[i];
        *vi = [s[0] * im, s[1] * im, s[2] * im];
    });
}

/// Plain kernel averaging `v_I = Σ_J φ_J(X_I) v̂_J` (not momentum consistent).
pub fn average_smooth(rows: &Rows, vh: &[[f64; 3]], v: &mut [[f64; 3]]) {
    v.par_iter_mut().enumerate().for_each(|(i, vi)| {
        let mut s = [0.0; 3];
        for p in rows.range(i) {
            let j = rows.cols[p] as usize;
            let w = rows.phi[p];
            s[0] += w * vh[j][0];
            s[1] += w * vh[j][1];
            s[2] += w * vh[j][2];
        }
        *vi = s;
    });
}

/// `F̂_I = I + Σ_J (u_J − u_I) ⊗ ∇φ_J(X_I)`, u = x − X̂ (eq. 14).
#[inline]
pub fn incremental_f(rows: &Rows, x: &[[f64; 3]], xa: &[[f64; 3]], i: usize) -> M3 {
    let ui = vec3(&x[i]) - vec3(&xa[i]);
    let mut f = Matrix3::identity();
    for p in rows.range(i) {
        let j = rows.cols[p] as usize;
        let du = (vec3(&x[j]) - vec3(&xa[j])) - ui;
        f += du * vec3(&rows.grad[p]).transpose();
    }
    tensor::rows(&f)
}

/// [`incremental_f`] from the stored displacements `u = x − X̂` (same arithmetic).
#[inline]
fn incremental_f_u(rows: &Rows, u: &[[f64; 3]], i: usize) -> Matrix3<f64> {
    let ui = vec3(&u[i]);
    let mut f = Matrix3::identity();
    let r = rows.offsets[i]..rows.offsets[i + 1];
    for (&j, g) in rows.cols[r.clone()].iter().zip(&rows.grad[r]) {
        let du = vec3(&u[j as usize]) - ui;
        f += du * vec3(g).transpose();
    }
    f
}

/// The inverse of a flat-stored deformation gradient; `None` when singular.
#[inline]
fn inverse(f: &M3) -> Option<Matrix3<f64>> {
    tensor::inverse(&tensor::mat(f), 1e-300)
}

/// `V σ F̂⁻ᵀ` (Voigt σ, tensor shear).
#[inline]
fn stress_factor(s: &[f64; 6], vol: f64, finv: &Matrix3<f64>) -> M3 {
    let sm = Matrix3::new(s[0], s[5], s[4], s[5], s[1], s[3], s[4], s[3], s[2]);
    tensor::rows(&(sm * finv.transpose() * vol))
}

/// What a particle's material carries from step to step: J2 plasticity's state, or the blast
/// solid's (Johnson–Cook: stress, ε̄ᵖ, temperature; with an equation of state, J and the
/// work of the pressure).
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub enum Point {
    J2(J2State),
    Blast(BlastPoint),
}

impl Point {
    /// A virgin point of the law (`blast`: Johnson–Cook, None: J2).
    pub fn initial(blast: Option<&BlastSolid>) -> Point {
        match blast {
            Some(b) => Point::Blast(b.initial_state()),
            None => Point::J2(J2State::default()),
        }
    }

    /// Cauchy stress (Pa), Voigt order, tensor shear.
    pub fn stress(&self) -> &Sym {
        match self {
            Point::J2(s) => &s.stress,
            Point::Blast(b) => BlastSolid::stress(b),
        }
    }

    /// Accumulated equivalent plastic strain.
    pub fn eq_plastic_strain(&self) -> f64 {
        match self {
            Point::J2(s) => s.eq_plastic_strain,
            Point::Blast(b) => BlastSolid::eq_plastic_strain(b),
        }
    }

    /// A separated particle carries no stress (its plastic strain and heat are kept).
    fn unload(&mut self) {
        match self {
            Point::J2(s) => {
                s.stress = [0.0; 6];
                s.back_stress = [0.0; 6];
            }
            Point::Blast(b) => b.jc.stress = [0.0; 6],
        }
    }

    /// One step: the stress rotated with `spin` (Jaumann) and the strain increment `de`
    /// integrated by J2's radial return or the blast solid's (J = det F from continuity:
    /// the volume's trace `tr` of the step).
    fn update(
        &mut self,
        material: &J2Material,
        blast: Option<&BlastSolid>,
        de: &Sym,
        spin: &[[f64; 3]; 3],
        dt: f64,
        tr: f64,
    ) {
        match (self, blast) {
            (Point::J2(st), _) => {
                jaumann_rotate(&mut st.stress, spin, dt);
                jaumann_rotate(&mut st.back_stress, spin, dt);
                material.update(st, de);
            }
            (Point::Blast(b), Some(law)) => {
                let jac = b.jac / (1.0 - tr);
                law.step(b, de, spin, dt, jac, false);
            }
            (Point::Blast(_), None) => unreachable!("a blast-solid point without its law"),
        }
    }
}

/// Kinematics (eq. 12–14), continuity density (eq. 8–9) and the J2 update.
fn kinematics_and_stress(m: &mut Model, dt: f64) -> StepResult {
    let rows = &m.rows;
    let u = &m.u;
    let (material, blast) = (&m.p.material, m.p.blast.as_ref());
    let mass = &m.mass;
    let damaged = &m.damaged;
    let failed = std::sync::atomic::AtomicUsize::new(usize::MAX);
    // The largest equivalent plastic strain (bond failure's test, eq. 15) and whether any
    // density is not positive are reduced in the same pass: no serial sweep of the states.
    // Both reductions are exact (max, or), so the result does not depend on the split.
    let (max_eps, bad_rho) = m
        .fhat
        .par_iter_mut()
        .zip(m.mat.par_iter_mut())
        .zip(m.rho.par_iter_mut())
        .zip(m.vol.par_iter_mut())
        .zip(m.bmat.par_iter_mut())
        .zip(m.eint.par_iter_mut())
        .enumerate()
        .map(|(i, (((((fh, st), rho), vol), bm), ei))| {
            'update: {
                // A particle with broken bonds (eq. 16) whose remaining support no longer gives
                // an invertible deformation (or a positive density) has separated: it carries no
                // stress from now on (its state is kept, its force contribution is zero). An
                // intact particle in that state is a divergence.
                let separate = |st: &mut Point, bm: &mut M3| {
                    if damaged[i] {
                        st.unload();
                        *bm = [[0.0; 3]; 3];
                    } else {
                        failed.fetch_min(i, std::sync::atomic::Ordering::Relaxed);
                    }
                };
                let f_new = incremental_f_u(rows, u, i);
                let f_old = tensor::mat(fh);
                let Some(fmi) = tensor::inverse(&((f_new + f_old) * 0.5), 1e-300) else {
                    separate(st, bm);
                    break 'update;
                };
                // L Δt = (F̂ⁿ⁺¹ − F̂ⁿ) F̂_mid⁻¹
                let ldt = (f_new - f_old) * fmi;
                let de = [
                    ldt[(0, 0)],
                    ldt[(1, 1)],
                    ldt[(2, 2)],
                    0.5 * (ldt[(1, 2)] + ldt[(2, 1)]),
                    0.5 * (ldt[(0, 2)] + ldt[(2, 0)]),
                    0.5 * (ldt[(0, 1)] + ldt[(1, 0)]),
                ];
                let spin = tensor::rows(&((ldt - ldt.transpose()) * 0.5 / dt));
                let s_old = *st.stress();
                let v_old = *vol;
                // Continuity (eq. 8) and volume (eq. 9) below.
                let tr = de[0] + de[1] + de[2];
                st.update(material, blast, &de, &spin, dt, tr);
                if damaged[i] && !(1.0 - tr > 0.0 && f_new.determinant() > 0.0) {
                    separate(st, bm);
                    break 'update;
                }
                *rho *= 1.0 - tr;
                *vol = mass[i] / *rho;
                let s = st.stress();
                let work = 0.5
                    * ((s[0] + s_old[0]) * de[0]
                        + (s[1] + s_old[1]) * de[1]
                        + (s[2] + s_old[2]) * de[2]
                        + 2.0
                            * ((s[3] + s_old[3]) * de[3]
                                + (s[4] + s_old[4]) * de[4]
                                + (s[5] + s_old[5]) * de[5]));
                *ei += 0.5 * (v_old + *vol) * work;
                *fh = tensor::rows(&f_new);
                let Some(fi) = tensor::inverse(&f_new, 1e-300) else {
                    separate(st, bm);
                    break 'update;
                };
                *bm = stress_factor(st.stress(), *vol, &fi);
            }
            (st.eq_plastic_strain(), !(*rho > 0.0))
        })
        .reduce(|| (0.0, false), |a, b| (a.0.max(b.0), a.1 || b.1));
    m.max_eps = max_eps;
    let bad = failed.into_inner();
    if bad != usize::MAX || bad_rho {
        return Err(format!(
            "particle {}: singular deformation gradient or non-positive density",
            if bad == usize::MAX {
                m.rho.iter().position(|r| !(*r > 0.0)).unwrap_or(0)
            } else {
                bad
            }
        ));
    }
    Ok(())
}

/// Direct nodal integration internal force, gathered (eq. 28):
/// `f_K = −Σ_I B_I ∇φ_K(X_I)`, `B_I = V_I σ_I F̂_I⁻ᵀ`, with `∇φ_K(X_I)` the mirror entry
/// (stored in row order as `grad_t`).
pub fn internal_force(rows: &Rows, bmat: &[M3], f: &mut [[f64; 3]]) {
    let (offsets, cols, grad_t) = (&rows.offsets, &rows.cols, &rows.grad_t);
    f.par_iter_mut().enumerate().for_each(|(k, fk)| {
        let mut s = Vector3::zeros();
        let r = offsets[k]..offsets[k + 1];
        for (&i, g) in cols[r.clone()].iter().zip(&grad_t[r]) {
            s -= tensor::mat(&bmat[i as usize]) * vec3(g);
        }
        *fk = s.into();
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::bolted_plates;

    /// The bearing-contact candidates (rigid particle, material particle within 2 h) from the
    /// reused cell list equal a brute-force search, in compressed-row order, after the bolt
    /// has moved against the plates; refreshes reuse the search buffers.
    #[test]
    fn contact_candidates_match_brute_force() {
        let h = 1e-3;
        let s = bolted_plates(2e-3, 8e-3, 12e-3, 8e-3, 2e-3, 3e-3, 1e-3, h);
        let p = ModelParams {
            blast: None,
            material: J2Material {
                young: 70e9,
                poisson: 0.3,
                yield_stress: 3e8,
                iso_hardening: 1e8,
                kin_hardening: 0.0,
            },
            density: 2700.0,
            spacing: h,
            support: 2.0 * h,
            eps_crit: 0.5,
            e_crit: 1.0,
            reanchor_every: 100,
            smoothing: Smoothing::Consistent,
            cfl: 0.4,
            bearing: Some(1e9),
        };
        let mut m = Model::new(p, s.x, s.vol, s.part, &s.rigid_parts).unwrap();
        let mut capacity = None;
        for shift in [0.0, 0.4, 0.9] {
            // move the bolt along x against the hole wall
            for i in 0..m.len() {
                if m.kind[i] == Kind::Rigid {
                    m.x[i][0] = m.x0[i][0] + shift * h;
                }
            }
            m.contact_pairs.clear();
            m.bearing_contact();
            let r2 = mechanics::neighbour::radius_squared(2.0 * h);
            let mut brute = Vec::new();
            for i in 0..m.len() {
                if m.kind[i] != Kind::Rigid {
                    continue;
                }
                for j in 0..m.len() {
                    let d2: f64 = (0..3).map(|a| (m.x[j][a] - m.x[i][a]).powi(2)).sum();
                    if m.kind[j] != Kind::Rigid && d2 <= r2 {
                        brute.push((i as u32, j as u32));
                    }
                }
            }
            assert!(!brute.is_empty(), "the bolt must touch the plates");
            assert_eq!(m.contact_pairs, brute, "shift {shift} h");
            let c = (
                m.contact_search.near.capacity(),
                m.contact_search.xs.capacity(),
            );
            if let Some(c0) = capacity {
                assert_eq!(c, c0, "a refresh must reuse the search buffers");
            }
            capacity = Some(c);
        }
    }
}
