//! Chamber detonation, coarse level: the blast wave reaches the right
//! wall's centre (point 2) when its own measured speed predicts, and reflects there; and the
//! chamber at three resolutions converges (see the second test).
//!
//! * Speed: arrival times (first rise of 2 kPa, interpolated between windows) at two
//!   free-field probes above the bar, at radii r_a, r_b from the charge: D = Δr/Δt. The
//!   first front to reach point 2 is the one diffracted round the bar, along the shortest
//!   path from the charge (0, 0.2) over the bar's corners (0.1, 0.25), (0.3, 0.25) to (0.4,
//!   0.2): 0.4236 m. Predicted arrival t_b + (0.4236 − r_b)/D within 5 %: on this 1 cm grid a
//!   smeared front's arrival is uncertain by about one cell transit (27 µs, 2.7 % of 1 ms),
//!   and a diffracted front is slightly slower than a free one (both make it late).
//! * Reflection: the incident overpressure measured 5 cm in front of the wall (`near2`),
//!   before the reflection comes back, gives through the normal-reflection relation
//!   p5/p2 = ((3γ−1) p2/p1 − (γ−1)) / ((γ−1) p2/p1 + γ+1) the wall's reflected pressure;
//!   the wall's first peak must match it within 10 % of the overpressure (and be about twice
//!   the incident, which the no-reflection alternative — the incident itself — is not).

use cosim_tests::*;

const R_PATH: f64 = 0.423_606_797_749_979; // 2 √(0.1² + 0.05²) + 0.2
const P0: f64 = 1.0e5;
const GAMMA: f64 = 1.4;

/// Time the series first reaches `level`, interpolated linearly between samples.
fn arrival(s: &[(f64, f64)], level: f64) -> f64 {
    let i = s
        .iter()
        .position(|&(_, p)| p >= level)
        .expect("the shock arrives");
    assert!(i > 0);
    let (t0, p0) = s[i - 1];
    let (t1, p1) = s[i];
    t0 + (level - p0) / (p1 - p0) * (t1 - t0)
}

fn peak(s: &[(f64, f64)], from: f64, to: f64) -> f64 {
    s.iter()
        .filter(|(t, _)| *t >= from && *t <= to)
        .map(|&(_, p)| p)
        .fold(f64::MIN, nan_max)
}

#[test]
fn the_shock_reaches_the_right_wall_when_its_speed_predicts_and_reflects_there() {
    let (dir, id) = scratch("chamber-shock");
    let out = dir.join("out");
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let o = run_case(
        &case,
        &out,
        &id,
        &[
            // The gas's physics: the bar stays elastic and moves 3 µm, and its model moves
            // the probes' pressures by less than 3e-7 of their peaks over the whole 2 ms
            // (pd-rk-ba against pd-correspondence, measured); pd-correspondence runs the
            // coarse bar about 5 times faster than the default pd-rk-ba.
            "--variant",
            "correspondence",
            "--set",
            "run.end_time=1.3e-3",
            "--set",
            "run.output_every=0",
        ],
    );
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let mcap = out.join("run.mcap");
    let series = |probe: &str| node_series(&mcap, "gas", &format!("{probe}.pressure"));
    let (a, b, near, wall) = (
        series("free_a"),
        series("free_b"),
        series("near2"),
        series("point2"),
    );
    assert!(wall.len() > 400, "{} samples", wall.len());
    let level = P0 + 2.0e3;
    let (ta, tb) = (arrival(&a, level), arrival(&b, level));
    let (ra, rb) = (0.15f64.hypot(0.15), 0.30f64.hypot(0.15));
    let speed = (rb - ra) / (tb - ta);
    let predicted = tb + (R_PATH - rb) / speed;
    let t2 = arrival(&wall, level);
    println!(
        "shock speed {speed:.1} m/s (Mach {:.3}); point 2 reached at {:.4} ms, predicted {:.4} ms ({:+.2} %)",
        speed / (GAMMA * 287.0 * 290.0f64).sqrt(),
        t2 * 1e3,
        predicted * 1e3,
        100.0 * (t2 - predicted) / predicted
    );
    // A supersonic front: faster than sound in the 290 K air (341 m/s).
    assert!(speed > 341.0, "speed {speed}");
    assert!(
        (t2 - predicted).abs() <= 0.05 * predicted,
        "arrival {t2:e} s, predicted {predicted:e} s"
    );
    // Incident wave 5 cm before the wall, until the reflection is back there (the front
    // takes 0.05/D to reach the wall, the reflection as long to return).
    let back = t2 + 0.05 / speed;
    let incident = peak(&near, arrival(&near, level), back);
    let r = incident / P0;
    let reflected =
        incident * ((3.0 * GAMMA - 1.0) * r - (GAMMA - 1.0)) / ((GAMMA - 1.0) * r + GAMMA + 1.0);
    let measured = peak(&wall, t2, t2 + 0.3e-3);
    println!(
        "incident overpressure {:.2} kPa; wall {:.2} kPa, normal reflection predicts {:.2} kPa",
        (incident - P0) / 1e3,
        (measured - P0) / 1e3,
        (reflected - P0) / 1e3
    );
    assert!(
        ((measured - P0) - (reflected - P0)).abs() <= 0.10 * (reflected - P0),
        "wall {measured} Pa, reflection predicts {reflected} Pa"
    );
}

/// The chamber under refinement (the seed's Fig. 4): three resolutions refined together by 2
/// — gas 20², 40², 80² cells, bar 30 × 15, 60 × 30, 120 × 60 particles, δ 3.015 spacings,
/// one 2.5 µs window for all — to 1.2 ms (the shock reaches point 2 at about 1.03 ms). The
/// difference between neighbouring levels, the mean |Δ| over the 480 windows relative to the
/// finest level's largest value, must shrink with the refinement for the bar's
/// centre-of-mass displacement and the pressure at the right wall's centre (point 2); the
/// observed order log₂(d_coarse/d_fine) is printed (measured: 0.95 and 0.48). The pressure
/// at the detonation centre (point 1) is printed, not asserted: it does not converge at these
/// levels (measured: order −0.17), since the 6.1 mm charge it sits in is smaller than one
/// cell at all three and the probe reads its cell's average. (The case gives the charge by
/// its energy so that each level holds the same charge.) The bar runs as pd-correspondence:
/// at this charge the bar stays elastic and the model moves these quantities by little
/// (docs/cases.md), and the finest level costs a fifth of the time that way.
#[test]
fn the_bar_displacement_and_the_wall_pressure_converge_under_refinement() {
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let (dir, id) = scratch("chamber-conv");
    let levels = [
        (20, 6.666666666666667e-3),
        (40, 3.3333333333333335e-3),
        (80, 1.6666666666666668e-3),
    ];
    let mut runs = Vec::new();
    for (k, (cells, dx)) in levels.iter().enumerate() {
        let out = dir.join(format!("level{k}"));
        let sets = [
            format!("gas.grid.cells=[{cells}, {cells}, 1]"),
            format!("bar.spacing={dx:e}"),
            format!("bar.horizon={:e}", 3.015 * dx),
            "run.end_time=1.2e-3".to_string(),
            "run.window=2.5e-6".to_string(),
            "run.output_every=0".to_string(),
        ];
        let mut args = vec!["--variant", "correspondence"];
        for s in &sets {
            args.extend(["--set", s.as_str()]);
        }
        let o = run_case(&case, &out, &format!("{id}{k}"), &args);
        assert!(
            o.status.success(),
            "level {k}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let mcap = out.join("run.mcap");
        runs.push([
            node_series(&mcap, "bar", "com_displacement_x"),
            node_series(&mcap, "gas", "point1.pressure"),
            node_series(&mcap, "gas", "point2.pressure"),
        ]);
    }
    let names = [
        "bar centre-of-mass displacement",
        "pressure at point 1",
        "pressure at point 2",
    ];
    let asserted = [true, false, true];
    let mut shrank = 0;
    for (q, name) in names.iter().enumerate() {
        let n = runs[2][q].len();
        assert_eq!(n, 480, "{name}: {n} windows");
        assert!(
            runs.iter().all(|r| r[q].len() == n),
            "{name}: levels differ in windows"
        );
        let scale = runs[2][q].iter().map(|p| p.1.abs()).fold(0.0, f64::max);
        let diff = |a: usize, b: usize| {
            let (x, y) = (&runs[a][q], &runs[b][q]);
            assert!(
                x.iter().zip(y).all(|(p, r)| p.0 == r.0),
                "{name}: sample times differ"
            );
            x.iter().zip(y).map(|(p, r)| (p.1 - r.1).abs()).sum::<f64>() / (n as f64 * scale)
        };
        let (coarse, fine) = (diff(0, 1), diff(1, 2));
        println!(
            "{name}: mean difference 20²→40² {coarse:.3e}, 40²→80² {fine:.3e} of its largest value {scale:.4e}; observed order {:.2}",
            (coarse / fine).log2()
        );
        if asserted[q] {
            assert!(
                fine < coarse,
                "{name}: {fine:e} does not shrink from {coarse:e}"
            );
            shrank += 1;
        }
    }
    assert_eq!(shrank, 2);
}
