//! Momentum balance of the finite-volume scheme (conservation law, seed 002 §2.3): the
//! change of the gas momentum over a run equals the impulse of the domain boundary fluxes
//! (`Fluid::boundary_impulse`, the Σ_stages w_s dt ∮ F of SSP-RK3) to round-off. Run on a
//! 2-D blast whose shock reaches walls, a symmetry plane and outflow boundaries (the fused
//! 2-D stage, which stores only the boundary faces) and on a small 3-D blast (the unfused
//! stage), one and two materials.

mod common;
use common::solver;
use fluid_node::diagnostics;

fn case(nd: usize, two: bool) -> String {
    let cells = if nd == 3 {
        "[16, 14, 12]"
    } else {
        "[48, 40, 1]"
    };
    let helium = if two {
        r#"
        [materials.helium]
        eos = "ideal"
        gamma = 1.67
        [[regions]]
        shape = "sphere"
        center = [0.75, 0.5, 0.4]
        radius = 0.12
        material = "helium"
        density = 0.138
        pressure = 0.1
        "#
    } else {
        ""
    };
    let z = if nd == 3 {
        "z_lower = \"symmetry\"\n        z_upper = \"outflow\""
    } else {
        ""
    };
    format!(
        r#"
        [grid]
        cells = {cells}
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 0.8, 0.7]
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
        center = [0.3, 0.3, 0.3]
        radius = 0.15
        material = "air"
        density = 1.0
        pressure = 10.0
        {helium}
        [boundaries]
        x_lower = "wall"
        x_upper = "outflow"
        y_lower = "symmetry"
        y_upper = "outflow"
        {z}
    "#
    )
}

#[test]
fn momentum_change_equals_boundary_impulse() {
    for (nd, two) in [(2, false), (2, true), (3, false)] {
        let mut s = solver(&case(nd, two));
        let t0 = diagnostics::totals(&mut s.fluid).expect("totals");
        // long enough for the shock to reflect from the wall and leave through the outflow
        s.advance_to(0.25).expect("run");
        let t1 = diagnostics::totals(&mut s.fluid).expect("totals");
        let imp = s.fluid.boundary_impulse;
        // round-off scale: the gross momentum of the gas plus the impulse itself
        let scale = t1.momentum_gross + imp.iter().map(|x| x.abs()).sum::<f64>();
        for (d, &imp_d) in imp.iter().enumerate().take(nd) {
            let change = t1.momentum[d] - t0.momentum[d];
            println!(
                "{nd}-D two {two}: momentum {d}: change {change:.6e}, boundary impulse \
                 {imp_d:.6e}, residual / gross {:.1e}",
                (change - imp_d).abs() / scale
            );
            // the walls must push: a balance of two zeros would test nothing
            assert!(imp_d.abs() > 1e-3 * scale, "no boundary impulse in {d}");
            assert!(
                (change - imp_d).abs() <= 1e-12 * scale,
                "{nd}-D: momentum {d} changed by {change:e}, boundary impulse {imp_d:e}"
            );
        }
    }
}
