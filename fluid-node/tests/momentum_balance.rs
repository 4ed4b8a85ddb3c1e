//! Momentum and energy balance of the finite-volume scheme (conservation law, seed 002 §2.3): the
//! change of the gas momentum over a run equals the impulse of the domain boundary fluxes
//! (`Fluid::boundary_impulse`, the Σ_stages w_s dt ∮ F of SSP-RK3) to round-off. Run on a
//! 2-D blast whose shock reaches walls, a symmetry plane and outflow boundaries (the fused
//! 2-D stage, which stores only the boundary faces) and on a small 3-D blast (the unfused
//! stage), one and two materials; and the same blast fed by an inflow, where the energy
//! change equals the work of the boundary fluxes (`Fluid::boundary_work`).

use crate::common;
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

/// The walled blast with its `x_lower` wall turned into an inflow of denser, faster air.
fn inflow_blast_case(cells: [usize; 3], two: bool) -> String {
    let case = common::walled_blast_case(cells, two, "van_leer");
    let wall = "x_lower = \"wall\"";
    assert!(case.contains(wall), "the case has no x_lower wall");
    case.replace(
        wall,
        r#"x_lower = { kind = "inflow", material = "air", density = 1.5, pressure = 0.3, velocity = [0.4, 0.0, 0.0] }"#,
    )
}

/// Energy balance of the finite-volume scheme: the total energy is a conserved variable, so
/// its change over a run equals the work of the domain boundary fluxes
/// (`Fluid::boundary_work`, energy carried in through the inflow and out through the
/// outflow) to round-off, whatever the scheme dissipates inside (it turns kinetic into
/// internal energy). Checked with an inflow and an outflow on the fused 2-D stage and the
/// unfused 3-D one; the momentum balances there too, against the inflow's momentum flux.
#[test]
fn energy_change_equals_boundary_work_through_inflow_and_outflow() {
    let mut checked = 0;
    for (nd, two) in [(2, false), (2, true), (3, false)] {
        let cells = if nd == 3 { [16, 14, 12] } else { [48, 40, 1] };
        let mut s = solver(&inflow_blast_case(cells, two));
        let t0 = diagnostics::totals(&mut s.fluid).expect("totals");
        s.advance_to(0.25).expect("run");
        let t1 = diagnostics::totals(&mut s.fluid).expect("totals");
        let w = s.fluid.boundary_work;
        let (e0, e1) = (t0.kinetic + t0.internal, t1.kinetic + t1.internal);
        let scale = e0.max(e1) + w.abs();
        println!(
            "{nd}-D two {two}: energy {e0:.6e} -> {e1:.6e}, change {:.6e}, boundary work \
             {w:.6e}, residual / scale {:.1e}",
            e1 - e0,
            ((e1 - e0) - w).abs() / scale
        );
        // the inflow and outflow must carry energy: a balance of two zeros tests nothing
        assert!(w.abs() > 1e-3 * scale, "{nd}-D: no boundary work ({w:e})");
        assert!(
            ((e1 - e0) - w).abs() <= 1e-12 * scale,
            "{nd}-D: energy changed by {:e}, boundary work {w:e}",
            e1 - e0
        );
        let imp = s.fluid.boundary_impulse;
        let pscale = t1.momentum_gross + imp.iter().map(|x| x.abs()).sum::<f64>();
        for (d, &imp_d) in imp.iter().enumerate().take(nd) {
            let change = t1.momentum[d] - t0.momentum[d];
            assert!(
                (change - imp_d).abs() <= 1e-12 * pscale,
                "{nd}-D: momentum {d} changed by {change:e}, boundary impulse {imp_d:e}"
            );
        }
        checked += 1;
    }
    assert_eq!(checked, 3);
}
