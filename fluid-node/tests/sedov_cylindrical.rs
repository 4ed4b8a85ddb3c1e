//! Sedov blast, 2-D cylindrical (a line source on a 2-D grid; the README's case sections allows it), γ 1.4,
//! ρ0 1: E = α ρ0 R⁴/t² with α = 0.98407 per unit length, from integrating the similarity
//! equations (`common::sedov_alpha`; the same integration gives the README's case sections's spherical
//! 0.851072, checked here). Checks the shock radius at t = 1 within 3 % and the symmetry
//! between quadrants (mirror in x, y and the diagonal) to round-off.

use crate::common;
use common::{sedov_alpha, solver};
use fluid_node::diagnostics::cell_prim;

#[test]
fn sedov_cylindrical_radius_and_symmetry() {
    let n = 96;
    let h = 2.4 / n as f64;
    let a3 = sedov_alpha(3, 1.4);
    assert!((a3 - 0.851072).abs() < 2e-6, "spherical alpha {a3}");
    let e = sedov_alpha(2, 1.4);
    assert!((e - 0.98407).abs() < 1e-4, "cylindrical alpha {e}");
    // energy in the four cells around the centre (unit thickness in z)
    let p_in = 0.4 * e / (4.0 * h * h);
    let mut s = solver(&format!(
        r#"
        cfl = 0.5
        [grid]
        cells = [{n}, {n}, 1]
        lower = [-1.2, -1.2, 0.0]
        upper = [1.2, 1.2, 1.0]
        [materials.gas]
        eos = "ideal"
        gamma = 1.4
        [[regions]]
        shape = "all"
        material = "gas"
        density = 1.0
        pressure = 1.0e-6
        [[regions]]
        shape = "box"
        lower = [{lo}, {lo}, 0.0]
        upper = [{h}, {h}, 1.0]
        material = "gas"
        density = 1.0
        pressure = {p_in}
        [boundaries]
        x_lower = "outflow"
        x_upper = "outflow"
        y_lower = "outflow"
        y_upper = "outflow"
    "#,
        lo = -h
    ));
    s.advance_to(1.0).expect("run");
    let f = &s.fluid;
    let g = &f.grid;
    let rho = |i: usize, j: usize| cell_prim(f, g.row(j + g.g[1], g.g[2]), i + g.g[0]).0;
    // symmetry: mirrors in x, y and the diagonal
    let mut asym = 0.0_f64;
    for j in 0..n {
        for i in 0..n {
            let r = rho(i, j);
            for m in [rho(n - 1 - i, j), rho(i, n - 1 - j), rho(j, i)] {
                asym = asym.max((r - m).abs() / r);
            }
        }
    }
    // shock radius along the axis and the diagonal: outermost crossing of (1 + ρ_peak)/2
    let radius = |pts: Vec<(f64, f64)>| -> f64 {
        let peak = pts.iter().map(|p| p.1).fold(0.0, f64::max);
        let half = 0.5 * (1.0 + peak);
        let mut r = 0.0;
        for w in pts.windows(2) {
            if w[0].1 >= half && w[1].1 < half {
                r = w[0].0 + (half - w[0].1) / (w[1].1 - w[0].1) * (w[1].0 - w[0].0);
            }
        }
        r
    };
    let axis: Vec<(f64, f64)> = (n / 2..n)
        .map(|i| ((i as f64 + 0.5) * h - 1.2, rho(i, n / 2)))
        .collect();
    let diag: Vec<(f64, f64)> = (n / 2..n)
        .map(|i| (((i as f64 + 0.5) * h - 1.2) * 2f64.sqrt(), rho(i, i)))
        .collect();
    let (ra, rd) = (radius(axis), radius(diag));
    println!(
        "Sedov cylindrical {n}x{n}: shock radius axis {ra:.4}, diagonal {rd:.4} (exact 1.0); max quadrant asymmetry {asym:.3e}"
    );
    assert!((ra - 1.0).abs() < 0.03, "axis radius {ra}");
    assert!((rd - 1.0).abs() < 0.03, "diagonal radius {rd}");
    assert!(asym < 1e-12, "asymmetry {asym}");
}
