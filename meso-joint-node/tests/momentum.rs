//! Must-show 1 (seed 004 §2.1): a free, spinning and deforming body keeps its linear
//! momentum to round-off with the momentum-consistent gather/scatter pair (eq. 2–11); with
//! plain kernel averaging the same test shows the drift (so the test can fail). Angular
//! momentum is measured and reported alongside.

#![allow(clippy::needless_range_loop)]

use mechanics::j2::J2Material;
use meso_joint_node::config::Smoothing;
use meso_joint_node::geometry::block;
use meso_joint_node::model::{Model, ModelParams};

fn params(smoothing: Smoothing) -> ModelParams {
    ModelParams {
        material: J2Material {
            young: 210e9,
            poisson: 0.3,
            yield_stress: 1e9,
            iso_hardening: 0.0,
            kin_hardening: 1e9,
        },
        density: 7850.0,
        spacing: 1e-3,
        support: 1.75e-3,
        eps_crit: 0.5,
        e_crit: 1.0,
        reanchor_every: 7,
        smoothing,
        cfl: 0.4,
    }
}

/// Spinning (ω about a tilted axis) plus a non-affine deformation rate, so the body both
/// rotates and deforms; an irregular particle distribution via a pseudo-random jitter.
fn spinning_body(smoothing: Smoothing) -> Model {
    let h = 1e-3;
    let mut s = block([0.0; 3], [6e-3, 5e-3, 4e-3], h);
    let mut seed: u64 = 12345;
    for p in &mut s.x {
        for c in p.iter_mut() {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *c += 0.15 * h * (((seed >> 33) as f64) / (1u64 << 31) as f64 - 0.5);
        }
    }
    let mut m = Model::new(params(smoothing), s.x, s.vol, s.part, &s.rigid_parts).unwrap();
    let omega = [300.0, -200.0, 500.0];
    for i in 0..m.len() {
        let x = m.x[i];
        let c = [x[0] - 3e-3, x[1] - 2.5e-3, x[2] - 2e-3];
        let spin = [
            omega[1] * c[2] - omega[2] * c[1],
            omega[2] * c[0] - omega[0] * c[2],
            omega[0] * c[1] - omega[1] * c[0],
        ];
        // Non-affine deformation rate (quadratic in x) and a drift velocity.
        let def = [4e3 * c[0] * c[0], -3e3 * c[0] * c[1], 2e3 * c[2] * c[1]];
        m.vh[i] = [
            spin[0] + def[0] + 0.7,
            spin[1] + def[1] - 0.3,
            spin[2] + def[2] + 0.2,
        ];
    }
    m.initial_forces();
    m
}

fn lumped_momentum(m: &Model) -> [f64; 3] {
    let mut p = [0.0; 3];
    for i in 0..m.len() {
        for d in 0..3 {
            p[d] += m.mh[i] * m.v[i][d];
        }
    }
    p
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

#[test]
fn consistent_pair_conserves_momentum_and_plain_average_drifts() {
    let steps = 300;
    // Consistent MC-SPG: momentum Σ m_I v_I of the moving particles.
    let mut m = spinning_body(Smoothing::Consistent);
    let dt = m.stable_dt();
    let p_hat0: [f64; 3] = {
        let mut p = [0.0; 3];
        for i in 0..m.len() {
            for d in 0..3 {
                p[d] += m.mh[i] * m.vh[i][d];
            }
        }
        p
    };
    m.step(dt).unwrap();
    let p0 = m.momentum();
    let l0 = m.angular_momentum();
    let scale = m.mh.iter().sum::<f64>() * m.v.iter().map(|v| norm(*v)).fold(0.0, f64::max);
    let mut max_dp: f64 = 0.0;
    let mut max_dl: f64 = 0.0;
    let lscale = scale * 6e-3;
    for _ in 0..steps {
        m.step(dt).unwrap();
        let p = m.momentum();
        let l = m.angular_momentum();
        max_dp = max_dp.max(norm([p[0] - p0[0], p[1] - p0[1], p[2] - p0[2]]) / scale);
        max_dl = max_dl.max(norm([l[0] - l0[0], l[1] - l0[1], l[2] - l0[2]]) / lscale);
    }
    // The unsmoothed momentum equals the smoothed one (Σ_I P_I = Σ_J m̂_J v̂_J).
    assert!(norm([p0[0] - p_hat0[0], p0[1] - p_hat0[1], p0[2] - p_hat0[2]]) / scale < 1e-13);
    let strain = m
        .fhat
        .iter()
        .map(|f| (f[0][0] - 1.0).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "consistent: max |Δp|/(M v) = {max_dp:e}, max |ΔL|/(M v L) = {max_dl:e}, deformation |F̂xx − 1| ≤ {strain:e}"
    );
    assert!(max_dp < 1e-13, "linear momentum drift {max_dp:e}");

    // Without smoothing (bare DNI, central difference), angular momentum is exact: the
    // torque of the DNI forces vanishes because B F̂ᵀ = V σ is symmetric.
    let mut b = spinning_body(Smoothing::None);
    b.step(dt).unwrap();
    let lb0 = b.angular_momentum();
    let mut max_dlb: f64 = 0.0;
    for _ in 0..steps {
        b.step(dt).unwrap();
        let l = b.angular_momentum();
        max_dlb = max_dlb.max(norm([l[0] - lb0[0], l[1] - lb0[1], l[2] - lb0[2]]) / lscale);
    }
    eprintln!("no smoothing: max |ΔL|/(M v L) = {max_dlb:e}");
    assert!(
        max_dlb < 1e-13,
        "DNI forces must be torque-free: {max_dlb:e}"
    );

    // Plain averaging: the momentum of the moving particles Σ m̂ v drifts.
    let mut a = spinning_body(Smoothing::Average);
    a.step(dt).unwrap();
    let q0 = lumped_momentum(&a);
    let mut max_dq: f64 = 0.0;
    for _ in 0..steps {
        a.step(dt).unwrap();
        let q = lumped_momentum(&a);
        max_dq = max_dq.max(norm([q[0] - q0[0], q[1] - q0[1], q[2] - q0[2]]) / scale);
    }
    eprintln!("plain average: max |Δp|/(M v) = {max_dq:e}");
    assert!(
        max_dq > 1e3 * max_dp.max(1e-16) && max_dq > 1e-8,
        "plain averaging must show the drift: {max_dq:e}"
    );
}
