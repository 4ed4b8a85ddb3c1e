//! Displacement-based kinematics: the force models form bond
//! deformations from η = u_j − u_i against the reference bond ξ, so a body far from the
//! origin keeps full precision at small strain. A 6×6×6 block (Δx 1 mm, δ 3.015Δx) whose
//! reference coordinates are offset by 1e3 m (ulp 1.1e-13 m) is stretched uniformly by
//! ε = 1e-9 along x (bond elongations ~1e-12 m, ten ulps of the absolute position):
//! * pd-bond (Silling 2000, the README's case sections): every particle's force equals Σ_j c_ij s_ij ŷ_ij with
//!   the closed-form stretch of a uniformly stretched bond,
//!   s = (2ε + ε²)n_x² / (√(1 + (2ε + ε²)n_x²) + 1), to 1e-9 of the largest force. The old
//!   formula, c (1/|ξ| − 1/|y|) y with y from the absolute positions, is evaluated beside it
//!   and is off by O(1) (printed; asserted > 1e-2).
//! * pd-correspondence (seed 001 eq. 180–183): in one rate step (v = u, dt = 1) the stress is
//!   σ = λ D I + 2μ D e_x⊗e_x with D = ε/(1+ε) (L = Ḟ F⁻¹), P = J σ F⁻ᵀ with F = I + ε e_x⊗e_x,
//!   and every particle's force equals Σ_j ω V_j (P K_i⁻¹ + P K_j⁻¹) ξ (the stabilization
//!   vanishes for a homogeneous deformation, z = η − Hξ = 0), to 1e-9 of the largest force.
//!   With F formed from absolute positions, z carried a round-off of ~1e-13 m against
//!   Hξ ~ 1e-12 m, i.e. an error of order one in the stabilization force.
// Index loops over the 3 components read closer to the formulas.
#![allow(clippy::needless_range_loop)]

use mechanics::damage::NoDamage;
use mechanics::j2::J2Material;
use solid_node::pd::bond::BondModel;
use solid_node::pd::correspondence::{Correspondence, M3, inverse, matmul, mv};
use solid_node::pd::family::Bonds;
use solid_node::pd::geometry::cube_lattice;
use solid_node::pd::model::{Dim, Kinematics, PdModel};

const OFFSET: f64 = 1e3;
const EPS: f64 = 1e-9;

/// (offset reference positions, local positions, displacements u = ε x_local e_x, positions).
type Setup = (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<[f64; 3]>);

fn setup(dx: f64) -> Setup {
    let local = cube_lattice(6, dx);
    let x0: Vec<[f64; 3]> = local
        .iter()
        .map(|p| [p[0] + OFFSET, p[1] + 0.5 * OFFSET, p[2] - 0.3 * OFFSET])
        .collect();
    let u: Vec<[f64; 3]> = local.iter().map(|p| [EPS * p[0], 0.0, 0.0]).collect();
    let pos = x0
        .iter()
        .zip(&u)
        .map(|(x, u)| std::array::from_fn(|d| x[d] + u[d]))
        .collect();
    (x0, local, u, pos)
}

fn max_abs(v: &[[f64; 3]]) -> f64 {
    v.iter().flatten().fold(0.0_f64, |m, x| m.max(x.abs()))
}

fn max_rel(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let d = a
        .iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
    d / max_abs(b)
}

#[test]
fn bond_forces_far_from_origin_match_closed_form_stretch() {
    let dx = 1e-3;
    let (x0, _, u, pos) = setup(dx);
    let vol = vec![dx * dx * dx; x0.len()];
    let mut bonds = Bonds::build(&x0, 3.015 * dx);
    let zero = vec![[0.0; 3]; x0.len()];
    let k0 = Kinematics {
        x0: &x0,
        pos: &x0,
        disp: &zero,
        vel: &zero,
        vol: &vol,
    };
    let mut m = BondModel::new(Dim::Three, 200e9, 3.015 * dx, dx, None, &k0, &bonds);
    let k = Kinematics {
        x0: &x0,
        pos: &pos,
        disp: &u,
        vel: &zero,
        vol: &vol,
    };
    let mut f = vec![[0.0; 3]; x0.len()];
    m.force_density(&k, &mut bonds, 0.0, &mut f);
    let mut exact = vec![[0.0; 3]; x0.len()];
    let mut old = vec![[0.0; 3]; x0.len()];
    for i in 0..x0.len() {
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            let (x, il) = (bonds.xi[b], bonds.inv_len[b]);
            let nx = x[0] * il;
            let a = (2.0 * EPS + EPS * EPS) * nx * nx;
            let s = a / ((1.0 + a).sqrt() + 1.0);
            let y = [x[0] * (1.0 + EPS), x[1], x[2]];
            let ly = (1.0 + s) / il;
            // the old formula, from absolute positions
            let yo: [f64; 3] = std::array::from_fn(|d| pos[j][d] - pos[i][d]);
            let lo = (yo[0] * yo[0] + yo[1] * yo[1] + yo[2] * yo[2]).sqrt();
            for d in 0..3 {
                exact[i][d] += m.coef[b] * s / ly * y[d];
                old[i][d] += m.coef[b] * (il - 1.0 / lo) * yo[d];
            }
        }
    }
    let (e_new, e_old) = (max_rel(&f, &exact), max_rel(&old, &exact));
    println!(
        "pd-bond, offset {OFFSET} m, ε = {EPS:e}: largest force {:.3e} N/m³; max relative error displacement form {e_new:.3e}, absolute-position form {e_old:.3e}",
        max_abs(&exact)
    );
    assert!(max_abs(&exact) > 0.0);
    // ξ itself is rounded at the offset (ulp 1.1e-13 m on 1 mm bonds, 1.1e-10 relative)
    assert!(e_new <= 1e-9, "displacement form: {e_new:e}");
    assert!(
        e_old > 1e-2,
        "the old formula should lose the strain here: {e_old:e}"
    );
}

#[test]
fn correspondence_forces_far_from_origin_match_closed_form_stress() {
    let dx = 1e-3;
    let (x0, _, u, pos) = setup(dx);
    let vol = vec![dx * dx * dx; x0.len()];
    let delta = 3.015 * dx;
    let mut bonds = Bonds::build(&x0, delta);
    let zero = vec![[0.0; 3]; x0.len()];
    let mat = J2Material {
        young: 200e9,
        poisson: 0.3,
        yield_stress: f64::MAX,
        iso_hardening: 0.0,
        kin_hardening: 0.0,
    };
    let k0 = Kinematics {
        x0: &x0,
        pos: &x0,
        disp: &zero,
        vel: &zero,
        vol: &vol,
    };
    let mut m = Correspondence::new(Dim::Three, mat, 0.5, delta, dx, NoDamage, &k0, &bonds);
    // one rate step of dt = 1 with v = u imposes the displacement on the stress too
    let k = Kinematics {
        x0: &x0,
        pos: &pos,
        disp: &u,
        vel: &u,
        vol: &vol,
    };
    let mut f = vec![[0.0; 3]; x0.len()];
    m.force_density(&k, &mut bonds, 1.0, &mut f);
    // closed form: D = ε/(1+ε), σ = λ D I + 2μ D e_x⊗e_x, P = J σ F⁻ᵀ
    let mu = mat.shear_modulus();
    let lambda = mat.bulk_modulus() - 2.0 / 3.0 * mu;
    let dd = EPS / (1.0 + EPS);
    let jac = 1.0 + EPS;
    let p: M3 = [
        [(lambda + 2.0 * mu) * dd * jac / (1.0 + EPS), 0.0, 0.0],
        [0.0, lambda * dd * jac, 0.0],
        [0.0, 0.0, lambda * dd * jac],
    ];
    let a: Vec<M3> = (0..x0.len())
        .map(|i| {
            let mut kk = [[0.0; 3]; 3];
            for b in bonds.offsets[i]..bonds.offsets[i + 1] {
                let w = vol[bonds.nbr[b] as usize];
                let x = bonds.xi[b];
                for r in 0..3 {
                    for c in 0..3 {
                        kk[r][c] += w * x[r] * x[c];
                    }
                }
            }
            matmul(&p, &inverse(&kk, 0.0).expect("full-rank family"))
        })
        .collect();
    let mut exact = vec![[0.0; 3]; x0.len()];
    for i in 0..x0.len() {
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            let (ti, tj) = (mv(&a[i], &bonds.xi[b]), mv(&a[j], &bonds.xi[b]));
            for d in 0..3 {
                exact[i][d] += vol[j] * (ti[d] + tj[d]);
            }
        }
    }
    let e = max_rel(&f, &exact);
    println!(
        "pd-correspondence, offset {OFFSET} m, ε = {EPS:e}: largest force {:.3e} N/m³, max relative error {e:.3e}",
        max_abs(&exact)
    );
    assert!(max_abs(&exact) > 0.0);
    // ξ itself is rounded at the offset (ulp 1.1e-13 m on 1 mm bonds, 1.1e-10 relative)
    assert!(e <= 1e-9, "{e:e}");
}
