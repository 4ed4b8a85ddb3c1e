//! The elastic BLT kernel of `element::element_step` on four elements at once ("lanes"), for
//! the throughput of the element pass. Every lane runs exactly the
//! operations of the scalar kernel in the same order (IEEE add, sub, mul, div and sqrt are
//! exact per lane, and nothing is fused), so the results are bit-identical to the scalar
//! path — `tests::four_lanes_equal_the_scalar_kernel` checks it. Only the elastic material
//! takes this path; a block with a degenerate element falls back to the scalar kernel, which
//! reports it. The formulas and their seed references are in `element.rs`.

use crate::element::{ElemConst, R_EINT, R_H, R_HG, R_Q, R_WPRES, RES, Section};
use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

/// Four f64 lanes; the operators act lane by lane (the compiler maps them to SIMD).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(32))]
pub struct F4(pub [f64; 4]);

impl F4 {
    #[inline(always)]
    pub fn s(x: f64) -> F4 {
        F4([x; 4])
    }
    #[inline(always)]
    pub fn sqrt(self) -> F4 {
        F4(self.0.map(f64::sqrt))
    }
    #[inline(always)]
    pub fn from_fn(mut f: impl FnMut(usize) -> f64) -> F4 {
        F4([f(0), f(1), f(2), f(3)])
    }
}

macro_rules! binop {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for F4 {
            type Output = F4;
            #[inline(always)]
            fn $f(self, b: F4) -> F4 {
                let a = self.0;
                let b = b.0;
                F4([a[0] $op b[0], a[1] $op b[1], a[2] $op b[2], a[3] $op b[3]])
            }
        }
        impl $tr<F4> for f64 {
            type Output = F4;
            #[inline(always)]
            fn $f(self, b: F4) -> F4 {
                F4::s(self).$f(b)
            }
        }
        impl $tr<f64> for F4 {
            type Output = F4;
            #[inline(always)]
            fn $f(self, b: f64) -> F4 {
                self.$f(F4::s(b))
            }
        }
    };
}
binop!(Add, add, +);
binop!(Sub, sub, -);
binop!(Mul, mul, *);
binop!(Div, div, /);

impl Neg for F4 {
    type Output = F4;
    #[inline(always)]
    fn neg(self) -> F4 {
        F4(self.0.map(|x| -x))
    }
}
impl AddAssign for F4 {
    #[inline(always)]
    fn add_assign(&mut self, b: F4) {
        *self = *self + b;
    }
}
impl SubAssign for F4 {
    #[inline(always)]
    fn sub_assign(&mut self, b: F4) {
        *self = *self - b;
    }
}

type V3 = [F4; 3];

#[inline(always)]
fn sub3(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
fn dot3(a: V3, b: V3) -> F4 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
fn cross3(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `element::Geom` of four elements.
struct Geom4 {
    e: [V3; 3],
    b1: [F4; 4],
    b2: [F4; 4],
    area: F4,
    gam: [F4; 4],
}

/// `element::geometry` lane by lane; `None` if any lane is degenerate.
#[inline(always)]
fn geometry4(x: &[V3; 4]) -> Option<Geom4> {
    let s31 = sub3(x[2], x[0]);
    let s42 = sub3(x[3], x[1]);
    let n = cross3(s31, s42);
    let nn = dot3(n, n).sqrt();
    let r3 = 1.0 / nn;
    let e3 = [n[0] * r3, n[1] * r3, n[2] * r3];
    let s21 = sub3(x[1], x[0]);
    let p = dot3(s21, e3);
    let t = [s21[0] - p * e3[0], s21[1] - p * e3[1], s21[2] - p * e3[2]];
    let tn = dot3(t, t).sqrt();
    let r1 = 1.0 / tn;
    let e1 = [t[0] * r1, t[1] * r1, t[2] * r1];
    let e2 = cross3(e3, e1);
    let c = [
        0.25 * (x[0][0] + x[1][0] + x[2][0] + x[3][0]),
        0.25 * (x[0][1] + x[1][1] + x[2][1] + x[3][1]),
        0.25 * (x[0][2] + x[1][2] + x[2][2] + x[3][2]),
    ];
    let mut xl = [F4::s(0.0); 4];
    let mut yl = [F4::s(0.0); 4];
    for i in 0..4 {
        let r = sub3(x[i], c);
        xl[i] = dot3(r, e1);
        yl[i] = dot3(r, e2);
    }
    let area = 0.5 * ((xl[2] - xl[0]) * (yl[3] - yl[1]) - (xl[3] - xl[1]) * (yl[2] - yl[0]));
    // The scalar kernel's checks: nn > 0, tn > 0, area > 0 (false for NaN too).
    let ok = (0..4).all(|l| nn.0[l] > 0.0 && tn.0[l] > 0.0 && area.0[l] > 0.0);
    if !ok {
        return None;
    }
    let inv = 0.5 / area;
    let b1 = [
        (yl[1] - yl[3]) * inv,
        (yl[2] - yl[0]) * inv,
        (yl[3] - yl[1]) * inv,
        (yl[0] - yl[2]) * inv,
    ];
    let b2 = [
        (xl[3] - xl[1]) * inv,
        (xl[0] - xl[2]) * inv,
        (xl[1] - xl[3]) * inv,
        (xl[2] - xl[0]) * inv,
    ];
    let hx = xl[0] - xl[1] + xl[2] - xl[3];
    let hy = yl[0] - yl[1] + yl[2] - yl[3];
    let h = [1.0, -1.0, 1.0, -1.0];
    let mut gam = [F4::s(0.0); 4];
    for i in 0..4 {
        gam[i] = 0.25 * (h[i] - hx * b1[i] - hy * b2[i]);
    }
    Some(Geom4 {
        e: [e1, e2, e3],
        b1,
        b2,
        area,
        gam,
    })
}

/// Node positions x_{n+1}, velocities v_{n+½} and angular velocities ω_{n+½}.
pub struct NodeState<'a> {
    pub x: &'a [[f64; 3]],
    pub v: &'a [[f64; 3]],
    pub w: &'a [[f64; 3]],
}

/// `element::element_step` for four elastic elements: `conn[l]`, `pressure[l]`, `stress[l]`
/// (nip·3 values), `res[l]`, `fe[l]` of lane l. Returns `false` — having written nothing — if
/// any of the four is degenerate.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn element_step_x4(
    conn: [[u32; 4]; 4],
    nodes: &NodeState,
    dt: f64,
    sec: &Section,
    kc: &ElemConst,
    pressure: [f64; 4],
    stress: [&mut [f64]; 4],
    res: [&mut [f64; RES]; 4],
    fe: [&mut [[f64; 6]; 4]; 4],
) -> bool {
    // Gather the nodes of the four elements into lanes.
    let z0 = F4::s(0.0);
    let mut x = [[z0; 3]; 4];
    let mut v = [[z0; 3]; 4];
    let mut w = [[z0; 3]; 4];
    for l in 0..4 {
        for i in 0..4 {
            let n = conn[l][i] as usize;
            let (xn, vn, wn) = (nodes.x[n], nodes.v[n], nodes.w[n]);
            for k in 0..3 {
                x[i][k].0[l] = xn[k];
                v[i][k].0[l] = vn[k];
                w[i][k].0[l] = wn[k];
            }
        }
    }
    let mut xm = x;
    let hdt = 0.5 * dt;
    for i in 0..4 {
        for k in 0..3 {
            xm[i][k] -= hdt * v[i][k];
        }
    }
    let Some(gm) = geometry4(&xm) else {
        return false;
    };
    let Some(g1) = geometry4(&x) else {
        return false;
    };
    let h = F4::from_fn(|l| res[l][R_H]);
    let mut vl = [[F4::s(0.0); 3]; 4];
    let mut wl = [[F4::s(0.0); 3]; 4];
    for i in 0..4 {
        for a in 0..3 {
            vl[i][a] = dot3(gm.e[a], v[i]);
        }
        for a in 0..2 {
            wl[i][a] = dot3(gm.e[a], w[i]);
        }
    }
    let (b1, b2) = (gm.b1, gm.b2);
    let mut dm = [z0; 3];
    let mut kap = [z0; 3];
    let mut gs = [z0; 2];
    let mut wsum = [z0; 2];
    let mut hq = [z0; 5];
    for i in 0..4 {
        dm[0] += b1[i] * vl[i][0];
        dm[1] += b2[i] * vl[i][1];
        dm[2] += b2[i] * vl[i][0] + b1[i] * vl[i][1];
        kap[0] += b1[i] * wl[i][1];
        kap[1] -= b2[i] * wl[i][0];
        kap[2] += b2[i] * wl[i][1] - b1[i] * wl[i][0];
        gs[0] += b1[i] * vl[i][2];
        gs[1] += b2[i] * vl[i][2];
        wsum[0] += wl[i][0];
        wsum[1] += wl[i][1];
        let gi = gm.gam[i];
        hq[0] += gi * vl[i][0];
        hq[1] += gi * vl[i][1];
        hq[2] += gi * wl[i][0];
        hq[3] += gi * wl[i][1];
        hq[4] += gi * vl[i][2];
    }
    gs[0] += 0.25 * wsum[1];
    gs[1] -= 0.25 * wsum[0];
    let area_m = gm.area;
    let mut nres = [z0; 3];
    let mut mres = [z0; 3];
    let mut de_int = z0;
    let mut dzz = z0;
    let nip = sec.nip;
    let (c, nu, gmod, nu_e) = (kc.c, kc.nu, kc.g, kc.nu_e);
    let mut st = stress;
    for k in 0..nip {
        let z = 0.5 * h * sec.zeta[k];
        let wk = 0.5 * h * sec.weight[k];
        let de = [
            (dm[0] + z * kap[0]) * dt,
            (dm[1] + z * kap[1]) * dt,
            (dm[2] + z * kap[2]) * dt,
        ];
        let mut old = [z0; 3];
        for l in 0..4 {
            for a in 0..3 {
                old[a].0[l] = st[l][3 * k + a];
            }
        }
        let ds = [
            c * (de[0] + nu * de[1]),
            c * (nu * de[0] + de[1]),
            gmod * de[2],
        ];
        let sn = [old[0] + ds[0], old[1] + ds[1], old[2] + ds[2]];
        for (l, s) in st.iter_mut().enumerate() {
            for a in 0..3 {
                s[3 * k + a] = sn[a].0[l];
            }
        }
        dzz += wk * nu_e * (sn[0] - old[0] + sn[1] - old[1]);
        de_int += wk
            * 0.5
            * ((old[0] + sn[0]) * de[0] + (old[1] + sn[1]) * de[1] + (old[2] + sn[2]) * de[2]);
        for a in 0..3 {
            nres[a] += wk * sn[a];
            mres[a] += wk * z * sn[a];
        }
    }
    let mut rs = res;
    let rget = |rs: &[&mut [f64; RES]; 4], j: usize| F4::from_fn(|l| rs[l][j]);
    let ks = kc.ks * h;
    let mut q = [z0; 2];
    for a in 0..2 {
        let old = rget(&rs, R_Q + a);
        let new = old + ks * gs[a] * dt;
        q[a] = new;
        de_int += 0.5 * (old + new) * gs[a] * dt;
    }
    de_int = de_int * area_m;
    let mut bb = z0;
    for i in 0..4 {
        bb += b1[i] * b1[i] + b2[i] * b2[i];
    }
    let h3 = h * h * h;
    let abb = area_m * bb;
    let khg = [kc.hg[0] * h * abb, kc.hg[1] * h3 * abb, kc.hg[2] * h3 * bb];
    let kk = [khg[0], khg[0], khg[1], khg[1], khg[2]];
    let mut hg = [z0; 5];
    for a in 0..5 {
        let old = rget(&rs, R_HG + a);
        let new = old + kk[a] * hq[a] * dt;
        hg[a] = new;
        de_int += 0.5 * (old + new) * hq[a] * dt;
    }
    let eint = rget(&rs, R_EINT) + de_int;
    let hnew = if sec.update_thickness {
        h * (1.0 + dzz / h)
    } else {
        h
    };
    let a = g1.area;
    let pa = 0.25 * F4(pressure) * a;
    let an = [a * nres[0], a * nres[1], a * nres[2]];
    let am = [a * mres[0], a * mres[1], a * mres[2]];
    let aq = [a * q[0], a * q[1]];
    let mut f = [[z0; 6]; 4];
    for i in 0..4 {
        let (c1, c2, gi) = (g1.b1[i], g1.b2[i], g1.gam[i]);
        let fl = [
            (c1 * an[0] + c2 * an[2]) + gi * hg[0],
            (c2 * an[1] + c1 * an[2]) + gi * hg[1],
            (c1 * aq[0] + c2 * aq[1]) + gi * hg[4] - pa,
        ];
        let ml = [
            -(c2 * am[1] + c1 * am[2] + 0.25 * aq[1]) + gi * hg[2],
            (c1 * am[0] + c2 * am[2] + 0.25 * aq[0]) + gi * hg[3],
        ];
        for k in 0..3 {
            f[i][k] = g1.e[0][k] * fl[0] + g1.e[1][k] * fl[1] + g1.e[2][k] * fl[2];
            f[i][3 + k] = g1.e[0][k] * ml[0] + g1.e[1][k] * ml[1];
        }
    }
    let mut wp = z0;
    for i in 0..4 {
        wp += pa * dot3(g1.e[2], v[i]) * dt;
    }
    for (l, fl) in fe.into_iter().enumerate() {
        for i in 0..4 {
            for k in 0..6 {
                fl[i][k] = f[i][k].0[l];
            }
        }
    }
    for (l, r) in rs.iter_mut().enumerate() {
        r[R_Q] = q[0].0[l];
        r[R_Q + 1] = q[1].0[l];
        for a in 0..5 {
            r[R_HG + a] = hg[a].0[l];
        }
        r[R_EINT] = eint.0[l];
        r[R_H] = hnew.0[l];
        if pressure[l] != 0.0 {
            r[R_WPRES] += wp.0[l];
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::{ElemInput, Material, element_step};

    /// A cheap deterministic sequence in [−1, 1).
    fn lcg(s: &mut u64) -> f64 {
        *s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    #[test]
    fn four_lanes_equal_the_scalar_kernel() {
        let mut seed = 7u64;
        for nip in [2, 3, 5] {
            for update in [false, true] {
                let sec = Section::new(nip, 5.0 / 6.0, [0.05, 0.04, 0.03], update);
                let mat = Material::Elastic {
                    youngs: 2.1e11,
                    poisson: 0.3,
                };
                let kc = ElemConst::new(&sec, &mat);
                // Sixteen nodes, four warped, distorted, moving quads over them.
                let mut x = vec![[0.0; 3]; 16];
                let mut v = vec![[0.0; 3]; 16];
                let mut w = vec![[0.0; 3]; 16];
                let base = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
                for l in 0..4 {
                    for i in 0..4 {
                        let n = 4 * l + i;
                        x[n] = [
                            base[i][0] + 0.15 * lcg(&mut seed),
                            base[i][1] + 0.15 * lcg(&mut seed),
                            0.05 * lcg(&mut seed),
                        ];
                        v[n] = [lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)];
                        w[n] = [lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)];
                    }
                }
                let conn: [[u32; 4]; 4] =
                    std::array::from_fn(|l| std::array::from_fn(|i| (4 * l + i) as u32));
                let pressure = [0.0, 1.0e5, 0.0, -3.0e4];
                let mut st: Vec<Vec<f64>> = (0..4)
                    .map(|_| (0..3 * nip).map(|_| 1e8 * lcg(&mut seed)).collect())
                    .collect();
                let mut rs: Vec<[f64; RES]> = (0..4)
                    .map(|_| {
                        let mut r = [0.0; RES];
                        for v in r.iter_mut() {
                            *v = 1e3 * lcg(&mut seed);
                        }
                        r[R_H] = 0.01 * (1.0 + 0.1 * lcg(&mut seed));
                        r
                    })
                    .collect();
                let mut fes = vec![[[0.0; 6]; 4]; 4];
                let (mut st1, mut rs1, mut fe1) = (st.clone(), rs.clone(), fes.clone());
                let dt = 1e-3;
                for l in 0..4 {
                    let cn = conn[l];
                    let inp = ElemInput {
                        x: cn.map(|n| x[n as usize]),
                        v: cn.map(|n| v[n as usize]),
                        w: cn.map(|n| w[n as usize]),
                    };
                    let mut pl = vec![0.0; nip * crate::element::PL];
                    assert!(element_step(
                        &inp,
                        dt,
                        &sec,
                        &mat,
                        &kc,
                        pressure[l],
                        &mut st1[l],
                        &mut pl,
                        &mut rs1[l],
                        &mut fe1[l],
                    ));
                }
                let nodes = NodeState {
                    x: &x,
                    v: &v,
                    w: &w,
                };
                let [s0, s1, s2, s3] = &mut st[..] else {
                    panic!("four")
                };
                let [r0, r1, r2, r3] = &mut rs[..] else {
                    panic!("four")
                };
                let [f0, f1, f2, f3] = &mut fes[..] else {
                    panic!("four")
                };
                assert!(element_step_x4(
                    conn,
                    &nodes,
                    dt,
                    &sec,
                    &kc,
                    pressure,
                    [s0, s1, s2, s3],
                    [r0, r1, r2, r3],
                    [f0, f1, f2, f3],
                ));
                // Bit for bit (to_bits, so that even the sign of a zero must agree).
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                for l in 0..4 {
                    assert_eq!(bits(&st[l]), bits(&st1[l]), "stress, nip {nip}, lane {l}");
                    assert_eq!(bits(&rs[l]), bits(&rs1[l]), "res, nip {nip}, lane {l}");
                    let fa: Vec<f64> = fes[l].iter().flatten().copied().collect();
                    let fb: Vec<f64> = fe1[l].iter().flatten().copied().collect();
                    assert_eq!(bits(&fa), bits(&fb), "forces, nip {nip}, lane {l}");
                }
                assert!(fes.iter().flatten().flatten().any(|f| *f != 0.0));
            }
        }
        // A degenerate lane makes the block refuse without writing anything.
        let sec = Section::new(3, 5.0 / 6.0, [0.05; 3], true);
        let mat = Material::Elastic {
            youngs: 1.0,
            poisson: 0.3,
        };
        let kc = ElemConst::new(&sec, &mat);
        let mut x = vec![[0.0; 3]; 16];
        for l in 0..4 {
            let s = if l == 2 { 0.0 } else { 1.0 };
            x[4 * l] = [0.0, 0.0, 0.0];
            x[4 * l + 1] = [1.0, 0.0, 0.0];
            x[4 * l + 2] = [1.0, s, 0.0];
            x[4 * l + 3] = [0.0, s, 0.0];
        }
        let z = vec![[0.0; 3]; 16];
        let nodes = NodeState {
            x: &x,
            v: &z,
            w: &z,
        };
        let conn: [[u32; 4]; 4] =
            std::array::from_fn(|l| std::array::from_fn(|i| (4 * l + i) as u32));
        let mut st = vec![vec![0.0; 9]; 4];
        let mut rs = vec![[1.0; RES]; 4];
        let mut fes = vec![[[0.0; 6]; 4]; 4];
        let [s0, s1, s2, s3] = &mut st[..] else {
            panic!("four")
        };
        let [r0, r1, r2, r3] = &mut rs[..] else {
            panic!("four")
        };
        let [f0, f1, f2, f3] = &mut fes[..] else {
            panic!("four")
        };
        assert!(!element_step_x4(
            conn,
            &nodes,
            1e-3,
            &sec,
            &kc,
            [0.0; 4],
            [s0, s1, s2, s3],
            [r0, r1, r2, r3],
            [f0, f1, f2, f3],
        ));
        assert!(rs.iter().all(|r| r.iter().all(|&v| v == 1.0)));
    }
}
