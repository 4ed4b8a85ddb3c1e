//! Sod shock tube (the README's case sections "Fluid node"): density L1 error against the exact Riemann
//! solution at t = 0.2, ≤ 1 % at 400 cells, observed order ≥ 0.9 over 200/400/800 cells.

use crate::common;
use common::{ExactRiemann, solver};
use fluid_node::diagnostics::x_line;

fn sod(n: usize, limiter: &str) -> f64 {
    let mut s = solver(&fluid_node::setup::sod_case(n, limiter));
    s.advance_to(0.2).expect("run");
    let ex = ExactRiemann::new(1.4, (1.0, 0.0, 1.0), (0.125, 0.0, 0.1));
    let dx = 1.0 / n as f64;
    let mut err = 0.0;
    let mut norm = 0.0;
    for (x, rho, _, _) in x_line(&s.fluid, 0, 0) {
        // cell average of the exact solution (16-point midpoint rule)
        let mut r_ex = 0.0;
        for q in 0..16 {
            let xq = x + ((q as f64 + 0.5) / 16.0 - 0.5) * dx;
            r_ex += ex.sample((xq - 0.5) / 0.2).0 / 16.0;
        }
        err += (rho - r_ex).abs() * dx;
        norm += r_ex.abs() * dx;
    }
    err / norm
}

#[test]
fn exact_solver_reproduces_reference_star_state() {
    let ex = ExactRiemann::new(1.4, (1.0, 0.0, 1.0), (0.125, 0.0, 0.1));
    assert!((ex.p_star - 0.30313).abs() < 1e-5, "p* {}", ex.p_star);
    assert!((ex.u_star - 0.92745).abs() < 1e-5, "u* {}", ex.u_star);
    // star densities at the contact's two sides and the shock position at t = 0.2
    let l = ex.sample(0.9);
    let r = ex.sample(0.95);
    assert!((l.0 - 0.42632).abs() < 1e-5, "rho*L {}", l.0);
    assert!((r.0 - 0.26557).abs() < 1e-5, "rho*R {}", r.0);
    assert!((ex.sample((0.8504 - 0.5) / 0.2).0 - 0.26557).abs() < 1e-5);
    assert!((ex.sample((0.8505 - 0.5) / 0.2).0 - 0.125).abs() < 1e-12);
}

#[test]
fn sod_l1_error_and_order() {
    let e: Vec<f64> = [200, 400, 800]
        .iter()
        .map(|&n| sod(n, "van_leer"))
        .collect();
    let o1 = (e[0] / e[1]).log2();
    let o2 = (e[1] / e[2]).log2();
    let order = (e[0] / e[2]).log2() / 2.0;
    println!(
        "Sod density L1 (relative): 200 {:.4e}, 400 {:.4e}, 800 {:.4e}; orders {o1:.3}, {o2:.3}, overall {order:.3}",
        e[0], e[1], e[2]
    );
    assert!(e[1] <= 0.01, "L1 at 400 cells {}", e[1]);
    assert!(order >= 0.9, "observed order {order}");
}
