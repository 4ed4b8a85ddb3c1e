//! Seed 003 §5.1 and §5.2 as monolithic `fem-2d` runs through `cosim run` (the small variants
//! of `examples/seed003_wave.toml` and `examples/seed003_cantilever.toml`), against closed
//! forms: the compressive wave reaches mid-length at 5 m / c (within a fifth of a step) and the points behind the front
//! move at v = p / (ρ c h) (1-D long-wave theory); the loaded end peaks at 2 p L / (E h) when
//! the reflection returns; the slowly loaded cantilever settles at Timoshenko's static end
//! deflection within the bilinear mesh's bending error.

use cosim_tests::*;
use std::path::{Path, PathBuf};

const YOUNG: f64 = 72e9;
const DENSITY: f64 = 2700.0;

fn run_small(case: &str, tag: &str) -> PathBuf {
    let (dir, id) = scratch(tag);
    let out = dir.join("out");
    let case = workspace_root().join("examples").join(case);
    let o = run_case(&case, &out, &id, &["--variant", "small"]);
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(shm_files(&id).is_empty(), "shared memory left behind");
    out
}

/// Least-squares line through the samples with t in [a, b]: (slope, intercept on the t axis,
/// samples used).
fn line(series: &[(f64, f64)], a: f64, b: f64) -> (f64, f64, usize) {
    let pts: Vec<(f64, f64)> = series
        .iter()
        .copied()
        .filter(|&(t, _)| t >= a && t <= b)
        .collect();
    let n = pts.len() as f64;
    let (st, su) = pts
        .iter()
        .fold((0.0, 0.0), |(st, su), &(t, u)| (st + t, su + u));
    let (mt, mu) = (st / n, su / n);
    let (mut num, mut den) = (0.0, 0.0);
    for &(t, u) in &pts {
        num += (t - mt) * (u - mu);
        den += (t - mt) * (t - mt);
    }
    let slope = num / den;
    (slope, mt - mu / slope, pts.len())
}

fn series(out: &Path, node: &str, key: &str) -> Vec<(f64, f64)> {
    node_series(&out.join("run.mcap"), node, key)
}

#[test]
fn wave_reaches_mid_length_at_the_bar_speed() {
    let out = run_small("seed003_wave.toml", "s3wave");
    let s = summary(&out);
    let windows = s["windows"].as_u64().unwrap_or(0);
    let (c, p, l) = ((YOUNG / DENSITY).sqrt(), 1e4, 10.0);
    let v = p / (DENSITY * c * 1.0);
    // The node's step: the window over its substeps.
    let substeps = series(&out, "bar", "substeps");
    let dt = 5e-5 / substeps.first().map_or(f64::NAN, |s| s.1);
    // Displacements are compressive (−x): flip them.
    let flip = |v: Vec<(f64, f64)>| v.into_iter().map(|(t, u)| (t, -u)).collect::<Vec<_>>();
    let a = flip(series(&out, "bar", "A_ux"));
    let b = flip(series(&out, "bar", "B_ux"));
    assert_eq!(a.len() as u64, windows);
    assert_eq!(b.len() as u64, windows);
    // A: zero until the front arrives at 5/c, then u = v (t − 5/c) until the reflection from
    // the fixed end returns at 15/c. Fitted away from both smeared fronts.
    let (slope, t0, n) = line(&a, 8.0 / c, 12.5 / c);
    println!(
        "A: slope {slope:e} (v = {v:e}), arrival {t0:e} s (5/c = {:e}, dt {dt:e}), {n} samples",
        5.0 / c
    );
    assert!(n >= 15, "{n} samples");
    assert!((slope - v).abs() < 0.03 * v, "slope {slope} vs {v}");
    assert!(
        (t0 - 5.0 / c).abs() < 0.2 * dt,
        "arrival {t0} vs {}",
        5.0 / c
    );
    // B, the loaded end: u = v t from t = 0 until 2L/c, then the triangle wave's peak
    // 2 p L / (E h) at 2L/c.
    let (slope, t0, n) = line(&b, 2.0 / c, 18.0 / c);
    println!("B: slope {slope:e}, start {t0:e} s, {n} samples");
    assert!(n >= 30, "{n} samples");
    assert!((slope - v).abs() < 0.03 * v, "slope {slope} vs {v}");
    assert!(t0.abs() < 0.2 * dt, "start {t0}");
    let peak = b.iter().map(|&(_, u)| u).fold(f64::NEG_INFINITY, nan_max);
    let exact = 2.0 * p * l / YOUNG;
    println!("B: peak {peak:e}, 2pL/(Eh) = {exact:e}");
    assert!(
        (peak - exact).abs() < 0.05 * exact,
        "peak {peak} vs {exact}"
    );
}

#[test]
fn slowly_loaded_cantilever_settles_at_the_static_deflection() {
    let out = run_small("seed003_cantilever.toml", "s3cant");
    let s = summary(&out);
    let windows = s["windows"].as_u64().unwrap_or(0);
    let b = series(&out, "beam", "B_uy");
    assert_eq!(b.len() as u64, windows);
    // Timoshenko: P L³/(3EI) + P L/(κ G A), P = 100 kN, κ = 5/6.
    let (p, l, nu): (f64, f64, f64) = (1e5, 10.0, 0.3);
    let g = YOUNG / (2.0 * (1.0 + nu));
    let exact = p * l.powi(3) / (3.0 * YOUNG / 12.0) + p * l / (5.0 / 6.0 * g);
    // After the ramp (t ≥ 0.5 s) the end rests at the static deflection; the ramp leaves a
    // vibration of order 840 / (ω₁T)⁴ ≈ 1e-3 of it. The 40 × 4 mesh of bilinear quads is
    // stiffer in bending than the beam by about 3 % (`mechanics::fem2d`'s cantilever test
    // measures this h² error against the same closed form: 3.2 % at 40 × 4).
    let late: Vec<f64> = b
        .iter()
        .filter(|&&(t, _)| t >= 0.5)
        .map(|&(_, u)| -u)
        .collect();
    assert!(late.len() >= 90, "{} samples", late.len());
    let (lo, hi) = late
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &u| {
            (a.min(u), b.max(u))
        });
    println!("end deflection in [{lo:e}, {hi:e}] after the ramp; Timoshenko {exact:e}");
    assert!(hi - lo < 0.01 * exact, "still vibrating: [{lo}, {hi}]");
    let mean = late.iter().sum::<f64>() / late.len() as f64;
    let err = (mean - exact) / exact;
    assert!((-0.04..0.0).contains(&err), "relative error {err}");
    // The run wrote the mesh for ParaView.
    let (ok, text) = check_vtk(&out.join("beam"), &["displacement", "velocity", "stress"]);
    assert!(ok, "{text}");
}
