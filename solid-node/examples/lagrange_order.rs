//! Observed order of the Lagrange-multiplier multi-time-step coupling on the split bar
//! (seed 003 §4–§5): u, v, a at the interface and at the tip and λ, for the methods gs4, gc
//! and ph, step ratios m = 2, 3, 4, 8, under three halvings of the system step, against a
//! single-domain run of the same mesh with a 128 times smaller step.
//!
//! `cargo run --release -p solid-node --example lagrange_order [small]`

use mechanics::time::{Design, Gs4};
use protocol::scheme::lagrange::Method;
use solid_node::lagrange::split_bar::{self, Half};

fn u0(r1: f64, r2: f64, rs: f64) -> Gs4 {
    Gs4::u0(Design {
        rho1: r1,
        rho2: r2,
        rho_s: rs,
    })
}

fn main() {
    let small = std::env::args().any(|a| a == "small");
    let dt0 = split_bar::left_transit();
    let t_end = 2.0 * split_bar::ramp_time();
    let steps0 = (t_end / dt0).round() as usize;
    let refine = 128;
    let reference = split_bar::single(u0(1.0, 1.0, 0.0), dt0 / refine as f64, steps0 * refine, 1);
    let ratios: &[usize] = if small { &[2] } else { &[2, 3, 4, 8] };
    println!(
        "split bar, ΔT₀ = h_left/c = {dt0:.4e} s, {steps0} system steps to {t_end:.4e} s; \
         reference: one domain, U0(1,1,0) at ΔT₀/{refine}"
    );
    let newmark = u0(1.0, 1.0, 0.0);
    let pairs: [(&str, Gs4, Gs4); 5] = [
        ("implicit U0(1,1,0) | implicit U0(1,1,0)", newmark, newmark),
        (
            "implicit U0(1,1,0) | explicit CD",
            newmark,
            Gs4::central_difference(),
        ),
        (
            "explicit CD | implicit U0(1,1,0)",
            Gs4::central_difference(),
            newmark,
        ),
        (
            "implicit U0(0.8,0.8,0.8) | implicit U0(0.8,0.8,0.8)",
            u0(0.8, 0.8, 0.8),
            u0(0.8, 0.8, 0.8),
        ),
        (
            "implicit U0(0.9,0.6,0.3) | implicit U0(1,1,0)",
            u0(0.9, 0.6, 0.3),
            newmark,
        ),
    ];
    for (name, lc, rc) in pairs {
        println!("\n{name} (left | right); orders over halvings 1→2, 2→4, 4→8 of ΔT₀");
        println!(
            "{:>4} {:>2} | {:^17} | {:^17} | {:^17} | {:^17} | {:^17} | {:^17} | {:^17} | {:>9}",
            "meth", "m", "u_Γ", "v_Γ", "a_Γ", "u_tip", "v_tip", "a_tip", "λ", "err u_tip"
        );
        for method in [Method::Gs4, Method::Gc, Method::Ph] {
            for &m in ratios {
                // An explicit right half sub-cycles at its own Courant limit: h_r = h_l / 3.
                if !rc.explicit || m >= 4 {
                    let mut errs = Vec::new();
                    for level in 0..4 {
                        let dt = dt0 / (1 << level) as f64;
                        let h = split_bar::split(
                            method,
                            Half {
                                coef: lc,
                                substeps: 1,
                            },
                            Half {
                                coef: rc,
                                substeps: m,
                            },
                            dt,
                            steps0 << level,
                        );
                        match h {
                            Ok(h) => errs.push(split_bar::errors(&h, &reference).0),
                            Err(e) => {
                                println!("{method:?} m = {m}: {e}");
                                break;
                            }
                        }
                    }
                    if errs.len() == 4 {
                        let cell = |k: usize| {
                            (0..3)
                                .map(|l| format!("{:5.2}", (errs[l][k] / errs[l + 1][k]).log2()))
                                .collect::<Vec<_>>()
                                .join(" ")
                        };
                        println!(
                            "{:>4} {:>2} | {} | {} | {} | {} | {} | {} | {} | {:9.2e}",
                            format!("{method:?}").to_lowercase(),
                            m,
                            cell(0),
                            cell(1),
                            cell(2),
                            cell(3),
                            cell(4),
                            cell(5),
                            cell(6),
                            errs[0][3]
                        );
                    }
                }
            }
        }
    }
}
