//! Must-show 1 (seed 004 §2.1): a free, spinning and deforming body keeps its linear and
//! angular momentum to round-off with the momentum-consistent gather/scatter pair (eq. 2–11),
//! re-anchoring every 7 steps. The same test fails for the two non-consistent variants:
//! plain kernel averaging drifts in linear momentum, and eq. 3 with the RK shape functions
//! of the scatter rows (`Shepard`: gather weights reproduce constants only) drifts in angular
//! momentum. The conserved quantities are those of `model.rs`'s module doc: `Σ m̂ v̂` and
//! `Σ y × m̂ v̂` (y the unsmoothed positions).

#![allow(clippy::needless_range_loop)]

use mechanics::j2::J2Material;
use mechanics::tensor::{self, Vector3};
use meso_joint_node::config::Smoothing;
use meso_joint_node::geometry::block;
use meso_joint_node::model::{Model, ModelParams};

fn params(smoothing: Smoothing) -> ModelParams {
    ModelParams {
        blast: None,
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
        bearing: None,
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
    Vector3::from(a).norm()
}

fn diff(a: [f64; 3], b: [f64; 3]) -> f64 {
    (Vector3::from(a) - Vector3::from(b)).norm()
}

const STEPS: usize = 2000;

/// Run `STEPS` steps and return the largest relative drifts of `Model::momentum` and
/// `Model::angular_momentum` (scaled by M·v_max and M·v_max·size), and of the smoothed
/// `Σ x × m̂ v`, with the rotation angle reached.
fn drifts(smoothing: Smoothing, dt: f64) -> (f64, f64, f64, f64) {
    let mut m = spinning_body(smoothing);
    m.step(dt).unwrap();
    let p0 = m.momentum();
    let l0 = m.angular_momentum();
    let s0 = m.smoothed_angular_momentum();
    let scale = m.mh.iter().sum::<f64>() * m.v.iter().map(|v| norm(*v)).fold(0.0, f64::max);
    let lscale = scale * 6e-3;
    let (mut dp, mut dl, mut ds): (f64, f64, f64) = (0.0, 0.0, 0.0);
    for _ in 0..STEPS {
        m.step(dt).unwrap();
        dp = dp.max(diff(m.momentum(), p0) / scale);
        dl = dl.max(diff(m.angular_momentum(), l0) / lscale);
        ds = ds.max(diff(m.smoothed_angular_momentum(), s0) / lscale);
    }
    let strain = m
        .fhat
        .iter()
        .zip(&m.ftot_a)
        .map(|(f, g)| {
            let t = tensor::mat(f) * tensor::mat(g);
            // symmetric part of F − I with the rotation removed to first order
            (0..3).map(|a| (t[(a, a)] - 1.0).abs()).fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    eprintln!(
        "{smoothing:?}: max |Δp|/(M v) = {dp:e}, max |ΔL|/(M v ℓ) = {dl:e}, smoothed Σ x × m̂ v: {ds:e}; {} re-anchors, rotation {:.3} rad, max |F_aa − 1| {strain:.2e}",
        m.steps / m.p.reanchor_every,
        norm([300.0, -200.0, 500.0]) * m.time
    );
    (dp, dl, ds, strain)
}

#[test]
fn consistent_pair_conserves_linear_and_angular_momentum_and_the_others_drift() {
    let dt = spinning_body(Smoothing::Consistent).stable_dt();
    // The unsmoothed momentum equals the conjugate momentum at the start.
    let (dp, dl, _, _) = drifts(Smoothing::Consistent, dt);
    assert!(dp < 1e-13, "linear momentum drift {dp:e}");
    assert!(dl < 1e-13, "angular momentum drift {dl:e}");

    // Without smoothing (bare DNI, central difference), angular momentum is exact: the
    // torque of the DNI forces vanishes because B F̂ᵀ = V σ is symmetric.
    let (_, dlb, _, _) = drifts(Smoothing::None, dt);
    assert!(dlb < 1e-13, "DNI forces must be torque-free: {dlb:e}");

    // Eq. 3 with the scatter rows' RK functions: linear momentum exact, angular drifts.
    let (dps, dls, _, _) = drifts(Smoothing::Shepard, dt);
    assert!(dps < 1e-13, "Shepard linear momentum drift {dps:e}");
    assert!(
        dls > 1e3 * dl.max(1e-16) && dls > 1e-8,
        "the Shepard pair must show the angular drift: {dls:e}"
    );

    // Plain averaging: the momentum of the moving particles Σ m̂ v drifts.
    let mut a = spinning_body(Smoothing::Average);
    a.step(dt).unwrap();
    let q0 = lumped_momentum(&a);
    let scale = a.mh.iter().sum::<f64>() * a.v.iter().map(|v| norm(*v)).fold(0.0, f64::max);
    let mut max_dq: f64 = 0.0;
    for _ in 0..STEPS {
        a.step(dt).unwrap();
        max_dq = max_dq.max(diff(lumped_momentum(&a), q0) / scale);
    }
    eprintln!("plain average: max |Δp|/(M v) = {max_dq:e}");
    assert!(
        max_dq > 1e3 * dp.max(1e-16) && max_dq > 1e-8,
        "plain averaging must show the drift: {max_dq:e}"
    );
}

/// The consistent gather reproduces a rigid motion exactly (`Σ_J ψ_I(X_J) = 1`,
/// `Σ_J ψ_I(X_J)(X_J − X_I) = 0`): smoothing `v̂ = c + ω × X` returns it unchanged, also at
/// boundary particles, while the Shepard weights of eq. 3 do not.
#[test]
fn consistent_smoothing_reproduces_rigid_motion() {
    let omega = [300.0, -200.0, 500.0];
    let rigid = |x: &[f64; 3]| -> [f64; 3] {
        [
            0.7 + omega[1] * x[2] - omega[2] * x[1],
            -0.3 + omega[2] * x[0] - omega[0] * x[2],
            0.2 + omega[0] * x[1] - omega[1] * x[0],
        ]
    };
    let mut worst = [0.0f64; 2];
    for (k, sm) in [Smoothing::Consistent, Smoothing::Shepard]
        .into_iter()
        .enumerate()
    {
        let mut m = spinning_body(sm);
        for i in 0..m.len() {
            m.vh[i] = rigid(&m.x[i]);
            m.f[i] = [0.0; 3];
        }
        m.velocity_phase(0.0);
        for i in 0..m.len() {
            worst[k] = worst[k].max(diff(m.v[i], rigid(&m.x[i])));
        }
    }
    eprintln!(
        "rigid motion reproduced: consistent {:e} m/s, Shepard {:e} m/s",
        worst[0], worst[1]
    );
    assert!(worst[0] < 1e-12, "consistent gather: {:e}", worst[0]);
    assert!(
        worst[1] > 1e-6,
        "Shepard gather should not reproduce it: {:e}",
        worst[1]
    );
}
