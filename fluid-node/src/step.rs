//! The time loop of the fluid node (seed 002 §2.3–§2.4, Fig. 4): primitive recovery with the
//! mixture closure, MUSCL reconstruction of primitive variables with a TVD limiter, HLLC
//! fluxes, the quasi-conservative volume-fraction update of Johnsen & Colonius (2006), and
//! the three-stage SSP Runge–Kutta scheme of Shu & Osher (seed 002 eq. 35 uses its weights).
//! rayon parallelises over rows; every reduction is per row then in row order.
//!
//! Throughput: the row kernels are compiled for SSE2, AVX2 and
//! AVX-512 and chosen at run time (`simd.rs`, bit-identical results); each cell's limited
//! slope is computed once for both of its faces; and a 2-D stage without an immersed body
//! runs fused per block of rows (x and y fluxes into row-local scratch, then the update),
//! so no flux array goes through memory. None of this changes a value: the same
//! operations on the same operands in the same order as the plain per-face form.

use crate::boundary::{Boundary, fill_ghosts_yz, fill_row_x};
use crate::eos::Material;
use crate::grid::Grid;
use crate::immersed::{self, WallPatch};
use crate::limiter::Limiter;
use crate::mixture::{self, Phase};
use crate::model::Fluid;
use crate::riemann::{MAXF, face_state, hllc};
use crate::simd::multiversion;
use protocol::{SolverError, SolverResult};
use rayon::prelude::*;
use std::time::Instant;

/// SSP-RK3 in Shu–Osher form: U_s = a U_0 + b (U_{s-1} + dt L(U_{s-1})).
pub const RK3: [(f64, f64); 3] = [(0.0, 1.0), (0.75, 0.25), (1.0 / 3.0, 2.0 / 3.0)];
/// Effective weight of each stage's flux in the step (1/6, 1/6, 2/3).
pub const RK3_FLUX_WEIGHT: [f64; 3] = [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0];
/// Weight of the momentum removed by each stage's projection (seed 002 eq. 35).
pub const RK3_PROJECTION_WEIGHT: [f64; 3] = [1.0 / 6.0, 2.0 / 3.0, 1.0];

/// Names of the primitive variables for error messages.
pub fn prim_name(nm: usize, v: usize) -> String {
    if v < nm {
        if nm == 1 {
            "density".into()
        } else {
            format!("partial density of material {v}")
        }
    } else if v < nm + 3 {
        ["velocity x", "velocity y", "velocity z"][v - nm].into()
    } else if v == nm + 3 {
        "pressure".into()
    } else {
        format!("volume fraction of material {}", v - nm - 4)
    }
}

/// Conserved → primitive on one row's interior cells. Returns the first inadmissible
/// (i, variable, value).
fn prim_row<const NM: usize>(
    ph: &[Phase; NM],
    cons: &[f64],
    prim: &mut [f64],
    mx: usize,
    irange: std::ops::Range<usize>,
) -> Option<(usize, usize, f64)> {
    let nv = 2 * NM + 3;
    for i in irange {
        let mut ar = [0.0; NM];
        let mut al = [0.0; NM];
        let mut rho = 0.0;
        for k in 0..NM {
            let a = cons[k * mx + i];
            if !(a >= 0.0) {
                // tiny negative partial densities of a trace phase are round-off
                if NM > 1
                    && a > -1e-12
                        * cons
                            .iter()
                            .skip(i)
                            .step_by(mx)
                            .take(NM)
                            .map(|x| x.abs())
                            .sum::<f64>()
                {
                    ar[k] = 0.0;
                    continue;
                }
                return Some((i, k, a));
            }
            ar[k] = a;
            rho += a;
        }
        if !(rho > 0.0) {
            return Some((i, 0, rho));
        }
        let inv = 1.0 / rho;
        let u = cons[NM * mx + i] * inv;
        let v = cons[(NM + 1) * mx + i] * inv;
        let w = cons[(NM + 2) * mx + i] * inv;
        let rhoe = cons[(NM + 3) * mx + i] - 0.5 * rho * (u * u + v * v + w * w);
        let mut sa = 0.0;
        for k in 0..NM - 1 {
            let a = cons[(NM + 4 + k) * mx + i];
            al[k] = a;
            sa += a;
        }
        al[NM - 1] = (1.0 - sa).max(0.0);
        let p = mixture::pressure(ph, &ar, &al, rhoe);
        let c2 = mixture::sound_speed2(ph, &ar, &al, rho, p);
        if !(c2 > 0.0) || !c2.is_finite() || !p.is_finite() {
            return Some((i, NM + 3, p));
        }
        for k in 0..NM {
            prim[k * mx + i] = ar[k];
        }
        prim[NM * mx + i] = u;
        prim[(NM + 1) * mx + i] = v;
        prim[(NM + 2) * mx + i] = w;
        prim[(NM + 3) * mx + i] = p;
        for k in 0..NM - 1 {
            prim[(NM + 4 + k) * mx + i] = al[k];
        }
        debug_assert!(nv == 2 * NM + 3);
    }
    None
}

/// What [`prim_row`] finds wrong with one cell's conserved values `c` (2·NM + 3 of them):
/// the inadmissible primitive variable and its value, or `None`. The device path names a
/// cell its kernels rejected with this.
pub(crate) fn diagnose(phases: &[Phase], c: &[f64]) -> Option<(usize, f64)> {
    fn one<const NM: usize>(phases: &[Phase], c: &[f64]) -> Option<(usize, f64)> {
        let ph: [Phase; NM] = std::array::from_fn(|k| phases[k].clone());
        let mut prim = vec![0.0; c.len()];
        prim_row::<NM>(&ph, c, &mut prim, 1, 0..1).map(|(_, v, x)| (v, x))
    }
    match phases.len() {
        1 => one::<1>(phases, c),
        2 => one::<2>(phases, c),
        3 => one::<3>(phases, c),
        _ => one::<4>(phases, c),
    }
}

/// [`prim_row`] with a branch-free, vectorisable loop for a single ideal gas (the same
/// arithmetic, so identical values); any inadmissible cell reruns the general row to name it.
#[inline(always)]
fn prim_row_fast_body<const NM: usize>(
    ph: &[Phase; NM],
    cons: &[f64],
    prim: &mut [f64],
    mx: usize,
    irange: std::ops::Range<usize>,
) -> Option<(usize, usize, f64)> {
    let (gamma, inv_g, off) = match (&ph[0].eos, NM) {
        (Material::Ideal(g), 1) => (g.gamma, ph[0].inv_g, ph[0].off),
        _ => return prim_row::<NM>(ph, cons, prim, mx, irange),
    };
    let (lo, hi) = (irange.start, irange.end);
    let n = hi - lo;
    let c: [&[f64]; 5] = std::array::from_fn(|v| &cons[v * mx + lo..v * mx + hi]);
    let (pr, rest) = prim.split_at_mut(mx);
    let (pu, rest) = rest.split_at_mut(mx);
    let (pv, rest) = rest.split_at_mut(mx);
    let (pw, pp) = rest.split_at_mut(mx);
    let (pr, pu, pv, pw) = (
        &mut pr[lo..hi],
        &mut pu[lo..hi],
        &mut pv[lo..hi],
        &mut pw[lo..hi],
    );
    let pp = &mut pp[lo..hi];
    let (c0, c1, c2s, c3, c4) = (&c[0][..n], &c[1][..n], &c[2][..n], &c[3][..n], &c[4][..n]);
    let mut bad = false;
    for t in 0..n {
        let a = c0[t];
        let rho = 0.0 + a;
        let inv = 1.0 / rho;
        let u = c1[t] * inv;
        let v = c2s[t] * inv;
        let w = c3[t] * inv;
        let rhoe = c4[t] - 0.5 * rho * (u * u + v * v + w * w);
        let p = (rhoe - 1.0 * off) / inv_g;
        let cc = gamma * p / rho;
        bad |= !(a >= 0.0) | !(rho > 0.0) | !(cc > 0.0) | !cc.is_finite() | !p.is_finite();
        pr[t] = a;
        pu[t] = u;
        pv[t] = v;
        pw[t] = w;
        pp[t] = p;
    }
    if bad {
        return prim_row::<NM>(ph, cons, prim, mx, irange);
    }
    None
}

multiversion! {
    /// [`prim_row_fast_body`] for the widest instruction set allowed.
    fn prim_row_fast<const NM: usize>(
        ph: &[Phase; NM],
        cons: &[f64],
        prim: &mut [f64],
        mx: usize,
        irange: std::ops::Range<usize>,
    ) -> Option<(usize, usize, f64)> = prim_row_fast_body;
}

/// Primitive variables of every interior cell, and the x ghost cells of each interior row
/// just after its primitives, while the row is in cache (`boundary::fill_row_x`; the y and z
/// ghosts, and the x ghosts again where an immersed body changed cells, come later); a
/// diverged cell becomes an error naming the cell, the time and the variable.
fn prim_all<const NM: usize>(f: &mut Fluid, ph: &[Phase; NM], stage: usize) -> SolverResult<()> {
    let grid = &f.grid;
    let simd = f.simd;
    let nv = f.nv;
    let mx = grid.mx();
    let ir = grid.irange();
    let bcx = &f.bc[0];
    f.cons
        .par_chunks(nv * mx)
        .zip(f.prim.par_chunks_mut(nv * mx))
        .zip(f.row_bad.par_iter_mut())
        .enumerate()
        .for_each(|(r, ((c, p), bad))| {
            *bad = if grid.interior_row(r) {
                let b = prim_row_fast::<NM>(simd, ph, c, p, mx, ir.clone());
                if b.is_none() && grid.g[0] > 0 {
                    fill_row_x(grid, p, nv, NM, bcx);
                }
                b
            } else {
                None
            };
        });
    check_rows::<NM>(f, stage)?;
    f.prim_valid = true;
    Ok(())
}

/// The first inadmissible cell recorded in `row_bad` (in row order) as an error naming the
/// cell, the time, the variable and the RK stage whose primitives were being recovered.
fn check_rows<const NM: usize>(f: &Fluid, stage: usize) -> SolverResult<()> {
    let grid = &f.grid;
    for (r, bad) in f.row_bad.iter().enumerate() {
        if let Some((i, v, val)) = *bad {
            let (j, k) = grid.jk(r);
            let x = grid.centre(i, j, k);
            let (ii, jj, kk) = (i - grid.g[0], j - grid.g[1], k - grid.g[2]);
            return Err(SolverError::Diverged {
                time: f.time,
                reason: format!(
                    "cell ({ii}, {jj}, {kk}) at x = ({:.6e}, {:.6e}, {:.6e}) m: {} = {val:e} (RK stage {})",
                    x[0],
                    x[1],
                    x[2],
                    prim_name(NM, v),
                    stage + 1
                ),
            });
        }
    }
    Ok(())
}

/// Where a fused stage puts the primitives of the rows it updates, for the next stage (no
/// immersed body, which changes cells after the update): the block's rows of `prim_next`
/// and of `row_bad`, and the x boundary conditions.
pub(crate) struct NextPrims<'a> {
    prim: &'a mut [f64],
    bad: &'a mut [Option<(usize, usize, f64)>],
    bcx: &'a [Boundary; 2],
}

impl NextPrims<'_> {
    /// What [`prim_all`] does to a row, on row `k` of the block from its updated conserved
    /// variables `u`, while they are in cache: the same calls, so the same values.
    #[inline(always)]
    fn row<const NM: usize>(&mut self, grid: &Grid, ph: &[Phase; NM], k: usize, u: &[f64]) {
        let nv = 2 * NM + 3;
        let mx = grid.mx();
        let p = &mut self.prim[k * nv * mx..(k + 1) * nv * mx];
        let b = prim_row_fast_body::<NM>(ph, u, p, mx, grid.irange());
        if b.is_none() && grid.g[0] > 0 {
            fill_row_x(grid, p, nv, NM, self.bcx);
        }
        self.bad[k] = b;
    }
}

/// Largest Σ_d (|u_d| + c)/Δx_d over the interior cells of one row block of primitives `p`
/// (row `r`); 0 for a ghost row.
#[inline(always)]
fn row_rate_body<const NM: usize>(grid: &Grid, ph: &[Phase; NM], p: &[f64], r: usize) -> f64 {
    let nv = 2 * NM + 3;
    let mx = grid.mx();
    let nd = grid.nd;
    let idx = [1.0 / grid.dx[0], 1.0 / grid.dx[1], 1.0 / grid.dx[2]];
    let ir = grid.irange();
    let mut m = 0.0_f64;
    let ideal = match (&ph[0].eos, NM) {
        (Material::Ideal(g), 1) => Some(g.gamma),
        _ => None,
    };
    if let (true, Some(gamma)) = (grid.interior_row(r), ideal) {
        // single ideal gas: the same arithmetic as `face_state` on contiguous slices
        let (lo, hi) = (ir.start, ir.end);
        let rho = &p[lo..hi];
        let n = rho.len();
        let vel: [&[f64]; 3] = std::array::from_fn(|d| &p[(1 + d) * mx + lo..][..n]);
        let pr = &p[4 * mx + lo..][..n];
        m = match nd {
            1 => rate_ideal::<1>(gamma, idx, rho, vel, pr),
            2 => rate_ideal::<2>(gamma, idx, rho, vel, pr),
            _ => rate_ideal::<3>(gamma, idx, rho, vel, pr),
        };
    } else if grid.interior_row(r) {
        for i in ir.clone() {
            let mut q = [0.0; MAXF];
            for (v, qv) in q.iter_mut().enumerate().take(nv) {
                *qv = p[v * mx + i];
            }
            let c = match face_state::<NM>(ph, &q) {
                Some(s) => s.c,
                None => f64::INFINITY,
            };
            let mut s = 0.0;
            for d in 0..nd {
                s += (q[NM + d].abs() + c) * idx[d];
            }
            m = m.max(s);
        }
    }
    m
}

/// Largest Σ_d (|u_d| + c)/Δx_d over contiguous single-ideal-gas cells, c = ∞ where
/// `face_state` would reject the cell. Rates of blocks of cells into a stack buffer
/// (branch-free, so it vectorises), then running maxima per lane; a maximum is exact, so
/// the grouping does not change the value.
#[inline(always)]
fn rate_ideal<const ND: usize>(
    gamma: f64,
    idx: [f64; 3],
    rho: &[f64],
    vel: [&[f64]; 3],
    pr: &[f64],
) -> f64 {
    const B: usize = 64;
    const W: usize = 8;
    let mut acc = [0.0_f64; W];
    let mut buf = [0.0_f64; B];
    let n = rho.len();
    let mut t0 = 0;
    while t0 < n {
        let m = B.min(n - t0);
        let rho = &rho[t0..t0 + m];
        let pr = &pr[t0..t0 + m];
        let vel = vel.map(|v| &v[t0..t0 + m]);
        let out = &mut buf[..m];
        for t in 0..m {
            let c2 = gamma * pr[t] / rho[t];
            let ok = (rho[t] > 0.0) & (c2 > 0.0) & (c2 < f64::INFINITY);
            let c = if ok { c2.sqrt() } else { f64::INFINITY };
            let mut s = 0.0;
            for d in 0..ND {
                s += (vel[d][t].abs() + c) * idx[d];
            }
            out[t] = s;
        }
        for (t, &s) in out.iter().enumerate() {
            // f64::max semantics (a NaN rate is ignored), as a select
            let a = &mut acc[t % W];
            *a = if s > *a { s } else { *a };
        }
        t0 += m;
    }
    acc.iter().fold(0.0, |a, &b| a.max(b))
}

multiversion! {
    /// [`row_rate_body`] for the widest instruction set allowed.
    fn row_rate<const NM: usize>(grid: &Grid, ph: &[Phase; NM], p: &[f64], r: usize) -> f64
        = row_rate_body;
}

/// Largest Σ_d (|u_d| + c)/Δx_d over the interior (for the CFL step).
fn max_rate<const NM: usize>(f: &mut Fluid, ph: &[Phase; NM]) -> f64 {
    let grid = &f.grid;
    let simd = f.simd;
    let nv = f.nv;
    let mx = grid.mx();
    f.prim
        .par_chunks(nv * mx)
        .zip(f.row_max.par_iter_mut())
        .enumerate()
        .for_each(|(r, (p, out))| {
            *out = row_rate::<NM>(simd, grid, ph, p, r);
        });
    f.row_max.iter().fold(0.0, |a, &b| a.max(b))
}

thread_local! {
    /// Per-thread scratch for the primitives of one row in [`stable_dt_of`].
    static ROW_SCRATCH: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// The CFL-limited step of the current state without touching the model (the `Solver`
/// query between windows): primitives row by row into per-thread scratch, the same
/// arithmetic as [`stable_dt`], so the same value. The maximum is exact in any order, so the
/// rayon reduction is deterministic.
pub fn stable_dt_of(f: &Fluid) -> SolverResult<f64> {
    match f.nmat() {
        1 => stable_dt_of_nm::<1>(f),
        2 => stable_dt_of_nm::<2>(f),
        3 => stable_dt_of_nm::<3>(f),
        4 => stable_dt_of_nm::<4>(f),
        n => Err(SolverError::Other(format!(
            "{n} materials: at most 4 are supported"
        ))),
    }
}

fn stable_dt_of_nm<const NM: usize>(f: &Fluid) -> SolverResult<f64> {
    let ph: [Phase; NM] = std::array::from_fn(|k| f.phases[k].clone());
    let grid = &f.grid;
    let simd = f.simd;
    let nv = f.nv;
    let mx = grid.mx();
    let ir = grid.irange();
    let rate = if f.prim_valid {
        f.prim
            .par_chunks(nv * mx)
            .enumerate()
            .map(|(r, p)| row_rate::<NM>(simd, grid, &ph, p, r))
            .reduce(|| 0.0, f64::max)
    } else {
        f.cons
            .par_chunks(nv * mx)
            .enumerate()
            .map(|(r, c)| {
                if !grid.interior_row(r) {
                    return 0.0;
                }
                ROW_SCRATCH.with(|cell| {
                    let mut p = cell.borrow_mut();
                    if p.len() < nv * mx {
                        p.resize(nv * mx, 0.0);
                    }
                    match prim_row_fast::<NM>(simd, &ph, c, &mut p, mx, ir.clone()) {
                        Some(_) => f64::INFINITY,
                        None => row_rate::<NM>(simd, grid, &ph, &p, r),
                    }
                })
            })
            .reduce(|| 0.0, f64::max)
    };
    if !(rate > 0.0) || !rate.is_finite() {
        return Err(SolverError::Diverged {
            time: f.time,
            reason: format!("no finite stable time step (largest wave rate {rate:e} 1/s)"),
        });
    }
    Ok(f.cfl / rate)
}

thread_local! {
    /// Per-thread scratch of the flux kernels (face values, sound speeds, energies and
    /// limited slopes of one line); grows once, then reused every step (no allocation per
    /// step).
    static LINE_SCRATCH: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Lines of y faces per rayon task: the lines of a block run in order on one thread, so a
/// row's limited slopes serve the faces on both its sides.
const FACE_BLOCK: usize = 16;

/// Limited slopes of one variable across a stencil: `s[i] = σ(q[i] - qm[i], qp[i] - q[i])`
/// (qm, q, qp: the cells before, at and after along the reconstruction direction).
#[inline(always)]
fn slope_var<S: Fn(f64, f64) -> f64>(slope: S, qm: &[f64], q: &[f64], qp: &[f64], s: &mut [f64]) {
    let n = s.len();
    let (qm, q, qp) = (&qm[..n], &q[..n], &qp[..n]);
    for (((s, &qm), &q), &qp) in s.iter_mut().zip(qm).zip(q).zip(qp) {
        *s = slope(q - qm, qp - q);
    }
}

/// [`slope_var`] for the limiter `lim`.
#[inline(always)]
fn slopes(lim: Limiter, qm: &[f64], q: &[f64], qp: &[f64], s: &mut [f64]) {
    match lim {
        Limiter::Minmod => slope_var(crate::limiter::minmod, qm, q, qp, s),
        Limiter::VanLeer => slope_var(crate::limiter::van_leer, qm, q, qp, s),
        Limiter::Mc => slope_var(crate::limiter::mc, qm, q, qp, s),
    }
}

/// MUSCL face values from cell values and limited slopes (seed 002 §2.3): `lo = q + ½s` on
/// the side of the face towards the cell, `hi = q - ½s` on the other.
#[inline(always)]
fn face_values(q: &[f64], s: &[f64], out: &mut [f64], sign: f64) {
    let n = out.len();
    let (q, s) = (&q[..n], &s[..n]);
    for ((o, &q), &s) in out.iter_mut().zip(q).zip(s) {
        *o = if sign > 0.0 { q + 0.5 * s } else { q - 0.5 * s };
    }
}

/// Limited MUSCL face values of the faces i0-1/2+1 .. of one x row, each cell's slope
/// computed once for both of its faces: face t lies between cells `i0 + t` and
/// `i0 + t + 1`, `lo[t] = q + ½σ` of the left cell and `hi[t] = q - ½σ` of the right one
/// (σ of a cell from its two neighbour differences, the same calls as a per-face
/// reconstruction).
#[inline(always)]
fn recon_row_x(lim: Limiter, q: &[f64], i0: usize, s: &mut [f64], lo: &mut [f64], hi: &mut [f64]) {
    let n = lo.len();
    let s = &mut s[..n + 1];
    slopes(lim, &q[i0 - 1..], &q[i0..], &q[i0 + 1..], s);
    face_values(&q[i0..], &s[..n], lo, 1.0);
    face_values(&q[i0 + 1..], &s[1..], hi, -1.0);
}

/// Sound speed and total energy per volume of every face side of a single ideal gas
/// (branch-free, so it vectorises; the same arithmetic as [`face_state`], so identical
/// values). c = NaN marks a side `face_state` would reject.
#[inline(always)]
fn sides_ideal(gamma: f64, inv_g: f64, off: f64, q: [&[f64]; 5], c: &mut [f64], e: &mut [f64]) {
    let n = c.len();
    let (e, rho, vx, vy, vz, pr) = (
        &mut e[..n],
        &q[0][..n],
        &q[1][..n],
        &q[2][..n],
        &q[3][..n],
        &q[4][..n],
    );
    for t in 0..n {
        let (r, p) = (rho[t], pr[t]);
        let c2 = gamma * p / r;
        // c2 > 0 and finite, written without short-circuit so that the loop vectorises
        let ok = (r > 0.0) & (c2 > 0.0) & (c2 < f64::INFINITY);
        c[t] = if ok { c2.sqrt() } else { f64::NAN };
        e[t] = (p * inv_g + 1.0 * off) + 0.5 * r * (vx[t] * vx[t] + vy[t] * vy[t] + vz[t] * vz[t]);
    }
}

/// HLLC fluxes of a line (or a batch of lines) of `len` faces from their reconstructed
/// sides: `lb`/`rb` hold the left and right face values (variable v of face t at
/// `v * ls + t`), `ce` is
/// scratch of 4·len; face t's flux entry v goes to `out[v * ostride + o0 + t]`. `cell(v, t)`
/// gives variable v of the cells left and right of face t, for the first-order fallback
/// where a reconstructed side is inadmissible.
#[inline(always)]
fn riemann_line<const NM: usize, const D: usize>(
    ph: &[Phase; NM],
    lb: &[f64],
    rb: &[f64],
    ls: usize,
    ce: &mut [f64],
    out: &mut [f64],
    ostride: usize,
    o0: usize,
    len: usize,
    cell: impl Fn(usize, usize) -> [f64; 2],
) {
    let nv = 2 * NM + 3;
    let (i0, i1) = (o0, o0 + len);
    let mx = ostride;
    // single ideal gas: sound speed and total energy of every face side in one
    // vectorisable pass, then every face at once; faces with a rejected side are redone
    // by the general path below
    let ideal = match (&ph[0].eos, NM) {
        (Material::Ideal(g), 1) => Some((g.gamma, ph[0].inv_g, ph[0].off)),
        _ => None,
    };
    let ce = &mut ce[..4 * len];
    let mut all_ok = false;
    if let Some((gamma, inv_g, off)) = ideal {
        let (cl, rest) = ce.split_at_mut(len);
        let (el, rest) = rest.split_at_mut(len);
        let (cr, er) = rest.split_at_mut(len);
        let lsides: [&[f64]; 5] = std::array::from_fn(|v| &lb[v * ls..v * ls + len]);
        let rsides: [&[f64]; 5] = std::array::from_fn(|v| &rb[v * ls..v * ls + len]);
        sides_ideal(gamma, inv_g, off, lsides, cl, el);
        sides_ideal(gamma, inv_g, off, rsides, cr, er);
        let (o0, rest) = out.split_at_mut(mx);
        let (o1, rest) = rest.split_at_mut(mx);
        let (o2, rest) = rest.split_at_mut(mx);
        let (o3, rest) = rest.split_at_mut(mx);
        let (o4, o5) = rest.split_at_mut(mx);
        hllc::flux_line_ideal::<D>(
            lsides,
            rsides,
            cl,
            el,
            cr,
            er,
            [
                &mut o0[i0..i1],
                &mut o1[i0..i1],
                &mut o2[i0..i1],
                &mut o3[i0..i1],
                &mut o4[i0..i1],
                &mut o5[i0..i1],
            ],
        );
        // any rejected side? (a vectorisable reduction, no early exit)
        let cr = &cr[..len];
        all_ok = !cl
            .iter()
            .zip(cr)
            .fold(false, |bad, (a, b)| bad | a.is_nan() | b.is_nan());
    }
    if all_ok {
        return;
    }
    let (cl, rest) = ce.split_at(len);
    let (_, rest) = rest.split_at(len);
    let (cr, _) = rest.split_at(len);
    for (t, i) in (i0..i1).enumerate() {
        if ideal.is_some() && !cl[t].is_nan() && !cr[t].is_nan() {
            continue;
        }
        let mut l = [0.0; MAXF];
        let mut r = [0.0; MAXF];
        for v in 0..nv {
            l[v] = lb[v * ls + t];
            r[v] = rb[v * ls + t];
        }
        let (sl, sr) = match (face_state::<NM>(ph, &l), face_state::<NM>(ph, &r)) {
            (Some(a), Some(b)) => (a, b),
            // first order where the reconstruction leaves the admissible set
            _ => {
                let mut q1 = [0.0; MAXF];
                let mut q2 = [0.0; MAXF];
                for v in 0..nv {
                    [q1[v], q2[v]] = cell(v, t);
                }
                match (face_state::<NM>(ph, &q1), face_state::<NM>(ph, &q2)) {
                    (Some(a), Some(b)) => (a, b),
                    _ => {
                        for v in 0..=nv {
                            out[v * mx + i] = f64::NAN;
                        }
                        continue;
                    }
                }
            }
        };
        let fl = hllc::flux_dir::<NM, D>(&sl, &sr);
        for v in 0..=nv {
            out[v * mx + i] = fl[v];
        }
    }
}

/// MUSCL-reconstructed HLLC fluxes of the x faces of primitive row `row` (nv blocks of
/// `mx`), faces `irange` (indexed by the cell on their left). `work` is scratch of at
/// least (2·nv + 5)·len + 1 values.
#[inline(always)]
fn flux_row_x_into<const NM: usize>(
    ph: &[Phase; NM],
    lim: Limiter,
    row: &[f64],
    out: &mut [f64],
    mx: usize,
    irange: std::ops::Range<usize>,
    work: &mut [f64],
) {
    let nv = 2 * NM + 3;
    let (i0, i1) = (irange.start, irange.end);
    let len = i1 - i0;
    let (lb, rest) = work.split_at_mut(nv * len);
    let (rb, rest) = rest.split_at_mut(nv * len);
    let (ce, rest) = rest.split_at_mut(4 * len);
    let s = &mut rest[..len + 1];
    for v in 0..nv {
        let q = &row[v * mx..(v + 1) * mx];
        let lo = &mut lb[v * len..(v + 1) * len];
        let hi = &mut rb[v * len..(v + 1) * len];
        recon_row_x(lim, q, i0, s, lo, hi);
    }
    let cell = |v: usize, t: usize| [row[v * mx + i0 + t], row[v * mx + i0 + t + 1]];
    riemann_line::<NM, 0>(ph, lb, rb, len, ce, out, mx, i0, len, cell);
}

/// [`flux_row_x_into`] with a growable per-thread scratch.
#[inline(always)]
fn flux_row_x_body<const NM: usize>(
    ph: &[Phase; NM],
    lim: Limiter,
    row: &[f64],
    out: &mut [f64],
    mx: usize,
    irange: std::ops::Range<usize>,
    buf: &mut Vec<f64>,
) {
    let nv = 2 * NM + 3;
    let need = (2 * nv + 5) * irange.len() + 1;
    if buf.len() < need {
        buf.resize(need, 0.0);
    }
    flux_row_x_into::<NM>(ph, lim, row, out, mx, irange, buf);
}

multiversion! {
    /// [`flux_row_x_body`] for the widest instruction set allowed.
    fn flux_row_x<const NM: usize>(
        ph: &[Phase; NM],
        lim: Limiter,
        row: &[f64],
        out: &mut [f64],
        mx: usize,
        irange: std::ops::Range<usize>,
        buf: &mut Vec<f64>,
    ) = flux_row_x_body;
}

/// MUSCL-reconstructed HLLC fluxes of a block of lines of faces normal to `D` (1 or 2):
/// `out` holds the flux rows `r0..` (a face row r lies between primitive rows r and
/// r + stride), `prim` all primitive rows (blocks of `nv·mx`). The lines run in order;
/// when line r + stride follows line r (y faces), [`face_line`] reuses the slopes of the
/// row they share.
#[inline(always)]
fn flux_block_body<const NM: usize, const D: usize>(
    ph: &[Phase; NM],
    lim: Limiter,
    grid: &Grid,
    prim: &[f64],
    r0: usize,
    out: &mut [f64],
    buf: &mut Vec<f64>,
) {
    let nv = 2 * NM + 3;
    let nf = nv + 1;
    let mx = grid.mx();
    let g = grid.g;
    let n = grid.n;
    let len = grid.n[0];
    let need = (4 * nv + 4) * len;
    if buf.len() < need {
        buf.resize(need, 0.0);
    }
    let (work, sl) = buf.split_at_mut((2 * nv + 4) * len);
    let mut cached = None;
    for (k, out) in out.chunks_mut(nf * mx).enumerate() {
        let r = r0 + k;
        let (j, kk) = grid.jk(r);
        // faces between row r and the next row along D
        let (t, other_ok) = if D == 1 {
            (j, kk >= g[2] && kk < g[2] + n[2])
        } else {
            (kk, j >= g[1] && j < g[1] + n[1])
        };
        if !other_ok || t + 1 < g[D] || t >= g[D] + n[D] {
            continue;
        }
        face_line::<NM, D>(ph, lim, grid, prim, r, out, work, sl, &mut cached);
    }
}

multiversion! {
    /// [`flux_block_body`] for the widest instruction set allowed.
    fn flux_block<const NM: usize, const D: usize>(
        ph: &[Phase; NM],
        lim: Limiter,
        grid: &Grid,
        prim: &[f64],
        r0: usize,
        out: &mut [f64],
        buf: &mut Vec<f64>,
    ) = flux_block_body;
}

/// Fluxes through every interior face in direction d.
fn fluxes<const NM: usize>(f: &mut Fluid, ph: &[Phase; NM], d: usize) {
    let grid = &f.grid;
    let simd = f.simd;
    let nv = f.nv;
    let nf = nv + 1;
    let mx = grid.mx();
    let lim = f.limiter;
    let prim = &f.prim;
    let g = grid.g;
    let n = grid.n;
    let rowblk = nv * mx;
    if d == 0 {
        f.flux[0]
            .par_chunks_mut(nf * mx)
            .enumerate()
            .for_each(|(r, out)| {
                if !grid.interior_row(r) {
                    return;
                }
                let row = &prim[r * rowblk..(r + 1) * rowblk];
                LINE_SCRATCH.with(|cell| {
                    let mut buf = cell.borrow_mut();
                    let faces = g[0] - 1..g[0] + n[0];
                    flux_row_x::<NM>(simd, ph, lim, row, out, mx, faces, &mut buf);
                });
            });
        return;
    }
    f.flux[d]
        .par_chunks_mut(FACE_BLOCK * nf * mx)
        .enumerate()
        .for_each(|(b, out)| {
            LINE_SCRATCH.with(|cell| {
                let mut buf = cell.borrow_mut();
                let r0 = b * FACE_BLOCK;
                if d == 1 {
                    flux_block::<NM, 1>(simd, ph, lim, grid, prim, r0, out, &mut buf);
                } else {
                    flux_block::<NM, 2>(simd, ph, lim, grid, prim, r0, out, &mut buf);
                }
            });
        });
}

/// Rows per rayon task of the fused stage on a 2-D grid: about eight tasks per thread for load
/// balance, at most 32 rows so that a task's rows stay in cache, at least 4 so that the
/// extra y line each task recomputes stays cheap. Any block size gives the same values
/// (each face's fluxes are the same arithmetic whichever task computes them).
fn fused_block_rows(rows: usize) -> usize {
    (rows / (8 * rayon::current_num_threads())).clamp(4, 32)
}

/// The fluxes of face line `r` normal to `D` (1 or 2; between primitive rows r and
/// r + stride) into `out`: limited MUSCL face values (seed 002 §2.3), then
/// [`riemann_line`]. `sl` holds two rows of limited slopes (nv·len each) and
/// `cached = (row, half)` says which half holds the slopes of which row, so consecutive
/// lines compute each row's slopes once. `work` is scratch of at least (2·nv + 4)·len.
/// The values are those of a per-face reconstruction (the same limiter calls on the same
/// differences).
#[inline(always)]
fn face_line<const NM: usize, const D: usize>(
    ph: &[Phase; NM],
    lim: Limiter,
    grid: &Grid,
    prim: &[f64],
    r: usize,
    out: &mut [f64],
    work: &mut [f64],
    sl: &mut [f64],
    cached: &mut Option<(usize, usize)>,
) {
    let nv = 2 * NM + 3;
    let mx = grid.mx();
    let ir = grid.irange();
    let (i0, i1) = (ir.start, ir.end);
    let len = i1 - i0;
    let rowblk = nv * mx;
    let stride = grid.row_stride(D);
    let (lb, rest) = work.split_at_mut(nv * len);
    let (rb, rest) = rest.split_at_mut(nv * len);
    let ce = &mut rest[..4 * len];
    let rows: [&[f64]; 4] = std::array::from_fn(|s| {
        let q = r + s * stride - stride;
        &prim[q * rowblk..(q + 1) * rowblk]
    });
    // half `h` of `sl` gets row r's slopes (reused if cached), the other half those of the
    // next row along D
    let reuse = matches!(*cached, Some((row, _)) if row == r);
    let h = match *cached {
        Some((row, half)) if row == r => half,
        _ => 0,
    };
    let (s0, s1) = sl[..2 * nv * len].split_at_mut(nv * len);
    let (sr, sn) = if h == 0 { (s0, s1) } else { (s1, s0) };
    for v in 0..nv {
        let var = |s: usize| &rows[s][v * mx + i0..v * mx + i1];
        let sv = &mut sr[v * len..(v + 1) * len];
        if !reuse {
            slopes(lim, var(0), var(1), var(2), sv);
        }
        face_values(var(1), sv, &mut lb[v * len..(v + 1) * len], 1.0);
        let sv = &mut sn[v * len..(v + 1) * len];
        slopes(lim, var(1), var(2), var(3), sv);
        face_values(var(2), sv, &mut rb[v * len..(v + 1) * len], -1.0);
    }
    *cached = Some((r + stride, 1 - h));
    let cell = |v: usize, t: usize| [rows[1][v * mx + i0 + t], rows[2][v * mx + i0 + t]];
    riemann_line::<NM, D>(ph, lb, rb, len, ce, out, mx, i0, len, cell);
}

/// Planes (rows of constant k) per rayon task of the fused 3-D stage: on one thread all of
/// them (one task, so no z-face plane is computed twice); otherwise about four tasks per
/// thread, at least 3 planes (so that the first task holds the lower ghost plane whose z
/// faces it computes, for [`boundary_flux`]) and at most 16 (the z-face plane each task
/// recomputes below its planes costs 1/planes of the z faces). Any block size gives the same
/// values.
fn fused_block_planes(planes: usize) -> usize {
    match rayon::current_num_threads() {
        1 => planes,
        t => (planes / (4 * t)).clamp(3, 16),
    }
}

/// y lines per tile of the fused stage: a tile's face batches, slopes and the primitive
/// rows they read stay in cache while the tile sweeps up its planes.
const TILE_J: usize = 8;

/// MUSCL face values of a batch of `lines` lines of `w` faces into `lb`/`rb` (nv blocks of
/// lines·w, line l's faces at `l * w ..`): `ends(l) = [ql, sl, qr, sr]` places line l's
/// left sides' cells at `q[ql..]` and their limited slopes at `s[sl..]` (variable v `mx`
/// further on per v), its right sides' at `qr`, `sr` (seed 002 §2.3: lo = q + ½σ,
/// hi = q − ½σ).
#[inline(always)]
fn face_batch(
    q: &[f64],
    s: &[f64],
    nv: usize,
    mx: usize,
    lines: usize,
    w: usize,
    lb: &mut [f64],
    rb: &mut [f64],
    ends: impl Fn(usize) -> [usize; 4],
) {
    let m = lines * w;
    for l in 0..lines {
        let [ql, sl, qr, sr] = ends(l);
        for v in 0..nv {
            let o = v * mx;
            let lo = &mut lb[v * m + l * w..v * m + (l + 1) * w];
            face_values(&q[ql + o..], &s[sl + o..], lo, 1.0);
            let hi = &mut rb[v * m + l * w..v * m + (l + 1) * w];
            face_values(&q[qr + o..], &s[sr + o..], hi, -1.0);
        }
    }
}

/// Limited slopes and both MUSCL face values of a stencil: `p = q + ½σ` (the side of the
/// cell's upper face), `m = q − ½σ` (its lower face), σ from the differences to the cells
/// before (`qm`) and after (`qp`); the operations of [`slopes`] then [`face_values`].
#[inline(always)]
fn sides_var<S: Fn(f64, f64) -> f64>(
    slope: S,
    qm: &[f64],
    q: &[f64],
    qp: &[f64],
    p: &mut [f64],
    m: &mut [f64],
) {
    let n = p.len();
    let (qm, q, qp, m) = (&qm[..n], &q[..n], &qp[..n], &mut m[..n]);
    for t in 0..n {
        let s = slope(q[t] - qm[t], qp[t] - q[t]);
        p[t] = q[t] + 0.5 * s;
        m[t] = q[t] - 0.5 * s;
    }
}

/// The face sides of a tile of rows of the fused stage along one direction.
#[derive(Clone, Copy)]
struct Sides<'a> {
    prim: &'a [f64],
    lim: Limiter,
    nv: usize,
    mx: usize,
    i0: usize,
    n0: usize,
}

impl Sides<'_> {
    /// [`sides_var`] of `rows` rows, the first at `c` in `prim`, the next ones one row
    /// further each, their stencil neighbours `off` before and after: row l's variable v
    /// at `v * (rows · n0) + l * n0` of `p` and `m` (interior cells only).
    #[inline(always)]
    fn rows(&self, c: usize, rows: usize, off: usize, p: &mut [f64], m: &mut [f64]) {
        let (prim, mx, n0) = (self.prim, self.mx, self.n0);
        let vs = rows * n0;
        for l in 0..rows {
            for v in 0..self.nv {
                let q = c + l * self.nv * mx + v * mx + self.i0;
                let o = v * vs + l * n0;
                let (p, m) = (&mut p[o..o + n0], &mut m[o..o + n0]);
                let (qm, q, qp) = (&prim[q - off..], &prim[q..], &prim[q + off..]);
                match self.lim {
                    Limiter::Minmod => sides_var(crate::limiter::minmod, qm, q, qp, p, m),
                    Limiter::VanLeer => sides_var(crate::limiter::van_leer, qm, q, qp, p, m),
                    Limiter::Mc => sides_var(crate::limiter::mc, qm, q, qp, p, m),
                }
            }
        }
    }
}

/// The fluxes of the z faces between planes k and k + 1 of rows j0..j0 + jn into `out`
/// (nf blocks of jn·n0, row l's faces at `l * n0 ..`) from the face sides `lp` (plane k's
/// upper sides) and `hm` (plane k + 1's lower sides), laid out as [`Sides::rows`] does;
/// walls applied. `ce`: scratch of [`riemann_line`].
#[inline(always)]
fn z_faces<const NM: usize>(
    ph: &[Phase; NM],
    grid: &Grid,
    prim: &[f64],
    walls: Option<WallPatch<'_>>,
    j0: usize,
    jn: usize,
    k: usize,
    lp: &[f64],
    hm: &[f64],
    out: &mut [f64],
    ce: &mut [f64],
) {
    let nv = 2 * NM + 3;
    let mx = grid.mx();
    let rowblk = nv * mx;
    let (i0, n0) = (grid.g[0], grid.n[0]);
    let zs = jn * n0;
    let qs = [grid.row(j0, k) * rowblk, grid.row(j0, k + 1) * rowblk];
    let cell = |v: usize, t: usize| {
        let (l, x) = (t / n0, t % n0);
        let o = l * rowblk + v * mx + i0 + x;
        [prim[qs[0] + o], prim[qs[1] + o]]
    };
    riemann_line::<NM, 2>(ph, lp, hm, zs, ce, out, zs, 0, zs, cell);
    if let Some(w) = walls {
        for l in 0..jn {
            let line = grid.row(j0 + l, k);
            w.apply_strided(2, line, &mut out[l * n0..], zs, i0, n0);
        }
    }
}

/// One RK stage of a block of rows, fused: a block of planes of a 3-D grid or a block of
/// rows of a 2-D one. The block's interior y lines go in tiles of [`TILE_J`] rows; a tile
/// sweeps up the planes (a 2-D grid has one) and, per plane, computes its faces in three
/// batches (the z faces above its rows, in 3-D; the y faces between them; the x faces of
/// each row), each batch one long vectorised pass of [`riemann_line`] rather than a pass per
/// line. For z and y, each row's limited slopes and both its face values come in one pass
/// ([`Sides::rows`]), laid out so that the batch reads them in place; for x, the slopes of
/// the tile's contiguous rows come in one pass (ghost columns included, never read), then
/// the face values. Each row's z sides are computed once (the tile keeps those of the plane
/// above), each y-face line once per block (a tile hands its top line to the next tile of
/// the same plane), and the rows are updated at once, so no flux array is written or read
/// back (the memory traffic of the stage halves). Faces that are immersed walls take the
/// stage's wall fluxes (`walls`). Only the domain boundary faces are stored in `fl` (the
/// block's rows of `x_bound`, `flux[1]`, `flux[2]`; the last empty in 2-D), for
/// [`boundary_flux`]. Every value is that of `fluxes` + `write_wall_fluxes` + `update`: the
/// same operations on the same operands per face.
#[inline(always)]
fn fused_block_body<const NM: usize, const D3: bool>(
    ph: &[Phase; NM],
    lim: Limiter,
    grid: &Grid,
    prim: &[f64],
    r0: usize,
    u: &mut [f64],
    u0: &[f64],
    fl: [&mut [f64]; 3],
    a: f64,
    b: f64,
    dt: f64,
    buf: &mut Vec<f64>,
    first: bool,
    walls: Option<WallPatch<'_>>,
    mut next: Option<NextPrims<'_>>,
) {
    let nv = 2 * NM + 3;
    let nf = nv + 1;
    let mx = grid.mx();
    let (g, n, m1) = (grid.g, grid.n, grid.m[1]);
    let (i0, n0) = (g[0], n[0]);
    let nx = n0 + 1;
    let rowblk = nv * mx;
    let fblk = nf * mx;
    let nrows = u.len() / rowblk;
    let jt = TILE_J.min(n[1]);
    let d3 = D3;
    debug_assert_eq!(d3, grid.nd > 2);
    // the block's interior planes k and y lines j: in 3-D whole planes, in 2-D rows of the
    // one plane
    let (klo, khi, jlo, jhi) = if d3 {
        let (kp0, kp1) = (r0 / m1, (r0 + nrows) / m1);
        (kp0.max(g[2]), kp1.min(g[2] + n[2]), g[1], g[1] + n[1])
    } else {
        (0, 1, r0.max(g[1]), (r0 + nrows).min(g[1] + n[1]))
    };
    let planes = khi.saturating_sub(klo);
    // the largest batch: jt + 1 lines of y faces or jt lines of x faces
    let mb = (jt + 1) * nx;
    let need = 2 * nv * mb
        + 4 * mb
        + 4 * nv * jt * n0
        + 2 * nv * (jt + 2) * n0
        + rowblk * jt
        + nf * (2 * jt * n0 + (jt + 1) * n0 + jt * nx)
        + nf * n0 * planes;
    if buf.len() < need {
        buf.resize(need, 0.0);
    }
    let (lb, rest) = buf.split_at_mut(nv * mb);
    let (rb, rest) = rest.split_at_mut(nv * mb);
    let (ce, rest) = rest.split_at_mut(4 * mb);
    // face sides (q ± ½σ) of the tile's rows in two planes, and of jt + 2 rows of a plane
    let zsn = nv * jt * n0;
    let (zpa, rest) = rest.split_at_mut(zsn);
    let (zma, rest) = rest.split_at_mut(zsn);
    let (zpb, rest) = rest.split_at_mut(zsn);
    let (zmb, rest) = rest.split_at_mut(zsn);
    let (yp, rest) = rest.split_at_mut(nv * (jt + 2) * n0);
    let (ym, rest) = rest.split_at_mut(nv * (jt + 2) * n0);
    let (sx, rest) = rest.split_at_mut(jt * rowblk);
    let (za, rest) = rest.split_at_mut(nf * jt * n0);
    let (zb, rest) = rest.split_at_mut(nf * jt * n0);
    let (yf, rest) = rest.split_at_mut(nf * (jt + 1) * n0);
    let (xf, rest) = rest.split_at_mut(nf * jt * nx);
    let ytop = &mut rest[..nf * n0 * planes];
    let [xb, fyb, fzb] = fl;
    // keep the domain boundary face line `line` normal to d (1 or 2), held at `src[v *
    // stride]..` (interior faces only), if this block holds its row
    let keep = |fb: &mut [f64], line: usize, src: &[f64], stride: usize| {
        if line >= r0 && line < r0 + nrows {
            let o = (line - r0) * fblk;
            for v in 0..nf {
                let d = o + v * mx + i0;
                fb[d..d + n0].copy_from_slice(&src[v * stride..v * stride + n0]);
            }
        }
    };
    if first {
        // U ← U0 for the rows no tile visits (ghost rows); the interior rows are copied just
        // before their update, while they are in cache
        for (k, (uu, u0r)) in u.chunks_mut(rowblk).zip(u0.chunks(rowblk)).enumerate() {
            if !grid.interior_row(r0 + k) {
                uu.copy_from_slice(u0r);
            }
        }
    }
    // offset in `prim` of row (j, k)
    let at = |j: usize, k: usize| grid.row(j, k) * rowblk;
    let mut j0 = jlo;
    while planes > 0 && j0 < jhi {
        let j1 = (j0 + jt).min(jhi);
        let jn = j1 - j0;
        let (mut z_lo, mut z_hi) = (&mut *za, &mut *zb);
        // the face sides of this tile's rows in planes k (`lo`) and k + 1 (`hi`)
        let (mut lo, mut hi) = ((&mut *zpa, &mut *zma), (&mut *zpb, &mut *zmb));
        let zs = jn * n0;
        let plane = at(0, 1);
        let sides = Sides {
            prim,
            lim,
            nv,
            mx,
            i0,
            n0,
        };
        if d3 {
            // the z faces below the block's first plane
            sides.rows(at(j0, klo - 1), jn, plane, lo.0, lo.1);
            sides.rows(at(j0, klo), jn, plane, hi.0, hi.1);
            z_faces::<NM>(ph, grid, prim, walls, j0, jn, klo - 1, lo.0, hi.1, z_lo, ce);
            if klo - 1 == g[2] - 1 {
                for l in 0..jn {
                    keep(fzb, grid.row(j0 + l, klo - 1), &z_lo[l * n0..], zs);
                }
            }
        }
        for k in klo..khi {
            if d3 {
                // `hi` holds plane k's sides: plane k + 1's go to `lo`
                std::mem::swap(&mut lo, &mut hi);
                sides.rows(at(j0, k + 1), jn, plane, hi.0, hi.1);
                z_faces::<NM>(ph, grid, prim, walls, j0, jn, k, lo.0, hi.1, z_hi, ce);
                if k == g[2] + n[2] - 1 {
                    for l in 0..jn {
                        keep(fzb, grid.row(j0 + l, k), &z_hi[l * n0..], zs);
                    }
                }
            }
            // y faces: line slot s lies between rows j0 - 1 + s and j0 + s; the block's first
            // tile computes slot 0, the later ones take it from the tile below
            let ys = (jn + 1) * n0;
            let top = &mut ytop[(k - klo) * nf * n0..(k - klo + 1) * nf * n0];
            let jb = if j0 == jlo { j0 - 1 } else { j0 };
            let skip = jb + 1 - j0;
            if skip == 1 {
                for v in 0..nf {
                    yf[v * ys..v * ys + n0].copy_from_slice(&top[v * n0..(v + 1) * n0]);
                }
            }
            let lines = j1 - jb;
            let c = at(jb, k);
            // the sides of rows jb..=j1; line l: row jb + l's upper, row jb + l + 1's lower
            let vs = (lines + 1) * n0;
            sides.rows(c, lines + 1, rowblk, yp, ym);
            let cell = |v: usize, t: usize| {
                let (l, x) = (t / n0, t % n0);
                let o = c + l * rowblk + v * mx + i0 + x;
                [prim[o], prim[o + rowblk]]
            };
            let (yl, yr) = (&*yp, &ym[n0..]);
            riemann_line::<NM, 1>(ph, yl, yr, vs, ce, yf, ys, skip * n0, lines * n0, cell);
            for l in 0..lines {
                let (j, sl) = (jb + l, (skip + l) * n0);
                let line = grid.row(j, k);
                if let Some(w) = walls {
                    w.apply_strided(1, line, &mut yf[sl..], ys, i0, n0);
                }
                if j == g[1] - 1 || j == g[1] + n[1] - 1 {
                    keep(fyb, line, &yf[sl..], ys);
                }
            }
            for v in 0..nf {
                top[v * n0..(v + 1) * n0].copy_from_slice(&yf[v * ys + jn * n0..v * ys + ys]);
            }
            // x faces of each row: face t of a row between cells i0 - 1 + t and i0 + t
            let c = at(j0, k);
            slopes(
                lim,
                &prim[c - 1..],
                &prim[c..],
                &prim[c + 1..],
                &mut sx[..jn * rowblk],
            );
            face_batch(prim, sx, nv, mx, jn, nx, lb, rb, |l| {
                let o = l * rowblk + i0 - 1;
                [c + o, o, c + o + 1, o + 1]
            });
            let xs = jn * nx;
            let cell = |v: usize, t: usize| {
                let (l, x) = (t / nx, t % nx);
                let o = c + l * rowblk + v * mx + i0 - 1 + x;
                [prim[o], prim[o + 1]]
            };
            riemann_line::<NM, 0>(ph, lb, rb, xs, ce, xf, xs, 0, xs, cell);
            for l in 0..jn {
                let r = grid.row(j0 + l, k);
                if let Some(w) = walls {
                    w.apply_strided(0, r, &mut xf[l * nx..], xs, i0 - 1, nx);
                }
                // the domain boundary x faces, for the boundary impulse
                let xb = &mut xb[(r - r0) * 2 * nf..(r - r0 + 1) * 2 * nf];
                for v in 0..nf {
                    xb[v] = xf[v * xs + l * nx];
                    xb[nf + v] = xf[v * xs + l * nx + n0];
                }
                let o = (r - r0) * rowblk;
                let (uu, u0r) = (&mut u[o..o + rowblk], &u0[o..o + rowblk]);
                if first {
                    uu.copy_from_slice(u0r);
                }
                // (a 2-D update reads no z faces)
                let faces = [
                    (&*xf, xs, l * nx),
                    (&*yf, ys, (l + 1) * n0),
                    (&*yf, ys, l * n0),
                    (&*z_hi, zs, l * n0),
                    (&*z_lo, zs, l * n0),
                ];
                update_row_strided::<NM>(grid, faces, uu, u0r, a, b, dt);
                if let Some(nx) = next.as_mut() {
                    nx.row::<NM>(grid, ph, r - r0, uu);
                }
            }
            std::mem::swap(&mut z_lo, &mut z_hi);
        }
        j0 = j1;
    }
}

multiversion! {
    /// [`fused_block_body`] for the widest instruction set allowed.
    fn fused_block<const NM: usize, const D3: bool>(
        ph: &[Phase; NM],
        lim: Limiter,
        grid: &Grid,
        prim: &[f64],
        r0: usize,
        u: &mut [f64],
        u0: &[f64],
        fl: [&mut [f64]; 3],
        a: f64,
        b: f64,
        dt: f64,
        buf: &mut Vec<f64>,
        first: bool,
        walls: Option<WallPatch<'_>>,
        next: Option<NextPrims<'_>>,
    ) = fused_block_body;
}

/// [`fluxes`] in every direction, then [`update`], fused per block of rows (of planes in 3-D;
/// [`fused_block_body`]), the immersed walls' fluxes (`walls`) applied on the way. `first`:
/// the first stage, for which `cons` holds nothing yet and each row is copied from `cons0`
/// before its update. `next`: also the primitives of each updated row into `prim_next`
/// ([`NextPrims`]).
fn fused_stage<const NM: usize>(
    f: &mut Fluid,
    ph: &[Phase; NM],
    walls: Option<WallPatch<'_>>,
    a: f64,
    b: f64,
    dt: f64,
    first: bool,
    next: bool,
) {
    // z faces apart (the fields are borrowed one by one below); a 2-D grid has none, and its
    // blocks get none to keep
    let mut fz = std::mem::take(&mut f.flux[2]);
    let fzb = f.nv + 1;
    if f.grid.nd > 2 {
        let nb = fused_block_planes(f.grid.m[2]) * f.grid.m[1];
        let fzs = fz.par_chunks_mut(nb * fzb * f.grid.mx());
        fused_blocks::<NM, true>(f, ph, walls, [a, b, dt], first, next, nb, fzs);
    } else {
        let nb = fused_block_rows(f.grid.rows());
        let blocks = f.grid.rows().div_ceil(nb);
        let none = rayon::iter::repeat_n((), blocks).map(|()| -> &mut [f64] { &mut [] });
        fused_blocks::<NM, false>(f, ph, walls, [a, b, dt], first, next, nb, none);
    }
    f.flux[2] = fz;
}

/// [`fused_block`] over every block of `nb` rows in parallel (`[a, b, dt]`, `first`, `next`
/// as for [`fused_stage`]), `fz` giving each its rows of z faces to keep.
fn fused_blocks<'z, const NM: usize, const D3: bool>(
    f: &mut Fluid,
    ph: &[Phase; NM],
    walls: Option<WallPatch<'_>>,
    [a, b, dt]: [f64; 3],
    first: bool,
    next: bool,
    nb: usize,
    fz: impl IndexedParallelIterator<Item = &'z mut [f64]>,
) {
    let grid = &f.grid;
    let simd = f.simd;
    let lim = f.limiter;
    let nv = f.nv;
    let nf = nv + 1;
    let mx = grid.mx();
    let prim = &f.prim;
    let fy = &mut f.flux[1];
    let bcx = &f.bc[0];
    f.cons
        .par_chunks_mut(nb * nv * mx)
        .zip(f.cons0.par_chunks(nb * nv * mx))
        .zip(f.x_bound.par_chunks_mut(nb * 2 * nf))
        .zip(fy.par_chunks_mut(nb * nf * mx))
        .zip(fz)
        .zip(f.prim_next.par_chunks_mut(nb * nv * mx))
        .zip(f.row_bad.par_chunks_mut(nb))
        .enumerate()
        .for_each(|(blk, ((((((u, u0), xb), fyb), fzb), pn), bad))| {
            LINE_SCRATCH.with(|cell| {
                let mut buf = cell.borrow_mut();
                let r0 = blk * nb;
                let next = next.then_some(NextPrims { prim: pn, bad, bcx });
                fused_block::<NM, D3>(
                    simd,
                    ph,
                    lim,
                    grid,
                    prim,
                    r0,
                    u,
                    u0,
                    [xb, fyb, fzb],
                    a,
                    b,
                    dt,
                    &mut buf,
                    first,
                    walls,
                    next,
                );
            });
        });
}

/// Residual and RK stage update of every interior cell: U = a U0 + b (U + dt L(U)).
fn update<const NM: usize>(f: &mut Fluid, a: f64, b: f64, dt: f64) {
    let grid = &f.grid;
    let simd = f.simd;
    let nv = f.nv;
    let mx = grid.mx();
    let fl = &f.flux;
    f.cons
        .par_chunks_mut(nv * mx)
        .zip(f.cons0.par_chunks(nv * mx))
        .enumerate()
        .for_each(|(r, (u, u0))| {
            if grid.interior_row(r) {
                update_row::<NM>(simd, grid, fl, r, u, u0, a, b, dt);
            }
        });
}

/// The stage update of interior row `r` (`u`, `u0`: its blocks of U and U0).
#[inline(always)]
fn update_row_body<const NM: usize>(
    grid: &Grid,
    fl: &[Vec<f64>; 3],
    r: usize,
    u: &mut [f64],
    u0: &[f64],
    a: f64,
    b: f64,
    dt: f64,
) {
    let nv = 2 * NM + 3;
    let nf = nv + 1;
    let mx = grid.mx();
    let nd = grid.nd;
    let fb = nf * mx;
    let fx = &fl[0][r * fb..(r + 1) * fb];
    let (fy, fym) = if nd > 1 {
        (&fl[1][r * fb..(r + 1) * fb], &fl[1][(r - 1) * fb..r * fb])
    } else {
        (fx, fx)
    };
    let s2 = grid.row_stride(2);
    let (fz, fzm) = if nd > 2 {
        (
            &fl[2][r * fb..(r + 1) * fb],
            &fl[2][(r - s2) * fb..(r + 1 - s2) * fb],
        )
    } else {
        (fx, fx)
    };
    update_row_faces::<NM>(grid, [fx, fy, fym, fz, fzm], u, u0, a, b, dt);
}

/// The stage update of one interior row from its face-flux rows `[x, y upper, y lower,
/// z upper, z lower]` (each nf blocks of `mx`, indexed by the cell left of / below the face;
/// rows of absent directions are ignored).
#[inline(always)]
fn update_row_faces<const NM: usize>(
    grid: &Grid,
    faces: [&[f64]; 5],
    u: &mut [f64],
    u0: &[f64],
    a: f64,
    b: f64,
    dt: f64,
) {
    let mx = grid.mx();
    let lo = grid.irange().start;
    let [fx, fy, fym, fz, fzm] = faces;
    let faces = [
        (fx, mx, lo - 1),
        (fy, mx, lo),
        (fym, mx, lo),
        (fz, mx, lo),
        (fzm, mx, lo),
    ];
    update_row_strided::<NM>(grid, faces, u, u0, a, b, dt);
}

/// [`update_row_faces`] with the face fluxes in any layout: `(data, stride, at)` holds
/// variable v's flux through the lower face of the row's first interior cell (x: its left
/// face) at `data[v * stride + at]`, the next cells' faces following.
#[inline(always)]
fn update_row_strided<const NM: usize>(
    grid: &Grid,
    faces: [(&[f64], usize, usize); 5],
    u: &mut [f64],
    u0: &[f64],
    a: f64,
    b: f64,
    dt: f64,
) {
    let nv = 2 * NM + 3;
    let mx = grid.mx();
    let nd = grid.nd;
    let idx = [1.0 / grid.dx[0], 1.0 / grid.dx[1], 1.0 / grid.dx[2]];
    let ir = grid.irange();
    let (lo, hi) = (ir.start, ir.end);
    let n = hi - lo;
    // variable v's faces: n + 1 in x, n otherwise
    let var = |v: usize| -> [&[f64]; 5] {
        std::array::from_fn(|f| {
            let (d, s, at) = faces[f];
            &d[v * s + at..v * s + at + n + usize::from(f == 0)]
        })
    };
    // face velocities (Johnsen–Colonius) for the α rows
    let uf = var(nv);
    for v in 0..nv {
        let o = v * mx;
        let is_alpha = v >= NM + 4;
        // slices of exactly n (n + 1 for x faces) so the loop has no bounds checks
        let uv = &mut u[o + lo..o + hi];
        let u0v = &u0[o + lo..o + hi];
        let fs = var(v);
        // the stage update with the dimension and the α terms fixed at compile time
        // (so the loop vectorises); the same operations as the general form
        match (nd, is_alpha) {
            (1, false) => update_var::<1, false>(uv, u0v, fs, uf, idx, a, b, dt),
            (2, false) => update_var::<2, false>(uv, u0v, fs, uf, idx, a, b, dt),
            (_, false) => update_var::<3, false>(uv, u0v, fs, uf, idx, a, b, dt),
            (1, true) => update_var::<1, true>(uv, u0v, fs, uf, idx, a, b, dt),
            (2, true) => update_var::<2, true>(uv, u0v, fs, uf, idx, a, b, dt),
            (_, true) => update_var::<3, true>(uv, u0v, fs, uf, idx, a, b, dt),
        }
    }
}

multiversion! {
    /// [`update_row_body`] for the widest instruction set allowed.
    fn update_row<const NM: usize>(
        grid: &Grid,
        fl: &[Vec<f64>; 3],
        r: usize,
        u: &mut [f64],
        u0: &[f64],
        a: f64,
        b: f64,
        dt: f64,
    ) = update_row_body;
}

/// One variable of one row: U = a U0 + b (U + dt L(U)) with L the flux divergence
/// (`fs` = x faces (n + 1), y upper/lower, z upper/lower faces) and, for a volume fraction
/// (ALPHA), the Johnsen–Colonius term α ∇·u_face from the face velocities `uf`.
#[inline(always)]
fn update_var<const ND: usize, const ALPHA: bool>(
    uv: &mut [f64],
    u0v: &[f64],
    fs: [&[f64]; 5],
    uf: [&[f64]; 5],
    idx: [f64; 3],
    a: f64,
    b: f64,
    dt: f64,
) {
    let n = uv.len();
    let u0v = &u0v[..n];
    let fxv = &fs[0][..n + 1];
    let (fyv, fymv, fzv, fzmv) = (&fs[1][..n], &fs[2][..n], &fs[3][..n], &fs[4][..n]);
    let ufx = &uf[0][..n + 1];
    let (ufy, ufym, ufz, ufzm) = (&uf[1][..n], &uf[2][..n], &uf[3][..n], &uf[4][..n]);
    for t in 0..n {
        let mut dfx = fxv[t + 1] - fxv[t];
        if ALPHA {
            dfx -= uv[t] * (ufx[t + 1] - ufx[t]);
        }
        let mut res = -dfx * idx[0];
        if ND > 1 {
            let mut dfy = fyv[t] - fymv[t];
            if ALPHA {
                dfy -= uv[t] * (ufy[t] - ufym[t]);
            }
            res -= dfy * idx[1];
        }
        if ND > 2 {
            let mut dfz = fzv[t] - fzmv[t];
            if ALPHA {
                dfz -= uv[t] * (ufz[t] - ufzm[t]);
            }
            res -= dfz * idx[2];
        }
        let mut nu = a * u0v[t] + b * (uv[t] + dt * res);
        if ALPHA {
            nu = nu.clamp(0.0, 1.0);
        }
        uv[t] = nu;
    }
}

/// The stage update of a radial grid (docs/physics.md, "Radial geometries"): in x, the
/// flux difference weighted by the faces' areas over the cell's volume,
/// −(A₊F₊ − A₋F₋)/V, and in the radial momentum the pressure's push on the cell's sides,
/// +p (A₊ − A₋)/V (the form in which a gas at rest and uniform pressure stays at rest to
/// round-off); in y (the axis of an axisymmetric grid) the Cartesian difference. Mass and
/// energy are conserved in the rings' and shells' volumes. For the volume fractions the
/// Johnsen–Colonius term takes the same weights: −(A₊αu₊ − A₋αu₋)/V + α(A₊u₊ − A₋u₋)/V.
fn update_radial<const NM: usize>(f: &mut Fluid, a: f64, b: f64, dt: f64) {
    let grid = &f.grid;
    let nv = f.nv;
    let nf = nv + 1;
    let mx = grid.mx();
    let fl = &f.flux;
    let prim = &f.prim;
    let ir = grid.irange();
    let idy = 1.0 / grid.dx[1];
    let axis = grid.nd > 1;
    let cols = &grid.columns;
    f.cons
        .par_chunks_mut(nv * mx)
        .zip(f.cons0.par_chunks(nv * mx))
        .enumerate()
        .for_each(|(r, (u, u0))| {
            if !grid.interior_row(r) {
                return;
            }
            let fb = nf * mx;
            let fx = &fl[0][r * fb..(r + 1) * fb];
            let (fy, fym) = if axis {
                (&fl[1][r * fb..(r + 1) * fb], &fl[1][(r - 1) * fb..r * fb])
            } else {
                (fx, fx)
            };
            let p = &prim[(r * nv + NM + 3) * mx..(r * nv + NM + 4) * mx];
            // face velocities for the α rows (indexed like the fluxes)
            let (ux, uy, uym) = (&fx[nv * mx..], &fy[nv * mx..], &fym[nv * mx..]);
            for v in 0..nv {
                let is_alpha = v >= NM + 4;
                let o = v * mx;
                for i in ir.clone() {
                    let (wl, wh) = (cols[i].lo_per_volume, cols[i].hi_per_volume);
                    let mut res = -(wh * fx[o + i] - wl * fx[o + i - 1]);
                    if is_alpha {
                        res += u[o + i] * (wh * ux[i] - wl * ux[i - 1]);
                    }
                    if v == NM {
                        res += p[i] * (wh - wl);
                    }
                    if axis {
                        let mut dfy = fy[o + i] - fym[o + i];
                        if is_alpha {
                            dfy -= u[o + i] * (uy[i] - uym[i]);
                        }
                        res -= dfy * idy;
                    }
                    let mut nu = a * u0[o + i] + b * (u[o + i] + dt * res);
                    if is_alpha {
                        nu = nu.clamp(0.0, 1.0);
                    }
                    u[o + i] = nu;
                }
            }
        });
}

/// The fluxes of the two domain boundary x faces of every interior row from `flux[0]` into
/// `x_bound` (the unfused stages; the fused ones store them there directly).
fn store_x_bound(f: &mut Fluid) {
    let grid = &f.grid;
    let nf = f.nf();
    let mx = grid.mx();
    let (i0, i1) = (grid.g[0] - 1, grid.g[0] + grid.n[0] - 1);
    for (r, xb) in f.x_bound.chunks_mut(2 * nf).enumerate() {
        if grid.interior_row(r) {
            let fr = &f.flux[0][r * nf * mx..(r + 1) * nf * mx];
            for v in 0..nf {
                xb[v] = fr[v * mx + i0];
                xb[nf + v] = fr[v * mx + i1];
            }
        }
    }
}

/// Impulse (entries 0–2) and work (entry 3) on the gas of the fluxes through the domain
/// boundary faces over `dt_w`: the momentum and total-energy fluxes, which follow each
/// other in the variable order (`vel0() .. vel0() + 3`, then `ip()`). A face whose cell
/// inside the domain is solid (`kind`, the immersed body's cell classes) bounds no gas: the
/// body covers the wall there, and its flux enters neither the gas nor these sums.
fn boundary_flux(f: &Fluid, kind: Option<&[u8]>, dt_w: f64) -> [f64; 4] {
    if !f.grid.columns.is_empty() {
        return boundary_flux_radial(f, dt_w);
    }
    let grid = &f.grid;
    let nm = f.nmat();
    let nf = f.nf();
    let mx = grid.mx();
    let (g, n) = (grid.g, grid.n);
    debug_assert_eq!(f.ip(), nm + 3);
    let mut imp = [0.0; 4];
    for d in 0..grid.nd {
        let area = grid.face_area(d);
        let fr = |r: usize| &f.flux[d][r * nf * mx..(r + 1) * nf * mx];
        // per quantity, the sums over the lower and upper boundary faces, each in row order
        let mut lo = [0.0; 4];
        let mut hi = [0.0; 4];
        // one boundary face line (d > 0, face row r, the row of its domain cells rc): the
        // sum over its interior faces, in x order
        let line = |r: usize, rc: usize, c: usize| {
            let o = (nm + c) * mx + g[0];
            let faces = &fr(r)[o..o + n[0]];
            match kind {
                None => faces.iter().sum::<f64>(),
                Some(kind) => faces
                    .iter()
                    .zip(&kind[rc * mx + g[0]..])
                    .filter(|&(_, &k)| k != immersed::SOLID)
                    .map(|(x, _)| x)
                    .sum::<f64>(),
            }
        };
        let gas = |cell: usize| kind.is_none_or(|kind| kind[cell] != immersed::SOLID);
        for k in g[2]..g[2] + n[2] {
            match d {
                0 => {
                    for j in g[1]..g[1] + n[1] {
                        let r = grid.row(j, k);
                        let xb = &f.x_bound[r * 2 * nf..(r + 1) * 2 * nf];
                        let (a, b) = (gas(r * mx + g[0]), gas(r * mx + g[0] + n[0] - 1));
                        for c in 0..4 {
                            if a {
                                lo[c] += xb[nm + c];
                            }
                            if b {
                                hi[c] += xb[nf + nm + c];
                            }
                        }
                    }
                }
                1 => {
                    let (a, b) = (grid.row(g[1] - 1, k), grid.row(g[1] + n[1] - 1, k));
                    let (ca, cb) = (grid.row(g[1], k), b);
                    for c in 0..4 {
                        lo[c] += line(a, ca, c);
                        hi[c] += line(b, cb, c);
                    }
                }
                _ => {}
            }
        }
        if d == 2 {
            for j in g[1]..g[1] + n[1] {
                let (a, b) = (grid.row(j, g[2] - 1), grid.row(j, g[2] + n[2] - 1));
                let (ca, cb) = (grid.row(j, g[2]), b);
                for c in 0..4 {
                    lo[c] += line(a, ca, c);
                    hi[c] += line(b, cb, c);
                }
            }
        }
        for c in 0..4 {
            imp[c] += dt_w * area * (lo[c] - hi[c]);
        }
    }
    imp
}

/// [`boundary_flux`] of a radial grid: the faces' fluxes times their areas (the whole
/// revolution). Of the momentum only the axial component of an axisymmetric grid is a
/// momentum of the gas: the radial flux of a ring or shell pushes every direction at once,
/// so its impulse is zero by symmetry, as is the gas's radial momentum (`diagnostics`).
fn boundary_flux_radial(f: &Fluid, dt_w: f64) -> [f64; 4] {
    let grid = &f.grid;
    let nm = f.nmat();
    let nf = f.nf();
    let mx = grid.mx();
    let (g, n) = (grid.g, grid.n);
    let cols = &grid.columns;
    let (a_lo, a_hi) = (cols[g[0]].area_lo, cols[g[0] + n[0] - 1].area_hi);
    let mut lo = [0.0; 4];
    let mut hi = [0.0; 4];
    for j in g[1]..g[1] + n[1] {
        let r = grid.row(j, g[2]);
        let xb = &f.x_bound[r * 2 * nf..(r + 1) * 2 * nf];
        for c in 0..4 {
            lo[c] += a_lo * xb[nm + c];
            hi[c] += a_hi * xb[nf + nm + c];
        }
    }
    if grid.nd > 1 {
        // the axis's end faces: a ring's area each, the volume over its length
        let (ra, rb) = (grid.row(g[1] - 1, g[2]), grid.row(g[1] + n[1] - 1, g[2]));
        let fr = |r: usize| &f.flux[1][r * nf * mx..(r + 1) * nf * mx];
        for c in 0..4 {
            let o = (nm + c) * mx;
            for i in grid.irange() {
                let area = cols[i].volume / grid.dx[1];
                lo[c] += area * fr(ra)[o + i];
                hi[c] += area * fr(rb)[o + i];
            }
        }
    }
    let mut imp = [0.0; 4];
    for c in 0..4 {
        imp[c] = dt_w * (lo[c] - hi[c]);
    }
    // radial (x) and swirl (z) impulses vanish by symmetry
    imp[0] = 0.0;
    imp[2] = 0.0;
    if grid.nd == 1 {
        imp[1] = 0.0;
    }
    imp
}

/// The CFL-limited step now (s).
pub fn stable_dt(f: &mut Fluid) -> SolverResult<f64> {
    match f.nmat() {
        1 => stable_dt_nm::<1>(f),
        2 => stable_dt_nm::<2>(f),
        3 => stable_dt_nm::<3>(f),
        4 => stable_dt_nm::<4>(f),
        n => Err(SolverError::Other(format!(
            "{n} materials: at most 4 are supported"
        ))),
    }
}

fn stable_dt_nm<const NM: usize>(f: &mut Fluid) -> SolverResult<f64> {
    let ph: [Phase; NM] = std::array::from_fn(|k| f.phases[k].clone());
    if !f.prim_valid {
        prim_all::<NM>(f, &ph, 0)?;
    }
    Ok(f.cfl / max_rate::<NM>(f, &ph))
}

/// One SSP-RK3 step of at most `dt_max`; returns the step taken.
pub fn step(f: &mut Fluid, dt_max: f64) -> SolverResult<f64> {
    match f.nmat() {
        1 => step_nm::<1>(f, dt_max),
        2 => step_nm::<2>(f, dt_max),
        3 => step_nm::<3>(f, dt_max),
        4 => step_nm::<4>(f, dt_max),
        n => Err(SolverError::Other(format!(
            "{n} materials: at most 4 are supported"
        ))),
    }
}

fn step_nm<const NM: usize>(f: &mut Fluid, dt_max: f64) -> SolverResult<f64> {
    let t_step = Instant::now();
    let mut clock = t_step;
    let ph: [Phase; NM] = std::array::from_fn(|k| f.phases[k].clone());
    if !f.prim_valid {
        prim_all::<NM>(f, &ph, 0)?;
    }
    let rate = max_rate::<NM>(f, &ph);
    if !(rate > 0.0) || !rate.is_finite() {
        return Err(SolverError::Diverged {
            time: f.time,
            reason: format!("no finite stable time step (largest wave rate {rate:e} 1/s)"),
        });
    }
    let dt = (f.cfl / rate).min(dt_max);
    let fused = f.fused && f.grid.nd >= 2 && f.grid.columns.is_empty();
    if fused {
        // U0 ← U by swapping; the first fused stage copies each row back before updating it
        std::mem::swap(&mut f.cons, &mut f.cons0);
    } else {
        let chunk = f.nv * f.grid.mx();
        f.cons0
            .par_chunks_mut(chunk)
            .zip(f.cons.par_chunks(chunk))
            .for_each(|(a, b)| a.copy_from_slice(b));
    }
    f.timing.kernels_s += lap(&mut clock);
    let mut ib = f.immersed.take();
    let result = (|| -> SolverResult<()> {
        // whether the stage before computed this stage's primitives (fused, no immersed body)
        let mut have_prims = false;
        for (s, &(a, b)) in RK3.iter().enumerate() {
            if s > 0 && !have_prims {
                prim_all::<NM>(f, &ph, s)?;
                f.timing.kernels_s += lap(&mut clock);
            }
            if let Some(im) = ib.as_ref() {
                immersed::fill_solid_prims(f, im);
                f.timing.immersed_s += lap(&mut clock);
            }
            let vel0 = f.vel0();
            // `prim_all` filled the x ghosts; the solid-cell fills may have changed cells
            // that some rows' x ghosts copy: those rows only are filled again
            if let Some(im) = ib.as_ref() {
                immersed::refill_x_ghosts(f, im);
            }
            fill_ghosts_yz(&f.grid, &mut f.prim, f.nv, vel0, &f.bc);
            f.timing.ghosts_s += lap(&mut clock);
            let dt_w = RK3_FLUX_WEIGHT[s] * dt;
            if fused {
                // fluxes and update fused per block of rows; only the domain boundary
                // faces are stored, which is all `boundary_flux` reads
                if let Some(im) = ib.as_mut() {
                    immersed::wall_fluxes::<NM>(f, &ph, im, dt_w);
                    f.timing.immersed_s += lap(&mut clock);
                }
                let nf = f.nf();
                let walls = ib
                    .as_ref()
                    .map(|im| immersed::WallPatch::new(im, f.grid.mx(), nf));
                // the next stage's primitives while each row is in cache, unless an
                // immersed body's projection changes the cells after the update
                let next = ib.is_none() && s + 1 < RK3.len();
                fused_stage::<NM>(f, &ph, walls, a, b, dt, s == 0, next);
                f.add_boundary_flux(ib.as_ref(), dt_w);
                if next {
                    std::mem::swap(&mut f.prim, &mut f.prim_next);
                    check_rows::<NM>(f, s + 1)?;
                    f.prim_valid = true;
                }
                have_prims = next;
            } else {
                for d in 0..f.grid.nd {
                    fluxes::<NM>(f, &ph, d);
                }
                f.timing.kernels_s += lap(&mut clock);
                if let Some(im) = ib.as_mut() {
                    immersed::wall_fluxes::<NM>(f, &ph, im, dt_w);
                    immersed::write_wall_fluxes(f, im);
                    f.timing.immersed_s += lap(&mut clock);
                }
                store_x_bound(f);
                f.add_boundary_flux(ib.as_ref(), dt_w);
                if f.grid.columns.is_empty() {
                    update::<NM>(f, a, b, dt);
                } else {
                    update_radial::<NM>(f, a, b, dt);
                }
            }
            f.timing.kernels_s += lap(&mut clock);
            if let Some(im) = ib.as_mut() {
                immersed::project(f, im, RK3_PROJECTION_WEIGHT[s]);
                f.timing.immersed_s += lap(&mut clock);
            }
        }
        Ok(())
    })();
    f.immersed = ib;
    result?;
    f.prim_valid = false;
    f.time += dt;
    f.steps += 1;
    f.timing.steps_s += t_step.elapsed().as_secs_f64();
    f.timing.cell_updates += f.grid.cells() as f64;
    Ok(dt)
}

/// Seconds since `clock`, which moves on to now.
#[inline]
fn lap(clock: &mut Instant) -> f64 {
    let now = Instant::now();
    let s = (now - *clock).as_secs_f64();
    *clock = now;
    s
}

impl Fluid {
    /// Adds the impulse and work of the domain boundary faces' fluxes over `dt_w` (a stage's
    /// flux weight × dt) to the boundary accumulators.
    fn add_boundary_flux(&mut self, ib: Option<&immersed::Immersed>, dt_w: f64) {
        let kind = ib.map(|im| &im.kind[..]).filter(|k| !k.is_empty());
        let bi = boundary_flux(self, kind, dt_w);
        for c in 0..3 {
            self.boundary_impulse[c] += bi[c];
        }
        self.boundary_work += bi[3];
    }
}
