//! Two-material interface advected at constant velocity and pressure (the README's case sections,
//! must-show 5): with the five-equation model and the Johnsen–Colonius α update the
//! pressure and velocity stay constant to 1e-6 relative — here air/helium and air/water
//! (stiffened gas) in 1-D, and air/helium on a diagonal in 2-D, over a full period.

use crate::common;
use common::solver;
use fluid_node::diagnostics::cell_prim;

fn max_deviation(s: &fluid_node::EulerSolver, p0: f64, v0: [f64; 3]) -> (f64, f64, f64) {
    let f = &s.fluid;
    let g = &f.grid;
    let vref = v0.iter().map(|x| x * x).sum::<f64>().sqrt();
    let (mut dp, mut dv, mut amin) = (0.0_f64, 0.0_f64, 1.0_f64);
    for r in 0..g.rows() {
        if !g.interior_row(r) {
            continue;
        }
        for i in g.irange() {
            let (_, v, p, al) = cell_prim(f, r, i);
            dp = dp.max((p / p0 - 1.0).abs());
            for d in 0..3 {
                dv = dv.max((v[d] - v0[d]).abs() / vref);
            }
            amin = amin.min(al[0]).min(1.0 - al[0]);
        }
    }
    (dp, dv, amin)
}

fn one_d(second: &str, rho2: f64, p0: f64, u: f64) -> (f64, f64, f64) {
    let mut s = solver(&format!(
        r#"
        cfl = 0.6
        [grid]
        cells = [200, 1, 1]
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 1.0, 1.0]
        [materials.air]
        eos = "ideal"
        gamma = 1.4
        [materials.helium]
        eos = "ideal"
        gamma = 1.67
        [materials.water]
        eos = "stiffened"
        gamma = 4.4
        p_inf = 6.0e8
        [[regions]]
        shape = "all"
        material = "air"
        density = 1.2
        pressure = {p0}
        velocity = [{u}, 0.0, 0.0]
        [[regions]]
        shape = "box"
        lower = [0.25, 0.0, 0.0]
        upper = [0.55, 1.0, 1.0]
        material = "{second}"
        density = {rho2}
        pressure = {p0}
        velocity = [{u}, 0.0, 0.0]
        [boundaries]
        x_lower = "periodic"
        x_upper = "periodic"
    "#
    ));
    s.advance_to(1.0 / u).expect("run");
    max_deviation(&s, p0, [u, 0.0, 0.0])
}

#[test]
fn air_helium_1d() {
    let (dp, dv, amin) = one_d("helium", 0.166, 1.0e5, 100.0);
    println!("air/helium 1-D: max |Δp|/p {dp:.3e}, max |Δu|/u {dv:.3e}, min α {amin:.3e}");
    assert!(dp < 1e-6 && dv < 1e-6);
}

#[test]
fn air_water_1d() {
    let (dp, dv, amin) = one_d("water", 1000.0, 1.0e5, 100.0);
    println!("air/water 1-D: max |Δp|/p {dp:.3e}, max |Δu|/u {dv:.3e}, min α {amin:.3e}");
    assert!(dp < 1e-6 && dv < 1e-6);
}

#[test]
fn air_helium_2d_diagonal() {
    let (p0, u) = (1.0e5, 100.0);
    let mut s = solver(&format!(
        r#"
        cfl = 0.6
        [grid]
        cells = [48, 48, 1]
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 1.0, 1.0]
        [materials.air]
        eos = "ideal"
        gamma = 1.4
        [materials.helium]
        eos = "ideal"
        gamma = 1.67
        [[regions]]
        shape = "all"
        material = "air"
        density = 1.2
        pressure = {p0}
        velocity = [{u}, {u}, 0.0]
        [[regions]]
        shape = "sphere"
        center = [0.5, 0.5, 0.0]
        radius = 0.25
        material = "helium"
        density = 0.166
        pressure = {p0}
        velocity = [{u}, {u}, 0.0]
        [boundaries]
        x_lower = "periodic"
        x_upper = "periodic"
        y_lower = "periodic"
        y_upper = "periodic"
    "#
    ));
    s.advance_to(1.0 / u).expect("run");
    let (dp, dv, amin) = max_deviation(&s, p0, [u, u, 0.0]);
    println!(
        "air/helium 2-D diagonal: max |Δp|/p {dp:.3e}, max |Δv|/|v| {dv:.3e}, min α {amin:.3e}"
    );
    assert!(dp < 1e-6 && dv < 1e-6);
}
