//! Shared helpers of the verification tests: the exact Riemann solver of the ideal-gas Euler
//! equations (Toro, "Riemann Solvers and Numerical Methods for Fluid Dynamics", ch. 4) and
//! small case builders.

#![allow(dead_code)]

use fluid_node::EulerSolver;
use fluid_node::setup;

/// Exact solution of a 1-D Riemann problem, sampled at ξ = (x - x0)/t.
pub struct ExactRiemann {
    pub g: f64,
    pub l: (f64, f64, f64),
    pub r: (f64, f64, f64),
    pub p_star: f64,
    pub u_star: f64,
}

impl ExactRiemann {
    pub fn new(g: f64, l: (f64, f64, f64), r: (f64, f64, f64)) -> Self {
        let (rl, ul, pl) = l;
        let (rr, ur, pr) = r;
        let cl = (g * pl / rl).sqrt();
        let cr = (g * pr / rr).sqrt();
        let fk = |p: f64, rk: f64, pk: f64, ck: f64| -> (f64, f64) {
            if p > pk {
                let a = 2.0 / ((g + 1.0) * rk);
                let b = (g - 1.0) / (g + 1.0) * pk;
                let s = (a / (p + b)).sqrt();
                ((p - pk) * s, s * (1.0 - 0.5 * (p - pk) / (b + p)))
            } else {
                let e = (g - 1.0) / (2.0 * g);
                let pr = p / pk;
                (
                    2.0 * ck / (g - 1.0) * (pr.powf(e) - 1.0),
                    1.0 / (rk * ck) * pr.powf(-(g + 1.0) / (2.0 * g)),
                )
            }
        };
        let mut p = 0.5 * (pl + pr);
        for _ in 0..100 {
            let (f1, d1) = fk(p, rl, pl, cl);
            let (f2, d2) = fk(p, rr, pr, cr);
            let dp = (f1 + f2 + ur - ul) / (d1 + d2);
            p = (p - dp).max(1e-12);
            if dp.abs() < 1e-15 * p {
                break;
            }
        }
        let (f1, _) = fk(p, rl, pl, cl);
        let (f2, _) = fk(p, rr, pr, cr);
        let u = 0.5 * (ul + ur) + 0.5 * (f2 - f1);
        ExactRiemann {
            g,
            l,
            r,
            p_star: p,
            u_star: u,
        }
    }

    /// (ρ, u, p) at ξ = x/t.
    pub fn sample(&self, xi: f64) -> (f64, f64, f64) {
        let g = self.g;
        let (p, u) = (self.p_star, self.u_star);
        let side = |k: (f64, f64, f64), sgn: f64| -> (f64, f64, f64) {
            // sgn = -1 for the left wave, +1 for the right wave, in the frame ξ' = sgn ξ
            let (rk, uk, pk) = k;
            let ck = (g * pk / rk).sqrt();
            let xs = sgn * xi;
            let (uk_s, u_s) = (sgn * uk, sgn * u);
            if p > pk {
                let s = uk_s + ck * ((g + 1.0) / (2.0 * g) * p / pk + (g - 1.0) / (2.0 * g)).sqrt();
                if xs > s {
                    (rk, uk, pk)
                } else {
                    let pr = p / pk;
                    let gg = (g - 1.0) / (g + 1.0);
                    (rk * (pr + gg) / (gg * pr + 1.0), u, p)
                }
            } else {
                let head = uk_s + ck;
                let cs = ck * (p / pk).powf((g - 1.0) / (2.0 * g));
                let tail = u_s + cs;
                if xs > head {
                    (rk, uk, pk)
                } else if xs < tail {
                    (rk * (p / pk).powf(1.0 / g), u, p)
                } else {
                    let c = 2.0 / (g + 1.0) * (ck - (g - 1.0) / 2.0 * (uk_s - xs));
                    let uu = 2.0 / (g + 1.0) * (-ck + (g - 1.0) / 2.0 * uk_s + xs);
                    let r = rk * (c / ck).powf(2.0 / (g - 1.0));
                    let pp = pk * (c / ck).powf(2.0 * g / (g - 1.0));
                    (r, sgn * uu, pp)
                }
            }
        };
        if xi < u {
            let (r, uu, pp) = side(self.l, -1.0);
            (r, uu, pp)
        } else {
            side(self.r, 1.0)
        }
    }
}

/// A solver from params TOML text; panics with the error in tests.
pub fn solver(text: &str) -> EulerSolver {
    match setup::from_toml_str(text) {
        Ok(f) => EulerSolver::from_fluid(f),
        Err(e) => panic!("set-up failed: {e}"),
    }
}

/// Sedov energy constant α(ν, γ) with E = α ρ0 R^{ν+2} / t² (ν = 1 planar, both sides;
/// 2 cylindrical, per unit length; 3 spherical).
pub fn sedov_alpha(nu: usize, g: f64) -> f64 {
    fluid_node::exact::Sedov::new(nu, g).alpha
}

/// A blast off-centre in a box with every boundary kind, one gas or air + helium, 2-D or
/// 3-D, with the given limiter (3-D when cells[2] > 1): the shock crosses every kernel path (x rows, blocked y and
/// z lines, reflecting and outflow ghosts).
pub fn walled_blast_case(cells: [usize; 3], two: bool, limiter: &str) -> String {
    let nd = if cells[2] > 1 { 3 } else { 2 };
    let cells = format!("{cells:?}");
    let helium = if two {
        r#"
        [materials.helium]
        eos = "ideal"
        gamma = 1.67
        [[regions]]
        shape = "sphere"
        center = [0.7, 0.6, 0.5]
        radius = 0.15
        material = "helium"
        density = 0.138
        pressure = 0.1
        "#
    } else {
        ""
    };
    let z = if nd == 3 {
        "z_lower = \"wall\"\n        z_upper = \"outflow\""
    } else {
        ""
    };
    format!(
        r#"
        limiter = "{limiter}"
        [grid]
        cells = {cells}
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 0.9, 0.8]
        [materials.air]
        eos = "ideal"
        gamma = 1.4
        [[regions]]
        shape = "all"
        material = "air"
        density = 1.0
        pressure = 0.1
        [[regions]]
        shape = "sphere"
        center = [0.35, 0.4, 0.3]
        radius = 0.15
        material = "air"
        density = 1.0
        pressure = 10.0
        {helium}
        [boundaries]
        x_lower = "wall"
        x_upper = "outflow"
        y_lower = "symmetry"
        y_upper = "wall"
        {z}
    "#
    )
}

/// Particle positions (flat xyz) half a cell apart filling the box `lo..hi` of a grid of cell
/// size `dx`; on a 2-D grid (`nd` 2) one layer at z = 0.4.
pub fn particle_block(dx: [f64; 3], nd: usize, lo: [f64; 3], hi: [f64; 3]) -> Vec<f64> {
    let sp = [0.5 * dx[0], 0.5 * dx[1], 0.5 * dx[2]];
    let count = |d: usize| ((hi[d] - lo[d]) / sp[d]).round() as usize;
    let nz = if nd == 3 { count(2) } else { 1 };
    let mut x = Vec::new();
    for a in 0..count(0) {
        for b in 0..count(1) {
            for c in 0..nz {
                let z = if nd == 3 {
                    lo[2] + (c as f64 + 0.5) * sp[2]
                } else {
                    0.4
                };
                x.extend_from_slice(&[
                    lo[0] + (a as f64 + 0.5) * sp[0],
                    lo[1] + (b as f64 + 0.5) * sp[1],
                    z,
                ]);
            }
        }
    }
    x
}
