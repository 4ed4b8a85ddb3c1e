//! Normal shock reflection from a rigid wall, γ 1.4 (the README's case sections): the pressure behind the
//! reflected shock over the pressure ahead of the incident one, p5/p1 = 5.4253 (Ms 1.5) and
//! 15.0 (Ms 2), within 2 % on a 400-cell grid. Incident state from the Rankine–Hugoniot
//! relations; the run ends when the exact reflected shock has travelled 0.25 from the wall.

use crate::common;
use common::solver;
use fluid_node::diagnostics::x_line;

const G: f64 = 1.4;

/// (ρ2, u2, p2, W) behind a shock of Mach number ms running into (1, 0, 1).
pub fn post_shock(ms: f64) -> (f64, f64, f64, f64) {
    let c1 = G.sqrt();
    let w = ms * c1;
    let r2 = (G + 1.0) * ms * ms / ((G - 1.0) * ms * ms + 2.0);
    let p2 = 1.0 + 2.0 * G / (G + 1.0) * (ms * ms - 1.0);
    (r2, w * (1.0 - 1.0 / r2), p2, w)
}

fn reflect(ms: f64, expected: f64) -> f64 {
    let (r2, u2, p2, w) = post_shock(ms);
    // reflected shock: p5/p2 from the normal-shock relations in the frame of state 2
    let p52 = ((3.0 * G - 1.0) * p2 - (G - 1.0)) / ((G - 1.0) * p2 + (G + 1.0));
    let p5 = p52 * p2;
    let r52 = (1.0 + (G + 1.0) / (G - 1.0) * p52) / ((G + 1.0) / (G - 1.0) + p52);
    let wr = r2 * u2 / (r52 * r2 - r2);
    assert!(
        (p5 - expected).abs() < 1e-3 * expected,
        "reference relations give {p5}"
    );
    let t_end = 0.5 / w + 0.25 / wr;
    let mut s = solver(&format!(
        r#"
        cfl = 0.5
        [grid]
        cells = [400, 1, 1]
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 1.0, 1.0]
        [materials.air]
        eos = "ideal"
        gamma = 1.4
        [[regions]]
        shape = "all"
        material = "air"
        density = 1.0
        pressure = 1.0
        [[regions]]
        shape = "half_space"
        point = [0.5, 0.0, 0.0]
        normal = [-1.0, 0.0, 0.0]
        material = "air"
        density = {r2}
        pressure = {p2}
        velocity = [{u2}, 0.0, 0.0]
        [boundaries]
        x_lower = {{ kind = "inflow", material = "air", density = {r2}, pressure = {p2}, velocity = [{u2}, 0.0, 0.0] }}
        x_upper = "wall"
    "#
    ));
    s.advance_to(t_end).expect("run");
    let line = x_line(&s.fluid, 0, 0);
    let region: Vec<f64> = line
        .iter()
        .filter(|c| c.0 > 0.8 && c.0 < 0.98)
        .map(|c| c.3)
        .collect();
    region.iter().sum::<f64>() / region.len() as f64
}

#[test]
fn reflected_pressure_ms_1_5() {
    let p5 = reflect(1.5, 5.4253);
    println!(
        "Ms 1.5: p5/p1 = {p5:.4} (exact 5.4253), error {:.3} %",
        100.0 * (p5 / 5.4253 - 1.0)
    );
    assert!((p5 / 5.4253 - 1.0).abs() < 0.02);
}

#[test]
fn reflected_pressure_ms_2() {
    let p5 = reflect(2.0, 15.0);
    println!(
        "Ms 2: p5/p1 = {p5:.4} (exact 15.0), error {:.3} %",
        100.0 * (p5 / 15.0 - 1.0)
    );
    assert!((p5 / 15.0 - 1.0).abs() < 0.02);
}
