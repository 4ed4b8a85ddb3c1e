//! Radial geometries (docs/physics.md, "Radial geometries"): 1-D cylindrical and spherical
//! grids and 2-D axisymmetric ones, against exact solutions.
//!
//! * A gas at rest at uniform pressure stays at rest to round-off in every geometry (the
//!   pressure's push on a ring's or shell's sides balances the face fluxes).
//! * Sedov's point blast (γ 1.4, ρ0 1, E 1) given by `energy`: the energy deposited to 1e-12,
//!   mass and energy conserved to round-off in the shells' volumes.
//! * The same blast on a radial grid and on a 2-D Cartesian, 2-D axisymmetric or 3-D Cartesian
//!   grid agree within either's error against the similarity solution.
//!
//! Noh's implosion and Sedov's blast against their exact solutions, with observed convergence,
//! run from their case files in the end-to-end tests (`tests/tests/fluid_cases.rs`).

use crate::common;
use common::solver;
use fluid_node::diagnostics::{cell_prim, totals, x_line};
use fluid_node::exact::Sedov;

/// The parameter table of an ideal gas (γ, ρ0, p0) at rest on the grid [0, upper] of
/// `cells` in `geometry`, `extra` appended (regions, boundaries).
fn gas_case(
    geometry: &str,
    cells: [usize; 3],
    upper: [f64; 3],
    gamma: f64,
    rho0: f64,
    p0: f64,
    extra: &str,
) -> String {
    format!(
        r#"
        geometry = "{geometry}"
        cfl = 0.5
        [grid]
        cells = {cells:?}
        lower = [0.0, 0.0, 0.0]
        upper = {upper:?}
        [materials.gas]
        eos = "ideal"
        gamma = {gamma}
        [[regions]]
        shape = "all"
        material = "gas"
        density = {rho0}
        pressure = {p0}
        {extra}
    "#
    )
}

/// [`gas_case`] on a 1-D radial grid of `n` cells over [0, 1.2].
fn radial_1d(geometry: &str, n: usize, gamma: f64, rho0: f64, p0: f64, extra: &str) -> String {
    gas_case(geometry, [n, 1, 1], [1.2, 1.0, 1.0], gamma, rho0, p0, extra)
}

#[test]
fn a_gas_at_rest_stays_at_rest_in_every_radial_geometry() {
    let cases = [
        ("cylindrical", [60, 1, 1], 0.0),
        ("spherical", [60, 1, 1], 0.0),
        ("spherical", [60, 1, 1], 0.3),
        ("axisymmetric", [24, 20, 1], 0.0),
    ];
    for (geometry, cells, r0) in cases {
        let walls = "[boundaries]\nx_upper = \"wall\"\ny_lower = \"wall\"\ny_upper = \"wall\"";
        let text = gas_case(geometry, cells, [1.0; 3], 1.4, 1.3, 2.1e5, walls).replace(
            "lower = [0.0, 0.0, 0.0]",
            &format!("lower = [{r0}, 0.0, 0.0]"),
        );
        let mut s = solver(&text);
        let c = (1.4_f64 * 2.1e5 / 1.3).sqrt();
        for _ in 0..40 {
            fluid_node::step::step(&mut s.fluid, 1.0).expect("step");
        }
        let f = &s.fluid;
        let g = &f.grid;
        let (mut du, mut dp, mut cells_seen) = (0.0_f64, 0.0_f64, 0);
        for r in 0..g.rows() {
            if !g.interior_row(r) {
                continue;
            }
            for i in g.irange() {
                let (_, v, p, _) = cell_prim(f, r, i);
                du = du.max(v[0].abs()).max(v[1].abs());
                dp = dp.max((p - 2.1e5).abs() / 2.1e5);
                cells_seen += 1;
            }
        }
        println!(
            "{geometry} from r {r0}: {cells_seen} cells, max |u|/c {:.2e}, max |Δp|/p {dp:.2e}",
            du / c
        );
        assert_eq!(cells_seen, g.cells());
        assert!(du / c < 1e-12, "{geometry}: |u|/c {}", du / c);
        assert!(dp < 1e-12, "{geometry}: Δp/p {dp}");
    }
}

#[test]
fn sedov_deposits_its_energy_exactly_and_conserves_mass_and_energy() {
    let (gamma, rho0, p0, e) = (1.4, 1.0, 1e-6, 1.0);
    for (geometry, nu) in [("cylindrical", 2), ("spherical", 3)] {
        let sedov = Sedov::new(nu, gamma);
        // the time at which the shock reaches r = 1
        let t = (sedov.alpha * rho0 / e).sqrt();
        for n in [120, 240] {
            let dr = 1.2 / n as f64;
            let blast = blast(3.0 * dr, rho0, e);
            let mut s = solver(&radial_1d(geometry, n, gamma, rho0, p0, &blast));
            let before = totals(&mut s.fluid).expect("totals");
            s.advance_to(t).expect("run");
            let after = totals(&mut s.fluid).expect("totals");
            let e0 = before.kinetic + before.internal;
            let e1 = after.kinetic + after.internal - s.fluid.boundary_work;
            let ambient = volume(geometry, 1.2) - volume(geometry, 3.0 * dr);
            let e_blast = e0 - p0 / (gamma - 1.0) * ambient;
            println!(
                "Sedov {geometry} {n} cells: blast energy {e_blast:.15} (given 1), energy drift {:.2e} over {} steps, mass drift {:.2e}",
                (e1 - e0) / e0,
                s.fluid.steps,
                (after.mass - before.mass) / before.mass
            );
            assert!((e_blast - e).abs() < 1e-12, "deposited {e_blast}");
            // round-off, growing with the steps (about 1e-16 each)
            let tol = 1e-15 * s.fluid.steps as f64;
            assert!(
                ((e1 - e0) / e0).abs() < tol,
                "energy drift {}",
                (e1 - e0) / e0
            );
            assert!(((after.mass - before.mass) / before.mass).abs() < tol);
        }
    }
}

/// A region of `energy` (J) at density rho0 within `radius` of the origin.
fn blast(radius: f64, rho0: f64, energy: f64) -> String {
    format!(
        r#"
        [[regions]]
        shape = "sphere"
        center = [0.0, 0.0, 0.0]
        radius = {radius}
        material = "gas"
        density = {rho0}
        energy = {energy}
    "#
    )
}

/// Volume within radius r (per metre of axis when cylindrical).
fn volume(geometry: &str, r: f64) -> f64 {
    let pi = std::f64::consts::PI;
    match geometry {
        "spherical" => 4.0 / 3.0 * pi * r.powi(3),
        _ => pi * r * r,
    }
}

/// Density at radius r of a 1-D radial run, linear between cell centres.
fn interpolate(line: &[(f64, f64, f64, f64)], r: f64) -> f64 {
    let k = line.partition_point(|c| c.0 < r);
    if k == 0 {
        return line[0].1;
    }
    if k == line.len() {
        return line[k - 1].1;
    }
    let (a, b) = (line[k - 1], line[k]);
    a.1 + (r - a.0) / (b.0 - a.0) * (b.1 - a.1)
}

#[test]
fn sedov_on_radial_grids_agrees_with_the_cartesian_and_axisymmetric_runs() {
    let (gamma, rho0, p0, e) = (1.4, 1.0, 1e-6, 1.0);
    // (geometry of the multi-D run, cells, share of the blast it holds, the 1-D geometry)
    let runs = [
        ("cartesian", [96, 96, 1], 0.25, "cylindrical", 2),
        ("axisymmetric", [64, 64, 1], 0.5, "spherical", 3),
        ("cartesian", [32, 32, 32], 0.125, "spherical", 3),
    ];
    for (geometry, cells, share, radial, nu) in runs {
        let sedov = Sedov::new(nu, gamma);
        let t = (sedov.alpha * rho0 / e).sqrt();
        let n = cells[0];
        let dr = 1.2 / n as f64;
        let blast = |energy: f64| blast(3.0 * dr, rho0, energy);
        let mut one = solver(&radial_1d(radial, n, gamma, rho0, p0, &blast(e)));
        one.advance_to(t).expect("1-D run");
        let line = x_line(&one.fluid, 0, 0);
        let upper_z = if cells[2] > 1 { 1.2 } else { 1.0 };
        let boundaries =
            "[boundaries]\nx_lower = \"symmetry\"\ny_lower = \"symmetry\"\nz_lower = \"symmetry\"";
        let mut multi = solver(&gas_case(
            geometry,
            cells,
            [1.2, 1.2, upper_z],
            gamma,
            rho0,
            p0,
            &format!("{}\n{boundaries}", blast(share * e)),
        ));
        let started = std::time::Instant::now();
        multi.advance_to(t).expect("multi-D run");
        let f = &multi.fluid;
        let g = &f.grid;
        let (mut d_line, mut d_exact, mut d_line_exact, mut norm, mut seen) =
            (0.0, 0.0, 0.0, 0.0, 0);
        for row in 0..g.rows() {
            if !g.interior_row(row) {
                continue;
            }
            let (j, k) = g.jk(row);
            for i in g.irange() {
                let x = g.centre(i, j, k);
                let r = (x[0] * x[0] + x[1] * x[1] + if cells[2] > 1 { x[2] * x[2] } else { 0.0 })
                    .sqrt();
                if r > 1.15 {
                    continue;
                }
                let rho = cell_prim(f, row, i).0;
                let exact = sedov.state(e, rho0, p0, r, t).0;
                let on_line = interpolate(&line, r);
                d_line += (rho - on_line).abs();
                d_exact += (rho - exact).abs();
                d_line_exact += (on_line - exact).abs();
                norm += exact;
                seen += 1;
            }
        }
        let (d_line, d_exact, d_line_exact) = (d_line / norm, d_exact / norm, d_line_exact / norm);
        println!(
            "Sedov {geometry} {cells:?} ({:.1} s) against {radial} {n} cells, over {seen} cells within r 1.15: \
             L1 density difference {d_line:.4}; errors against the exact solution: {geometry} {d_exact:.4}, {radial} {d_line_exact:.4}",
            started.elapsed().as_secs_f64()
        );
        assert!(seen > cells.iter().product::<usize>() / 3);
        // the two runs differ by less than either's error against the exact solution: what
        // the radial grid computes is what the multi-D grid does, at a thousandth of the cost
        assert!(
            d_line < d_exact.min(d_line_exact),
            "{geometry}: difference {d_line} vs error {d_exact}"
        );
    }
}
