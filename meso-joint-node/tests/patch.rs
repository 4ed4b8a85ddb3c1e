//! Must-show 2: the first-order RK shape functions reproduce a linear velocity field exactly
//! (values and gradients) at every particle of an irregular cloud, boundary included, and an
//! affine motion gives the exact deformation gradient (eq. 14) everywhere.

#![allow(clippy::needless_range_loop)]

use mechanics::j2::J2Material;
use meso_joint_node::config::Smoothing;
use meso_joint_node::geometry::block;
use meso_joint_node::model::{Model, ModelParams, incremental_f};

fn jittered_model() -> Model {
    let h = 1e-3;
    let mut s = block([0.0; 3], [5e-3, 4e-3, 4e-3], h);
    let mut seed: u64 = 99;
    for p in &mut s.x {
        for c in p.iter_mut() {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *c += 0.25 * h * (((seed >> 33) as f64) / (1u64 << 31) as f64 - 0.5);
        }
    }
    let p = ModelParams {
        blast: None,
        material: J2Material {
            young: 210e9,
            poisson: 0.3,
            yield_stress: 1e9,
            iso_hardening: 0.0,
            kin_hardening: 0.0,
        },
        density: 7850.0,
        spacing: h,
        support: 1.8 * h,
        eps_crit: 0.5,
        e_crit: 1.0,
        reanchor_every: 10,
        smoothing: Smoothing::Consistent,
        cfl: 0.4,
        bearing: None,
    };
    Model::new(p, s.x, s.vol, s.part, &s.rigid_parts).unwrap()
}

#[test]
fn linear_velocity_field_is_reproduced_exactly() {
    let m = jittered_model();
    let g = [
        [120.0, -40.0, 15.0],
        [30.0, 80.0, -60.0],
        [-25.0, 45.0, 10.0],
    ];
    let v0 = [0.4, -0.2, 1.3];
    let field = |x: &[f64; 3]| -> [f64; 3] {
        std::array::from_fn(|r| v0[r] + g[r][0] * x[0] + g[r][1] * x[1] + g[r][2] * x[2])
    };
    let vel: Vec<[f64; 3]> = m.x.iter().map(field).collect();
    let (mut err_v, mut err_g) = (0.0f64, 0.0f64);
    for i in 0..m.len() {
        let mut vi = [0.0; 3];
        let mut gi = [[0.0; 3]; 3];
        for p in m.rows.range(i) {
            let j = m.rows.cols[p] as usize;
            for r in 0..3 {
                vi[r] += m.rows.phi[p] * vel[j][r];
                for c in 0..3 {
                    gi[r][c] += vel[j][r] * m.rows.grad[p][c];
                }
            }
        }
        let e = field(&m.x[i]);
        for r in 0..3 {
            err_v = err_v.max((vi[r] - e[r]).abs());
            for c in 0..3 {
                err_g = err_g.max((gi[r][c] - g[r][c]).abs());
            }
        }
    }
    eprintln!(
        "patch test: max value error {err_v:e} m/s, max gradient error {err_g:e} 1/s over {} particles",
        m.len()
    );
    // Velocities are O(1) m/s, gradients O(100) 1/s: round-off bounds.
    assert!(err_v < 1e-13, "value error {err_v:e}");
    assert!(err_g < 1e-9, "gradient error {err_g:e}");
}

#[test]
fn affine_motion_gives_the_exact_deformation_gradient() {
    let mut m = jittered_model();
    let a = [[1.05, 0.02, -0.01], [0.03, 0.97, 0.04], [-0.02, 0.01, 1.02]];
    for i in 0..m.len() {
        let x = m.x[i];
        m.x[i] = std::array::from_fn(|r| 1e-4 + a[r][0] * x[0] + a[r][1] * x[1] + a[r][2] * x[2]);
    }
    let mut err = 0.0f64;
    for i in 0..m.len() {
        let f = incremental_f(&m.rows, &m.x, &m.xa, i);
        for r in 0..3 {
            for c in 0..3 {
                err = err.max((f[r][c] - a[r][c]).abs());
            }
        }
    }
    eprintln!("affine patch: max |F̂ − A| = {err:e}");
    assert!(err < 1e-12, "{err:e}");
}

#[test]
fn consistent_smoothing_reproduces_uniform_and_linear_velocities() {
    // ψ of eq. 3 with the mass-weighted first-order correction (shape.rs): a uniform and a
    // linear v̂ are smoothed to themselves exactly, also at boundary particles of a jittered
    // cloud.
    let mut m = jittered_model();
    let u = [0.3, -0.7, 0.2];
    for v in &mut m.vh {
        *v = u;
    }
    meso_joint_node::model::gather_consistent(&m.rows, &m.vh, &mut m.v);
    let e =
        m.v.iter()
            .map(|v| (0..3).map(|d| (v[d] - u[d]).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
    assert!(e < 1e-14, "{e:e}");
    let g = 100.0;
    for i in 0..m.len() {
        m.vh[i] = [g * m.x[i][0], -0.5 * g * m.x[i][2], 0.25 * g * m.x[i][1]];
    }
    meso_joint_node::model::gather_consistent(&m.rows, &m.vh, &mut m.v);
    let e = (0..m.len())
        .map(|i| {
            let ex = [g * m.x[i][0], -0.5 * g * m.x[i][2], 0.25 * g * m.x[i][1]];
            (0..3)
                .map(|d| (m.v[i][d] - ex[d]).abs())
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    let vmax = (0..m.len())
        .map(|i| g * m.x[i][0].abs())
        .fold(0.0, f64::max);
    eprintln!("gather smoothing of a linear field: max error {e:e} m/s of {vmax:e}");
    assert!(e < 1e-13 * vmax, "{e:e}");
}
