//! Observed order of the Lagrange-multiplier multi-time-step coupling on the split bar
//! (seed 003 §4–§5): u, v, a at the interface and at the tip and λ, for the methods
//! gs4, gc and ph, step ratios m = 1 (the single-domain integrator), 2, 3, 4, 8, under three
//! halvings of the system step, against a single-domain run of the same mesh with a 128 times
//! smaller step, and the energy the interface dissipated (−Σ of the interface work on every
//! side). The first table repeats the first pair under the sin² ramp, to show why the
//! others use the septic one (`solid_node::lagrange`).
//!
//! `cargo run --release -p solid-node --example lagrange_order [small]`

use mechanics::time::{Design, Gs4};
use protocol::scheme::lagrange::Method;
use solid_node::fixtures::split_bar::{self, Half, Histories, Ramp};

fn u0(r1: f64, r2: f64, rs: f64) -> Gs4 {
    Gs4::u0(Design {
        rho1: r1,
        rho2: r2,
        rho_s: rs,
    })
}

/// Errors at ΔT₀ … ΔT₀/8, or why the run failed.
fn study(
    ramp: Ramp,
    method: Method,
    (lc, rc): (Gs4, Gs4),
    m: usize,
    reference: &Histories,
) -> Result<Vec<([f64; 7], f64)>, String> {
    let dt0 = split_bar::left_transit();
    let steps0 = (2.0 * split_bar::ramp_time() / dt0).round() as usize;
    (0..4)
        .map(|level| {
            let left = Half {
                coef: lc,
                substeps: 1,
            };
            let right = Half {
                coef: rc,
                substeps: m,
            };
            let dt = dt0 / (1 << level) as f64;
            split_bar::split(ramp, method, left, right, dt, steps0 << level).map(|h| {
                let dissipated = -h.interface_work.last().copied().unwrap_or(0.0);
                (split_bar::errors(&h, reference).0, dissipated)
            })
        })
        .collect()
}

fn main() {
    let small = std::env::args().any(|a| a == "small");
    let dt0 = split_bar::left_transit();
    let t_end = 2.0 * split_bar::ramp_time();
    let steps0 = (t_end / dt0).round() as usize;
    let refine = 128;
    let newmark = u0(1.0, 1.0, 0.0);
    let reference =
        |ramp| split_bar::single(ramp, newmark, dt0 / refine as f64, steps0 * refine, 1);
    let ratios: &[usize] = if small { &[1, 2] } else { &[1, 2, 3, 4, 8] };
    println!(
        "split bar, ΔT₀ = h_left/c = {dt0:.4e} s, {steps0} system steps to {t_end:.4e} s; \
         reference: one domain, U0(1,1,0) at ΔT₀/{refine}; errors: largest over the run, \
         relative to the reference's largest value"
    );
    let pairs: [(&str, Gs4, Gs4, Ramp); 6] = [
        (
            "implicit U0(1,1,0) | implicit U0(1,1,0), sin² ramp",
            newmark,
            newmark,
            Ramp::Sin2,
        ),
        (
            "implicit U0(1,1,0) | implicit U0(1,1,0)",
            newmark,
            newmark,
            Ramp::Septic,
        ),
        (
            "implicit U0(1,1,0) | explicit CD",
            newmark,
            Gs4::central_difference(),
            Ramp::Septic,
        ),
        (
            "explicit CD | implicit U0(1,1,0)",
            Gs4::central_difference(),
            newmark,
            Ramp::Septic,
        ),
        (
            "implicit U0(0.8,0.8,0.8) | implicit U0(0.8,0.8,0.8)",
            u0(0.8, 0.8, 0.8),
            u0(0.8, 0.8, 0.8),
            Ramp::Septic,
        ),
        (
            "implicit U0(0.9,0.6,0.3) | implicit U0(1,1,0)",
            u0(0.9, 0.6, 0.3),
            newmark,
            Ramp::Septic,
        ),
    ];
    let sin2 = reference(Ramp::Sin2);
    let septic = reference(Ramp::Septic);
    for (name, lc, rc, ramp) in pairs {
        let reference = if ramp == Ramp::Sin2 { &sin2 } else { &septic };
        println!("\n{name} (left | right); orders over halvings 1→2, 2→4, 4→8 of ΔT₀");
        println!(
            "{:>4} {:>2} | {:^17} | {:^17} | {:^17} | {:^17} | {:^17} | {:^17} | {:^17} | {:>9} | ΔE_Γ (J) dissipated at the interface by t_end, ΔT₀ … ΔT₀/8",
            "meth", "m", "u_Γ", "v_Γ", "a_Γ", "u_tip", "v_tip", "a_tip", "λ", "err u_tip"
        );
        for method in [Method::Gs4, Method::Gc, Method::Ph] {
            for &m in ratios {
                // An explicit right half sub-cycles at or below its own Courant limit
                // (h_right = h_left/3); m = 3 sits exactly on it and is left out.
                if (rc.explicit && m < 4) || (ramp == Ramp::Sin2 && method != Method::Gs4) {
                    continue;
                }
                let errs = match study(ramp, method, (lc, rc), m, reference) {
                    Ok(e) => e,
                    Err(e) => {
                        println!("{method:?} m = {m}: {e}");
                        continue;
                    }
                };
                let cell = |k: usize| {
                    (0..3)
                        .map(|l| format!("{:5.2}", (errs[l].0[k] / errs[l + 1].0[k]).log2()))
                        .collect::<Vec<_>>()
                        .join(" ")
                };
                println!(
                    "{:>4} {:>2} | {} | {} | {} | {} | {} | {} | {} | {:9.2e} | {}",
                    format!("{method:?}").to_lowercase(),
                    m,
                    cell(0),
                    cell(1),
                    cell(2),
                    cell(3),
                    cell(4),
                    cell(5),
                    cell(6),
                    errs[0].0[3],
                    errs.iter()
                        .map(|e| format!("{:9.2e}", e.1))
                        .collect::<Vec<_>>()
                        .join(" ")
                );
            }
        }
    }
}
