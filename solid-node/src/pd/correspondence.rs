//! pd-correspondence: non-ordinary state-based (correspondence) peridynamics, seed 001
//! §4.1–4.3: shape tensor K (eq. 182), nonlocal deformation gradient F = N K⁻¹ (eq. 181),
//! force state T = ω P K⁻¹ ξ (eq. 180) with P the first Piola–Kirchhoff stress, and Silling's
//! zero-energy-mode stabilization (eq. 184–189). The stress is a rate form (seed 000 App. B):
//! L = Ḟ F⁻¹, Jaumann-rotated Cauchy stress, J2 radial return with isotropic and kinematic
//! hardening (`mechanics::j2`), bond damage by any `mechanics::damage::DamageModel` (App. C).
//! 2-D: plane strain (Δε_zz = 0) or plane stress (Δε_zz solved for σ_zz = 0 by
//! `J2Material::update_plane_stress`), with F_zz = 1 in the kinematics.
//!
//! Stabilization, eq. (186): T̂ = ω { P K⁻¹ ξ + (G C/ω₀) z },  z = y − F ξ (eq. 184). As printed,
//! G C z/ω₀ is not a force state dimensionally (C of eq. 188 is a bond micromodulus, N/m⁶,
//! and ω₀ = ∫ω dV a volume); we normalise ω₀ by the full-horizon volume V_H and use δ as the
//! length scale, T_s = ω G C (V_H/ω₀) z/δ, so that in the bulk the non-uniform part of a
//! bond of length δ is resisted like a bond-based bond of micromodulus G·C (Silling 2017).
//! Per particle we fold it into Â = P K⁻¹ − κ H/δ, κ = G C V_H/ω₀, so the force of a bond is
//! ω V_j [(Â_i + Â_j) ξ + (κ_i + κ_j) η/δ] (eq. 183), since z = y − Fξ = η − Hξ.
//! Kinematics from displacements: η = u_j − u_i, the displacement gradient H = (Σ ω V η⊗ξ) K⁻¹
//! and F = I + H, so small strains keep full precision far from the origin.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use super::family::{Bonds, par_row_blocks, par_rows, spared};
use super::model::{Dim, Kinematics, PdModel};
use mechanics::damage::{BondInput, DamageModel};
use mechanics::j2::{J2Material, J2State, Sym, von_mises};
use mechanics::simd::Simd;
use mechanics::stress_law::StressLaw;
use mechanics::tensor::{self, IDENTITY};
use protocol::checkpoint::{check_len, decode_state, encode_state};
use protocol::solver::SolverResult;
use rayon::prelude::*;
use std::borrow::Cow;
use std::f64::consts::PI;
use std::sync::atomic::{AtomicU64, Ordering};

/// A 3×3 matrix in the row-major flat storage of the per-particle arrays.
pub type M3 = tensor::Rows3;

/// `a b` (nalgebra, in flat storage).
#[inline]
pub fn matmul(a: &M3, b: &M3) -> M3 {
    tensor::rows(&(tensor::mat(a) * tensor::mat(b)))
}

#[inline]
pub fn det(a: &M3) -> f64 {
    tensor::mat(a).determinant()
}

/// Inverse by the adjugate (`mechanics::tensor::inverse`); `None` when |det| ≤ tiny.
#[inline]
pub fn inverse(a: &M3, tiny: f64) -> Option<M3> {
    tensor::inverse(&tensor::mat(a), tiny).map(|m| tensor::rows(&m))
}

/// `a v`.
#[inline]
pub fn mv(a: &M3, v: &[f64; 3]) -> [f64; 3] {
    (tensor::mat(a) * tensor::vec3(v)).into()
}

#[cfg(target_arch = "x86_64")]
mod avx512;

/// Per-particle kinematic results of pass 1 (not gathered by neighbours).
#[derive(Debug, Clone, Copy, Default)]
pub struct PointKin {
    /// A = P K⁻¹ (force state T = ω A ξ, eq. 180).
    pub a: M3,
    /// Nonlocal deformation gradient F (eq. 181).
    pub f: M3,
    /// K⁻¹ of the current intact family, and the Σ ω_D V_j it was built for.
    pub kinv: M3,
    pub wsum: f64,
    /// False when the family cannot carry a gradient (fully or nearly broken).
    pub active: bool,
}

/// What the force pass gathers from each neighbour (kept small: 12 numbers).
#[derive(Debug, Clone, Copy, Default)]
pub struct BondSide {
    /// Â = P K⁻¹ − κ H/δ: the stabilized force state is ω (Â ξ + κ η/δ).
    pub ahat: M3,
    /// κ = G C V_H/ω₀ (0 for an inactive particle).
    pub kappa: f64,
    /// Von Mises stress, equivalent plastic strain and failure indicator, for bond damage.
    pub vm: f64,
    pub eqp: f64,
    pub fail: f64,
}

/// What a checkpoint holds of a correspondence body (`PdModel::save_state`, and the device
/// path's state in the same form): per particle its material state (`S`, the stress law's),
/// plastic work and strain energy given up by bond damage.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
#[serde(bound(
    serialize = "S: serde::Serialize",
    deserialize = "S: serde::de::DeserializeOwned"
))]
pub struct CorrHistory<'a, S: Clone = J2State> {
    pub state: Cow<'a, [S]>,
    pub plastic_work: Cow<'a, [f64]>,
    pub released: Cow<'a, [f64]>,
}

impl<S: Clone + serde::de::DeserializeOwned> CorrHistory<'_, S> {
    /// Decodes a history of `particles` particles, refusing one of another size.
    pub fn decode(bytes: &[u8], particles: usize) -> SolverResult<Self> {
        let h: Self = decode_state(bytes)?;
        check_len("particle J2 states", h.state.len(), particles)?;
        check_len("plastic work", h.plastic_work.len(), particles)?;
        Ok(h)
    }
}

/// The correspondence model, generic over its damage law (monomorphized bond loop) and its
/// stress law (J2 plasticity unless said otherwise).
pub struct Correspondence<D: DamageModel, L: StressLaw = J2Material> {
    pub dim: Dim,
    pub material: L,
    /// Stabilization constant G of eq. (186) (seed 001 uses 0.5).
    pub stabilization: f64,
    /// Bond micromodulus C of eq. (188).
    pub micromodulus: f64,
    /// Full-horizon volume V_H (πδ²h in 2-D).
    pub horizon_volume: f64,
    pub damage: D,
    pub horizon: f64,
    pub state: Vec<L::State>,
    /// Plastic work density per particle since the start (J/m³).
    pub plastic_work: Vec<f64>,
    /// Per-particle scratch of the strain-energy sum (J).
    energy: Vec<f64>,
    /// Strain energy given up by bond damage per particle since the start (J; see
    /// `release`).
    released: Vec<f64>,
    /// The bonds' intact fractions when damage was last booked (empty until the first
    /// force evaluation and after a checkpoint is loaded: then taken as they are).
    booked: Vec<f64>,
    pub kin: Vec<PointKin>,
    pub side: Vec<BondSide>,
    /// det K of the intact family (to detect a family too damaged for a gradient).
    k0det: Vec<f64>,
    /// Instruction set of the bond kernels (the widest the CPU has). SSE2 and AVX2 give the
    /// same bits; AVX-512 runs the explicit kernels, which sum in eight lanes instead of row
    /// order and agree with the others to rounding (see `avx512.rs`).
    pub simd: Simd,
    /// Per-particle records of the explicit AVX-512 kernels, packed each step.
    #[cfg(target_arch = "x86_64")]
    packed: avx512::Packed,
}

impl<D: DamageModel, L: StressLaw> Correspondence<D, L> {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        dim: Dim,
        material: L,
        stabilization: f64,
        horizon: f64,
        thickness: f64,
        damage: D,
        k: &Kinematics,
        bonds: &Bonds,
    ) -> Self {
        let (e, nu) = material.elastic_constants();
        let kb = e / (3.0 * (1.0 - 2.0 * nu));
        // eq. (188)–(189)
        let (c, vh) = match dim {
            Dim::Three => (
                18.0 * kb / (PI * horizon.powi(4)),
                4.0 / 3.0 * PI * horizon.powi(3),
            ),
            Dim::PlaneStress => (
                12.0 * (e / (2.0 * (1.0 - nu))) / (PI * thickness * horizon.powi(3)),
                PI * horizon * horizon * thickness,
            ),
            Dim::PlaneStrain => (
                12.0 * (e / (2.0 * (1.0 + nu) * (1.0 - 2.0 * nu)))
                    / (PI * thickness * horizon.powi(3)),
                PI * horizon * horizon * thickness,
            ),
        };
        let n = bonds.particles();
        let mut m = Correspondence {
            dim,
            material,
            stabilization,
            micromodulus: c,
            horizon_volume: vh,
            damage,
            horizon,
            state: vec![material.initial_state(); n],
            plastic_work: vec![0.0; n],
            energy: vec![0.0; n],
            released: vec![0.0; n],
            booked: Vec::new(),
            kin: vec![
                PointKin {
                    wsum: f64::NAN,
                    ..Default::default()
                };
                n
            ],
            side: vec![BondSide::default(); n],
            #[cfg(target_arch = "x86_64")]
            packed: avx512::Packed::default(),
            k0det: vec![0.0; n],
            simd: Simd::detect(),
        };
        for i in 0..n {
            m.k0det[i] = det(&shape_tensor(dim, i, k, bonds));
        }
        m
    }

    /// Pass 1 at every particle: F (eq. 181), Ḟ, L = Ḟ F⁻¹, the rate-form stress update
    /// (Jaumann + radial return, seed 000 App. B), A = P K⁻¹ and Â.
    fn pass1(&mut self, k: &Kinematics, bonds: &Bonds, dt: f64) {
        let mat = self.material;
        let kappa0 = self.stabilization * self.micromodulus * self.horizon_volume;
        let inv_h = 1.0 / self.horizon;
        let (dim, k0det) = (self.dim, &self.k0det);
        let (offsets, nbr, intact) = (&bonds.offsets, &bonds.nbr, &bonds.intact);
        let simd = self.simd;
        let explicit = self.explicit_avx512();
        #[cfg(target_arch = "x86_64")]
        if explicit {
            self.packed.pack_particles(k);
        }
        #[cfg(target_arch = "x86_64")]
        let packed = &self.packed;
        self.state
            .par_iter_mut()
            .zip(self.plastic_work.par_iter_mut())
            .zip(self.kin.par_iter_mut())
            .zip(self.side.par_iter_mut())
            .with_min_len(256)
            .enumerate()
            .for_each(|(i, (((st, wp), pk), sd))| {
                let r = offsets[i]..offsets[i + 1];
                let (ui, vi, xp) = (k.disp[i], k.vel[i], k.x0[i]);
                // nn = Σ ω V_j η⊗ξ with η = u_j − u_i, so H = nn K⁻¹ is the displacement
                // gradient and F = I + H (eq. 181 with y = ξ + η, Σ ω V ξ⊗ξ K⁻¹ = I), free of
                // the cancellation of forming y from absolute positions.
                let (rn, ri) = (&nbr[r.clone()], &intact[r]);
                let multiversioned =
                    || family_sums(simd, rn, ri, k.x0, k.disp, k.vel, k.vol, (xp, ui, vi));
                #[cfg(target_arch = "x86_64")]
                let sums = if explicit {
                    // SAFETY: `explicit` holds only on a CPU with AVX-512 F/DQ/VL.
                    unsafe { avx512::family_sums(i, packed, rn, ri) }
                } else {
                    multiversioned()
                };
                #[cfg(not(target_arch = "x86_64"))]
                let sums = multiversioned();
                let FamilySums { mut nn, nd, w0 } = sums;
                if w0 != pk.wsum {
                    // The family changed (or first call): rebuild K⁻¹ (eq. 182).
                    pk.wsum = w0;
                    let kk = shape_tensor(dim, i, k, bonds);
                    match inverse(&kk, 1e-3 * k0det[i].abs()) {
                        Some(kinv) => {
                            pk.kinv = kinv;
                            pk.active = true;
                        }
                        None => pk.active = false,
                    }
                }
                if !pk.active {
                    // Fully (or nearly) broken: a free particle, no stress carried.
                    pk.a = [[0.0; 3]; 3];
                    pk.f = IDENTITY;
                    *sd = BondSide {
                        ahat: [[0.0; 3]; 3],
                        kappa: 0.0,
                        vm: von_mises(L::stress(st)),
                        eqp: L::eq_plastic_strain(st),
                        fail: L::failure(st),
                    };
                    return;
                }
                if !dim.three_d() {
                    // H_zz = 0 (F_zz = 1)
                    nn[2][2] = 0.0;
                }
                let h = matmul(&nn, &pk.kinv);
                let f: M3 = std::array::from_fn(|a| {
                    std::array::from_fn(|c| h[a][c] + if a == c { 1.0 } else { 0.0 })
                });
                let finv = inverse(&f, 1e-300);
                if dt > 0.0
                    && let Some(finv) = finv
                {
                    let fdot = matmul(&nd, &pk.kinv);
                    let l = matmul(&fdot, &finv);
                    let (spin, de) = mechanics::j2::spin_and_strain_step(&l, dt);
                    // seed 000 eq. (B.2)–(B.4): Jaumann rate, then the law's update
                    *wp += mat.step(st, &de, &spin, dt, det(&f), dim == Dim::PlaneStress);
                }
                let s = mechanics::j2::to_matrix(L::stress(st));
                // P = J σ F⁻ᵀ, A = P K⁻¹
                let a = match finv {
                    Some(finv) => {
                        let jac = det(&f);
                        let finv_t: M3 =
                            std::array::from_fn(|r| std::array::from_fn(|c| jac * finv[c][r]));
                        matmul(&matmul(&s, &finv_t), &pk.kinv)
                    }
                    None => [[0.0; 3]; 3],
                };
                let kappa = if w0 > 0.0 { kappa0 / w0 } else { 0.0 };
                let kd = kappa * inv_h;
                pk.a = a;
                pk.f = f;
                *sd = BondSide {
                    // Â = A − κH/δ: with y − Fξ = η − Hξ (eq. 184) the stabilization is
                    // formed from displacements too
                    ahat: std::array::from_fn(|r| std::array::from_fn(|c| a[r][c] - kd * h[r][c])),
                    kappa,
                    vm: von_mises(L::stress(st)),
                    eqp: L::eq_plastic_strain(st),
                    fail: L::failure(st),
                };
            });
        #[cfg(target_arch = "x86_64")]
        if explicit {
            self.packed.pack_sides(&self.side);
        }
    }

    /// True when the bond kernels run as explicit AVX-512 (the instruction set allows it and
    /// the CPU has it).
    fn explicit_avx512(&self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            self.simd == Simd::Avx512 && mechanics::simd::has_avx512()
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }

    /// What [`point_energy`] reads.
    fn energy_view(&self) -> EnergyView<'_, L> {
        EnergyView {
            dim: self.dim,
            mat: self.material,
            inv_h: 1.0 / self.horizon,
            kappa0: self.stabilization * self.micromodulus * self.horizon_volume,
            state: &self.state,
            kin: &self.kin,
            side: &self.side,
            k0det: &self.k0det,
        }
    }

    /// Books the strain energy that this evaluation's bond damage took from the families it
    /// touched: for every row whose intact fractions changed since the last
    /// booking, [`point_energy`] with the fractions before less that with the fractions
    /// now, at the same displacements and stress, is released; strain energy + released
    /// energy is then unchanged by damage. (The stabilisation part can grow when a family
    /// loses a bond: κ = κ₀/Σ ω V_j grows, so a single event may release a negative amount.)
    /// Runs only on an evaluation that changed a bond.
    fn release(&mut self, k: &Kinematics, bonds: &Bonds) {
        // taken out for the pass (no allocation), so the view can borrow the rest
        let (mut released, mut booked) = (
            std::mem::take(&mut self.released),
            std::mem::take(&mut self.booked),
        );
        let view = self.energy_view();
        let offsets = &bonds.offsets;
        par_rows(
            offsets,
            &mut released,
            &mut booked,
            &|i, rel: &mut f64, old| {
                let now = &bonds.intact[offsets[i]..offsets[i + 1]];
                if old == now {
                    return;
                }
                *rel +=
                    point_energy(&view, i, k, bonds, old) - point_energy(&view, i, k, bonds, now);
                old.copy_from_slice(now);
            },
        );
        self.released = released;
        self.booked = booked;
    }

    /// Runs only the stress update (pass 1), e.g. for prescribed-motion tests.
    pub fn update_stress(&mut self, k: &Kinematics, bonds: &Bonds, dt: f64) {
        self.pass1(k, bonds, dt);
    }

    /// Virial stress ½ Σ_j (T_i⟨ξ⟩ − T_j⟨−ξ⟩) ⊗ ξ V_j at particle i (without stabilization,
    /// which vanishes for a homogeneous deformation); equals P in the bulk.
    pub fn virial_stress(&self, i: usize, k: &Kinematics, bonds: &Bonds) -> M3 {
        let mut s = [[0.0; 3]; 3];
        let ai = self.kin[i].a;
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            let w = bonds.intact[b] * k.vol[j];
            let aj = self.kin[j].a;
            let x = bonds.xi[b];
            let t: [f64; 3] = std::array::from_fn(|r| {
                (ai[r][0] + aj[r][0]) * x[0]
                    + (ai[r][1] + aj[r][1]) * x[1]
                    + (ai[r][2] + aj[r][2]) * x[2]
            });
            for r in 0..3 {
                for c in 0..3 {
                    s[r][c] += 0.5 * w * t[r] * x[c];
                }
            }
        }
        s
    }
}

/// Shape tensor K = Σ ω V_j ξ⊗ξ over intact bonds (eq. 182); K_zz = 1 in 2-D.
fn shape_tensor(dim: Dim, i: usize, k: &Kinematics, bonds: &Bonds) -> M3 {
    let mut kk = [[0.0; 3]; 3];
    for b in bonds.offsets[i]..bonds.offsets[i + 1] {
        let w = bonds.intact[b] * k.vol[bonds.nbr[b] as usize];
        let x = bonds.xi[b];
        for a in 0..3 {
            for c in 0..3 {
                kk[a][c] += w * x[a] * x[c];
            }
        }
    }
    if !dim.three_d() {
        kk[2][2] = 1.0;
    }
    kk
}

/// What pass 1 sums over a family: N = Σ ω V_j η⊗ξ, Ṅ = Σ ω V_j (v_j − v_i)⊗ξ, Σ ω V_j.
#[derive(Debug, Clone, Copy, Default)]
pub struct FamilySums {
    pub nn: M3,
    pub nd: M3,
    pub w0: f64,
}

/// Pass-1 sums over one row (`me` = X_i, u_i, v_i), in row order. ξ = X_j − X_i is formed
/// from the neighbour's X (bit for bit `Bonds::xi`, built the same way), which is in cache
/// next to its u and v, instead of streaming a per-bond array. One sweep with nineteen
/// accumulators: they spill on the 16-register SSE2/AVX2 builds, not on AVX-512's 32.
#[inline(always)]
fn family_sums_body(
    nbr: &[u32],
    intact: &[f64],
    x0: &[[f64; 3]],
    disp: &[[f64; 3]],
    vel: &[[f64; 3]],
    vol: &[f64],
    me: ([f64; 3], [f64; 3], [f64; 3]),
) -> FamilySums {
    let (xp, ui, vi) = me;
    let mut nn = [[0.0; 3]; 3];
    let mut nd = [[0.0; 3]; 3];
    let mut w0 = 0.0;
    for (&j, &om) in nbr.iter().zip(intact) {
        if om == 0.0 {
            continue;
        }
        let j = j as usize;
        let w = om * vol[j];
        w0 += w;
        let xj = x0[j];
        let x = [xj[0] - xp[0], xj[1] - xp[1], xj[2] - xp[2]];
        let (uj, vj) = (disp[j], vel[j]);
        let wy = [
            w * (uj[0] - ui[0]),
            w * (uj[1] - ui[1]),
            w * (uj[2] - ui[2]),
        ];
        let wv = [
            w * (vj[0] - vi[0]),
            w * (vj[1] - vi[1]),
            w * (vj[2] - vi[2]),
        ];
        for a in 0..3 {
            for c in 0..3 {
                nn[a][c] += wy[a] * x[c];
                nd[a][c] += wv[a] * x[c];
            }
        }
    }
    FamilySums { nn, nd, w0 }
}

// Each kernel is compiled for SSE2, AVX2 and AVX-512 ([`mechanics::simd`]); the scalar loops
// gain the wider register file (no spilled accumulators), and no FMA, so every path gives
// the same bits.
mechanics::simd::multiversion! {
    fn family_sums<>(
        nbr: &[u32],
        intact: &[f64],
        x0: &[[f64; 3]],
        disp: &[[f64; 3]],
        vel: &[[f64; 3]],
        vol: &[f64],
        me: ([f64; 3], [f64; 3], [f64; 3]),
    ) -> FamilySums = family_sums_body;
}

/// A bond's force state difference per unit ω V_j, T_i⟨ξ⟩ − T_j⟨−ξ⟩ (eq. 183 with 186), for
/// the bond ξ = `x` with relative displacement `e`, between particles whose force-pass
/// quantities are `pi` and `pj`.
#[inline(always)]
fn pair(pi: &BondSide, pj: &BondSide, x: &[f64; 3], e: &[f64; 3], inv_h: f64) -> [f64; 3] {
    let ks = (pi.kappa + pj.kappa) * inv_h;
    std::array::from_fn(|c| {
        let t = (pi.ahat[c][0] + pj.ahat[c][0]) * x[0]
            + (pi.ahat[c][1] + pj.ahat[c][1]) * x[1]
            + (pi.ahat[c][2] + pj.ahat[c][2]) * x[2];
        t + ks * e[c]
    })
}

/// The force pass (eq. 183 with 186) over the block of particles `lo..lo + f.len()`, whose
/// rows' intact fractions are `intact`.
#[inline(always)]
fn force_block_body<D: DamageModel>(
    lo: usize,
    f: &mut [[f64; 3]],
    intact: &mut [f64],
    offsets: &[usize],
    nbr: &[u32],
    inv_len: &[f64],
    x0: &[[f64; 3]],
    disp: &[[f64; 3]],
    vol: &[f64],
    point: &[BondSide],
    damage: &D,
    no_fail: &[bool],
    inv_h: f64,
) -> u32 {
    let base = offsets[lo];
    let mut changed = 0;
    // (1 + s0)² of a pure critical-stretch law
    let limit = damage.stretch_limit().map(|s0| (1.0 + s0) * (1.0 + s0));
    for (p, fi) in f.iter_mut().enumerate() {
        let i = lo + p;
        let pi = &point[i];
        let (up, xp) = (disp[i], x0[i]);
        let mut acc = [0.0; 3];
        let r = offsets[i]..offsets[i + 1];
        let row = &mut intact[r.start - base..r.end - base];
        for ((om, &j), &il) in row.iter_mut().zip(&nbr[r.clone()]).zip(&inv_len[r]) {
            if *om == 0.0 {
                continue;
            }
            let j = j as usize;
            let pj = &point[j];
            // ξ = X_j − X_i as in pass 1
            let xj = x0[j];
            let x = [xj[0] - xp[0], xj[1] - xp[1], xj[2] - xp[2]];
            let q = disp[j];
            let e = [q[0] - up[0], q[1] - up[1], q[2] - up[2]];
            // seed 000 App. C: bond-associated quantities, symmetric in i and j so both
            // copies of the bond evolve identically.
            let w = match limit {
                // s > s0 ⇔ |y|²/|ξ|² > (1 + s0)²: no square root or division on the path
                Some(lim) => {
                    let y = [x[0] + e[0], x[1] + e[1], x[2] + e[2]];
                    let q = y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
                    if q * il * il > lim { 0.0 } else { *om }
                }
                None => {
                    let input = BondInput {
                        stretch: super::bond::stretch_over_len(&x, &e, il).0,
                        von_mises: 0.5 * (pi.vm + pj.vm),
                        eq_plastic_strain: 0.5 * (pi.eqp + pj.eqp),
                        failure: 0.5 * (pi.fail + pj.fail),
                    };
                    damage.update(*om, &input)
                }
            };
            // a no-fail zone keeps the bond (tested only when it is about to weaken)
            let w = if w != *om && spared(no_fail, i, j) {
                *om
            } else {
                w
            };
            changed += u32::from(w != *om);
            *om = w;
            if w == 0.0 {
                continue;
            }
            let w = w * vol[j];
            let t = pair(pi, pj, &x, &e, inv_h);
            for c in 0..3 {
                acc[c] += w * t[c];
            }
        }
        *fi = acc;
    }
    changed
}

mechanics::simd::multiversion! {
    fn force_block<D: DamageModel>(
        lo: usize,
        f: &mut [[f64; 3]],
        intact: &mut [f64],
        offsets: &[usize],
        nbr: &[u32],
        inv_len: &[f64],
        x0: &[[f64; 3]],
        disp: &[[f64; 3]],
        vol: &[f64],
        point: &[BondSide],
        damage: &D,
        no_fail: &[bool],
        inv_h: f64,
    ) -> u32 = force_block_body;
}

/// A particle whose shape tensor has become singular through damage (its intact bonds too
/// few or too weak, det K < 10⁻³ det K₀) carries no stress; its remaining bonds break for
/// good, both ways, so it is reported fully damaged, counts as detached in fragment counts,
/// feels no force from its former neighbours, and cannot carry stress again. A particle
/// whose family is degenerate already in the reference state (det K₀ = 0: no neighbours, or
/// all of them on a line or a plane in 3-D) never had a gradient to lose and keeps its bonds,
/// as before. Bonds a no-fail zone keeps stay. Serial and cheap: one flag per particle, and
/// the rows of inactive particles. Returns how many bond copies it broke.
fn detach_inactive(kin: &[PointKin], k0det: &[f64], bonds: &mut Bonds) -> u32 {
    let mut broke = 0;
    for (i, pk) in kin.iter().enumerate() {
        if pk.active || k0det[i] == 0.0 {
            continue;
        }
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            // a no-fail zone keeps its bonds even to a particle that lost its gradient
            if bonds.intact[b] == 0.0 || spared(&bonds.no_fail, i, bonds.nbr[b] as usize) {
                continue;
            }
            bonds.intact[b] = 0.0;
            broke += 1;
            // families are symmetric (one horizon), so (j, i) exists
            if let Some(q) = bonds.twin(i, b) {
                bonds.intact[q] = 0.0;
                broke += 1;
            }
        }
    }
    broke
}

/// What a particle's strain energy reads from the model (see [`point_energy`]).
struct EnergyView<'a, L: StressLaw> {
    dim: Dim,
    mat: L,
    inv_h: f64,
    /// κ₀ = G C V_H (κ = κ₀/Σ ω V_j).
    kappa0: f64,
    state: &'a [L::State],
    kin: &'a [PointKin],
    side: &'a [BondSide],
    k0det: &'a [f64],
}

/// Particle i's strain energy V_i [w_e(σ_i) + ψ_i] (J) with its family as `row` (the intact
/// fractions of its bonds) holds it: w_e = ½ σ : C⁻¹ : σ of its stress (seed 000 eq. 14 and
/// 19: the internal energy whose rate is the stress power σ : L, less the plastic work) and
/// the zero-energy-mode stabilisation ψ_i = ½ (κ_i/δ) Σ_j ω V_j |z_ij|², z = η − Hξ
/// (eq. 184): the potential whose derivative is the stabilisation force state ω κ z/δ of
/// eq. (186) (the variation through H vanishes, since H is the least-squares fit of η).
/// For the family pass 1 last saw (Σ ω V_j equal to the one its K⁻¹ was built for), H and
/// κ are pass 1's; for a family that damage changed since, K⁻¹, H and κ = κ₀/Σ ω V_j are
/// formed as the next pass 1 forms them, so the energy follows damage at once. A particle
/// that carries no gradient (fully broken, or too few bonds left) stores nothing.
fn point_energy<L: StressLaw>(
    v: &EnergyView<L>,
    i: usize,
    k: &Kinematics,
    bonds: &Bonds,
    row: &[f64],
) -> f64 {
    let r = bonds.offsets[i]..bonds.offsets[i + 1];
    let (nbr, xis) = (&bonds.nbr[r.clone()], &bonds.xi[r]);
    let pk = &v.kin[i];
    let mut w0 = 0.0;
    for (&om, &j) in row.iter().zip(nbr) {
        if om != 0.0 {
            w0 += om * k.vol[j as usize];
        }
    }
    let ui = k.disp[i];
    let (f, kappa) = if w0 == pk.wsum {
        if !pk.active {
            return 0.0;
        }
        (pk.f, v.side[i].kappa)
    } else {
        // K (eq. 182) and N = Σ ω V_j η⊗ξ of the family as it is now (as pass 1 and
        // `shape_tensor` form them)
        let (mut kk, mut nn) = ([[0.0; 3]; 3], [[0.0; 3]; 3]);
        for ((&om, &j), x) in row.iter().zip(nbr).zip(xis) {
            if om == 0.0 {
                continue;
            }
            let j = j as usize;
            let w = om * k.vol[j];
            let uj = k.disp[j];
            let wy = [
                w * (uj[0] - ui[0]),
                w * (uj[1] - ui[1]),
                w * (uj[2] - ui[2]),
            ];
            for a in 0..3 {
                for c in 0..3 {
                    kk[a][c] += w * x[a] * x[c];
                    nn[a][c] += wy[a] * x[c];
                }
            }
        }
        if !v.dim.three_d() {
            kk[2][2] = 1.0;
            nn[2][2] = 0.0;
        }
        let Some(kinv) = inverse(&kk, 1e-3 * v.k0det[i].abs()) else {
            return 0.0;
        };
        let h = matmul(&nn, &kinv);
        let f: M3 = std::array::from_fn(|a| {
            std::array::from_fn(|c| h[a][c] + if a == c { 1.0 } else { 0.0 })
        });
        (f, if w0 > 0.0 { v.kappa0 / w0 } else { 0.0 })
    };
    let mut psi = 0.0;
    if kappa != 0.0 {
        for ((&w, &j), x) in row.iter().zip(nbr).zip(xis) {
            if w == 0.0 {
                continue;
            }
            let j = j as usize;
            let uj = k.disp[j];
            let mut z2 = 0.0;
            for a in 0..3 {
                // z = η − Hξ, H = F − I
                let hx = (f[a][0] - f64::from(a == 0)) * x[0]
                    + (f[a][1] - f64::from(a == 1)) * x[1]
                    + (f[a][2] - f64::from(a == 2)) * x[2];
                let z = (uj[a] - ui[a]) - hx;
                z2 += z * z;
            }
            psi += w * k.vol[j] * z2;
        }
        psi *= 0.5 * kappa * v.inv_h;
    }
    k.vol[i] * (v.mat.stored_energy(&v.state[i]) + psi)
}

impl<D: DamageModel, L: StressLaw> PdModel for Correspondence<D, L> {
    fn name(&self) -> &'static str {
        "pd-correspondence"
    }

    fn force_density(&mut self, k: &Kinematics, bonds: &mut Bonds, dt: f64, f: &mut [[f64; 3]]) {
        if self.booked.len() != bonds.len() {
            self.booked.clone_from(&bonds.intact);
        }
        self.pass1(k, bonds, dt);
        let detached = detach_inactive(&self.kin, &self.k0det, bonds);
        let point = &self.side;
        let damage = &self.damage;
        let inv_h = 1.0 / self.horizon;
        let (offsets, nbr, inv_len) = (&bonds.offsets, &bonds.nbr, &bonds.inv_len);
        let no_fail = &bonds.no_fail;
        let simd = self.simd;
        // bonds whose intact fraction this evaluation changed (counted per block)
        let changed = AtomicU64::new(u64::from(detached));
        let count = |n: u32| {
            if n > 0 {
                changed.fetch_add(u64::from(n), Ordering::Relaxed);
            }
        };
        #[cfg(target_arch = "x86_64")]
        let done = if self.explicit_avx512()
            && let Some(s0) = damage.stretch_limit()
        {
            let (packed, lim) = (&self.packed, (1.0 + s0) * (1.0 + s0));
            par_row_blocks(offsets, f, &mut bonds.intact, &|lo, fb, ib| {
                // SAFETY: `explicit_avx512` holds only on a CPU with AVX-512 F/DQ/VL.
                count(unsafe {
                    avx512::force_block(
                        lo, fb, ib, offsets, nbr, inv_len, packed, lim, no_fail, inv_h,
                    )
                });
            });
            true
        } else {
            false
        };
        #[cfg(not(target_arch = "x86_64"))]
        let done = false;
        if !done {
            par_row_blocks(offsets, f, &mut bonds.intact, &|lo, fb, ib| {
                count(force_block::<D>(
                    simd, lo, fb, ib, offsets, nbr, inv_len, k.x0, k.disp, k.vol, point, damage,
                    no_fail, inv_h,
                ));
            });
        }
        if changed.into_inner() > 0 {
            self.release(k, bonds);
        }
    }

    fn stable_dt(&self, k: &Kinematics, bonds: &Bonds, density: f64) -> f64 {
        // seed 001 §4.2: Δt ≤ l/c, l the spacing, c the dilatational wave speed.
        let c = (self.material.wave_modulus() / density).sqrt();
        let mut lmin = f64::INFINITY;
        for i in 0..bonds.particles() {
            for b in bonds.offsets[i]..bonds.offsets[i + 1] {
                lmin = lmin.min(1.0 / bonds.inv_len[b]);
            }
        }
        let _ = k;
        lmin / c
    }

    /// Σ_i V_i [w_e(σ_i) + ψ_i]: see [`point_energy`].
    fn strain_energy(&mut self, k: &Kinematics, bonds: &Bonds) -> f64 {
        // taken out for the pass (no allocation), so the view can borrow the rest
        let mut energy = std::mem::take(&mut self.energy);
        let view = self.energy_view();
        let offsets = &bonds.offsets;
        super::family::par_points(&mut energy, &|i, e: &mut f64| {
            *e = point_energy(
                &view,
                i,
                k,
                bonds,
                &bonds.intact[offsets[i]..offsets[i + 1]],
            );
        });
        let total = energy.iter().sum();
        self.energy = energy;
        total
    }

    fn fracture_energy(&self) -> f64 {
        self.released.iter().sum()
    }

    fn plastic_work(&self, vol: &[f64]) -> f64 {
        self.plastic_work.iter().zip(vol).map(|(w, v)| w * v).sum()
    }

    fn stress(&self) -> Option<Vec<Sym>> {
        Some(self.state.iter().map(|s| *L::stress(s)).collect())
    }

    fn plastic_strain(&self) -> Option<Vec<f64>> {
        Some(self.state.iter().map(L::eq_plastic_strain).collect())
    }

    fn set_failure_factors(&mut self, factor: &[f64]) {
        for (st, &f) in self.state.iter_mut().zip(factor) {
            L::set_failure_factor(st, f);
        }
    }

    fn point_scalars(&self) -> Vec<(&'static str, Vec<f64>)> {
        let names = self.material.scalar_names();
        names
            .iter()
            .enumerate()
            .map(|(k, &name)| (name, self.state.iter().map(|s| L::scalar(s, k)).collect()))
            .collect()
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        encode_state(&CorrHistory {
            state: Cow::Borrowed(&self.state),
            plastic_work: Cow::Borrowed(&self.plastic_work),
            released: Cow::Borrowed(&self.released),
        })
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        let h = CorrHistory::<L::State>::decode(bytes, self.state.len())?;
        check_len(
            "released bond energy",
            h.released.len(),
            self.released.len(),
        )?;
        self.state = h.state.into_owned();
        self.plastic_work = h.plastic_work.into_owned();
        self.released = h.released.into_owned();
        // the loaded intact fractions are booked as they are at the next evaluation
        self.booked.clear();
        // K⁻¹ is rebuilt from the restored bond damage on the next step.
        for k in self.kin.iter_mut() {
            k.wsum = f64::NAN;
        }
        Ok(())
    }

    fn set_simd(&mut self, simd: Simd) {
        self.simd = simd;
    }

    fn partial_force(
        &self,
        k: &Kinematics,
        bonds: &Bonds,
        i: usize,
        from: &[u8],
    ) -> Option<[f64; 3]> {
        // force_block_body's sum over row i, on the bonds' intact fractions as the last
        // force pass left them, restricted to the marked neighbours
        let (pi, up, xp) = (&self.side[i], k.disp[i], k.x0[i]);
        let inv_h = 1.0 / self.horizon;
        let r = bonds.offsets[i]..bonds.offsets[i + 1];
        let mut acc = [0.0; 3];
        for (&om, &j) in bonds.intact[r.clone()].iter().zip(&bonds.nbr[r]) {
            let j = j as usize;
            if om == 0.0 || from[j] == 0 {
                continue;
            }
            let pj = &self.side[j];
            let xj = k.x0[j];
            let x = [xj[0] - xp[0], xj[1] - xp[1], xj[2] - xp[2]];
            let q = k.disp[j];
            let e = [q[0] - up[0], q[1] - up[1], q[2] - up[2]];
            let w = om * k.vol[j];
            let t = pair(pi, pj, &x, &e, inv_h);
            for c in 0..3 {
                acc[c] += w * t[c];
            }
        }
        Some(acc)
    }

    fn point_energies(&self) -> Option<&[f64]> {
        Some(&self.energy)
    }

    fn stiffness_bound(&self, k: &Kinematics, bonds: &Bonds, i: usize) -> f64 {
        // (K + 4G/3) Δx-scaled: modulus × V_i / l_min²
        let modulus = self.material.wave_modulus();
        let l = (bonds.offsets[i]..bonds.offsets[i + 1])
            .map(|b| 1.0 / bonds.inv_len[b])
            .fold(f64::INFINITY, f64::min);
        if l.is_finite() {
            4.0 * modulus * k.vol[i] / (l * l)
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pd::bond::{LANES, assert_same_bits, lane_sum, lane_tree};
    use crate::pd::geometry::cube_lattice;
    use mechanics::damage::{BrittleVonMises, CriticalStretch};

    /// The force loop as it was before the kernels were multiversioned (ξ streamed from
    /// `Bonds::xi`, the stretch formed for every damage law), kept as their bitwise reference.
    /// `lanes`: sum in the eight-lane order of the explicit AVX-512 kernels (`lane_tree`)
    /// instead of row order.
    fn force_scalar<D: DamageModel>(
        m: &Correspondence<D>,
        k: &Kinematics,
        bonds: &Bonds,
        intact: &mut [f64],
        lanes: bool,
    ) -> Vec<[f64; 3]> {
        let inv_h = 1.0 / m.horizon;
        let point = &m.side;
        (0..bonds.particles())
            .map(|i| {
                let pi = &point[i];
                let up = k.disp[i];
                // lane k % 8 for bond k of the row, or one lane
                let mut acc = [[0.0; LANES]; 3];
                let lane = |k: usize| if lanes { k % LANES } else { 0 };
                for (k8, b) in (bonds.offsets[i]..bonds.offsets[i + 1]).enumerate() {
                    let om = &mut intact[b];
                    if *om == 0.0 {
                        continue;
                    }
                    let (j, x, il) = (bonds.nbr[b] as usize, &bonds.xi[b], bonds.inv_len[b]);
                    let pj = &point[j];
                    let q = k.disp[j];
                    let e = [q[0] - up[0], q[1] - up[1], q[2] - up[2]];
                    let input = BondInput {
                        stretch: crate::pd::bond::stretch_over_len(x, &e, il).0,
                        von_mises: 0.5 * (pi.vm + pj.vm),
                        eq_plastic_strain: 0.5 * (pi.eqp + pj.eqp),
                        failure: 0.5 * (pi.fail + pj.fail),
                    };
                    let w = m.damage.update(*om, &input);
                    *om = w;
                    if w == 0.0 {
                        continue;
                    }
                    let w = w * k.vol[j];
                    let ks = (pi.kappa + pj.kappa) * inv_h;
                    for c in 0..3 {
                        let t = (pi.ahat[c][0] + pj.ahat[c][0]) * x[0]
                            + (pi.ahat[c][1] + pj.ahat[c][1]) * x[1]
                            + (pi.ahat[c][2] + pj.ahat[c][2]) * x[2];
                        acc[c][lane(k8)] += w * (t + ks * e[c]);
                    }
                }
                acc.map(|l| if lanes { lane_tree(&l) } else { l[0] })
            })
            .collect()
    }

    /// X, u, v, V and the bonds of the test body.
    type State = (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<f64>, Bonds);

    /// A deformed, moving block far from the origin with long rows (250 members); some bonds
    /// broken beforehand.
    fn state() -> State {
        let dx = 1e-3;
        let x0: Vec<[f64; 3]> = cube_lattice(10, dx)
            .into_iter()
            .map(|p| [p[0] - 30.0, p[1] + 70.0, p[2]])
            .collect();
        let mut bonds = Bonds::build(&x0, 4.02 * dx);
        assert!((0..bonds.particles()).any(|i| bonds.offsets[i + 1] - bonds.offsets[i] > 200));
        for b in (0..bonds.len()).step_by(23) {
            bonds.intact[b] = 0.0;
        }
        let f = |i: usize, a: f64, s: f64| s * (i as f64 * a).sin();
        let disp = (0..x0.len())
            .map(|i| [f(i, 0.37, 2e-4), f(i, 0.11, -3e-4), f(i, 0.71, 5e-4)])
            .collect();
        let vel = (0..x0.len())
            .map(|i| [f(i, 0.53, 3.0), f(i, 0.29, 1.0), f(i, 0.97, -2.0)])
            .collect();
        let vol = vec![dx * dx * dx; x0.len()];
        (x0, disp, vel, vol, bonds)
    }

    fn check<D: DamageModel + Clone>(damage: D, min_breaks: usize) {
        let (x0, disp, vel, vol, bonds) = state();
        let k = Kinematics {
            x0: &x0,
            pos: &x0,
            disp: &disp,
            vel: &vel,
            vol: &vol,
        };
        let mat = J2Material {
            young: 200e9,
            poisson: 0.3,
            yield_stress: 300e6,
            iso_hardening: 1e9,
            kin_hardening: 5e8,
        };
        let mut m = Correspondence::new(Dim::Three, mat, 0.5, 4.02e-3, 1.0, damage, &k, &bonds);
        m.pass1(&k, &bonds, 1e-6);
        // the explicit AVX-512 kernels' records (None without AVX-512)
        #[cfg(target_arch = "x86_64")]
        let packed = mechanics::simd::has_avx512().then(|| {
            let mut p = avx512::Packed::default();
            p.pack_particles(&k);
            p.pack_sides(&m.side);
            p
        });
        #[cfg(target_arch = "x86_64")]
        if packed.is_none() {
            eprintln!("no AVX-512 on this CPU: the explicit AVX-512 kernels are not tested here");
        }
        for i in 0..bonds.particles() {
            let r = bonds.offsets[i]..bonds.offsets[i + 1];
            let (mut nn, mut nd, mut w0) = ([[0.0; 3]; 3], [[0.0; 3]; 3], 0.0);
            for b in r.clone() {
                if bonds.intact[b] == 0.0 {
                    continue;
                }
                let (j, x) = (bonds.nbr[b] as usize, bonds.xi[b]);
                let w = bonds.intact[b] * vol[j];
                w0 += w;
                for a in 0..3 {
                    for c in 0..3 {
                        nn[a][c] += w * (disp[j][a] - disp[i][a]) * x[c];
                    }
                }
            }
            for b in r.clone() {
                if bonds.intact[b] == 0.0 {
                    continue;
                }
                let (j, x) = (bonds.nbr[b] as usize, bonds.xi[b]);
                let w = bonds.intact[b] * vol[j];
                for a in 0..3 {
                    for c in 0..3 {
                        nd[a][c] += w * (vel[j][a] - vel[i][a]) * x[c];
                    }
                }
            }
            // the explicit AVX-512 kernel against the same sums in the lane order of
            // `lane_sum`
            let (mut ln, mut ld) = ([[0.0; 3]; 3], [[0.0; 3]; 3]);
            let terms = |f: &dyn Fn(usize, usize, &[f64; 3]) -> f64| -> f64 {
                let t: Vec<f64> = r
                    .clone()
                    .map(|b| {
                        if bonds.intact[b] == 0.0 {
                            -0.0
                        } else {
                            let (j, x) = (bonds.nbr[b] as usize, &bonds.xi[b]);
                            f(b, j, x)
                        }
                    })
                    .collect();
                lane_sum(&t)
            };
            let w = |b: usize, j: usize| bonds.intact[b] * vol[j];
            for a in 0..3 {
                for c in 0..3 {
                    ln[a][c] = terms(&|b, j, x| w(b, j) * (disp[j][a] - disp[i][a]) * x[c]);
                    ld[a][c] = terms(&|b, j, x| w(b, j) * (vel[j][a] - vel[i][a]) * x[c]);
                }
            }
            let lw = terms(&|b, j, _| w(b, j));
            #[cfg(target_arch = "x86_64")]
            if let Some(p) = &packed {
                // SAFETY: `packed` is Some only on a CPU with AVX-512 (checked above).
                let s = unsafe {
                    avx512::family_sums(i, p, &bonds.nbr[r.clone()], &bonds.intact[r.clone()])
                };
                let bits = |m: &M3| m.map(|r| r.map(f64::to_bits));
                assert_eq!(bits(&s.nn), bits(&ln), "explicit AVX-512: N at {i}");
                assert_eq!(bits(&s.nd), bits(&ld), "explicit AVX-512: Ṅ at {i}");
                assert_eq!(
                    s.w0.to_bits(),
                    lw.to_bits(),
                    "explicit AVX-512: Σ ω V at {i}"
                );
            }
            for simd in Simd::available() {
                let s = family_sums(
                    simd,
                    &bonds.nbr[r.clone()],
                    &bonds.intact[r.clone()],
                    &x0,
                    &disp,
                    &vel,
                    &vol,
                    (x0[i], disp[i], vel[i]),
                );
                let bits = |m: &M3| m.map(|r| r.map(f64::to_bits));
                assert_eq!(bits(&s.nn), bits(&nn), "{simd:?}: N at {i}");
                assert_eq!(bits(&s.nd), bits(&nd), "{simd:?}: Ṅ at {i}");
                assert_eq!(s.w0.to_bits(), w0.to_bits(), "{simd:?}: Σ ω V at {i}");
            }
        }
        let mut reference = bonds.intact.clone();
        let fref = force_scalar(&m, &k, &bonds, &mut reference, false);
        let breaks = reference
            .iter()
            .zip(&bonds.intact)
            .filter(|(a, b)| a != b)
            .count();
        assert!(breaks >= min_breaks, "{breaks} bonds broke");
        assert!(fref.iter().any(|f| f[0] != 0.0));
        for simd in Simd::available() {
            let mut intact = bonds.intact.clone();
            let mut fs = vec![[0.0; 3]; bonds.particles()];
            force_block::<D>(
                simd,
                0,
                &mut fs,
                &mut intact,
                &bonds.offsets,
                &bonds.nbr,
                &bonds.inv_len,
                &x0,
                &disp,
                &vol,
                &m.side,
                &m.damage,
                &bonds.no_fail,
                1.0 / m.horizon,
            );
            assert_same_bits(&format!("{simd:?}"), &fs, &intact, &fref, &reference);
        }
        #[cfg(target_arch = "x86_64")]
        if let (Some(p), Some(s0)) = (&packed, m.damage.stretch_limit()) {
            let mut reference = bonds.intact.clone();
            let rows = fref;
            let fref = force_scalar(&m, &k, &bonds, &mut reference, true);
            // the two summation orders agree to rounding: 1e-12 of the largest force
            let scale = rows.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
            let worst = rows
                .iter()
                .flatten()
                .zip(fref.iter().flatten())
                .fold(0.0f64, |a, (r, l)| a.max((r - l).abs()));
            assert!(
                worst <= 1e-12 * scale,
                "lane vs row order: {worst:e} of {scale:e}"
            );
            let mut intact = bonds.intact.clone();
            let mut fs = vec![[0.0; 3]; bonds.particles()];
            let o = &bonds.offsets;
            // blocks of 37 particles: block starts fall mid-way through the bond array
            for lo in (0..bonds.particles()).step_by(37) {
                let hi = (lo + 37).min(bonds.particles());
                // SAFETY: `packed` is Some only on a CPU with AVX-512.
                unsafe {
                    avx512::force_block(
                        lo,
                        &mut fs[lo..hi],
                        &mut intact[o[lo]..o[hi]],
                        o,
                        &bonds.nbr,
                        &bonds.inv_len,
                        p,
                        (1.0 + s0) * (1.0 + s0),
                        &bonds.no_fail,
                        1.0 / m.horizon,
                    )
                };
            }
            assert_same_bits("explicit AVX-512", &fs, &intact, &fref, &reference);
        }
    }

    /// Pass 1's family sums and the force kernel on every instruction set this CPU has,
    /// against the reference loops bit for bit, with bonds breaking by stretch (the squared
    /// length test) and by von Mises stress, and without damage.
    #[test]
    fn kernels_match_the_reference_loops_bitwise_on_every_instruction_set() {
        check(
            CriticalStretch {
                critical_stretch: 0.02,
            },
            100,
        );
        check(
            BrittleVonMises {
                critical_stress: 2e8,
            },
            100,
        );
        check(mechanics::damage::NoDamage, 0);
    }
}
