//! The Belytschko–Lin–Tsay four-node shell kernel: corotational frame, one-point in-plane
//! quadrature, Gauss points through the thickness, Belytschko–Tsay hourglass control. Free
//! functions over one element's data; the loop over elements is in `step.rs`. It evaluates the
//! internal force F_int of the macro-scale shells (seed 004 eq. 21, 26) in rate form.
//!
//! Kinematics (local frame ê₁, ê₂, ê₃; θ̂ the nodal angular velocities, z through the thickness):
//!   d̂x = Σ b1_I v̂x_I + z Σ b1_I θ̂y_I,  d̂y = Σ b2_I v̂y_I − z Σ b2_I θ̂x_I,
//!   γ̂xy = Σ (b2_I v̂x_I + b1_I v̂y_I) + z Σ (b2_I θ̂y_I − b1_I θ̂x_I),
//!   γ̂xz = Σ b1_I v̂z_I + ¼ Σ θ̂y_I,      γ̂yz = Σ b2_I v̂z_I − ¼ Σ θ̂x_I,
//! and the nodal forces are their power conjugates (so the element never creates energy).
//! Strain rates use the mid-step geometry x_{n+½} (a rigid rotation then gives exactly zero
//! strain, the Hughes–Winget property); forces use the geometry at t_{n+1}.

use mechanics::j2_plane_stress::{J2PlaneStress, PlaneStressPoint};
use mechanics::tensor::{Vector3, vec3};

/// Largest number of through-thickness integration points.
pub const MAX_IP: usize = 5;
/// Per-element scalar state: [Qx, Qy, hg×5, internal energy, pressure work, thickness].
pub const RES: usize = 10;
pub const R_Q: usize = 0;
pub const R_HG: usize = 2;
pub const R_EINT: usize = 7;
pub const R_WPRES: usize = 8;
pub const R_H: usize = 9;
/// Plastic state per integration point: back stress (3) and equivalent plastic strain.
pub const PL: usize = 4;

/// The material of the shell section.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    Elastic { youngs: f64, poisson: f64 },
    J2(J2PlaneStress),
}

impl Material {
    pub fn youngs(&self) -> f64 {
        match self {
            Material::Elastic { youngs, .. } => *youngs,
            Material::J2(m) => m.youngs,
        }
    }
    pub fn poisson(&self) -> f64 {
        match self {
            Material::Elastic { poisson, .. } => *poisson,
            Material::J2(m) => m.poisson,
        }
    }
}

/// Section and element constants shared by every element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Section {
    pub nip: usize,
    /// Gauss points ζ ∈ (−1, 1) and weights (sum 2).
    pub zeta: [f64; MAX_IP],
    pub weight: [f64; MAX_IP],
    pub shear_factor: f64,
    pub hg_membrane: f64,
    pub hg_bending: f64,
    pub hg_transverse: f64,
    pub update_thickness: bool,
}

impl Section {
    pub fn new(nip: usize, shear_factor: f64, hg: [f64; 3], update_thickness: bool) -> Self {
        let (zeta, weight) = gauss(nip);
        Section {
            nip,
            zeta,
            weight,
            shear_factor,
            hg_membrane: hg[0],
            hg_bending: hg[1],
            hg_transverse: hg[2],
            update_thickness,
        }
    }
}

/// Gauss–Legendre points and weights on [−1, 1] for 1..=5 points.
pub fn gauss(n: usize) -> ([f64; MAX_IP], [f64; MAX_IP]) {
    let mut z = [0.0; MAX_IP];
    let mut w = [0.0; MAX_IP];
    let (pz, pw): (&[f64], &[f64]) = match n {
        1 => (&[0.0], &[2.0]),
        2 => {
            let a = 1.0 / 3f64.sqrt();
            z[..2].copy_from_slice(&[-a, a]);
            w[..2].copy_from_slice(&[1.0, 1.0]);
            return (z, w);
        }
        3 => {
            let a = 0.6f64.sqrt();
            z[..3].copy_from_slice(&[-a, 0.0, a]);
            w[..3].copy_from_slice(&[5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0]);
            return (z, w);
        }
        4 => {
            let a = (3.0 / 7.0 - 2.0 / 7.0 * (6.0f64 / 5.0).sqrt()).sqrt();
            let b = (3.0 / 7.0 + 2.0 / 7.0 * (6.0f64 / 5.0).sqrt()).sqrt();
            let wa = (18.0 + 30f64.sqrt()) / 36.0;
            let wb = (18.0 - 30f64.sqrt()) / 36.0;
            z[..4].copy_from_slice(&[-b, -a, a, b]);
            w[..4].copy_from_slice(&[wb, wa, wa, wb]);
            return (z, w);
        }
        _ => {
            let a = (5.0 - 2.0 * (10.0f64 / 7.0).sqrt()).sqrt() / 3.0;
            let b = (5.0 + 2.0 * (10.0f64 / 7.0).sqrt()).sqrt() / 3.0;
            let w0 = 128.0 / 225.0;
            let wa = (322.0 + 13.0 * 70f64.sqrt()) / 900.0;
            let wb = (322.0 - 13.0 * 70f64.sqrt()) / 900.0;
            z.copy_from_slice(&[-b, -a, 0.0, a, b]);
            w.copy_from_slice(&[wb, wa, w0, wa, wb]);
            return (z, w);
        }
    };
    z[..1].copy_from_slice(pz);
    w[..1].copy_from_slice(pw);
    (z, w)
}

/// Corotational frame and one-point shape-function derivatives of one element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geom {
    /// Rows ê₁, ê₂, ê₃ (ê₁ along side 1–2 projected on the element plane, ê₃ = normal from
    /// the diagonals).
    pub e: [[f64; 3]; 3],
    pub b1: [f64; 4],
    pub b2: [f64; 4],
    pub area: f64,
    /// Belytschko–Tsay hourglass shape vector γ = ¼[h − (h·x̂) b1 − (h·ŷ) b2], h = (1,−1,1,−1).
    pub gam: [f64; 4],
    /// Nodal coordinates in the local frame (centroid origin).
    pub xl: [f64; 4],
    pub yl: [f64; 4],
}

/// Frame and B-matrix at the positions `x`; `None` if the element is degenerate (zero or
/// negative projected area).
#[inline(always)]
pub fn geometry(x: &[[f64; 3]; 4]) -> Option<Geom> {
    let x = x.map(Vector3::from);
    let n = (x[2] - x[0]).cross(&(x[3] - x[1]));
    let nn = n.norm();
    if nn.is_nan() || nn <= 0.0 {
        return None;
    }
    let e3 = n * (1.0 / nn);
    let s21 = x[1] - x[0];
    let t = s21 - e3 * s21.dot(&e3);
    let tn = t.norm();
    if tn.is_nan() || tn <= 0.0 {
        return None;
    }
    let e1 = t * (1.0 / tn);
    let e2 = e3.cross(&e1);
    let c = (x[0] + x[1] + x[2] + x[3]) * 0.25;
    let mut xl = [0.0; 4];
    let mut yl = [0.0; 4];
    for i in 0..4 {
        let r = x[i] - c;
        xl[i] = r.dot(&e1);
        yl[i] = r.dot(&e2);
    }
    let area = 0.5 * ((xl[2] - xl[0]) * (yl[3] - yl[1]) - (xl[3] - xl[1]) * (yl[2] - yl[0]));
    if area.is_nan() || area <= 0.0 {
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
    let mut gam = [0.0; 4];
    for i in 0..4 {
        gam[i] = 0.25 * (h[i] - hx * b1[i] - hy * b2[i]);
    }
    Some(Geom {
        e: [e1.into(), e2.into(), e3.into()],
        b1,
        b2,
        area,
        gam,
        xl,
        yl,
    })
}

/// Hourglass stiffnesses [membrane (×2), bending (×2), transverse] of an element.
#[inline]
fn hourglass_stiffness(sec: &Section, e: f64, g: f64, h: f64, geo: &Geom) -> [f64; 3] {
    let bb: f64 = (0..4)
        .map(|i| geo.b1[i] * geo.b1[i] + geo.b2[i] * geo.b2[i])
        .sum();
    let abb = geo.area * bb;
    [
        sec.hg_membrane * e * h * abb,
        sec.hg_bending * e * h * h * h / 12.0 * abb,
        sec.hg_transverse * sec.shear_factor * g * h * h * h / 12.0 * bb,
    ]
}

/// Largest eigenvalue of a 3×3 matrix with real, non-negative eigenvalues (trigonometric
/// solution of the characteristic cubic; used on C·BBᵀ, similar to a symmetric PSD matrix).
fn lambda_max3(p: [[f64; 3]; 3]) -> f64 {
    let q = (p[0][0] + p[1][1] + p[2][2]) / 3.0;
    let mut b = p;
    for i in 0..3 {
        b[i][i] -= q;
    }
    // tr(B²)/6 = Σ (λ − q)²/6 for any matrix (similarity invariant).
    let mut tr2 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            tr2 += b[i][j] * b[j][i];
        }
    }
    let p2 = (tr2 / 6.0).max(0.0);
    if p2 <= 1e-30 * q * q {
        return q;
    }
    let pp = p2.sqrt();
    let det = b[0][0] * (b[1][1] * b[2][2] - b[1][2] * b[2][1])
        - b[0][1] * (b[1][0] * b[2][2] - b[1][2] * b[2][0])
        + b[0][2] * (b[1][0] * b[2][1] - b[1][1] * b[2][0]);
    let r = (det / (2.0 * pp * pp * pp)).clamp(-1.0, 1.0);
    q + 2.0 * pp * (r.acos() / 3.0).cos()
}

/// Element stiffness estimates for the stable step, each ¼ m_e ω_e² of a DOF block of the
/// flat element with lumped mass: [membrane (u, v, exact largest eigenvalue of the one-point
/// membrane stiffness plus membrane hourglass), transverse (w, shear + hourglass),
/// rotational (θ, bending + shear + hourglass)]. The membrane block is decoupled from the
/// (w, θ) block, and a PSD block matrix has λ_max ≤ λ_max(ww) + λ_max(θθ), so a node's
/// squared frequency is bounded by max(Σ s_m/m, Σ s_w/m + Σ s_θ/I) (Gershgorin over the
/// elements: the mesh's λ_max never exceeds the largest element one).
#[inline]
pub fn stiffness_estimates(sec: &Section, mat: &Material, h: f64, geo: &Geom) -> [f64; 3] {
    let e = mat.youngs();
    let nu = mat.poisson();
    let g = e / (2.0 * (1.0 + nu));
    let (mut s11, mut s22, mut s12) = (0.0, 0.0, 0.0);
    for i in 0..4 {
        s11 += geo.b1[i] * geo.b1[i];
        s22 += geo.b2[i] * geo.b2[i];
        s12 += geo.b1[i] * geo.b2[i];
    }
    let bb = s11 + s22;
    let gg: f64 = geo.gam.iter().map(|x| x * x).sum();
    let k = hourglass_stiffness(sec, e, g, h, geo);
    let a = geo.area;
    // C (plane stress, engineering shear) times BBᵀ.
    let c = e / (1.0 - nu * nu);
    let cm = [[c, c * nu, 0.0], [c * nu, c, 0.0], [0.0, 0.0, g]];
    let bbt = [[s11, 0.0, s12], [0.0, s22, s12], [s12, s12, bb]];
    let mut p = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            p[i][j] = (0..3).map(|l| cm[i][l] * bbt[l][j]).sum();
        }
    }
    let memb = h * a * lambda_max3(p) + k[0] * gg;
    let trans = sec.shear_factor * g * h * a * bb + k[2] * gg;
    let d = e * h * h * h / (12.0 * (1.0 - nu * nu));
    let rot = a * (d * bb + 0.25 * sec.shear_factor * g * h) + k[1] * gg;
    [memb, trans, rot]
}

/// Everything one element needs from the nodes.
pub struct ElemInput {
    /// Positions at t_{n+1}.
    pub x: [[f64; 3]; 4],
    /// Velocities v_{n+½}.
    pub v: [[f64; 3]; 4],
    /// Angular velocities ω_{n+½} (global).
    pub w: [[f64; 3]; 4],
}

/// Constants shared by every element of a pass (material moduli and the thickness-free
/// factors of the hourglass stiffnesses), computed once per pass instead of per element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElemConst {
    /// Plane-stress modulus E/(1 − ν²).
    pub c: f64,
    pub nu: f64,
    /// Shear modulus G = E/(2(1 + ν)).
    pub g: f64,
    /// −ν/E (thickness strain per in-plane stress increment, elastic).
    pub nu_e: f64,
    /// κ G (transverse shear stiffness per unit thickness).
    pub ks: f64,
    /// Hourglass factors: membrane c_m E, bending c_b E/12, transverse c_t κ G/12; multiplied
    /// by h, h³, h³ (and A·Σb², A·Σb², Σb²) they give `hourglass_stiffness`.
    pub hg: [f64; 3],
    /// True for the elastic material (no return mapping).
    pub elastic: bool,
}

impl ElemConst {
    pub fn new(sec: &Section, mat: &Material) -> Self {
        let e = mat.youngs();
        let nu = mat.poisson();
        let g = e / (2.0 * (1.0 + nu));
        ElemConst {
            c: e / (1.0 - nu * nu),
            nu,
            g,
            nu_e: -nu / e,
            ks: sec.shear_factor * g,
            hg: [
                sec.hg_membrane * e,
                sec.hg_bending * e / 12.0,
                sec.hg_transverse * sec.shear_factor * g / 12.0,
            ],
            elastic: matches!(mat, Material::Elastic { .. }),
        }
    }
}

/// One element, one step: update the stresses from the rate of deformation over `dt`, then
/// write the nodal internal forces minus the pressure load (global frame, [f; m] per node)
/// into `fe`. Returns `false` if the element became degenerate. `kc` = `ElemConst::new(sec,
/// mat)`, hoisted out of the element loop.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn element_step(
    inp: &ElemInput,
    dt: f64,
    sec: &Section,
    mat: &Material,
    kc: &ElemConst,
    pressure: f64,
    stress: &mut [f64],
    plastic: &mut [f64],
    res: &mut [f64; RES],
    fe: &mut [[f64; 6]; 4],
) -> bool {
    let mut xm = inp.x;
    let hdt = 0.5 * dt;
    for i in 0..4 {
        for k in 0..3 {
            xm[i][k] -= hdt * inp.v[i][k];
        }
    }
    // Both frames are built here, once each: mid-step for the rates, end-of-step for forces.
    let Some(gm) = geometry(&xm) else {
        return false;
    };
    let Some(g1) = geometry(&inp.x) else {
        return false;
    };
    let h = res[R_H];
    // Local velocities and angular velocities on the mid-step frame.
    let mut vl = [[0.0; 3]; 4];
    let mut wl = [[0.0; 3]; 4];
    for i in 0..4 {
        for a in 0..3 {
            vl[i][a] = vec3(&gm.e[a]).dot(&vec3(&inp.v[i]));
        }
        for a in 0..2 {
            wl[i][a] = vec3(&gm.e[a]).dot(&vec3(&inp.w[i]));
        }
    }
    let (b1, b2) = (gm.b1, gm.b2);
    let mut dm = [0.0; 3];
    let mut kap = [0.0; 3];
    let mut gs = [0.0; 2];
    let mut wsum = [0.0; 2];
    let mut hq = [0.0; 5];
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
    // Through-thickness integration of the in-plane stresses (seed 004 eq. 26, rate form).
    let mut nres = [0.0; 3];
    let mut mres = [0.0; 3];
    let mut de_int = 0.0;
    let mut dzz = 0.0;
    let nip = sec.nip;
    let stress = &mut stress[..3 * nip];
    if kc.elastic {
        let (c, nu, gmod, nu_e) = (kc.c, kc.nu, kc.g, kc.nu_e);
        for k in 0..nip {
            let z = 0.5 * h * sec.zeta[k];
            let wk = 0.5 * h * sec.weight[k];
            let de = [
                (dm[0] + z * kap[0]) * dt,
                (dm[1] + z * kap[1]) * dt,
                (dm[2] + z * kap[2]) * dt,
            ];
            let s = &mut stress[3 * k..3 * k + 3];
            let old = [s[0], s[1], s[2]];
            let ds = [
                c * (de[0] + nu * de[1]),
                c * (nu * de[0] + de[1]),
                gmod * de[2],
            ];
            let sn = [old[0] + ds[0], old[1] + ds[1], old[2] + ds[2]];
            s[0] = sn[0];
            s[1] = sn[1];
            s[2] = sn[2];
            dzz += wk * nu_e * (sn[0] - old[0] + sn[1] - old[1]);
            de_int += wk
                * 0.5
                * ((old[0] + sn[0]) * de[0] + (old[1] + sn[1]) * de[1] + (old[2] + sn[2]) * de[2]);
            for c in 0..3 {
                nres[c] += wk * sn[c];
                mres[c] += wk * z * sn[c];
            }
        }
    } else if let Material::J2(m) = mat {
        for k in 0..nip {
            let z = 0.5 * h * sec.zeta[k];
            let wk = 0.5 * h * sec.weight[k];
            let de = [
                (dm[0] + z * kap[0]) * dt,
                (dm[1] + z * kap[1]) * dt,
                (dm[2] + z * kap[2]) * dt,
            ];
            let s = &mut stress[3 * k..3 * k + 3];
            let old = [s[0], s[1], s[2]];
            let p = &mut plastic[PL * k..PL * k + PL];
            let mut pt = PlaneStressPoint {
                stress: old,
                back: [p[0], p[1], p[2]],
                eqps: p[3],
            };
            let info = m.update(&mut pt, de);
            s.copy_from_slice(&pt.stress);
            p[..3].copy_from_slice(&pt.back);
            p[3] = pt.eqps;
            dzz += wk * info.d_eps_zz;
            de_int += wk
                * 0.5
                * ((old[0] + s[0]) * de[0] + (old[1] + s[1]) * de[1] + (old[2] + s[2]) * de[2]);
            for c in 0..3 {
                nres[c] += wk * s[c];
                mres[c] += wk * z * s[c];
            }
        }
    }
    // Transverse shear resultants Q = κ G h γ (elastic), incremental.
    let ks = kc.ks * h;
    for c in 0..2 {
        let old = res[R_Q + c];
        res[R_Q + c] += ks * gs[c] * dt;
        de_int += 0.5 * (old + res[R_Q + c]) * gs[c] * dt;
    }
    de_int *= area_m;
    // Hourglass resultants (stiffness form, so hourglass energy is stored, not dissipated);
    // the stiffnesses of `hourglass_stiffness` from the hoisted factors.
    let bb: f64 = (0..4).map(|i| b1[i] * b1[i] + b2[i] * b2[i]).sum();
    let h3 = h * h * h;
    let abb = area_m * bb;
    let khg = [kc.hg[0] * h * abb, kc.hg[1] * h3 * abb, kc.hg[2] * h3 * bb];
    let kk = [khg[0], khg[0], khg[1], khg[1], khg[2]];
    for c in 0..5 {
        let old = res[R_HG + c];
        res[R_HG + c] += kk[c] * hq[c] * dt;
        de_int += 0.5 * (old + res[R_HG + c]) * hq[c] * dt;
    }
    res[R_EINT] += de_int;
    if sec.update_thickness {
        res[R_H] = h * (1.0 + dzz / h);
    }
    // Nodal forces at t_{n+1} on the current frame (power conjugates of the rates above).
    let a = g1.area;
    let q = [res[R_Q], res[R_Q + 1]];
    let hg = [
        res[R_HG],
        res[R_HG + 1],
        res[R_HG + 2],
        res[R_HG + 3],
        res[R_HG + 4],
    ];
    let pa = 0.25 * pressure * a;
    let an = [a * nres[0], a * nres[1], a * nres[2]];
    let am = [a * mres[0], a * mres[1], a * mres[2]];
    let aq = [a * q[0], a * q[1]];
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
            fe[i][k] = g1.e[0][k] * fl[0] + g1.e[1][k] * fl[1] + g1.e[2][k] * fl[2];
            fe[i][3 + k] = g1.e[0][k] * ml[0] + g1.e[1][k] * ml[1];
        }
    }
    if pressure != 0.0 {
        let mut wp = 0.0;
        for i in 0..4 {
            wp += pa * vec3(&g1.e[2]).dot(&vec3(&inp.v[i])) * dt;
        }
        res[R_WPRES] += wp;
    }
    true
}

/// Membrane strain rates [d̂x, d̂y, γ̂xy] of the one-point element for nodal velocities given
/// in the local frame of `geo` (used by the patch test and diagnostics).
pub fn membrane_rates(geo: &Geom, vl: &[[f64; 3]; 4]) -> [f64; 3] {
    let mut d = [0.0; 3];
    for i in 0..4 {
        d[0] += geo.b1[i] * vl[i][0];
        d[1] += geo.b2[i] * vl[i][1];
        d[2] += geo.b2[i] * vl[i][0] + geo.b1[i] * vl[i][1];
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_rules_integrate_polynomials() {
        for n in 1..=5 {
            let (z, w) = gauss(n);
            let s: f64 = (0..n).map(|k| w[k]).sum();
            assert!((s - 2.0).abs() < 1e-14);
            // ∫ ζ² = 2/3 exact for n ≥ 2.
            if n >= 2 {
                let s2: f64 = (0..n).map(|k| w[k] * z[k] * z[k]).sum();
                assert!((s2 - 2.0 / 3.0).abs() < 1e-14, "n={n}");
            }
        }
    }

    #[test]
    fn membrane_estimate_is_the_exact_element_eigenvalue() {
        // Rectangle a × b, lumped mass: the largest membrane eigenvalue of the one-point
        // element is max(E/(1−ν²)·(1/a² + 1/b²)-type modes); check against brute force:
        // power iteration on (4/ρ) BᵀCB (ρ = 1, h = 1).
        let sec = Section::new(3, 5.0 / 6.0, [0.0; 3], false);
        let mat = Material::Elastic {
            youngs: 1.0,
            poisson: 0.3,
        };
        for (a, b) in [(1.0, 1.0), (5.0, 1.0), (1.0, 0.2)] {
            let x = [[0.0, 0.0, 0.0], [a, 0.0, 0.0], [a, b, 0.0], [0.0, b, 0.0]];
            let g = geometry(&x).unwrap_or_else(|| panic!("degenerate"));
            let s = stiffness_estimates(&sec, &mat, 1.0, &g);
            // ω² = s/(m/4) with m = ρhA.
            let w2 = s[0] / (0.25 * g.area);
            let c = 1.0 / (1.0 - 0.09);
            let gm = 1.0 / 2.6;
            let mut u = [1.0, -0.3, 0.7, 0.2, -0.5, 0.9, 0.1, -0.8];
            let mut lam = 0.0;
            for _ in 0..500 {
                let mut eps = [0.0; 3];
                for i in 0..4 {
                    eps[0] += g.b1[i] * u[2 * i];
                    eps[1] += g.b2[i] * u[2 * i + 1];
                    eps[2] += g.b2[i] * u[2 * i] + g.b1[i] * u[2 * i + 1];
                }
                let sig = [
                    c * (eps[0] + 0.3 * eps[1]),
                    c * (0.3 * eps[0] + eps[1]),
                    gm * eps[2],
                ];
                let mut ku = [0.0; 8];
                for i in 0..4 {
                    ku[2 * i] = 4.0 * (g.b1[i] * sig[0] + g.b2[i] * sig[2]);
                    ku[2 * i + 1] = 4.0 * (g.b2[i] * sig[1] + g.b1[i] * sig[2]);
                }
                let n: f64 = ku.iter().map(|v| v * v).sum::<f64>().sqrt();
                let un: f64 = u.iter().map(|v| v * v).sum::<f64>().sqrt();
                lam = n / un;
                u = ku.map(|v| v / n);
            }
            assert!((w2 - lam).abs() < 1e-9 * lam, "{a}x{b}: {w2} vs {lam}");
        }
    }

    #[test]
    fn b_matrix_reproduces_linear_fields_and_gamma_is_orthogonal() {
        let x = [
            [0.0, 0.0, 0.0],
            [2.0, 0.3, 0.0],
            [2.4, 1.7, 0.0],
            [-0.2, 1.2, 0.0],
        ];
        let g = geometry(&x).unwrap_or_else(|| panic!("degenerate"));
        let sx: f64 = (0..4).map(|i| g.b1[i] * g.xl[i]).sum();
        let sy: f64 = (0..4).map(|i| g.b2[i] * g.yl[i]).sum();
        let sxy: f64 = (0..4).map(|i| g.b1[i] * g.yl[i]).sum();
        assert!((sx - 1.0).abs() < 1e-14 && (sy - 1.0).abs() < 1e-14 && sxy.abs() < 1e-14);
        let gx: f64 = (0..4).map(|i| g.gam[i] * g.xl[i]).sum();
        let g1: f64 = g.gam.iter().sum();
        assert!(gx.abs() < 1e-14 && g1.abs() < 1e-14);
        let bad = [[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        assert!(geometry(&bad).is_none());
    }
}
