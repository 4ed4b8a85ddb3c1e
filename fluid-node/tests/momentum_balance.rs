//! Momentum balance of the finite-volume scheme (conservation law, seed 002 §2.3): the
//! change of the gas momentum over a run equals the impulse of the domain boundary fluxes
//! (`Fluid::boundary_impulse`, the Σ_stages w_s dt ∮ F of SSP-RK3) to round-off. Run on a
//! 2-D blast whose shock reaches walls, a symmetry plane and outflow boundaries (the fused
//! 2-D stage, which stores only the boundary faces) and on a small 3-D blast (the unfused
//! stage), one and two materials.

mod common;
use common::solver;
use fluid_node::diagnostics;

#[test]
fn momentum_change_equals_boundary_impulse() {
    for (nd, two) in [(2, false), (2, true), (3, false)] {
        let cells = if nd == 3 { [16, 14, 12] } else { [48, 40, 1] };
        let mut s = solver(&common::walled_blast_case(cells, two, "van_leer"));
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
