//! The time loop of the fluid node (seed 002 §2.3–§2.4, Fig. 4): primitive recovery with the
//! mixture closure, MUSCL reconstruction of primitive variables with a TVD limiter, HLLC
//! fluxes, the quasi-conservative volume-fraction update of Johnsen & Colonius (2006), and
//! the three-stage SSP Runge–Kutta scheme of Shu & Osher (seed 002 eq. 35 uses its weights).
//! rayon parallelises over rows; every reduction is per row then in row order.

use crate::boundary::fill_ghosts;
use crate::eos::Material;
use crate::grid::Grid;
use crate::immersed;
use crate::limiter::Limiter;
use crate::mixture::{self, Phase};
use crate::model::Fluid;
use crate::riemann::{FaceState, MAXF, hllc};
use protocol::{SolverError, SolverResult};
use rayon::prelude::*;

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

/// Build a face state from a primitive vector; `None` if inadmissible.
#[inline(always)]
pub fn face_state<const NM: usize>(ph: &[Phase; NM], q: &[f64; MAXF]) -> Option<FaceState<NM>> {
    let mut ar = [0.0; NM];
    let mut al = [0.0; NM];
    let mut rho = 0.0;
    let mut sa = 0.0;
    for k in 0..NM {
        ar[k] = q[k];
        rho += q[k];
        if !(q[k] >= 0.0) {
            return None;
        }
    }
    for k in 0..NM - 1 {
        let a = q[NM + 4 + k];
        if !(0.0..=1.0).contains(&a) {
            return None;
        }
        al[k] = a;
        sa += a;
    }
    // round-off may leave the last fraction a hair below zero
    al[NM - 1] = if sa > 1.0 && sa < 1.0 + 1e-12 {
        0.0
    } else {
        1.0 - sa
    };
    if !(rho > 0.0) || al[NM - 1] < 0.0 {
        return None;
    }
    let vel = [q[NM], q[NM + 1], q[NM + 2]];
    let p = q[NM + 3];
    let c2 = mixture::sound_speed2(ph, &ar, &al, rho, p);
    if !(c2 > 0.0) || !c2.is_finite() {
        return None;
    }
    let e = mixture::rhoe(ph, &ar, &al, p)
        + 0.5 * rho * (vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]);
    Some(FaceState {
        ar,
        al,
        vel,
        p,
        rho,
        e,
        c: c2.sqrt(),
    })
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

/// [`prim_row`] with a branch-free, vectorisable loop for a single ideal gas (the same
/// arithmetic, so identical values); any inadmissible cell reruns the general row to name it.
fn prim_row_fast<const NM: usize>(
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

/// Primitive variables of every interior cell; a diverged cell becomes an error naming the
/// cell, the time and the variable.
fn prim_all<const NM: usize>(f: &mut Fluid, ph: &[Phase; NM], stage: usize) -> SolverResult<()> {
    let grid = &f.grid;
    let nv = f.nv;
    let mx = grid.mx();
    let ir = grid.irange();
    f.cons
        .par_chunks(nv * mx)
        .zip(f.prim.par_chunks_mut(nv * mx))
        .zip(f.row_bad.par_iter_mut())
        .enumerate()
        .for_each(|(r, ((c, p), bad))| {
            *bad = if grid.interior_row(r) {
                prim_row_fast::<NM>(ph, c, p, mx, ir.clone())
            } else {
                None
            };
        });
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
    f.prim_valid = true;
    Ok(())
}

/// Largest Σ_d (|u_d| + c)/Δx_d over the interior cells of one row block of primitives `p`
/// (row `r`); 0 for a ghost row.
fn row_rate<const NM: usize>(grid: &Grid, ph: &[Phase; NM], p: &[f64], r: usize) -> f64 {
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
        for t in 0..n {
            let c2 = gamma * pr[t] / rho[t];
            let c = if rho[t] > 0.0 && c2 > 0.0 && c2.is_finite() {
                c2.sqrt()
            } else {
                f64::INFINITY
            };
            let mut s = 0.0;
            for d in 0..nd {
                s += (vel[d][t].abs() + c) * idx[d];
            }
            m = m.max(s);
        }
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

/// Largest Σ_d (|u_d| + c)/Δx_d over the interior (for the CFL step).
fn max_rate<const NM: usize>(f: &mut Fluid, ph: &[Phase; NM]) -> f64 {
    let grid = &f.grid;
    let nv = f.nv;
    let mx = grid.mx();
    f.prim
        .par_chunks(nv * mx)
        .zip(f.row_max.par_iter_mut())
        .enumerate()
        .for_each(|(r, (p, out))| {
            *out = row_rate::<NM>(grid, ph, p, r);
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
    let nv = f.nv;
    let mx = grid.mx();
    let ir = grid.irange();
    let rate = if f.prim_valid {
        f.prim
            .par_chunks(nv * mx)
            .enumerate()
            .map(|(r, p)| row_rate::<NM>(grid, &ph, p, r))
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
                    match prim_row_fast::<NM>(&ph, c, &mut p, mx, ir.clone()) {
                        Some(_) => f64::INFINITY,
                        None => row_rate::<NM>(grid, &ph, &p, r),
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
    /// Per-thread scratch for one line of reconstructed face values (left block, right
    /// block, each nv·mx); grows once, then reused every step (no allocation per step).
    static LINE_SCRATCH: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Limited MUSCL face values of one variable along a line: `lo[i] = q1[i] + ½σ(q1-q0,
/// q2-q1)`, `hi[i] = q2[i] - ½σ(q2-q1, q3-q2)` for i in `range`, where `qs[s][i]` is stencil
/// cell s of face i. Written as a plain slice loop so that it vectorises.
#[inline(always)]
fn recon_var<S: Fn(f64, f64) -> f64>(slope: S, qs: [&[f64]; 4], lo: &mut [f64], hi: &mut [f64]) {
    let n = lo.len();
    let (q0, q1, q2, q3) = (&qs[0][..n], &qs[1][..n], &qs[2][..n], &qs[3][..n]);
    let hi = &mut hi[..n];
    for i in 0..n {
        let dm = q1[i] - q0[i];
        let dc = q2[i] - q1[i];
        let dp = q3[i] - q2[i];
        lo[i] = q1[i] + 0.5 * slope(dm, dc);
        hi[i] = q2[i] - 0.5 * slope(dc, dp);
    }
}

/// MUSCL-reconstructed HLLC fluxes along one line of faces. `rows[s]` holds stencil cell s
/// (s = 0..3 around the face between cells 1 and 2) at x index `i + sh[s] - 1`.
/// Two passes: the limited face values of the whole line (vectorisable, one limiter call per
/// face side), then the Riemann solve of every face.
#[allow(clippy::too_many_arguments)]
fn flux_line<const NM: usize, const D: usize>(
    ph: &[Phase; NM],
    lim: Limiter,
    rows: [&[f64]; 4],
    sh: [usize; 4],
    out: &mut [f64],
    mx: usize,
    irange: std::ops::Range<usize>,
) {
    let nv = 2 * NM + 3;
    let (i0, i1) = (irange.start, irange.end);
    let len = i1 - i0;
    LINE_SCRATCH.with(|cell| {
        let mut buf = cell.borrow_mut();
        if buf.len() < (2 * nv + 4) * len {
            buf.resize((2 * nv + 4) * len, 0.0);
        }
        let (lb, rest) = buf.split_at_mut(nv * len);
        let (rb, extra) = rest.split_at_mut(nv * len);
        for v in 0..nv {
            let qs: [&[f64]; 4] =
                std::array::from_fn(|s| &rows[s][v * mx + i0 + sh[s] - 1..v * mx + i1 + sh[s] - 1]);
            let lo = &mut lb[v * len..(v + 1) * len];
            let hi = &mut rb[v * len..(v + 1) * len];
            match lim {
                Limiter::Minmod => recon_var(crate::limiter::minmod, qs, lo, hi),
                Limiter::VanLeer => recon_var(crate::limiter::van_leer, qs, lo, hi),
                Limiter::Mc => recon_var(crate::limiter::mc, qs, lo, hi),
            }
        }
        // single ideal gas: sound speed and total energy of every face side in one
        // vectorisable pass (the same arithmetic as `face_state`, so identical values);
        // c = NaN marks a side `face_state` would reject, which then takes the general path
        let ideal = match (&ph[0].eos, NM) {
            (Material::Ideal(g), 1) => Some((g.gamma, ph[0].inv_g, ph[0].off)),
            _ => None,
        };
        let (ce, _) = extra.split_at_mut(4 * len);
        if let Some((gamma, inv_g, off)) = ideal {
            let (cl, rest) = ce.split_at_mut(len);
            let (el, rest) = rest.split_at_mut(len);
            let (cr, er) = rest.split_at_mut(len);
            for (qb, c, e) in [(&*lb, cl, el), (&*rb, cr, er)] {
                let (rho, rest) = qb.split_at(len);
                let (vx, rest) = rest.split_at(len);
                let (vy, rest) = rest.split_at(len);
                let (vz, pr) = rest.split_at(len);
                let e = &mut e[..len];
                let pr = &pr[..len];
                for t in 0..len {
                    let (r, p) = (rho[t], pr[t]);
                    let c2 = gamma * p / r;
                    let ok = r > 0.0 && c2 > 0.0 && c2.is_finite();
                    c[t] = if ok { c2.sqrt() } else { f64::NAN };
                    e[t] = (p * inv_g + 1.0 * off)
                        + 0.5 * r * (vx[t] * vx[t] + vy[t] * vy[t] + vz[t] * vz[t]);
                }
            }
        }
        let (cl, rest) = ce.split_at(len);
        let (el, rest) = rest.split_at(len);
        let (cr, er) = rest.split_at(len);
        if ideal.is_some() {
            // every face at once (vectorised); faces with a rejected side are redone below
            let (o0, rest) = out.split_at_mut(mx);
            let (o1, rest) = rest.split_at_mut(mx);
            let (o2, rest) = rest.split_at_mut(mx);
            let (o3, rest) = rest.split_at_mut(mx);
            let (o4, o5) = rest.split_at_mut(mx);
            let lsides: [&[f64]; 5] = std::array::from_fn(|v| &lb[v * len..(v + 1) * len]);
            let rsides: [&[f64]; 5] = std::array::from_fn(|v| &rb[v * len..(v + 1) * len]);
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
        }
        for (t, i) in (i0..i1).enumerate() {
            if ideal.is_some() && !cl[t].is_nan() && !cr[t].is_nan() {
                continue;
            }
            let mut l = [0.0; MAXF];
            let mut r = [0.0; MAXF];
            for v in 0..nv {
                l[v] = lb[v * len + t];
                r[v] = rb[v * len + t];
            }
            let (sl, sr) = match (face_state::<NM>(ph, &l), face_state::<NM>(ph, &r)) {
                (Some(a), Some(b)) => (a, b),
                // first order where the reconstruction leaves the admissible set
                _ => {
                    let mut q1 = [0.0; MAXF];
                    let mut q2 = [0.0; MAXF];
                    for v in 0..nv {
                        q1[v] = rows[1][v * mx + i + sh[1] - 1];
                        q2[v] = rows[2][v * mx + i + sh[2] - 1];
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
    });
}

/// Fluxes through every interior face in direction d.
fn fluxes<const NM: usize>(f: &mut Fluid, ph: &[Phase; NM], d: usize) {
    let grid = &f.grid;
    let nv = f.nv;
    let nf = nv + 1;
    let mx = grid.mx();
    let lim = f.limiter;
    let prim = &f.prim;
    let g = grid.g;
    let n = grid.n;
    let stride = if d == 0 { 0 } else { grid.row_stride(d) };
    let rowblk = nv * mx;
    f.flux[d]
        .par_chunks_mut(nf * mx)
        .enumerate()
        .for_each(|(r, out)| {
            let (j, k) = grid.jk(r);
            match d {
                0 => {
                    if !grid.interior_row(r) {
                        return;
                    }
                    let row = &prim[r * rowblk..(r + 1) * rowblk];
                    flux_line::<NM, 0>(
                        ph,
                        lim,
                        [row; 4],
                        [0, 1, 2, 3],
                        out,
                        mx,
                        g[0] - 1..g[0] + n[0],
                    );
                }
                _ => {
                    // faces between row r and the next row along d
                    let (t, other_ok) = if d == 1 {
                        (j, k >= g[2] && k < g[2] + n[2])
                    } else {
                        (k, j >= g[1] && j < g[1] + n[1])
                    };
                    if !other_ok || t + 1 < g[d] || t >= g[d] + n[d] {
                        return;
                    }
                    let rr = |o: isize| -> &[f64] {
                        let q = (r as isize + o * stride as isize) as usize;
                        &prim[q * rowblk..(q + 1) * rowblk]
                    };
                    let rows = [rr(-1), rr(0), rr(1), rr(2)];
                    if d == 1 {
                        flux_line::<NM, 1>(ph, lim, rows, [1; 4], out, mx, grid.irange());
                    } else {
                        flux_line::<NM, 2>(ph, lim, rows, [1; 4], out, mx, grid.irange());
                    }
                }
            }
        });
}

/// Residual and RK stage update of every interior cell: U = a U0 + b (U + dt L(U)).
fn update<const NM: usize>(f: &mut Fluid, a: f64, b: f64, dt: f64) {
    let grid = &f.grid;
    let nv = f.nv;
    let nf = nv + 1;
    let mx = grid.mx();
    let nd = grid.nd;
    let idx = [1.0 / grid.dx[0], 1.0 / grid.dx[1], 1.0 / grid.dx[2]];
    let ir = grid.irange();
    let fl = &f.flux;
    let fb = nf * mx;
    f.cons
        .par_chunks_mut(nv * mx)
        .zip(f.cons0.par_chunks(nv * mx))
        .enumerate()
        .for_each(|(r, (u, u0))| {
            if !grid.interior_row(r) {
                return;
            }
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
            let uf = nv * mx;
            let (lo, hi) = (ir.start, ir.end);
            // face velocities (Johnsen–Colonius) for the α rows
            let ufx = &fx[uf + lo - 1..uf + hi];
            let (ufy, ufym) = (&fy[uf + lo..uf + hi], &fym[uf + lo..uf + hi]);
            let (ufz, ufzm) = (&fz[uf + lo..uf + hi], &fzm[uf + lo..uf + hi]);
            for v in 0..nv {
                let o = v * mx;
                let is_alpha = v >= NM + 4;
                // slices of exactly n (n + 1 for x faces) so the loop has no bounds checks
                let uv = &mut u[o + lo..o + hi];
                let u0v = &u0[o + lo..o + hi];
                let fxv = &fx[o + lo - 1..o + hi];
                let (fyv, fymv) = (&fy[o + lo..o + hi], &fym[o + lo..o + hi]);
                let (fzv, fzmv) = (&fz[o + lo..o + hi], &fzm[o + lo..o + hi]);
                let fs = [fxv, fyv, fymv, fzv, fzmv];
                let uf = [ufx, ufy, ufym, ufz, ufzm];
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
        });
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

/// Impulse on the gas of the fluxes through the domain boundary faces over `dt_w`.
fn boundary_impulse(f: &Fluid, dt_w: f64) -> [f64; 3] {
    let grid = &f.grid;
    let nm = f.nmat();
    let nf = f.nf();
    let mx = grid.mx();
    let g = grid.g;
    let n = grid.n;
    let mut imp = [0.0; 3];
    for d in 0..grid.nd {
        let area = grid.face_area(d);
        for c in 0..3 {
            let v = nm + c;
            let mut lo = 0.0;
            let mut hi = 0.0;
            for r in 0..grid.rows() {
                let (j, k) = grid.jk(r);
                let fr = &f.flux[d][r * nf * mx..(r + 1) * nf * mx];
                match d {
                    0 => {
                        if grid.interior_row(r) {
                            lo += fr[v * mx + g[0] - 1];
                            hi += fr[v * mx + g[0] + n[0] - 1];
                        }
                    }
                    _ => {
                        let (t, other_ok) = if d == 1 {
                            (j, k >= g[2] && k < g[2] + n[2])
                        } else {
                            (k, j >= g[1] && j < g[1] + n[1])
                        };
                        if !other_ok {
                            continue;
                        }
                        if t == g[d] - 1 {
                            lo += fr[v * mx + g[0]..v * mx + g[0] + n[0]].iter().sum::<f64>();
                        } else if t == g[d] + n[d] - 1 {
                            hi += fr[v * mx + g[0]..v * mx + g[0] + n[0]].iter().sum::<f64>();
                        }
                    }
                }
            }
            imp[c] += dt_w * area * (lo - hi);
        }
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
    let chunk = f.nv * f.grid.mx();
    f.cons0
        .par_chunks_mut(chunk)
        .zip(f.cons.par_chunks(chunk))
        .for_each(|(a, b)| a.copy_from_slice(b));
    let mut ib = f.immersed.take();
    let result = (|| -> SolverResult<()> {
        for (s, &(a, b)) in RK3.iter().enumerate() {
            if s > 0 {
                prim_all::<NM>(f, &ph, s)?;
            }
            if let Some(im) = ib.as_ref() {
                immersed::fill_solid_prims(f, im);
            }
            let vel0 = f.vel0();
            fill_ghosts(&f.grid, &mut f.prim, f.nv, vel0, &f.bc);
            for d in 0..f.grid.nd {
                fluxes::<NM>(f, &ph, d);
            }
            if let Some(im) = ib.as_mut() {
                immersed::wall_fluxes::<NM>(f, &ph, im, RK3_FLUX_WEIGHT[s] * dt);
            }
            let bi = boundary_impulse(f, RK3_FLUX_WEIGHT[s] * dt);
            for c in 0..3 {
                f.boundary_impulse[c] += bi[c];
            }
            update::<NM>(f, a, b, dt);
            if let Some(im) = ib.as_mut() {
                immersed::project(f, im, RK3_PROJECTION_WEIGHT[s]);
            }
        }
        Ok(())
    })();
    f.immersed = ib;
    result?;
    f.prim_valid = false;
    f.time += dt;
    f.steps += 1;
    Ok(dt)
}
