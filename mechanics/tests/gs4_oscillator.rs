//! GS4-II on the single-degree-of-freedom oscillator ü + ω² u = 0, u(0) = 1 (seed 003 §4):
//! each design against its closed forms — the exact discrete solutions of average
//! acceleration (ω̄Δt = 2 atan(Ω/2)) and central differences (ω̄Δt = 2 asin(Ω/2)), the
//! characteristic polynomial of the U0 family, its spectral radius at Ω → ∞ — and the
//! observed order under three step halvings in u, v and a. A design with ρ₁ρ₂ ≠ 1 balances
//! its acceleration at another time level than its loads: its a_n is second order at
//! t_n + (W₁ − Λ₆W₁)Δt and first order at t_n (tested as such; seed 003 claims second order
//! in a for every U0 design without saying at which time).

use mechanics::time::{Csr, Design, Gs4, LinearSystem, State, Stepper};
use std::f64::consts::PI;

fn oscillator(omega: f64) -> LinearSystem {
    LinearSystem {
        mass: vec![1.0],
        damping: vec![0.0],
        stiffness: Csr::from_triplets(1, vec![(0, 0, omega * omega)]),
    }
}

/// Runs `steps` steps from u = 1, v = 0, a = −ω² and returns every state.
fn run(coef: Gs4, omega: f64, dt: f64, steps: usize) -> Vec<[f64; 3]> {
    let sys = oscillator(omega);
    let mut st = Stepper::new(coef, dt, &sys).unwrap();
    let mut s = State {
        u: vec![1.0],
        v: vec![0.0],
        a: vec![-omega * omega],
    };
    let mut out = vec![[1.0, 0.0, -omega * omega]];
    for _ in 0..steps {
        st.step(&sys, &mut s, &[0.0]);
        out.push([s.u[0], s.v[0], s.a[0]]);
    }
    out
}

fn design(r1: f64, r2: f64, rs: f64) -> Gs4 {
    Gs4::u0(Design {
        rho1: r1,
        rho2: r2,
        rho_s: rs,
    })
}

/// The designs under test: name and coefficients.
fn designs() -> Vec<(&'static str, Gs4)> {
    vec![
        (
            "U0(1,1,0) implicit (average acceleration)",
            design(1.0, 1.0, 0.0),
        ),
        (
            "U0(1,1,0) explicit (central difference)",
            Gs4::central_difference(),
        ),
        ("U0(0,0,0) (WBZ-like)", design(0.0, 0.0, 0.0)),
        ("U0(0.8,0.8,1/8) (HHT-like)", design(0.8, 0.8, 0.125)),
        ("U0(0.5,0.5,0.5) (generalized-α)", design(0.5, 0.5, 0.5)),
        ("U0(0.9,0.6,0.3)", design(0.9, 0.6, 0.3)),
    ]
}

#[test]
fn average_acceleration_and_central_difference_match_their_exact_discrete_solutions() {
    let omega = 2.0 * PI;
    for (coef, phase, name) in [
        (design(1.0, 1.0, 0.0), 2.0 * (0.5f64).atan(), "trapezoid"),
        (
            Gs4::central_difference(),
            2.0 * (0.5f64).asin(),
            "central difference",
        ),
    ] {
        // Ω = ωΔt = 1: the closed forms give ω̄Δt = 2 atan(1/2), resp. 2 asin(1/2).
        let dt = 1.0 / omega;
        let states = run(coef, omega, dt, 1000);
        assert_eq!(states.len(), 1001);
        let mut worst: f64 = 0.0;
        for (n, s) in states.iter().enumerate() {
            worst = worst.max((s[0] - (n as f64 * phase).cos()).abs());
        }
        assert!(
            worst < 1e-11,
            "{name}: |u_n − cos(n ω̄Δt)| reached {worst:e}"
        );
        // Period error (T̄ − T)/T = Ω/ω̄Δt − 1: +7.8 % (trapezoid), −4.5 % (central difference).
        let elongation = 1.0 / phase - 1.0;
        println!(
            "{name}: period elongation at Ω = 1: {:+.4} %",
            100.0 * elongation
        );
    }
}

/// Coefficients (c₂, c₁, c₀) of λ³ + c₂λ² + c₁λ + c₀, the characteristic polynomial of a U0
/// design at W = Ω², with αm = 1 − Λ₆W₁, αf = 1 − W₁, β = λ₃ (derived by hand from the
/// recurrence; independent of the step code).
fn characteristic(c: &Gs4, w: f64) -> (f64, f64, f64) {
    let (am, af, b) = (1.0 - c.l6w1, 1.0 - c.w1, c.lam3);
    let d = w * af * b - w * b + am - 1.0;
    let c2 = -(-w * af * af + w * af * am + 3.0 * w * af * b - w * am - 2.0 * w * b + w + 3.0 * am
        - 2.0)
        / d;
    let c1 = (-2.0 * w * af * af + 2.0 * w * af * am + 3.0 * w * af * b - w * am - w * b
        + 3.0 * am
        - 1.0)
        / d;
    let c0 = -(-w * af * af + w * af * am + w * af * b + am) / d;
    (c2, c1, c0)
}

#[test]
fn implicit_designs_follow_their_characteristic_polynomial() {
    let omega = 2.0 * PI;
    let mut checked = 0;
    for (name, coef) in designs().into_iter().filter(|(_, c)| !c.explicit) {
        for big_omega in [0.1, 0.7, 3.0] {
            let states = run(coef, omega, big_omega / omega, 60);
            let (c2, c1, c0) = characteristic(&coef, big_omega * big_omega);
            for k in 0..3 {
                let scale = states.iter().fold(0.0f64, |m, s| m.max(s[k].abs()));
                for n in 0..states.len() - 3 {
                    let r = states[n + 3][k]
                        + c2 * states[n + 2][k]
                        + c1 * states[n + 1][k]
                        + c0 * states[n][k];
                    assert!(
                        r.abs() < 1e-12 * scale,
                        "{name}, Ω = {big_omega}, variable {k}: residual {r:e}"
                    );
                    checked += 1;
                }
            }
        }
    }
    assert_eq!(checked, 5 * 3 * 3 * 58);
}

#[test]
fn spectral_radius_at_infinity_is_the_design_s() {
    let omega = 1.0;
    for (name, coef, rho) in [
        ("U0(1,1,0)", design(1.0, 1.0, 0.0), 1.0),
        ("U0(0.8,0.4,0.2)", design(0.8, 0.4, 0.2), 0.8),
        ("U0(0.6,0.2,0.3)", design(0.6, 0.2, 0.3), 0.6),
    ] {
        let states = run(coef, omega, 1e5, 80);
        let norm = |s: &[f64; 3]| (s[0] * s[0] + s[1] * s[1] * 1e10 + s[2] * s[2] * 1e20).sqrt();
        let r = (norm(&states[80]) / norm(&states[60])).powf(1.0 / 20.0);
        assert!(
            (r - rho).abs() < 2e-3,
            "{name}: observed radius {r}, design {rho}"
        );
    }
    // U0(0,0,0) annihilates the high frequencies: all three roots are zero at Ω → ∞.
    let states = run(design(0.0, 0.0, 0.0), omega, 1e5, 4);
    assert!(
        states[4][0].abs() < 1e-6,
        "U0(0,0,0) left u = {:e}",
        states[4][0]
    );
}

/// The time, in steps after t_n, at which a design's a_n is a second-order acceleration:
/// δ = αm − αf = W₁ − Λ₆W₁. The equation of motion balances M ã at t_n + Λ₆W₁Δt against the
/// loads at t_n + W₁Δt (seed 003 eq. 67), so a_n lags or leads ẍ(t_n) by δΔt whenever
/// ρ₁ρ₂ ≠ 1 — the known property of the generalized-α family (Erlicher, Bonaventura and Bursi
/// 2002; Arnold and Brüls 2007). δ = 0 for U0(1,1,0) and central differences.
fn acceleration_shift(c: &Gs4) -> f64 {
    c.w1 - c.l6w1
}

/// Largest errors in u, v, a over every state of a run of `steps` steps to t = 2, sampling
/// the coarsest level's times only (every `stride`-th state), with the exact acceleration
/// taken at t + `shift`·Δt.
fn errors(coef: Gs4, omega: f64, steps: usize, stride: usize, shift: f64) -> ([f64; 3], usize) {
    let dt = 2.0 / steps as f64;
    let states = run(coef, omega, dt, steps);
    let mut e = [0.0f64; 3];
    let mut count = 0;
    for (n, s) in states.iter().enumerate().step_by(stride) {
        let t = n as f64 * dt;
        let ta = t + shift * dt;
        let exact = [
            (omega * t).cos(),
            -omega * (omega * t).sin(),
            -omega * omega * (omega * ta).cos(),
        ];
        for k in 0..3 {
            e[k] = e[k].max((s[k] - exact[k]).abs());
        }
        count += 1;
    }
    (e, count)
}

#[test]
fn every_design_is_second_order_in_u_v_and_a() {
    let omega = 2.0 * PI;
    let mut orders = 0;
    for (name, coef) in designs() {
        let shift = acceleration_shift(&coef);
        let levels: Vec<([f64; 3], usize)> = (0..4)
            .map(|level| errors(coef, omega, 160 << level, 1 << level, shift))
            .collect();
        for (e, count) in &levels {
            assert_eq!(*count, 161, "{name}: samples compared {e:?}");
        }
        for k in 0..3 {
            for l in 0..3 {
                let p = (levels[l].0[k] / levels[l + 1].0[k]).log2();
                println!("{name}: variable {k}, halving {l}: order {p:.3}");
                assert!(p >= 1.9, "{name}: variable {k}, halving {l}: order {p:.3}");
                orders += 1;
            }
        }
    }
    assert_eq!(orders, 6 * 3 * 3);
}

#[test]
fn shifted_designs_are_first_order_in_a_at_the_step_times() {
    // Measured against ẍ(t_n) itself, a_n of a design with δ ≠ 0 carries the O(δΔt) lag of
    // `acceleration_shift`: order 1 once the lag dominates (the finest halvings).
    let omega = 2.0 * PI;
    let mut checked = 0;
    for (name, coef) in designs() {
        let shift = acceleration_shift(&coef);
        if shift.abs() < 1e-12 {
            continue;
        }
        let e: Vec<f64> = (0..4)
            .map(|level| errors(coef, omega, 160 << level, 1 << level, 0.0).0[2])
            .collect();
        let p = (e[2] / e[3]).log2();
        println!("{name}: δ = {shift:.4}, a against ẍ(t_n): order {p:.3}");
        assert!((0.9..1.3).contains(&p), "{name}: order {p:.3}");
        checked += 1;
    }
    assert_eq!(checked, 4);
}
