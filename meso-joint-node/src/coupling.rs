//! Responder side of the shell–joint kinematic coupling (seed 004 §3, eq. 29–33;
//! ARCHITECTURE §5 kinematic): coupling particles are projected once onto the driver's shell
//! mid-surface (bilinear quads) in the reference configuration (eq. 29), follow the shell
//! motion with their through-thickness offset `d n` (eq. 31–32) at every substep, and return
//! per shell node the constraint force `Σ N_J f_I` and moment `Σ N_J (a_I × f_I)` (eq. 33).

use crate::shape::{cross, dot, norm, sub};

/// Projection of one coupling particle (eq. 29): four shell nodes, their bilinear weights
/// at the foot point, and the signed offset along the mid-surface normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    pub nodes: [u32; 4],
    pub weights: [f64; 4],
    pub offset: f64,
}

fn shape4(xi: f64, eta: f64) -> ([f64; 4], [f64; 4], [f64; 4]) {
    let n = [
        0.25 * (1.0 - xi) * (1.0 - eta),
        0.25 * (1.0 + xi) * (1.0 - eta),
        0.25 * (1.0 + xi) * (1.0 + eta),
        0.25 * (1.0 - xi) * (1.0 + eta),
    ];
    let dxi = [
        -0.25 * (1.0 - eta),
        0.25 * (1.0 - eta),
        0.25 * (1.0 + eta),
        -0.25 * (1.0 + eta),
    ];
    let deta = [
        -0.25 * (1.0 - xi),
        -0.25 * (1.0 + xi),
        0.25 * (1.0 + xi),
        0.25 * (1.0 - xi),
    ];
    (n, dxi, deta)
}

fn combine(w: &[f64; 4], p: &[[f64; 3]; 4]) -> [f64; 3] {
    std::array::from_fn(|d| w[0] * p[0][d] + w[1] * p[1][d] + w[2] * p[2][d] + w[3] * p[3][d])
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = norm(&a);
    if l > 0.0 { a.map(|c| c / l) } else { a }
}

/// Closest point of `x` on a bilinear quad (Newton on the foot-point conditions, clamped to
/// the parent square). Returns (ξ, η, distance²).
fn closest_on_quad(x: &[f64; 3], q: &[[f64; 3]; 4]) -> (f64, f64, f64) {
    let (mut xi, mut eta) = (0.0f64, 0.0f64);
    for _ in 0..20 {
        let (n, dxi, deta) = shape4(xi, eta);
        let p = combine(&n, q);
        let a = combine(&dxi, q);
        let b = combine(&deta, q);
        let r = sub(x, &p);
        // Gauss–Newton on |x − p(ξ, η)|².
        let (aa, ab, bb) = (dot(&a, &a), dot(&a, &b), dot(&b, &b));
        let (ra, rb) = (dot(&r, &a), dot(&r, &b));
        let det = aa * bb - ab * ab;
        if !(det.abs() > 0.0) {
            break;
        }
        let dx = (bb * ra - ab * rb) / det;
        let de = (aa * rb - ab * ra) / det;
        xi = (xi + dx).clamp(-1.0, 1.0);
        eta = (eta + de).clamp(-1.0, 1.0);
        if dx.abs() + de.abs() < 1e-14 {
            break;
        }
    }
    let (n, _, _) = shape4(xi, eta);
    let p = combine(&n, q);
    let r = sub(x, &p);
    (xi, eta, dot(&r, &r))
}

/// Node normals of a quad mesh: the area-weighted average of the cell normals.
pub fn node_normals(x: &[[f64; 3]], quads: &[[u32; 4]]) -> Vec<[f64; 3]> {
    let mut n = vec![[0.0; 3]; x.len()];
    for q in quads {
        let p: [[f64; 3]; 4] = std::array::from_fn(|k| x[q[k] as usize]);
        let c = cross(&sub(&p[2], &p[0]), &sub(&p[3], &p[1]));
        for &k in q {
            for d in 0..3 {
                n[k as usize][d] += c[d];
            }
        }
    }
    n.into_iter().map(unit).collect()
}

/// Project particles onto the mid-surface (eq. 29), in the reference configuration.
pub fn project(
    particles: &[[f64; 3]],
    nodes: &[[f64; 3]],
    normals: &[[f64; 3]],
    quads: &[[u32; 4]],
) -> Vec<Projection> {
    particles
        .iter()
        .map(|x| {
            let mut best = (f64::INFINITY, 0usize, 0.0, 0.0);
            for (c, q) in quads.iter().enumerate() {
                let p: [[f64; 3]; 4] = std::array::from_fn(|k| nodes[q[k] as usize]);
                let (xi, eta, d2) = closest_on_quad(x, &p);
                if d2 < best.0 {
                    best = (d2, c, xi, eta);
                }
            }
            let q = quads[best.1];
            let (w, _, _) = shape4(best.2, best.3);
            let p: [[f64; 3]; 4] = std::array::from_fn(|k| nodes[q[k] as usize]);
            let nn: [[f64; 3]; 4] = std::array::from_fn(|k| normals[q[k] as usize]);
            let foot = combine(&w, &p);
            let n = unit(combine(&w, &nn));
            Projection {
                nodes: q,
                weights: w,
                offset: dot(&sub(x, &foot), &n),
            }
        })
        .collect()
}

/// Position of a coupling particle for shell node positions `x` and normals `n` (eq. 31):
/// `Σ N_J x_J + d n̄`, n̄ the normalised interpolated normal. Also returns the lever arm `d n̄`.
pub fn follow(p: &Projection, x: &[[f64; 3]], n: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let xs: [[f64; 3]; 4] = std::array::from_fn(|k| x[p.nodes[k] as usize]);
    let ns: [[f64; 3]; 4] = std::array::from_fn(|k| n[p.nodes[k] as usize]);
    let mid = combine(&p.weights, &xs);
    let nb = unit(combine(&p.weights, &ns));
    let arm = nb.map(|c| c * p.offset);
    ([mid[0] + arm[0], mid[1] + arm[1], mid[2] + arm[2]], arm)
}

/// Constraint force and moment per shell node (eq. 33): `F_J += N_J f_I`,
/// `M_J += N_J (a_I × f_I)`; sequential, so deterministic.
pub fn constraint_loads(
    proj: &[Projection],
    f: &[[f64; 3]],
    arm: &[[f64; 3]],
    force: &mut [f64],
    moment: &mut [f64],
) {
    force.iter_mut().for_each(|v| *v = 0.0);
    moment.iter_mut().for_each(|v| *v = 0.0);
    for (k, p) in proj.iter().enumerate() {
        let m = cross(&arm[k], &f[k]);
        for a in 0..4 {
            let j = p.nodes[a] as usize;
            for d in 0..3 {
                force[3 * j + d] += p.weights[a] * f[k][d];
                moment[3 * j + d] += p.weights[a] * m[d];
            }
        }
    }
}

/// Rotate `v` by the rotation vector `theta` (Rodrigues).
pub fn rotate(theta: &[f64; 3], v: &[f64; 3]) -> [f64; 3] {
    let a = norm(theta);
    if a < 1e-300 {
        return *v;
    }
    let k = theta.map(|c| c / a);
    let kv = cross(&k, v);
    let kd = dot(&k, v);
    let (s, c) = a.sin_cos();
    std::array::from_fn(|d| v[d] * c + kv[d] * s + k[d] * kd * (1.0 - c))
}
