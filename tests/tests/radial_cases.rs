//! Noh's implosion and Sedov's point blast from their case files (`examples/noh.toml`,
//! `examples/sedov.toml`, each spherical and, as the variant `cylindrical`, cylindrical): the
//! case is read with its variant as `cosim run` reads it, the fluid node's parameters built as
//! the node builds them, and the run compared with the exact solution
//! (`fluid_node::exact`) at the case's end time, at resolutions doubling from 120 cells.
//!
//! * Noh (γ 5/3, u0 −1, t 0.6): density L1 error inside r 0.5 (where the outer outflow face's
//!   inflow has not reached) below 4 % at 960 cells, fitted order ≥ 0.8 over 120–960 cells;
//!   the post-shock plateau (0.06 < r < 0.18) within 2 % of 64 and 16 at 960 cells.
//! * Sedov (γ 1.4, E 1): density L1 error over the grid below 5 % at 480 cells, fitted order
//!   ≥ 0.7 over 120–480 cells; the shock within three cells of the exact radius.
//!
//! The levels put the exact shock at the same place within a cell each time, so the fitted
//! order is not the scatter of a shock's sub-cell position. Shocks limit a second-order scheme
//! to first order in L1; Sedov's steep post-shock profile keeps these levels short of it.
//! And `cosim run examples/noh.toml --variant small` runs as a real coupled run: it finishes,
//! and the coordinator's balance holds (the radial gas's momentum is zero by symmetry).

use cosim_tests::*;
use fluid_node::EulerSolver;
use fluid_node::diagnostics::x_line;
use fluid_node::exact::{Sedov, noh};

/// The gas node of `examples/CASE` with `variant` at `cells` cells, and the case's end time.
fn gas(case: &str, variant: Option<&str>, cells: usize) -> (EulerSolver, f64) {
    let path = workspace_root().join("examples").join(case);
    let sets = [format!("gas.grid.cells=[{cells}, 1, 1]")];
    // the node executable is found beside `cosim`, not beside this test: name it by its path
    let text = std::fs::read_to_string(&path)
        .expect("the case file")
        .replace(
            "solver = \"fluid-node\"",
            &format!("solver = {:?}", bin("fluid-node").display().to_string()),
        );
    let c =
        coordinator::case::load_variant_text(&text, &path, variant, &sets).expect("the case loads");
    let node = c
        .nodes
        .iter()
        .find(|n| n.name == "gas")
        .expect("a gas node");
    let p = fluid_node::setup::parse(&node.params).expect("params parse");
    let f = fluid_node::setup::build(&p).expect("params build");
    (EulerSolver::from_fluid(f), c.run.end_time)
}

/// L1 of the density's difference from `exact` over cells with r ≤ r_max, relative to the
/// exact profile's L1; and the cells measured.
fn l1(line: &[(f64, f64, f64, f64)], r_max: f64, exact: impl Fn(f64) -> f64) -> (f64, usize) {
    let (mut num, mut den, mut n) = (0.0, 0.0, 0);
    for &(r, rho, _, _) in line.iter().filter(|c| c.0 <= r_max) {
        num += (rho - exact(r)).abs();
        den += exact(r);
        n += 1;
    }
    (num / den, n)
}

/// Slope of the least-squares line through (level, −log₂ error): the observed order.
fn fitted_order(errors: &[f64]) -> f64 {
    let n = errors.len() as f64;
    let ys: Vec<f64> = errors.iter().map(|e| -e.log2()).collect();
    let mx = (n - 1.0) / 2.0;
    let my = ys.iter().sum::<f64>() / n;
    let sxy: f64 = ys
        .iter()
        .enumerate()
        .map(|(k, y)| (k as f64 - mx) * (y - my))
        .sum();
    let sxx: f64 = (0..errors.len()).map(|k| (k as f64 - mx).powi(2)).sum();
    sxy / sxx
}

#[test]
fn noh_from_its_case_file_converges_to_the_exact_solution() {
    let gamma = 5.0 / 3.0;
    for (variant, nu) in [(None, 3), (Some("cylindrical"), 2)] {
        let plateau_exact = noh(nu, gamma, 1.0, -1.0, 0.0, 1.0).0;
        let mut errors = Vec::new();
        for n in [120, 240, 480, 960] {
            let (mut s, t) = gas("noh.toml", variant, n);
            assert_eq!(t, 0.6, "the case's end time");
            s.advance_to(t).expect("run");
            let line = x_line(&s.fluid, 0, 0);
            let (e, cells) = l1(&line, 0.5, |r| noh(nu, gamma, 1.0, -1.0, r, t).0);
            assert_eq!(cells, n * 5 / 12, "cells in r ≤ 0.5");
            // away from the first dozen cells, which the first instants compress along a lower
            // adiabat than the shock does (a fixed number of cells: first order in L1)
            let plateau: Vec<f64> = line
                .iter()
                .filter(|c| c.0 > 0.06 && c.0 < 0.18)
                .map(|c| c.1)
                .collect();
            let mean = plateau.iter().sum::<f64>() / plateau.len() as f64;
            println!(
                "Noh ν {nu}, {n} cells: density L1 error {e:.4} over {cells} cells; plateau ρ {mean:.3} (exact {plateau_exact}) over {} cells",
                plateau.len()
            );
            if n == 960 {
                assert_eq!(plateau.len(), 96);
                assert!((mean / plateau_exact - 1.0).abs() < 0.02, "plateau {mean}");
                assert!(e < 0.04, "finest L1 {e}");
            }
            errors.push(e);
        }
        let fit = fitted_order(&errors);
        println!("Noh ν {nu}: fitted order {fit:.2}");
        assert!(fit >= 0.8, "ν {nu}: fitted order {fit}");
    }
}

#[test]
fn sedov_from_its_case_file_converges_to_the_similarity_solution() {
    let (gamma, rho0, p0, energy) = (1.4, 1.0, 1e-6, 1.0);
    for (variant, nu) in [(None, 3), (Some("cylindrical"), 2)] {
        let sedov = Sedov::new(nu, gamma);
        let mut errors = Vec::new();
        for n in [120, 240, 480] {
            let (mut s, t) = gas("sedov.toml", variant, n);
            s.advance_to(t).expect("run");
            let line = x_line(&s.fluid, 0, 0);
            let (e, cells) = l1(&line, 1.2, |r| sedov.state(energy, rho0, p0, r, t).0);
            let peak = line.iter().map(|c| c.1).fold(0.0, f64::max);
            let half = 0.5 * (rho0 + peak);
            let shock = line
                .windows(2)
                .filter(|w| w[0].1 >= half && w[1].1 < half)
                .map(|w| w[0].0 + (half - w[0].1) / (w[1].1 - w[0].1) * (w[1].0 - w[0].0))
                .next_back()
                .expect("a shock");
            let exact_r = sedov.radius(energy, rho0, t);
            println!(
                "Sedov ν {nu}, {n} cells, t {t}: density L1 error {e:.4} over {cells} cells; shock at {shock:.4} (exact {exact_r:.4}); {} steps",
                s.fluid.steps
            );
            assert_eq!(cells, n);
            assert!(
                (shock - exact_r).abs() < 3.0 * 1.2 / n as f64,
                "shock at {shock}"
            );
            if n == 480 {
                assert!(e < 0.05, "finest L1 {e}");
            }
            errors.push(e);
        }
        let fit = fitted_order(&errors);
        println!("Sedov ν {nu}: fitted order {fit:.2}");
        assert!(fit >= 0.7, "ν {nu}: fitted order {fit}");
    }
}

#[test]
fn noh_runs_through_cosim_with_its_balance_holding() {
    let (dir, id) = scratch("noh-small");
    let out = dir.join("out");
    let o = run_case(
        &workspace_root().join("examples/noh.toml"),
        &out,
        &id,
        &["--variant", "small"],
    );
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let s = summary(&out);
    println!("{s:#}");
    assert_eq!(s["status"], "finished");
    nothing_left(&id);
}
