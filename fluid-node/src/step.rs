//! The time loop of the fluid node (seed 002 §2.3–§2.4, Fig. 4): primitive recovery with the
//! mixture closure, MUSCL reconstruction of primitive variables with a TVD limiter, HLLC
//! fluxes, the quasi-conservative volume-fraction update of Johnsen & Colonius (2006), and
//! the three-stage SSP Runge–Kutta scheme of Shu & Osher (seed 002 eq. 35 uses its weights).
//! rayon parallelises over rows; every reduction is per row then in row order.

use crate::boundary::fill_ghosts;
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
                prim_row::<NM>(ph, c, p, mx, ir.clone())
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

/// Largest Σ_d (|u_d| + c)/Δx_d over the interior (for the CFL step).
fn max_rate<const NM: usize>(f: &mut Fluid, ph: &[Phase; NM]) -> f64 {
    let grid = &f.grid;
    let nv = f.nv;
    let mx = grid.mx();
    let nd = grid.nd;
    let idx = [1.0 / grid.dx[0], 1.0 / grid.dx[1], 1.0 / grid.dx[2]];
    let ir = grid.irange();
    f.prim
        .par_chunks(nv * mx)
        .zip(f.row_max.par_iter_mut())
        .enumerate()
        .for_each(|(r, (p, out))| {
            let mut m = 0.0_f64;
            if grid.interior_row(r) {
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
            *out = m;
        });
    f.row_max.iter().fold(0.0, |a, &b| a.max(b))
}

/// MUSCL-reconstructed HLLC fluxes along one line of faces. `rows[s]` holds stencil cell s
/// (s = 0..3 around the face between cells 1 and 2) at x index `i + sh[s] - 1`.
#[allow(clippy::too_many_arguments)]
fn flux_line<const NM: usize>(
    ph: &[Phase; NM],
    lim: Limiter,
    d: usize,
    rows: [&[f64]; 4],
    sh: [usize; 4],
    out: &mut [f64],
    mx: usize,
    irange: std::ops::Range<usize>,
) {
    let nv = 2 * NM + 3;
    for i in irange {
        let mut q = [[0.0; MAXF]; 4];
        for s in 0..4 {
            let o = i + sh[s] - 1;
            for v in 0..nv {
                q[s][v] = rows[s][v * mx + o];
            }
        }
        let mut l = [0.0; MAXF];
        let mut r = [0.0; MAXF];
        for v in 0..nv {
            let dm = q[1][v] - q[0][v];
            let dc = q[2][v] - q[1][v];
            let dp = q[3][v] - q[2][v];
            l[v] = q[1][v] + 0.5 * lim.slope(dm, dc);
            r[v] = q[2][v] - 0.5 * lim.slope(dc, dp);
        }
        let (sl, sr) = match (face_state::<NM>(ph, &l), face_state::<NM>(ph, &r)) {
            (Some(a), Some(b)) => (a, b),
            // first order where the reconstruction leaves the admissible set
            _ => match (face_state::<NM>(ph, &q[1]), face_state::<NM>(ph, &q[2])) {
                (Some(a), Some(b)) => (a, b),
                _ => {
                    for v in 0..=nv {
                        out[v * mx + i] = f64::NAN;
                    }
                    continue;
                }
            },
        };
        let fl = hllc::flux::<NM>(&sl, &sr, d);
        for v in 0..=nv {
            out[v * mx + i] = fl[v];
        }
    }
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
                    flux_line::<NM>(
                        ph,
                        lim,
                        0,
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
                    flux_line::<NM>(
                        ph,
                        lim,
                        d,
                        [rr(-1), rr(0), rr(1), rr(2)],
                        [1, 1, 1, 1],
                        out,
                        mx,
                        grid.irange(),
                    );
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
            for v in 0..nv {
                let o = v * mx;
                let is_alpha = v >= NM + 4;
                for i in ir.clone() {
                    let mut dfx = fx[o + i] - fx[o + i - 1];
                    if is_alpha {
                        dfx -= u[o + i] * (fx[uf + i] - fx[uf + i - 1]);
                    }
                    let mut res = -dfx * idx[0];
                    if nd > 1 {
                        let mut dfy = fy[o + i] - fym[o + i];
                        if is_alpha {
                            dfy -= u[o + i] * (fy[uf + i] - fym[uf + i]);
                        }
                        res -= dfy * idx[1];
                    }
                    if nd > 2 {
                        let mut dfz = fz[o + i] - fzm[o + i];
                        if is_alpha {
                            dfz -= u[o + i] * (fz[uf + i] - fzm[uf + i]);
                        }
                        res -= dfz * idx[2];
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
