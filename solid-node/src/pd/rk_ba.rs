//! pd-rk-ba: seed 000 App. A — the semi-Lagrangian correspondence PD rate form with
//! reproducing-kernel (RK) gradient operators of order n = 1 or 2 and bond-associative (BA)
//! stabilization.
//!
//! * Influence (A.3–A.4): cubic B-spline ω_r(|x|/δ) of the *current* bond x = x_j − x_i
//!   over the family found in the reference configuration (a member that moves beyond δ
//!   gets ω = 0; new neighbours are not searched for — adequate up to moderate distortion)
//!   (semi-Lagrangian: no mapping to the reference configuration), times the bond damage
//!   ω_D (C.1); ω̄ = Σ_j ω V_j (A.6).
//! * RK gradient kernel (A.2, A.7, A.8): Φ_j = ω Ξ̃ M⁻¹ Ξ(x_j), M = Σ_j ω Ξ Ξᵀ V_j, Ξ the
//!   monomials of degree 1..n (A.9); the monomials are taken of x/δ for conditioning and Φ
//!   scaled back by 1/δ. Point velocity gradient L = Σ_j (v_j − v_i) Φ_jᵀ V_j (A.1); it is exact
//!   for polynomial fields of degree ≤ n, at every particle with a non-singular M.
//! * BA velocity gradient per bond (A.11): L_b = L̄ + (v − L̄ x) xᵀ/|x|², L̄ = (L_i + L_j)/2.
//! * Bond-level rate-form J2 with Jaumann rate (App. B, `mechanics::j2`) updates the bond
//!   Cauchy stress σ_b (A.12); bond damage from σ_b, ε̄ᵖ_b and the stretch (App. C).
//! * Force state (A.13–A.14): T_ij = ω σ_b x/(ω̄_i |x|²) + z_i Φ_ij,
//!   z_i = Σ_j (½/ω̄_i + ½/ω̄_j) ω σ_b (I − x xᵀ/|x|²) V_j; force density
//!   f_i = Σ_j (T_ij − T_ji) V_j (seed 001 eq. 183), antisymmetric per pair, so linear
//!   momentum is conserved. (With ω̄_i = ω̄_j the PD stress Σ_j T_ij ⊗ x V_j equals σ: the
//!   z term supplies the transverse part that the first term lacks.)
//!
//! * Without BA (`bond_associative = false`, for stability studies): J2 at the particle from its
//!   point gradient L_i, and the plain correspondence force state T_ij = σ_i Φ_ij, so
//!   f_i = Σ_j (σ_i Φ_ij − σ_j Φ_ji) V_j — still antisymmetric per pair, but with the
//!   zero-energy modes that the bond-level gradient removes.
//!
//! Both copies of a bond (rows i and j) evolve bit-identically: L̄ is symmetric and the BA
//! term is even in (v, x) → (−v, −x). The force pass reads Φ_ji through the reverse-bond map.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use super::correspondence::M3;
use super::family::{Bonds, par_rows, spared};
use super::model::{Dim, Kinematics, PdModel};
use mechanics::blast_solid::BlastSolid;
use mechanics::damage::{BondInput, DamageModel};
use mechanics::j2::{
    J2Material, J2State, Sym, jaumann_rotate_skew, spin_and_strain_step, von_mises,
};
use mechanics::stress_law::StressLaw;
use mechanics::tensor::vec3;
use protocol::checkpoint::{check_len, decode_state, encode_state};
use protocol::solver::SolverResult;
use std::sync::atomic::{AtomicU64, Ordering};

/// The stress law at a bond of pd-rk-ba (at a particle without BA): J2 plasticity, the
/// seed's, or the blast solid (Johnson–Cook strength, Mie–Grüneisen pressure, Johnson–Cook
/// failure).
pub trait BondLaw: StressLaw {
    /// One step of the rate form: the Jaumann rotation with the spin, then the law over the
    /// strain increment `de`; returns the plastic work density of the step (J/m³; 0 where
    /// the point stayed elastic).
    fn bond_step(&self, st: &mut Self::State, de: &Sym, spin: &M3, dt: f64) -> f64;
}

impl BondLaw for J2Material {
    #[inline]
    fn bond_step(&self, st: &mut J2State, de: &Sym, spin: &M3, dt: f64) -> f64 {
        jaumann_rotate_skew(&mut st.stress, spin, dt);
        if self.kin_hardening != 0.0 {
            jaumann_rotate_skew(&mut st.back_stress, spin, dt);
        }
        let deqp = self.update(st, de);
        if deqp > 0.0 {
            mechanics::j2::plastic_work(st, deqp)
        } else {
            0.0
        }
    }
}

impl BondLaw for BlastSolid {
    /// The rate form has no deformation gradient: J follows d ln J = tr D dt from the
    /// point's last J, which the pressure takes (1 at rest).
    #[inline]
    fn bond_step(&self, st: &mut Self::State, de: &Sym, spin: &M3, dt: f64) -> f64 {
        let jac = st.jac * (de[0] + de[1] + de[2]).exp();
        self.step(st, de, spin, dt, jac, false)
    }
}

/// Largest monomial basis: 3-D, order 2 (x, y, z, x², xy, xz, y², yz, z²).
pub const MAX_BASIS: usize = 9;

/// Cubic B-spline influence of seed 000 eq. (A.3), η = |x|/δ.
#[inline]
pub fn bspline(eta: f64) -> f64 {
    if eta <= 0.0 || eta > 1.0 {
        0.0
    } else if eta <= 0.5 {
        2.0 / 3.0 - 4.0 * eta * eta + 4.0 * eta * eta * eta
    } else {
        let a = 1.0 - eta;
        4.0 / 3.0 * a * a * a
    }
}

/// Monomials Ξ⁽ⁿ⁾ (A.9) of `p` in `dims` dimensions up to degree `order` (1 or 2); the
/// first `dims` entries are the linear ones (Ξ̃ of A.8 selects them). Returns the length.
#[inline]
pub fn monomials(p: &[f64; 3], dims: usize, order: usize, out: &mut [f64; MAX_BASIS]) -> usize {
    let mut m = 0;
    for d in 0..dims {
        out[m] = p[d];
        m += 1;
    }
    if order >= 2 {
        for a in 0..dims {
            for b in a..dims {
                out[m] = p[a] * p[b];
                m += 1;
            }
        }
    }
    m
}

/// Basis size for (dims, order).
pub fn basis_len(dims: usize, order: usize) -> usize {
    if order >= 2 {
        dims + dims * (dims + 1) / 2
    } else {
        dims
    }
}

/// A particle keeps a gradient of a given order while the determinant of its equilibrated
/// moment matrix (M scaled to a unit diagonal, so that neither the family's size nor the
/// horizon enters) stays above this share of the same determinant in the reference
/// configuration, undamaged. Below it (a family reduced by damage to a few members or to
/// nearly one line) the inverse grows without bound and so would the gradient: the
/// particle falls back to the linear basis, and below the share there too it carries no
/// gradient. The same rule as pd-correspondence's shape tensor (1e-3 of its reference
/// determinant). The default of the case key `rk_condition_floor`.
pub const CONDITION_FLOOR: f64 = 1e-3;

/// The equilibrated Cholesky factor of the leading m×m block of a symmetric matrix (full
/// in `a`, row-major, stride MAX_BASIS): the factor of S A S with S = diag(A_aa^-1/2),
/// `scale` = S. Returns how many leading pivots were positive (m when the whole block is
/// positive definite) and the determinants of S A S's leading `dims` block and of the whole
/// block (0 where the factorisation broke down before their end). The factor of a leading
/// block of A is the leading block of A's factor, so one factorisation serves both orders.
fn factor_equilibrated(
    a: &mut [[f64; MAX_BASIS]; MAX_BASIS],
    m: usize,
    dims: usize,
    scale: &mut [f64; MAX_BASIS],
) -> (usize, [f64; 2]) {
    // a zero diagonal (a monomial no family member sees) ends the factor before its row
    let full = m;
    let m = (0..m).position(|i| !(a[i][i] > 0.0)).unwrap_or(m);
    for i in 0..m {
        scale[i] = 1.0 / a[i][i].sqrt();
    }
    for i in 0..m {
        for j in 0..m {
            a[i][j] *= scale[i] * scale[j];
        }
    }
    let (mut det, mut det_lin) = (1.0, 0.0);
    for j in 0..m {
        let mut s = a[j][j];
        for k in 0..j {
            s -= a[j][k] * a[j][k];
        }
        // a unit diagonal: the pivot is the share of the direction that the earlier ones
        // leave; round-off is about 1e-16
        if !(s > 1e-14) {
            return (j, [det_lin, 0.0]);
        }
        det *= s;
        if j + 1 == dims {
            det_lin = det;
        }
        let d = s.sqrt();
        a[j][j] = d;
        for i in j + 1..m {
            let mut s = a[i][j];
            for k in 0..j {
                s -= a[i][k] * a[j][k];
            }
            a[i][j] = s / d;
        }
    }
    (m, [det_lin, if m == full { det } else { 0.0 }])
}

/// Solves L Lᵀ y = b with the leading m×m block of the factor of [`factor_equilibrated`].
fn cholesky_solve(l: &[[f64; MAX_BASIS]; MAX_BASIS], m: usize, b: &mut [f64; MAX_BASIS]) {
    for i in 0..m {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i][k] * b[k];
        }
        b[i] = s / l[i][i];
    }
    for i in (0..m).rev() {
        let mut s = b[i];
        for k in i + 1..m {
            s -= l[k][i] * b[k];
        }
        b[i] = s / l[i][i];
    }
}

/// ω of every bond of row i on the configuration `pos`: ω_r(|x|/δ) ω_D (A.3, C.1); `w` holds
/// ω_D on entry.
#[inline]
fn omega_row(i: usize, horizon: f64, pos: &[[f64; 3]], nbr: &[u32], w: &mut [f64]) {
    let inv_h = 1.0 / horizon;
    let p = pos[i];
    for (&j, wb) in nbr.iter().zip(w.iter_mut()) {
        if !(*wb > 0.0) {
            *wb = 0.0;
            continue;
        }
        let q = pos[j as usize];
        let x = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
        let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt() * inv_h;
        *wb *= bspline(r);
    }
}

/// G = the first `dims` rows of M⁻¹ (A.7, A.8; monomials of x/δ) for bond weights ω of
/// row i, at the model's order where M is well conditioned, else of the linear block (see
/// [`CONDITION_FLOOR`]; `floor` holds the least equilibrated determinants, linear and full,
/// that keep each order: the floor's share of the reference configuration's; None: any
/// positive definite M is taken). Returns ω̄
/// (A.6), the degree of the gradient formed (0: none) and the equilibrated determinants.
fn moment_rows(
    i: usize,
    dims: usize,
    order: usize,
    horizon: f64,
    pos: &[[f64; 3]],
    vol: &[f64],
    nbr: &[u32],
    w: &[f64],
    floor: Option<[f64; 2]>,
    g: &mut [[f64; MAX_BASIS]; 3],
) -> (f64, u8, [f64; 2]) {
    let m = basis_len(dims, order);
    let inv_h = 1.0 / horizon;
    let mut mm = [[0.0; MAX_BASIS]; MAX_BASIS];
    let mut wbar = 0.0;
    let p = pos[i];
    *g = [[0.0; MAX_BASIS]; 3];
    // Constant basis sizes let the compiler unroll the rank-1 updates.
    match m {
        2 => accumulate::<2>(p, inv_h, pos, vol, nbr, w, dims, order, &mut mm, &mut wbar),
        3 => accumulate::<3>(p, inv_h, pos, vol, nbr, w, dims, order, &mut mm, &mut wbar),
        5 => accumulate::<5>(p, inv_h, pos, vol, nbr, w, dims, order, &mut mm, &mut wbar),
        _ => accumulate::<9>(p, inv_h, pos, vol, nbr, w, dims, order, &mut mm, &mut wbar),
    }
    for a in 0..m {
        for b in a + 1..m {
            mm[a][b] = mm[b][a];
        }
    }
    let mut scale = [0.0; MAX_BASIS];
    let (pivots, det) = factor_equilibrated(&mut mm, m, dims, &mut scale);
    let floor = floor.unwrap_or([0.0; 2]);
    let (size, degree) = if pivots == m && det[1] > floor[1] {
        (m, order as u8)
    } else if pivots >= dims && det[0] > floor[0] {
        (dims, 1)
    } else {
        return (wbar, 0, det);
    };
    // M⁻¹ = S (S M S)⁻¹ S
    for d in 0..dims {
        let mut e = [0.0; MAX_BASIS];
        e[d] = scale[d];
        cholesky_solve(&mm, size, &mut e);
        for a in 0..size {
            e[a] *= scale[a];
        }
        g[d] = e;
    }
    (wbar, degree, det)
}

/// M += ω V_j Ξ Ξᵀ (lower triangle) and ω̄ += ω V_j over a row, basis size `M`.
#[inline(always)]
fn accumulate<const M: usize>(
    p: [f64; 3],
    inv_h: f64,
    pos: &[[f64; 3]],
    vol: &[f64],
    nbr: &[u32],
    w: &[f64],
    dims: usize,
    order: usize,
    mm: &mut [[f64; MAX_BASIS]; MAX_BASIS],
    wbar: &mut f64,
) {
    let mut xi = [0.0; MAX_BASIS];
    for (&j, &om) in nbr.iter().zip(w) {
        if om == 0.0 {
            continue;
        }
        let j = j as usize;
        let q = pos[j];
        let x = [
            (q[0] - p[0]) * inv_h,
            (q[1] - p[1]) * inv_h,
            (q[2] - p[2]) * inv_h,
        ];
        let wv = om * vol[j];
        *wbar += wv;
        monomials(&x, dims, order, &mut xi);
        for a in 0..M {
            let s = wv * xi[a];
            for b in 0..=a {
                mm[a][b] += s * xi[b];
            }
        }
    }
}

/// Φ of one bond from the rows G: Φ_d = ω (G_d · Ξ(x/δ)) / δ (A.2).
#[inline]
fn phi_of(
    g: &[[f64; MAX_BASIS]; 3],
    om: f64,
    x: &[f64; 3],
    dims: usize,
    order: usize,
    horizon: f64,
) -> [f64; 3] {
    if om == 0.0 {
        return [0.0; 3];
    }
    let inv_h = 1.0 / horizon;
    let xs = [x[0] * inv_h, x[1] * inv_h, x[2] * inv_h];
    let mut xi = [0.0; MAX_BASIS];
    let m = monomials(&xs, dims, order, &mut xi);
    let mut out = [0.0; 3];
    for d in 0..dims {
        let mut s = 0.0;
        for a in 0..m {
            s += g[d][a] * xi[a];
        }
        out[d] = om * s * inv_h;
    }
    out
}

/// Per-particle results of the gradient pass.
#[derive(Debug, Clone, Copy)]
pub struct RkPoint {
    /// First `dims` rows of M⁻¹.
    pub g: [[f64; MAX_BASIS]; 3],
    /// Point velocity gradient L (A.1).
    pub l: M3,
    /// ω̄ (A.6).
    pub wbar: f64,
    /// Whether the particle has a gradient (false: its moment matrix is singular or too
    /// badly conditioned at any order, see [`CONDITION_FLOOR`]).
    pub active: bool,
    /// The degree of its gradient: the model's order, 1 where its family no longer
    /// supports that, 0 where it supports none.
    pub degree: u8,
    /// Its equilibrated moment matrix's determinants, linear block and whole.
    pub det: [f64; 2],
}

impl Default for RkPoint {
    fn default() -> Self {
        RkPoint {
            g: [[0.0; MAX_BASIS]; 3],
            l: [[0.0; 3]; 3],
            wbar: 0.0,
            active: false,
            degree: 0,
            det: [0.0; 2],
        }
    }
}

/// Shared gradient pass: ω per bond (from ω_D in `omega` on entry), G and ω̄ per particle,
/// then Φ per bond and the gradient of `field` per particle. `reference`: each particle's
/// equilibrated determinants in the reference configuration, against which its moment
/// matrix's conditioning is judged (None: any invertible one is taken).
fn gradient_pass(
    dims: usize,
    order: usize,
    horizon: f64,
    pos: &[[f64; 3]],
    vol: &[f64],
    field: &[[f64; 3]],
    bonds: &Bonds,
    reference: Option<&[[f64; 2]]>,
    point: &mut [RkPoint],
    omega: &mut [f64],
    phi: &mut [[f64; 3]],
) {
    let (offsets, nbr) = (&bonds.offsets, &bonds.nbr);
    par_rows(offsets, point, omega, &|i, pt, wrow| {
        let r = offsets[i]..offsets[i + 1];
        omega_row(i, horizon, pos, &nbr[r.clone()], wrow);
        let reference = reference.map(|d| d[i]);
        let (wbar, degree, det) = moment_rows(
            i, dims, order, horizon, pos, vol, &nbr[r], wrow, reference, &mut pt.g,
        );
        pt.wbar = wbar;
        pt.degree = degree;
        pt.active = degree > 0;
        pt.det = det;
    });
    let omega = &*omega;
    par_rows(offsets, point, phi, &|i, pt, prow| {
        let r = offsets[i]..offsets[i + 1];
        let p = pos[i];
        let u = field[i];
        let mut l = [[0.0; 3]; 3];
        for ((ph, &j), &om) in prow.iter_mut().zip(&nbr[r.clone()]).zip(&omega[r]) {
            if !pt.active || om == 0.0 {
                *ph = [0.0; 3];
                continue;
            }
            let j = j as usize;
            *ph = phi_of(
                &pt.g,
                om,
                &(vec3(&pos[j]) - vec3(&p)).into(),
                dims,
                order,
                horizon,
            );
            let du = vec3(&field[j]) - vec3(&u);
            let vj = vol[j];
            for a in 0..3 {
                for c in 0..3 {
                    l[a][c] += du[a] * ph[c] * vj;
                }
            }
        }
        pt.l = l;
    });
}

/// RK gradient (A.1) of a vector field at every particle, the kernel evaluated on the
/// configuration `pos` with undamaged bonds: ∇u_i = Σ_j (u_j − u_i) Φ_jᵀ V_j. Exact for
/// polynomial fields of degree ≤ `order` wherever the moment matrix is invertible;
/// particles where it is singular get zeros. (The model applies it to velocities.)
pub fn rk_gradient(
    dim: Dim,
    order: usize,
    horizon: f64,
    pos: &[[f64; 3]],
    vol: &[f64],
    bonds: &Bonds,
    field: &[[f64; 3]],
) -> Vec<M3> {
    let dims = if dim.three_d() { 3 } else { 2 };
    let mut point = vec![RkPoint::default(); bonds.particles()];
    let mut omega = vec![1.0; bonds.len()];
    let mut phi = vec![[0.0; 3]; bonds.len()];
    gradient_pass(
        dims, order, horizon, pos, vol, field, bonds, None, &mut point, &mut omega, &mut phi,
    );
    point.iter().map(|p| p.l).collect()
}

/// Per-bond history: the bond-level J2 state, the damage part ω_D of the influence, and ω
/// after this step's damage update (used by z and the force).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BondHistory<S = J2State> {
    pub state: S,
    pub wd: f64,
    pub om: f64,
    /// Plastic work done through this row's copy of the bond since the start (J):
    /// Σ V_i α V_j σ_b : Δεᵖ_b with α = ω/ω̄_i (seed 000 eq. 15–19).
    pub plastic_work: f64,
    /// The stored energy density w_e of the bond's stress at the start of this step, before
    /// its update (scratch of the force pass, for [`RkBa::release`]; not saved).
    pub e_prev: f64,
}

/// A bond's history as a checkpoint holds it: the law's state, ω_D and the plastic work.
type SavedBond<S> = (S, f64, f64);

/// The pd-rk-ba model, generic over its damage law and its stress law.
pub struct RkBa<D: DamageModel, L: BondLaw = J2Material> {
    pub dim: Dim,
    pub order: usize,
    pub horizon: f64,
    pub material: L,
    pub damage: D,
    pub point: Vec<RkPoint>,
    /// z_i of (A.14).
    pub z: Vec<M3>,
    /// ω and Φ per bond, from the gradient pass.
    pub omega: Vec<f64>,
    pub phi: Vec<[f64; 3]>,
    pub hist: Vec<BondHistory<L::State>>,
    /// Index of bond (j, i) for bond (i, j).
    pub rev: Vec<u32>,
    /// Row starts (a copy of the family offsets).
    offsets: Vec<usize>,
    /// Strain energy given up by bond damage per particle since the start (J; see
    /// [`RkBa::release`]).
    released: Vec<f64>,
    /// Whether the stress lives at the bonds (the BA model, the default) or at the particles.
    bond_associative: bool,
    /// Without BA: each particle's state and the plastic work done at it (J); empty with
    /// BA.
    point_state: Vec<(L::State, f64)>,
    /// Each particle's least equilibrated moment-matrix determinants (linear block, whole)
    /// that keep each order: `condition_floor` times those of the reference configuration
    /// with its whole family. Formed at the first step ([`RkBa::set_reference`]).
    reference_det: Vec<[f64; 2]>,
    /// The share of the reference determinants below which a particle's gradient falls
    /// back an order ([`CONDITION_FLOOR`] unless the case sets `rk_condition_floor`).
    condition_floor: f64,
}

/// Particle i's strain energy V_i S/W (J) with S = Σ_j ω_b V_j w_e(σ_b), W = Σ_j ω_b V_j over
/// its row (`hrow`, neighbours `nbr`) with the influences `om(b)` (b the index in the row):
/// the α-weighted bond energy of seed 000 eq. (15)–(18), α = ω/W. Zero when W = 0.
fn row_energy<L: BondLaw>(
    mat: &L,
    vol: &[f64],
    i: usize,
    nbr: &[u32],
    hrow: &[BondHistory<L::State>],
    om: impl Fn(usize) -> f64,
) -> f64 {
    family_average(vol, i, nbr, |b| (om(b), mat.stored_energy(&hrow[b].state)))
}

/// V_i Σ_j ω V_j w / Σ_j ω V_j over row i for (ω, w) = `bond(b)` (b the index in the row);
/// zero when the weights sum to zero.
fn family_average(vol: &[f64], i: usize, nbr: &[u32], bond: impl Fn(usize) -> (f64, f64)) -> f64 {
    let (mut s, mut w) = (0.0, 0.0);
    for (b, &j) in nbr.iter().enumerate() {
        let (o, e) = bond(b);
        if o != 0.0 {
            let wv = o * vol[j as usize];
            s += wv * e;
            w += wv;
        }
    }
    if w > 0.0 { vol[i] * s / w } else { 0.0 }
}

impl<D: DamageModel, L: BondLaw> RkBa<D, L> {
    pub fn new(
        dim: Dim,
        order: usize,
        horizon: f64,
        material: L,
        damage: D,
        bonds: &Bonds,
    ) -> Self {
        let n = bonds.particles();
        let nb = bonds.len();
        let rev = bonds.twins();
        RkBa {
            dim,
            order,
            horizon,
            material,
            damage,
            point: vec![RkPoint::default(); n],
            z: vec![[[0.0; 3]; 3]; n],
            omega: vec![0.0; nb],
            phi: vec![[0.0; 3]; nb],
            hist: bonds
                .intact
                .iter()
                .map(|&w| BondHistory {
                    state: material.initial_state(),
                    wd: w,
                    om: 0.0,
                    plastic_work: 0.0,
                    e_prev: 0.0,
                })
                .collect(),
            rev,
            offsets: bonds.offsets.clone(),
            released: vec![0.0; n],
            bond_associative: true,
            point_state: Vec::new(),
            reference_det: Vec::new(),
            condition_floor: CONDITION_FLOOR,
        }
    }

    /// Switches the bond-associative stabilization (on by default; see the module notes).
    /// Set before the first step: the stress history lives at the bonds with it and at the
    /// particles without it.
    /// The share of the reference determinants below which a gradient falls back an order
    /// (see [`CONDITION_FLOOR`]).
    pub fn set_condition_floor(&mut self, floor: f64) {
        self.condition_floor = floor;
    }

    pub fn set_bond_associative(&mut self, on: bool) {
        self.bond_associative = on;
        self.point_state = if on {
            Vec::new()
        } else {
            vec![(self.material.initial_state(), 0.0); self.point.len()]
        };
    }

    /// The unstabilized model's step after the gradient pass: Jaumann rate and J2 at each
    /// particle from its point gradient L_i, then f_i = Σ_j (σ_i Φ_ij − σ_j Φ_ji) V_j. It
    /// takes no damage (refused at set-up), so ω is the gradient pass's.
    fn point_forces(&mut self, k: &Kinematics, bonds: &Bonds, dt: f64, f: &mut [[f64; 3]]) {
        let (point, mat) = (&self.point, self.material);
        if dt > 0.0 {
            super::family::par_points(&mut self.point_state, &|i,
                                                               (st, work): &mut (
                L::State,
                f64,
            )| {
                let pi = &point[i];
                if !pi.active {
                    return;
                }
                let l = pi.l;
                let (spin, de) = spin_and_strain_step(&l, dt);
                let wp = mat.bond_step(st, &de, &spin, dt);
                if wp != 0.0 {
                    *work += k.vol[i] * wp;
                }
            });
        }
        let (offsets, nbr) = (&bonds.offsets, &bonds.nbr);
        let (state, phi, rev, omega) = (&self.point_state, &self.phi, &self.rev, &self.omega);
        super::family::par_points(f, &|i, fi: &mut [f64; 3]| {
            let si = mechanics::j2::to_matrix(L::stress(&state[i].0));
            let mut acc = [0.0; 3];
            for b in offsets[i]..offsets[i + 1] {
                if omega[b] == 0.0 {
                    continue;
                }
                let j = nbr[b] as usize;
                let sj = mechanics::j2::to_matrix(L::stress(&state[j].0));
                let (pij, pji) = (phi[b], phi[rev[b] as usize]);
                let vj = k.vol[j];
                for a in 0..3 {
                    let ti = si[a][0] * pij[0] + si[a][1] * pij[1] + si[a][2] * pij[2];
                    let tj = sj[a][0] * pji[0] + sj[a][1] * pji[1] + sj[a][2] * pji[2];
                    // negated exactly by row j's copy of the pair
                    acc[a] += (ti - tj) * vj;
                }
            }
            *fi = acc;
        });
    }

    /// Books the strain energy that this step's bond damage took from the rows it touched,
    /// at the bond stresses the step started from: the row's energy ([`row_energy`]) with the
    /// influences before the damage (this step's ω) less that with the influences after it
    /// (W renormalised, as the next gradient pass forms it) is released, so strain energy +
    /// released energy is unchanged by damage. The stresses are those before the step's
    /// update because a bond that breaks in a step never exerts the stress that step gave
    /// it: its increment was never paid for by the motion (in a breaking solid a bond can
    /// take an absurd one in a single step, and booking it would create energy). The energy is a family average: a bond less loaded than its family's
    /// average takes less than its share with it, and such an event releases a negative
    /// amount (the remaining bonds' weight grows). Runs only on a step whose damage changed
    /// an influence.
    fn release(&mut self, vol: &[f64], nbr: &[u32]) {
        let (omega, offsets) = (&self.omega, &self.offsets);
        par_rows(
            offsets,
            &mut self.released,
            &mut self.hist,
            &|i, rel: &mut f64, hrow| {
                let r = offsets[i]..offsets[i + 1];
                let (om0, nb) = (&omega[r.clone()], &nbr[r]);
                if hrow.iter().zip(om0).all(|(h, &w)| h.om == w) {
                    return;
                }
                let before = family_average(vol, i, nb, |b| (om0[b], hrow[b].e_prev));
                let after = family_average(vol, i, nb, |b| (hrow[b].om, hrow[b].e_prev));
                *rel += before - after;
            },
        );
    }

    /// The first particle whose moment matrix M (A.7) is singular in the reference
    /// configuration with the current bond damage (too few family members for the order),
    /// if any. Runs the gradient pass in the model's own buffers (every step forms them
    /// afresh).
    pub fn singular_particle(&mut self, k: &Kinematics, bonds: &Bonds) -> Option<usize> {
        for (w, h) in self.omega.iter_mut().zip(&self.hist) {
            *w = h.wd;
        }
        self.reference_pass(k, bonds);
        let order = self.order as u8;
        self.point.iter().position(|p| p.degree != order)
    }

    /// Each particle's equilibrated determinants in the reference configuration with every
    /// bond of its family intact (pre-cracks and damage aside, so that a restarted run
    /// judges against the same yardstick as the run it continues): the yardstick of
    /// [`CONDITION_FLOOR`], formed once, before the first step.
    fn set_reference(&mut self, k: &Kinematics, bonds: &Bonds) {
        self.omega.fill(1.0);
        self.reference_pass(k, bonds);
        let share = self.condition_floor;
        self.reference_det = self
            .point
            .iter()
            .map(|p| p.det.map(|d| share * d))
            .collect();
    }

    /// The gradient pass on the reference configuration with the influences ω_D in
    /// `self.omega`, judged by no yardstick.
    fn reference_pass(&mut self, k: &Kinematics, bonds: &Bonds) {
        let dims = if self.dim.three_d() { 3 } else { 2 };
        gradient_pass(
            dims,
            self.order,
            self.horizon,
            k.x0,
            k.vol,
            k.x0,
            bonds,
            None,
            &mut self.point,
            &mut self.omega,
            &mut self.phi,
        );
    }

    /// How many particles' gradients are of a lower degree than the model's order (their
    /// families damaged too far for it), and how many have none.
    pub fn reduced_gradients(&self) -> (usize, usize) {
        let order = self.order as u8;
        let lower = self.point.iter().filter(|p| p.degree != order).count();
        let none = self.point.iter().filter(|p| p.degree == 0).count();
        (lower - none, none)
    }

    /// The bond histories (for checkpoints and tests).
    pub fn bond_state(&self, b: usize) -> &L::State {
        &self.hist[b].state
    }
}

impl<D: DamageModel, L: BondLaw> PdModel for RkBa<D, L> {
    fn name(&self) -> &'static str {
        "pd-rk-ba"
    }

    fn force_density(&mut self, k: &Kinematics, bonds: &mut Bonds, dt: f64, f: &mut [[f64; 3]]) {
        let dims = if self.dim.three_d() { 3 } else { 2 };
        let (order, horizon) = (self.order, self.horizon);
        if self.reference_det.is_empty() {
            self.set_reference(k, bonds);
        }
        // 1. ω, Φ, ω̄ and the point velocity gradient L (A.1–A.8).
        for (w, h) in self.omega.iter_mut().zip(&self.hist) {
            *w = h.wd;
        }
        gradient_pass(
            dims,
            order,
            horizon,
            k.pos,
            k.vol,
            k.vel,
            bonds,
            Some(&self.reference_det),
            &mut self.point,
            &mut self.omega,
            &mut self.phi,
        );
        if !self.bond_associative {
            self.point_forces(k, bonds, dt, f);
            return;
        }
        // 2. Bond level: BA velocity gradient (A.11), Jaumann + J2 (App. B), damage (App. C),
        //    and z_i (A.14).
        let (offsets, nbr, inv_len) = (&bonds.offsets, &bonds.nbr, &bonds.inv_len);
        let no_fail = &bonds.no_fail;
        let (point, omega, mat, damage) = (&self.point, &self.omega, self.material, &self.damage);
        // rows whose damage changed an influence this step (see `release`)
        let damaged = AtomicU64::new(0);
        par_rows(offsets, &mut self.z, &mut self.hist, &|i, zi, hrow| {
            let r = offsets[i]..offsets[i + 1];
            let pi = &point[i];
            let (p, v) = (k.pos[i], k.vel[i]);
            let mut z = [[0.0; 3]; 3];
            let mut changed = false;
            for ((h, &j), (&om0, &il)) in hrow
                .iter_mut()
                .zip(&nbr[r.clone()])
                .zip(omega[r.clone()].iter().zip(&inv_len[r]))
            {
                // A particle whose moment matrix has become singular (too few intact bonds
                // left to form a gradient: every particle is active in the reference state,
                // set-up checks that) carries no force; its remaining bonds break for good,
                // both ways, so it is reported fully damaged, counts as detached, and cannot
                // pick up force again if its neighbours' geometry later allows a gradient.
                if om0 != 0.0 {
                    h.e_prev = mat.stored_energy(&h.state);
                }
                let j = j as usize;
                let pj = &point[j];
                let kept = spared(no_fail, i, j);
                if kept && om0 != 0.0 && !(pi.active && pj.active) {
                    // A bond a no-fail zone keeps, with an end that has no gradient: frozen
                    // (no force, state and influence unchanged, so no energy is booked as
                    // released) until both ends have one again. Both rows holding it see
                    // the same, so momentum stays exact.
                    h.om = om0;
                    continue;
                }
                if om0 == 0.0 || !pi.active {
                    if !pi.active {
                        h.wd = 0.0;
                    }
                    h.om = 0.0;
                    changed |= om0 != 0.0;
                    continue;
                }
                if !pj.active {
                    h.wd = 0.0;
                    h.om = 0.0;
                    changed = true;
                    continue;
                }
                let x: [f64; 3] = (vec3(&k.pos[j]) - vec3(&p)).into();
                let vv = vec3(&k.vel[j]) - vec3(&v);
                let x2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
                if dt > 0.0 {
                    // (A.11): L_b = L̄ + (v − L̄ x) xᵀ/|x|²
                    let lb: M3 = std::array::from_fn(|a| {
                        std::array::from_fn(|c| 0.5 * (pi.l[a][c] + pj.l[a][c]))
                    });
                    let res: [f64; 3] = std::array::from_fn(|a| {
                        vv[a] - (lb[a][0] * x[0] + lb[a][1] * x[1] + lb[a][2] * x[2])
                    });
                    let l: M3 = std::array::from_fn(|a| {
                        std::array::from_fn(|c| lb[a][c] + res[a] * x[c] / x2)
                    });
                    let (spin, de) = spin_and_strain_step(&l, dt);
                    // seed 000 eq. (B.2)–(B.4) at the bond level.
                    let wp = mat.bond_step(&mut h.state, &de, &spin, dt);
                    if wp != 0.0 {
                        // weighted with this step's α = ω/ω̄_i (ω before this step's damage)
                        h.plastic_work += k.vol[i] * om0 / pi.wbar * k.vol[j] * wp;
                    }
                }
                let input = BondInput {
                    stretch: x2.sqrt() * il - 1.0,
                    von_mises: von_mises(L::stress(&h.state)),
                    eq_plastic_strain: L::eq_plastic_strain(&h.state),
                    failure: L::failure(&h.state),
                };
                let wd = damage.update(h.wd, &input);
                // a no-fail zone keeps the bond (tested only when it is about to weaken)
                let wd = if wd < h.wd && kept { h.wd } else { wd };
                let om = if wd < h.wd { om0 * (wd / h.wd) } else { om0 };
                h.wd = wd;
                h.om = om;
                changed |= om != om0;
                if om == 0.0 {
                    continue;
                }
                // (A.14): (½/ω̄_i + ½/ω̄_j) ω σ (I − x xᵀ/|x|²) V_j
                let c = (0.5 / pi.wbar + 0.5 / pj.wbar) * om * k.vol[j];
                let s = mechanics::j2::to_matrix(L::stress(&h.state));
                let sx: [f64; 3] =
                    std::array::from_fn(|a| s[a][0] * x[0] + s[a][1] * x[1] + s[a][2] * x[2]);
                for a in 0..3 {
                    for b in 0..3 {
                        z[a][b] += c * (s[a][b] - sx[a] * x[b] / x2);
                    }
                }
            }
            *zi = z;
            if changed {
                damaged.fetch_add(1, Ordering::Relaxed);
            }
        });
        if damaged.into_inner() > 0 {
            self.release(k.vol, nbr);
        }
        // 3. Force density f_i = Σ_j (T_ij − T_ji) V_j with T of (A.13).
        let (point, z, phi, hist, rev) = (&self.point, &self.z, &self.phi, &self.hist, &self.rev);
        super::family::par_points(f, &|i, fi: &mut [f64; 3]| {
            let r = offsets[i]..offsets[i + 1];
            let (p, zi, wi) = (k.pos[i], &z[i], point[i].wbar);
            let mut acc = [0.0; 3];
            for b in r {
                let h = &hist[b];
                if h.om == 0.0 {
                    continue;
                }
                let j = nbr[b] as usize;
                let x: [f64; 3] = (vec3(&k.pos[j]) - vec3(&p)).into();
                let x2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2];
                let s = mechanics::j2::to_matrix(L::stress(&h.state));
                let c = h.om * (1.0 / wi + 1.0 / point[j].wbar) / x2;
                let (pij, pji) = (phi[b], phi[rev[b] as usize]);
                let zj = &z[j];
                let vj = k.vol[j];
                for a in 0..3 {
                    let t1 = c * (s[a][0] * x[0] + s[a][1] * x[1] + s[a][2] * x[2]);
                    let t2 = zi[a][0] * pij[0] + zi[a][1] * pij[1] + zi[a][2] * pij[2];
                    let t3 = zj[a][0] * pji[0] + zj[a][1] * pji[1] + zj[a][2] * pji[2];
                    // t1 + (t2 − t3) is negated exactly by row j's copy of the pair.
                    acc[a] += (t1 + (t2 - t3)) * vj;
                }
            }
            *fi = acc;
        });
    }

    fn stable_dt(&self, k: &Kinematics, bonds: &Bonds, density: f64) -> f64 {
        // seed 001 §4.2: Δt ≤ l/c, l the smallest bond, c the dilatational wave speed.
        let _ = k;
        let c = (self.material.wave_modulus() / density).sqrt();
        let lmin = bonds
            .inv_len
            .iter()
            .map(|il| 1.0 / il)
            .fold(f64::INFINITY, f64::min);
        lmin / c
    }

    fn sync_bonds(&self, bonds: &mut Bonds) {
        for (w, h) in bonds.intact.iter_mut().zip(&self.hist) {
            *w = h.wd;
        }
    }

    /// The kernel is evaluated on the current positions (A.3): a bond stretched to the
    /// horizon carries no force however little it is damaged, and ties nothing together
    /// (two pieces flying apart are two fragments).
    fn fragment_links(&self, pos: &[[f64; 3]], bonds: &mut Bonds) {
        let h2 = self.horizon * self.horizon;
        let (offsets, nbr) = (&bonds.offsets, &bonds.nbr);
        for (i, p) in pos.iter().enumerate() {
            for b in offsets[i]..offsets[i + 1] {
                let q = pos[nbr[b] as usize];
                let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
                let far = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] >= h2;
                bonds.intact[b] = if far { 0.0 } else { self.hist[b].wd };
            }
        }
    }

    /// Σ_i V_i Σ_j α_ij V_j w_e(σ_b): the bond-level elastic strain energy density
    /// ½ σ_b : C⁻¹ : σ_b averaged over each family with the normalised weight α = ω/ω̄_i
    /// of seed 000 eq. (15)–(18) (Σ_j α V_j = 1), the internal energy whose rate is the
    /// bond-associated stress power α σ_b : L_b of eq. (19), less the plastic work.
    /// ω̄_i = Σ_j ω V_j is formed from the influences after the last damage update (equal to
    /// the gradient pass's ω̄ where nothing broke), so the energy of a family that lost a
    /// bond is its renormalised average at once (see [`RkBa::release`]).
    fn strain_energy(&mut self, k: &Kinematics, bonds: &Bonds) -> f64 {
        let (mat, hist) = (self.material, &self.hist);
        if !self.bond_associative {
            // Σ_i V_i w_e(σ_i) without BA
            return (self.point_state.iter().zip(k.vol))
                .map(|((st, _), v)| v * mat.stored_energy(st))
                .sum();
        }
        let mut e = 0.0;
        for i in 0..bonds.particles() {
            let r = bonds.offsets[i]..bonds.offsets[i + 1];
            let hrow = &hist[r.clone()];
            e += row_energy(&mat, k.vol, i, &bonds.nbr[r], hrow, |b| hrow[b].om);
        }
        e
    }

    fn fracture_energy(&self) -> f64 {
        self.released.iter().sum()
    }

    /// `reduced_gradient_particles`: particles whose damaged families carry only a linear
    /// gradient (order 2 models); `gradient_free_particles`: those that carry none (their
    /// bonds broken for good).
    fn damage_scalars(&self) -> Vec<(&'static str, f64)> {
        let (reduced, none) = self.reduced_gradients();
        vec![
            ("reduced_gradient_particles", reduced as f64),
            ("gradient_free_particles", none as f64),
        ]
    }

    fn plastic_work(&self, vol: &[f64]) -> f64 {
        let _ = vol;
        if !self.bond_associative {
            return self.point_state.iter().map(|(_, w)| w).sum();
        }
        self.hist.iter().map(|h| h.plastic_work).sum()
    }

    fn stress(&self) -> Option<Vec<Sym>> {
        if !self.bond_associative {
            return Some(
                self.point_state
                    .iter()
                    .map(|(st, _)| *L::stress(st))
                    .collect(),
            );
        }
        Some(self.point_average(|h| *L::stress(&h.state)))
    }

    fn plastic_strain(&self) -> Option<Vec<f64>> {
        if !self.bond_associative {
            let eqp = self
                .point_state
                .iter()
                .map(|(st, _)| L::eq_plastic_strain(st));
            return Some(eqp.collect());
        }
        Some(self.point_scalar(L::eq_plastic_strain))
    }

    /// Per bond the mean of its two particles' factors (both copies alike), or per particle
    /// without BA.
    fn set_failure_factors(&mut self, factor: &[f64]) {
        for (st, &f) in self.point_state.iter_mut().zip(factor) {
            L::set_failure_factor(&mut st.0, f);
        }
        for i in 0..self.point.len() {
            for b in self.offsets[i]..self.offsets[i + 1] {
                // the neighbour: the row that holds the bond's twin
                let twin = self.rev[b] as usize;
                let j = self.offsets.partition_point(|&o| o <= twin) - 1;
                L::set_failure_factor(&mut self.hist[b].state, 0.5 * (factor[i] + factor[j]));
            }
        }
    }

    /// The law's own scalars (temperature, failure indicator): at the particles without BA,
    /// the ω-weighted means of their bonds' with it.
    fn point_scalars(&self) -> Vec<(&'static str, Vec<f64>)> {
        let names = self.material.scalar_names();
        let value = |k: usize| -> Vec<f64> {
            if self.bond_associative {
                self.point_scalar(|st| L::scalar(st, k))
            } else {
                self.point_state
                    .iter()
                    .map(|(st, _)| L::scalar(st, k))
                    .collect()
            }
        };
        names
            .iter()
            .enumerate()
            .map(|(k, &n)| (n, value(k)))
            .collect()
    }

    /// Per bond its J2 state, damage and plastic work (ω is recomputed at each evaluation),
    /// then the released energy per particle; without BA, each particle's J2 state and
    /// plastic work instead.
    fn save_state(&self) -> SolverResult<Vec<u8>> {
        if !self.bond_associative {
            return encode_state(&self.point_state);
        }
        let hist: Vec<SavedBond<L::State>> = self
            .hist
            .iter()
            .map(|h| (h.state, h.wd, h.plastic_work))
            .collect();
        encode_state(&(hist, &self.released))
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        if !self.bond_associative {
            let state: Vec<(L::State, f64)> = decode_state(bytes)?;
            check_len("particle states", state.len(), self.point_state.len())?;
            self.point_state = state;
            return Ok(());
        }
        let (hist, released): (Vec<SavedBond<L::State>>, Vec<f64>) = decode_state(bytes)?;
        check_len("bond histories", hist.len(), self.hist.len())?;
        check_len("released bond energy", released.len(), self.released.len())?;
        for (h, (state, wd, plastic_work)) in self.hist.iter_mut().zip(hist) {
            h.state = state;
            h.wd = wd;
            h.plastic_work = plastic_work;
        }
        self.released = released;
        Ok(())
    }

    fn stiffness_bound(&self, k: &Kinematics, bonds: &Bonds, i: usize) -> f64 {
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

impl<D: DamageModel, L: BondLaw> RkBa<D, L> {
    /// A scalar of the bonds' states per particle, the ω-weighted mean over its bonds (output
    /// only).
    fn point_scalar(&self, f: impl Fn(&L::State) -> f64) -> Vec<f64> {
        self.point_average(|h| [f(&h.state), 0.0, 0.0, 0.0, 0.0, 0.0])
            .iter()
            .map(|s| s[0])
            .collect()
    }

    /// Point value as the ω-weighted mean of its bonds' values (output only).
    fn point_average(&self, f: impl Fn(&BondHistory<L::State>) -> Sym) -> Vec<Sym> {
        let n = self.point.len();
        let mut out = vec![[0.0; 6]; n];
        for i in 0..n {
            let (start, end) = (self.offsets[i], self.offsets[i + 1]);
            let (mut acc, mut w) = ([0.0; 6], 0.0);
            for b in start..end {
                let h = &self.hist[b];
                let v = f(h);
                for c in 0..6 {
                    acc[c] += h.om * v[c];
                }
                w += h.om;
            }
            if w > 0.0 {
                out[i] = acc.map(|a| a / w);
            }
        }
        out
    }
}
