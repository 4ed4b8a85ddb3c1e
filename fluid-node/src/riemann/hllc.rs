//! HLLC approximate Riemann solver (Toro, Spruce & Speares 1994; seed 002 §2.3) for the
//! five-equation model, with the face velocity and volume-fraction flux of Johnsen &
//! Colonius (2006) so that the non-conservative α equation keeps pressure equilibrium at
//! material interfaces. Written mirror-symmetrically: F(L, R) and the mirrored problem give
//! fluxes equal up to sign exactly (wave speeds from negations, star speed with symmetric
//! grouping).

use super::{FaceState, MAXF};

/// Flux in direction `d` through a face with left state `l` and right state `r`. Output in
/// conserved ordering: [α_kρ_k (NM), m_x, m_y, m_z, E, α_k flux (NM-1), face velocity].
/// Entries of the α block hold (u α)_face; the last entry holds u_face (Johnsen–Colonius).
#[inline(always)]
pub fn flux<const NM: usize>(l: &FaceState<NM>, r: &FaceState<NM>, d: usize) -> [f64; MAXF] {
    match d {
        0 => flux_dir::<NM, 0>(l, r),
        1 => flux_dir::<NM, 1>(l, r),
        _ => flux_dir::<NM, 2>(l, r),
    }
}

/// [`flux`] with the normal direction `D` fixed at compile time (the hot-loop form: every
/// component index is then a constant and the flux vector stays in registers).
#[inline(always)]
pub fn flux_dir<const NM: usize, const D: usize>(
    l: &FaceState<NM>,
    r: &FaceState<NM>,
) -> [f64; MAXF] {
    let d = D;
    let ul = l.vel[d];
    let ur = r.vel[d];
    // Davis wave-speed estimates
    let sl = (ul - l.c).min(ur - r.c);
    let sr = (ul + l.c).max(ur + r.c);
    let ml = l.rho * (sl - ul);
    let mr = r.rho * (sr - ur);
    // s* = (pR - pL + ρL uL (sL - uL) - ρR uR (sR - uR)) / (ρL (sL - uL) - ρR (sR - uR))
    let num = (r.p - l.p) + (ml * ul - mr * ur);
    let den = ml - mr;
    let ss = num / den;
    let mut f = [0.0; MAXF];
    if ss >= 0.0 {
        side::<NM, D>(l, sl, ss, &mut f);
    } else {
        side::<NM, D>(r, sr, ss, &mut f);
    }
    f
}

/// Flux of one side: F_K if the fan is entirely on the other side of the face, F*_K
/// otherwise (F*_K = F_K + s_K (U*_K - U_K)).
#[inline(always)]
fn side<const NM: usize, const D: usize>(q: &FaceState<NM>, sk: f64, ss: f64, f: &mut [f64; MAXF]) {
    let d = D;
    let un = q.vel[d];
    let nf = 2 * NM + 3;
    // physical flux
    for k in 0..NM {
        f[k] = q.ar[k] * un;
    }
    for c in 0..3 {
        f[NM + c] = q.rho * q.vel[c] * un;
    }
    f[NM + d] += q.p;
    f[NM + 3] = (q.e + q.p) * un;
    for k in 0..NM - 1 {
        f[NM + 4 + k] = q.al[k] * un;
    }
    f[nf] = un;
    // the fan crosses the face: add s_K (U*_K - U_K)
    let crosses = if sk < 0.0 {
        0.0 <= ss && sk < 0.0
    } else {
        ss < 0.0 && sk > 0.0
    };
    if crosses {
        let chi = (sk - un) / (sk - ss);
        let sc = sk * (chi - 1.0);
        for k in 0..NM {
            f[k] += sc * q.ar[k];
        }
        for c in 0..3 {
            f[NM + c] += sc * q.rho * q.vel[c];
        }
        f[NM + d] += sk * chi * q.rho * (ss - un);
        let estar = chi * (q.e + (ss - un) * (q.rho * ss + q.p / (sk - un)));
        f[NM + 3] += sk * (estar - q.e);
        for k in 0..NM - 1 {
            f[NM + 4 + k] += sc * q.al[k];
        }
        f[nf] += sc;
    }
}

/// [`flux_dir`] for a single ideal gas over a whole line of faces, structure of arrays:
/// `l`, `r` hold the face sides' [ρ, u, v, w, p], `cl`/`cr` their sound speeds and `el`/`er`
/// their total energies per volume; `out` receives [ρ flux, m_x, m_y, m_z, E, u_face].
/// The same operations in the same order as `flux_dir` + `side` (so identical values), with
/// the side choice and the fan correction as selects instead of branches so that the loop
/// vectorises (the three divisions per face are most of the solver's time).
#[inline(always)]
pub fn flux_line_ideal<const D: usize>(
    l: [&[f64]; 5],
    r: [&[f64]; 5],
    cl: &[f64],
    el: &[f64],
    cr: &[f64],
    er: &[f64],
    out: [&mut [f64]; 6],
) {
    let n = cl.len();
    let l: [&[f64]; 5] = std::array::from_fn(|v| &l[v][..n]);
    let r: [&[f64]; 5] = std::array::from_fn(|v| &r[v][..n]);
    let (el, cr, er) = (&el[..n], &cr[..n], &er[..n]);
    let [o0, o1, o2, o3, o4, o5] = out;
    let (o0, o1, o2, o3, o4, o5) = (
        &mut o0[..n],
        &mut o1[..n],
        &mut o2[..n],
        &mut o3[..n],
        &mut o4[..n],
        &mut o5[..n],
    );
    for t in 0..n {
        let (rl, rr) = (l[0][t], r[0][t]);
        let vl = [l[1][t], l[2][t], l[3][t]];
        let vr = [r[1][t], r[2][t], r[3][t]];
        let (pl, pr) = (l[4][t], r[4][t]);
        let (ul, ur) = (vl[D], vr[D]);
        // min / max of finite values (both sides admissible: finite c, ρ > 0)
        let (a, b) = (ul - cl[t], ur - cr[t]);
        let sl = if b < a { b } else { a };
        let (a, b) = (ul + cl[t], ur + cr[t]);
        let sr = if b > a { b } else { a };
        let ml = rl * (sl - ul);
        let mr = rr * (sr - ur);
        let num = (pr - pl) + (ml * ul - mr * ur);
        let den = ml - mr;
        let ss = num / den;
        let left = ss >= 0.0;
        let rho = if left { rl } else { rr };
        let vel = [
            if left { vl[0] } else { vr[0] },
            if left { vl[1] } else { vr[1] },
            if left { vl[2] } else { vr[2] },
        ];
        let p = if left { pl } else { pr };
        let e = if left { el[t] } else { er[t] };
        let sk = if left { sl } else { sr };
        let un = vel[D];
        let f0 = rho * un;
        let mut fm = [rho * vel[0] * un, rho * vel[1] * un, rho * vel[2] * un];
        fm[D] += p;
        let fe = (e + p) * un;
        let crosses = (sk < 0.0 && 0.0 <= ss) || (ss < 0.0 && sk > 0.0);
        let chi = (sk - un) / (sk - ss);
        let sc = sk * (chi - 1.0);
        let mut gm = fm;
        for c in 0..3 {
            gm[c] += sc * rho * vel[c];
        }
        gm[D] += sk * chi * rho * (ss - un);
        let estar = chi * (e + (ss - un) * (rho * ss + p / (sk - un)));
        o0[t] = if crosses { f0 + sc * rho } else { f0 };
        o1[t] = if crosses { gm[0] } else { fm[0] };
        o2[t] = if crosses { gm[1] } else { fm[1] };
        o3[t] = if crosses { gm[2] } else { fm[2] };
        o4[t] = if crosses { fe + sk * (estar - e) } else { fe };
        o5[t] = if crosses { un + sc } else { un };
    }
}
