//! pd-bond: the prototype microelastic brittle bond-based model (Silling 2000; the README's case sections):
//! pairwise force density c·s·ŷ with micromodulus c = 18K/(πδ⁴) (3-D), 9E/(πhδ³) (2-D plane
//! stress), 48E/(5πhδ³) (2-D plane strain), and bonds that break for good above the
//! critical stretch s0. Surface correction by the energy method (Madenci & Oterkus 2014
//! §4.2): per-particle factors from a uniaxial stretch along each axis, so the discrete
//! stiffness equals the continuum one everywhere (also near free surfaces).
//! Bonds carry the influence ω(r) = 1 − r/δ: on a cubic lattice with δ ≈ 3Δx it makes the
//! discrete moments Σ ω r n_x²n_y² / Σ ω r n_x⁴ = 0.320 (continuum 1/3; 0.384 with ω = 1),
//! so the lattice is nearly isotropic and recovers E and ν; the correction factors absorb ω.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use super::family::{Bonds, par_points, par_row_blocks, par_rows, spared};
use super::model::{Dim, Kinematics, PdModel};
use mechanics::simd::Simd;
use mechanics::tensor::vec3;
use protocol::checkpoint::{check_len, decode_state, encode_state};
use protocol::solver::SolverResult;
use std::f64::consts::PI;
use std::sync::atomic::{AtomicU64, Ordering};

#[cfg(target_arch = "x86_64")]
mod avx512;

/// The bond-based model. `coef[b] = c · G_b · V_j` (zero once the bond is broken).
#[derive(Debug, Clone)]
pub struct BondModel {
    pub coef: Vec<f64>,
    /// (1 + s0)² for the critical stretch s0 (+∞ without damage): a bond breaks when
    /// |y|²/|ξ|² > (1 + s0)², i.e. s > s0.
    critical: f64,
    /// Micromodulus c of the continuum model.
    pub micromodulus: f64,
    /// Instruction set of the force kernel (the widest the CPU has; every choice gives the
    /// same bits).
    pub simd: Simd,
    /// Surface correction factors g_i (per axis), kept to rebuild a broken bond's c·G_b.
    factors: Vec<[f64; 3]>,
    horizon: f64,
    dims: usize,
    /// Energy released by the bonds of each particle's row that broke (J; each bond's two
    /// rows carry half of it each).
    released: Vec<f64>,
    /// Per-particle scratch of the strain-energy sum (J).
    energy: Vec<f64>,
    /// X and u per particle in one cache line, packed each step for the AVX-512 kernel.
    #[cfg(target_arch = "x86_64")]
    records: Vec<crate::pd::avx512::Record>,
}

/// Micromodulus c for the dimension (the README's case sections "Solid node").
pub fn micromodulus(dim: Dim, young: f64, horizon: f64, thickness: f64) -> f64 {
    match dim {
        // ν = 1/4: K = E / (3(1 − 2ν)) = 2E/3; c = 18K/(πδ⁴)
        Dim::Three => 18.0 * (2.0 * young / 3.0) / (PI * horizon.powi(4)),
        Dim::PlaneStress => 9.0 * young / (PI * thickness * horizon.powi(3)),
        Dim::PlaneStrain => 48.0 * young / (5.0 * PI * thickness * horizon.powi(3)),
    }
}

/// The Poisson ratio the bond-based model implies.
pub fn implied_poisson(dim: Dim) -> f64 {
    match dim {
        Dim::PlaneStress => 1.0 / 3.0,
        _ => 0.25,
    }
}

impl BondModel {
    /// Builds the model; `critical_stretch = None` for no damage.
    pub fn new(
        dim: Dim,
        young: f64,
        horizon: f64,
        thickness: f64,
        critical_stretch: Option<f64>,
        k: &Kinematics,
        bonds: &Bonds,
    ) -> Self {
        let c = micromodulus(dim, young, horizon, thickness);
        let g = surface_factors(dim, horizon, thickness, k, bonds);
        let dims = if dim.three_d() { 3 } else { 2 };
        let n = bonds.particles();
        let mut coef = vec![0.0; bonds.len()];
        for i in 0..n {
            for b in bonds.offsets[i]..bonds.offsets[i + 1] {
                let ij = (i, bonds.nbr[b] as usize);
                let cb = bond_coef(
                    c,
                    horizon,
                    dims,
                    &g,
                    ij,
                    &bonds.xi[b],
                    bonds.inv_len[b],
                    k.vol,
                );
                coef[b] = cb * bonds.intact[b];
            }
        }
        BondModel {
            coef,
            critical: critical_stretch.map_or(f64::INFINITY, |s0| (1.0 + s0) * (1.0 + s0)),
            micromodulus: c,
            simd: Simd::detect(),
            factors: g,
            horizon,
            dims,
            released: vec![0.0; n],
            energy: vec![0.0; n],
            #[cfg(target_arch = "x86_64")]
            records: Vec::new(),
        }
    }

    /// Virial (Lehoucq–Silling) stress ½ Σ_j f_ij ⊗ ξ_ij V_j at particle `i`; equals the
    /// Cauchy stress for a homogeneous deformation away from the surface.
    pub fn virial_stress(&self, i: usize, k: &Kinematics, bonds: &Bonds) -> [[f64; 3]; 3] {
        let mut s = [[0.0; 3]; 3];
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            let x = bonds.xi[b];
            let e: [f64; 3] = std::array::from_fn(|d| k.disp[j][d] - k.disp[i][d]);
            let y: [f64; 3] = std::array::from_fn(|d| x[d] + e[d]);
            let f = self.coef[b] * stretch_over_len(&x, &e, bonds.inv_len[b]).1;
            for a in 0..3 {
                for c in 0..3 {
                    s[a][c] += 0.5 * f * y[a] * bonds.xi[b][c];
                }
            }
        }
        s
    }
}

/// c·G_b·V_j of bond `b` of row `i` while intact: the micromodulus times the influence ω and
/// the surface correction of the bond's direction (the mean of its ends' factors).
fn bond_coef(
    c: f64,
    horizon: f64,
    dims: usize,
    g: &[[f64; 3]],
    (i, j): (usize, usize),
    xi: &[f64; 3],
    il: f64,
    vol: &[f64],
) -> f64 {
    let mut q = 0.0;
    for d in 0..dims {
        let nd = xi[d] * il;
        let gd = 0.5 * (g[i][d] + g[j][d]);
        q += (nd / gd).powi(2);
    }
    c * influence(1.0 / il, horizon) * vol[j] / q.sqrt()
}

/// The share of row `i`'s copy of a bond in the bond's micro-potential (J): the pair of
/// particles (i, j) stores w = ½ c_b s² |ξ| V_i V_j (Silling 2000: the micro-potential whose
/// derivative in |y| is the pair force c_b s V_i V_j), with `coef` = c_b V_j; each of the two
/// rows holding the bond carries half, ¼ coef s² |ξ| V_i.
#[inline]
pub fn bond_energy_share(coef: f64, s: f64, inv_len: f64, vol_i: f64) -> f64 {
    0.25 * coef * s * s / inv_len * vol_i
}

/// Bond influence ω(r) = 1 − r/δ.
#[inline]
pub fn influence(r: f64, horizon: f64) -> f64 {
    (1.0 - r / horizon).max(0.0)
}

/// Energy-method surface correction factors g_i^d = m∞ / m_i^d with
/// m_i^d = Σ_j ω V_j |ξ| n_d⁴ (uniaxial stretch along axis d) and m∞ the continuum integral
/// of the ω = 1 model the micromodulus belongs to: πδ⁴/5 in 3-D, πhδ³/4 in 2-D.
fn surface_factors(
    dim: Dim,
    horizon: f64,
    thickness: f64,
    k: &Kinematics,
    bonds: &Bonds,
) -> Vec<[f64; 3]> {
    let m_inf = if dim.three_d() {
        PI * horizon.powi(4) / 5.0
    } else {
        PI * thickness * horizon.powi(3) / 4.0
    };
    let moments = |i: usize| {
        let (mut m, mut m22) = ([0.0; 3], 0.0);
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            let il = bonds.inv_len[b];
            let w = influence(1.0 / il, horizon) * k.vol[j] / il;
            let n: [f64; 3] = std::array::from_fn(|d| bonds.xi[b][d] * il);
            for (d, md) in m.iter_mut().enumerate() {
                *md += w * n[d].powi(4);
            }
            m22 += w * n[0] * n[0] * n[1] * n[1];
        }
        (m, m22)
    };
    // Lattice ratio ρ = m22/m4 of a full family (continuum 1/3). The uniaxial-stretch
    // factors make C11 exact; this factor moves the calibration to uniaxial *stress*, so the
    // bulk Young's modulus is exact and ν takes the lattice value ρ/(1+ρ) (3-D), ρ (2-D).
    let full = (0..bonds.particles())
        .max_by_key(|&i| (bonds.offsets[i + 1] - bonds.offsets[i], usize::MAX - i))
        .unwrap_or(0);
    let (mf, m22f) = moments(full);
    let rho = if mf[0] > 0.0 { m22f / mf[0] } else { 1.0 / 3.0 };
    let e_factor = if dim.three_d() {
        (5.0 / 6.0) * (1.0 + rho) / ((1.0 - rho) * (1.0 + 2.0 * rho))
    } else {
        (8.0 / 9.0) / (1.0 - rho * rho)
    };
    (0..bonds.particles())
        .map(|i| {
            let (m, _) = moments(i);
            std::array::from_fn(|d| {
                if m[d] > 0.0 {
                    e_factor * m_inf / m[d]
                } else {
                    1.0
                }
            })
        })
        .collect()
}

/// Bond stretch without cancellation from the reference bond ξ and the relative displacement
/// η = u_j − u_i (y = ξ + η): s = (|y| − |ξ|)/|ξ| = η·(2ξ + η) / (|ξ| (|y| + |ξ|)).
/// Returns (s, s/|y|); `il` = 1/|ξ|. `s/|y|` = 1/|ξ| − 1/|y| is the factor of y in the force.
#[inline]
pub fn stretch_over_len(xi: &[f64; 3], eta: &[f64; 3], il: f64) -> (f64, f64) {
    let num = eta[0] * (2.0 * xi[0] + eta[0])
        + eta[1] * (2.0 * xi[1] + eta[1])
        + eta[2] * (2.0 * xi[2] + eta[2]);
    let (yx, yy, yz) = (xi[0] + eta[0], xi[1] + eta[1], xi[2] + eta[2]);
    let ly = (yx * yx + yy * yy + yz * yz).sqrt();
    // |ξ|(|y| + |ξ|) = (1 + |y|/|ξ|)/il²
    let t = num * il * il;
    let d = 1.0 + ly * il;
    (t / d, t / (d * ly))
}

/// Lanes of the row sum.
pub(crate) const LANES: usize = 8;

/// The summation order of a row's bond terms t₀ … t₍ₙ₋₁₎, shared by every path (scalar,
/// chunked, explicit AVX-512, WGSL): eight lane sums S_l = ((0 + t_l) + t₍l+8₎) + …, then
/// this tree, f = ((S₀ + S₄) + (S₂ + S₆)) + ((S₁ + S₅) + (S₃ + S₇)). Eight independent sums
/// keep the additions off one serial chain (a plain row-order sum waits an add latency per
/// bond, and measured 1.2× slower in the AVX-512 kernel); a skipped bond adds nothing, which
/// is the same as adding −0.0.
#[inline(always)]
pub(crate) fn lane_tree(s: &[f64; LANES]) -> f64 {
    ((s[0] + s[4]) + (s[2] + s[6])) + ((s[1] + s[5]) + (s[3] + s[7]))
}

/// The row sum of [`lane_tree`] over a row's terms.
#[cfg(test)]
pub(crate) fn lane_sum(terms: &[f64]) -> f64 {
    let mut s = [0.0; LANES];
    for (k, t) in terms.iter().enumerate() {
        s[k % LANES] += t;
    }
    lane_tree(&s)
}

/// Bonds per chunk of the row kernel (a multiple of [`LANES`]): the chunk's scratch (10 arrays
/// of this many doubles, 5 kB) stays in L1 next to the row.
const CHUNK: usize = 64;
const _: () = assert!(CHUNK.is_multiple_of(LANES));

/// The bond force loop: for particle `i`, f_i = Σ_j c_ij s/|y| y (= c s ŷ V_j; Silling 2000,
/// the README's case sections), breaking bonds with s > s0 first. The stretch is formed from the displacements
/// (see [`stretch_over_len`]): one sqrt and one division per bond. ξ = X_j − X_i is formed
/// from the reference positions (bit for bit `Bonds::xi`, which is built the same way): the
/// neighbour's X is in cache next to its u, where streaming `Bonds::xi` doubled the memory
/// traffic per bond (measured 90 vs 190 M bond-updates/s).
///
/// Three passes per chunk of `C` bonds, so the arithmetic vectorises (the sqrt and the
/// division dominate, and run 2, 4 or 8 wide on the SSE2, AVX2 and AVX-512 paths):
/// 1. gather the neighbours' X and u into structure-of-arrays scratch (scalar loads);
/// 2. per bond, independent of every other bond: η, y, |y|², the break test, the force
///    factor and its product with y (vectorised; a skipped bond contributes −0.0, the exact
///    identity of addition);
/// 3. the eight-lane sum of [`lane_tree`] (a chunk starts at a multiple of 8 in the row).
///
/// Every operation and the summation order are those of the one-pass loop (and of the WGSL
/// kernel), so the result is bit-identical on every instruction set and with the GPU.
#[inline(always)]
fn row_force_body<const C: usize>(
    sc: &mut Scratch<C>,
    i: usize,
    x0: &[[f64; 3]],
    disp: &[[f64; 3]],
    nbr: &[u32],
    inv_len: &[f64],
    coef: &mut [f64],
    critical: f64,
    no_fail: &[bool],
) -> ([f64; 3], u32) {
    // `critical` = (1 + s0)²
    let (ui, xi) = (disp[i], x0[i]);
    let mut lanes = [[0.0; LANES]; 3];
    let mut row_breaks = 0u32;
    let len = nbr.len().min(inv_len.len()).min(coef.len());
    let mut start = 0;
    while start < len {
        let n = C.min(len - start);
        let (nb, il, cf) = (
            &nbr[start..start + n],
            &inv_len[start..start + n],
            &mut coef[start..start + n],
        );
        // 1. gather
        for k in 0..n {
            let j = nb[k] as usize;
            let (xj, uj) = (x0[j], disp[j]);
            for d in 0..3 {
                sc.gx[d][k] = xj[d];
                sc.gu[d][k] = uj[d];
            }
        }
        // 2. per-bond terms (vectorised); the coefficients are only read here, so their
        //    cache lines stay clean unless a bond breaks
        let mut breaks = 0u32;
        {
            let (gxx, gxy, gxz) = (&sc.gx[0][..n], &sc.gx[1][..n], &sc.gx[2][..n]);
            let (gux, guy, guz) = (&sc.gu[0][..n], &sc.gu[1][..n], &sc.gu[2][..n]);
            let [tx, ty, tz] = &mut sc.term;
            let (tx, ty, tz) = (&mut tx[..n], &mut ty[..n], &mut tz[..n]);
            let qs = &mut sc.q[..n];
            for k in 0..n {
                let cb = cf[k];
                let il = il[k];
                let x = [gxx[k] - xi[0], gxy[k] - xi[1], gxz[k] - xi[2]];
                let (ex, ey, ez) = (gux[k] - ui[0], guy[k] - ui[1], guz[k] - ui[2]);
                let num = ex * (2.0 * x[0] + ex) + ey * (2.0 * x[1] + ey) + ez * (2.0 * x[2] + ez);
                let (yx, yy, yz) = (x[0] + ex, x[1] + ey, x[2] + ez);
                let q = yx * yx + yy * yy + yz * yz;
                // s > s0 ⇔ |y|²/|ξ|² > (1 + s0)² (no cancellation at a finite s0)
                let broken = q * il * il > critical;
                let ly = q.sqrt();
                let t = num * il * il;
                // s/|y| = t/(d |y|) = t/(|y|² il + |y|): only an add between the sqrt and
                // the division
                let m = cb * t / (q * il + ly);
                let live = cb != 0.0 && !broken;
                breaks += u32::from(broken && cb != 0.0);
                qs[k] = q;
                tx[k] = if live { m * yx } else { -0.0 };
                ty[k] = if live { m * yy } else { -0.0 };
                tz[k] = if live { m * yz } else { -0.0 };
            }
        }
        if breaks > 0 {
            for k in 0..n {
                if sc.q[k] * il[k] * il[k] > critical && cf[k] != 0.0 {
                    if spared(no_fail, i, nb[k] as usize) {
                        // a no-fail zone keeps it: its term as a live bond's
                        let x: [f64; 3] = std::array::from_fn(|d| sc.gx[d][k] - xi[d]);
                        let e: [f64; 3] = std::array::from_fn(|d| sc.gu[d][k] - ui[d]);
                        let t = live_term(&x, &e, cf[k], il[k]);
                        for d in 0..3 {
                            sc.term[d][k] = t[d];
                        }
                        breaks -= 1;
                    } else {
                        cf[k] = 0.0;
                    }
                }
            }
            row_breaks += breaks;
        }
        // 3. the lane sums (C is a multiple of LANES, so bond k of the chunk is lane k % 8)
        let full = n / LANES * LANES;
        for d in 0..3 {
            let (t, l) = (&sc.term[d][..n], &mut lanes[d]);
            for g in t[..full].chunks_exact(LANES) {
                for (a, b) in l.iter_mut().zip(g) {
                    *a += *b;
                }
            }
            for (a, b) in l.iter_mut().zip(&t[full..]) {
                *a += *b;
            }
        }
        start += n;
    }
    (
        [
            lane_tree(&lanes[0]),
            lane_tree(&lanes[1]),
            lane_tree(&lanes[2]),
        ],
        row_breaks,
    )
}

/// The force term c_b (s/|y|) y of a live bond with reference vector `x` and relative
/// displacement `e`, by the chunked loop's operations in its order (so bit for bit what
/// that loop sums for the bond).
#[inline]
fn live_term(x: &[f64; 3], e: &[f64; 3], cb: f64, il: f64) -> [f64; 3] {
    let (ex, ey, ez) = (e[0], e[1], e[2]);
    let num = ex * (2.0 * x[0] + ex) + ey * (2.0 * x[1] + ey) + ez * (2.0 * x[2] + ez);
    let (yx, yy, yz) = (x[0] + ex, x[1] + ey, x[2] + ez);
    let q = yx * yx + yy * yy + yz * yz;
    let ly = q.sqrt();
    let t = num * il * il;
    let m = cb * t / (q * il + ly);
    [m * yx, m * yy, m * yz]
}

/// Structure-of-arrays scratch of one chunk: gathered X_j and u_j, the bond terms, |y|².
struct Scratch<const C: usize> {
    gx: [[f64; C]; 3],
    gu: [[f64; C]; 3],
    term: [[f64; C]; 3],
    q: [f64; C],
}

/// The force densities of the block of particles `lo..lo + f.len()` (the bond slices of
/// those rows in `coef`), with one scratch for the block; returns how many bonds broke.
#[inline(always)]
fn block_force_body<const C: usize>(
    lo: usize,
    f: &mut [[f64; 3]],
    coef: &mut [f64],
    offsets: &[usize],
    x0: &[[f64; 3]],
    disp: &[[f64; 3]],
    nbr: &[u32],
    inv_len: &[f64],
    critical: f64,
    no_fail: &[bool],
) -> u32 {
    let mut sc = Scratch::<C> {
        gx: [[0.0; C]; 3],
        gu: [[0.0; C]; 3],
        term: [[0.0; C]; 3],
        q: [0.0; C],
    };
    let base = offsets[lo];
    let mut breaks = 0;
    for (k, fi) in f.iter_mut().enumerate() {
        let i = lo + k;
        let r = offsets[i]..offsets[i + 1];
        let row = &mut coef[r.start - base..r.end - base];
        let (fr, nb) = row_force_body::<C>(
            &mut sc,
            i,
            x0,
            disp,
            &nbr[r.clone()],
            &inv_len[r],
            row,
            critical,
            no_fail,
        );
        *fi = fr;
        breaks += nb;
    }
    breaks
}

mechanics::simd::multiversion! {
    fn block_force<const C: usize>(
        lo: usize,
        f: &mut [[f64; 3]],
        coef: &mut [f64],
        offsets: &[usize],
        x0: &[[f64; 3]],
        disp: &[[f64; 3]],
        nbr: &[u32],
        inv_len: &[f64],
        critical: f64,
        no_fail: &[bool],
    ) -> u32 = block_force_body;
}

/// The one-pass scalar loop the chunked kernel replaced, kept as the reference it is tested
/// against bit for bit.
#[cfg(test)]
fn row_force_scalar(
    i: usize,
    x0: &[[f64; 3]],
    disp: &[[f64; 3]],
    nbr: &[u32],
    inv_len: &[f64],
    coef: &mut [f64],
    critical: f64,
) -> [f64; 3] {
    let (ui, xi) = (disp[i], x0[i]);
    // the bond terms in row order, −0.0 for a skipped bond
    let mut terms = [vec![], vec![], vec![]];
    for ((&j, &il), c) in nbr.iter().zip(inv_len).zip(coef.iter_mut()) {
        let cb = *c;
        if cb == 0.0 {
            terms.iter_mut().for_each(|t| t.push(-0.0));
            continue;
        }
        let xj = x0[j as usize];
        let x = [xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]];
        let uj = disp[j as usize];
        let (ex, ey, ez) = (uj[0] - ui[0], uj[1] - ui[1], uj[2] - ui[2]);
        let num = ex * (2.0 * x[0] + ex) + ey * (2.0 * x[1] + ey) + ez * (2.0 * x[2] + ez);
        let (yx, yy, yz) = (x[0] + ex, x[1] + ey, x[2] + ez);
        let q = yx * yx + yy * yy + yz * yz;
        if q * il * il > critical {
            *c = 0.0;
            terms.iter_mut().for_each(|t| t.push(-0.0));
            continue;
        }
        let ly = q.sqrt();
        let t = num * il * il;
        let m = cb * t / (q * il + ly);
        terms[0].push(m * yx);
        terms[1].push(m * yy);
        terms[2].push(m * yz);
    }
    [
        lane_sum(&terms[0]),
        lane_sum(&terms[1]),
        lane_sum(&terms[2]),
    ]
}

impl BondModel {
    /// Books the bonds that broke in the last force evaluation (coefficient now 0, still
    /// intact in `bonds.intact`): each releases its micro-potential at the stretch it broke
    /// at (the displacements the evaluation read, unchanged since), and is marked broken.
    /// Runs only on an evaluation that broke a bond.
    fn release(&mut self, k: &Kinematics, bonds: &mut Bonds) {
        let (c, h, dims, g) = (self.micromodulus, self.horizon, self.dims, &self.factors);
        let coef = &self.coef;
        let (disp, vol) = (k.disp, k.vol);
        let (offsets, nbr, inv_len) = (&bonds.offsets, &bonds.nbr, &bonds.inv_len);
        let xi_all = &bonds.xi;
        par_rows(
            offsets,
            &mut self.released,
            &mut bonds.intact,
            &|i, rel: &mut f64, intact: &mut [f64]| {
                let r0 = offsets[i];
                for (m, w) in intact.iter_mut().enumerate() {
                    let b = r0 + m;
                    // (a weightless bond, a horizon long, never had force to lose: see
                    // `sync_bonds`)
                    if !(coef[b] == 0.0 && *w != 0.0) || influence(1.0 / inv_len[b], h) == 0.0 {
                        continue;
                    }
                    let j = nbr[b] as usize;
                    let eta = (vec3(&disp[j]) - vec3(&disp[i])).into();
                    let s = stretch_over_len(&xi_all[b], &eta, inv_len[b]).0;
                    let cb = bond_coef(c, h, dims, g, (i, j), &xi_all[b], inv_len[b], vol);
                    *rel += bond_energy_share(cb, s, inv_len[b], vol[i]);
                    *w = 0.0;
                }
            },
        );
    }
}

impl PdModel for BondModel {
    fn name(&self) -> &'static str {
        "pd-bond"
    }

    fn force_density(&mut self, k: &Kinematics, bonds: &mut Bonds, _dt: f64, f: &mut [[f64; 3]]) {
        let (x0, disp) = (k.x0, k.disp);
        let offsets = &bonds.offsets;
        let nbr = &bonds.nbr;
        let inv_len = &bonds.inv_len;
        let no_fail = &bonds.no_fail;
        let (s0, simd) = (self.critical, self.simd);
        // bonds broken in this evaluation (counted per block, so no contention)
        let breaks = AtomicU64::new(0);
        let count = |n: u32| {
            if n > 0 {
                breaks.fetch_add(u64::from(n), Ordering::Relaxed);
            }
        };
        #[cfg(target_arch = "x86_64")]
        let done = if simd == Simd::Avx512 && mechanics::simd::has_avx512() {
            avx512::pack(x0, disp, &mut self.records);
            let rec = &self.records;
            par_row_blocks(offsets, f, &mut self.coef, &|lo, fb, cb| {
                // SAFETY: the CPU has AVX-512 F/DQ/VL and AVX2 (checked above), all that
                // calling the target-feature kernel requires.
                count(unsafe {
                    avx512::block_force(lo, fb, cb, offsets, rec, nbr, inv_len, s0, no_fail)
                });
            });
            true
        } else {
            false
        };
        #[cfg(not(target_arch = "x86_64"))]
        let done = false;
        if !done {
            par_row_blocks(offsets, f, &mut self.coef, &|lo, fb, cb| {
                count(block_force::<CHUNK>(
                    simd, lo, fb, cb, offsets, x0, disp, nbr, inv_len, s0, no_fail,
                ));
            });
        }
        if breaks.into_inner() > 0 {
            self.release(k, bonds);
        }
    }

    fn strain_energy(&mut self, k: &Kinematics, bonds: &Bonds) -> f64 {
        let coef = &self.coef;
        let (x0, disp, vol) = (k.x0, k.disp, k.vol);
        par_points(&mut self.energy, &|i, e: &mut f64| {
            let mut sum = 0.0;
            for b in bonds.offsets[i]..bonds.offsets[i + 1] {
                if coef[b] == 0.0 {
                    continue;
                }
                let j = bonds.nbr[b] as usize;
                let xi = (vec3(&x0[j]) - vec3(&x0[i])).into();
                let eta = (vec3(&disp[j]) - vec3(&disp[i])).into();
                let s = stretch_over_len(&xi, &eta, bonds.inv_len[b]).0;
                sum += bond_energy_share(coef[b], s, bonds.inv_len[b], vol[i]);
            }
            *e = sum;
        });
        self.energy.iter().sum()
    }

    fn fracture_energy(&self) -> f64 {
        self.released.iter().sum()
    }

    fn stable_dt(&self, k: &Kinematics, bonds: &Bonds, density: f64) -> f64 {
        // Silling & Askari 2005: Δt < √(2ρ / Σ_j V_j c / |ξ|)
        let _ = k;
        let mut dt = f64::INFINITY;
        for i in 0..bonds.particles() {
            let s: f64 = (bonds.offsets[i]..bonds.offsets[i + 1])
                .map(|b| self.coef[b] * bonds.inv_len[b])
                .sum();
            if s > 0.0 {
                dt = dt.min((2.0 * density / s).sqrt());
            }
        }
        dt
    }

    /// A bond whose coefficient is 0 is broken, unless it never had weight: a bond exactly a
    /// horizon long has influence ω = 1 − |ξ|/δ = 0, carries no force from the start, and is
    /// not damage (it stays intact, so an undamaged body reads damage 0 whatever δ/Δx).
    fn sync_bonds(&self, bonds: &mut Bonds) {
        let h = self.horizon;
        for ((w, &c), &il) in bonds.intact.iter_mut().zip(&self.coef).zip(&bonds.inv_len) {
            if c == 0.0 {
                *w = if influence(1.0 / il, h) > 0.0 {
                    0.0
                } else {
                    1.0
                };
            }
        }
    }

    /// The bonds that carry force tie their particles: a weightless one (see `sync_bonds`)
    /// ties nothing.
    fn fragment_links(&self, _pos: &[[f64; 3]], bonds: &mut Bonds) {
        for (w, &c) in bonds.intact.iter_mut().zip(&self.coef) {
            if c == 0.0 {
                *w = 0.0;
            }
        }
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        encode_state(&(&self.coef, &self.released))
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        let (coef, released): (Vec<f64>, Vec<f64>) = decode_state(bytes)?;
        check_len("bond coefficients", coef.len(), self.coef.len())?;
        check_len("released bond energy", released.len(), self.released.len())?;
        self.coef = coef;
        self.released = released;
        Ok(())
    }

    fn set_simd(&mut self, simd: Simd) {
        self.simd = simd;
    }

    fn stiffness_bound(&self, k: &Kinematics, bonds: &Bonds, i: usize) -> f64 {
        // Σ_j c V_j / |ξ| is the force density per unit displacement; times V_i.
        let s: f64 = (bonds.offsets[i]..bonds.offsets[i + 1])
            .map(|b| self.coef[b] * bonds.inv_len[b])
            .sum();
        s * k.vol[i]
    }
}

/// Forces and bond states equal the reference's bit for bit (the kernels' tests).
#[cfg(test)]
pub(crate) fn assert_same_bits(
    path: &str,
    fs: &[[f64; 3]],
    bond_state: &[f64],
    fref: &[[f64; 3]],
    state_ref: &[f64],
) {
    assert_eq!(fs.len(), fref.len());
    for (i, (f, r)) in fs.iter().zip(fref).enumerate() {
        for d in 0..3 {
            assert_eq!(
                f[d].to_bits(),
                r[d].to_bits(),
                "{path}: particle {i}, component {d}: {} vs {}",
                f[d],
                r[d]
            );
        }
    }
    assert!(
        bond_state.len() == state_ref.len()
            && bond_state
                .iter()
                .zip(state_ref)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
        "{path}: bond states differ"
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pd::geometry::cube_lattice;

    /// The chunked kernel against the one-pass loop, bit for bit, on every instruction set
    /// this CPU has: rows longer and shorter than a chunk (surface particles), bonds broken
    /// before the step, bonds breaking in it, and a body far from the origin.
    #[test]
    fn chunked_kernel_matches_the_one_pass_loop_bitwise() {
        let dx = 1e-3;
        // δ = 4.02 Δx: 250-member interior rows (several chunks), 0.1 km off the origin.
        let x0: Vec<[f64; 3]> = cube_lattice(11, dx)
            .into_iter()
            .map(|p| [p[0] + 100.0, p[1] - 50.0, p[2]])
            .collect();
        let bonds = Bonds::build(&x0, 4.02 * dx);
        assert!(
            (0..bonds.particles()).any(|i| bonds.offsets[i + 1] - bonds.offsets[i] > 3 * CHUNK)
        );
        let disp: Vec<[f64; 3]> = (0..x0.len())
            .map(|i| {
                let a = i as f64;
                [
                    1e-5 * (a * 0.37).sin(),
                    -2e-5 * (a * 0.11).cos(),
                    4e-5 * (a * 0.71).sin(),
                ]
            })
            .collect();
        let mut coef0: Vec<f64> = (0..bonds.len())
            .map(|b| 1e17 * (1.0 + 0.3 * ((b * 7919) % 101) as f64 / 101.0))
            .collect();
        for b in (0..bonds.len()).step_by(17) {
            coef0[b] = 0.0;
        }
        // s0 = 1 %: a share of the bonds (|η| up to ~7e-5 over Δx = 1e-3) break.
        let critical = 1.01f64 * 1.01;
        let mut reference = coef0.clone();
        let fref: Vec<[f64; 3]> = (0..bonds.particles())
            .map(|i| {
                let r = bonds.offsets[i]..bonds.offsets[i + 1];
                row_force_scalar(
                    i,
                    &x0,
                    &disp,
                    &bonds.nbr[r.clone()],
                    &bonds.inv_len[r.clone()],
                    &mut reference[r],
                    critical,
                )
            })
            .collect();
        let newly = reference
            .iter()
            .zip(&coef0)
            .filter(|(a, b)| **a == 0.0 && **b != 0.0)
            .count();
        assert!(newly > 100, "the test should break bonds: {newly}");
        assert!(fref.iter().any(|f| f[0] != 0.0));
        let same = |path: &str, fs: &[[f64; 3]], coef: &[f64]| {
            assert_same_bits(path, fs, coef, &fref, &reference)
        };
        for simd in Simd::available() {
            let mut coef = coef0.clone();
            let mut fs = vec![[0.0; 3]; bonds.particles()];
            block_force::<CHUNK>(
                simd,
                0,
                &mut fs,
                &mut coef,
                &bonds.offsets,
                &x0,
                &disp,
                &bonds.nbr,
                &bonds.inv_len,
                critical,
                &bonds.no_fail,
            );
            same(&format!("{simd:?}"), &fs, &coef);
        }
        // The explicit AVX-512 kernel (records transposed in registers), run in blocks of
        // 37 particles so block starts fall mid-way through the bond array.
        #[cfg(target_arch = "x86_64")]
        if mechanics::simd::has_avx512() {
            let mut rec = Vec::new();
            avx512::pack(&x0, &disp, &mut rec);
            let mut coef = coef0.clone();
            let mut fs = vec![[0.0; 3]; bonds.particles()];
            let o = &bonds.offsets;
            for lo in (0..bonds.particles()).step_by(37) {
                let hi = (lo + 37).min(bonds.particles());
                // SAFETY: the CPU has AVX-512 (checked above).
                unsafe {
                    avx512::block_force(
                        lo,
                        &mut fs[lo..hi],
                        &mut coef[o[lo]..o[hi]],
                        o,
                        &rec,
                        &bonds.nbr,
                        &bonds.inv_len,
                        critical,
                        &bonds.no_fail,
                    )
                };
            }
            same("explicit AVX-512", &fs, &coef);
        } else {
            eprintln!("no AVX-512 on this CPU: the explicit AVX-512 kernel is not tested here");
        }
    }
}
