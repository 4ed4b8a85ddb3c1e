//! Seed 003 §5.1–§5.3 as coupled `fem-2d` subdomains through `cosim run`: the
//! small variants of `examples/seed003_wave_split.toml` (explicit | implicit and implicit |
//! implicit, m = 2), `seed003_cantilever_split.toml` (implicit m = 2, and implicit |
//! explicit) and `seed003_three.toml` (three subdomains, one coupling) each match the
//! monolithic run of the same mesh with a tiny step (the `small-reference` variants of
//! `seed003_wave.toml` and `seed003_cantilever.toml`) within 1 % in the displacement history
//! at the points A, B (and C); the three-subdomain cantilever is second order for gs4 and first
//! for gc under step halving, and so is its interface energy ΔE_Γ in summary.json; an
//! explicit | implicit pair runs stable with the explicit side exactly at its critical step
//! bound; the audit of every coupled run closes (momentum to round-off). Seed 003 §5.4, the
//! notched specimen as fem-2d | pd-correspondence | pd-correspondence
//! (`examples/seed003_notch.toml`, gs4 at one particle step per system step and gc with the
//! particles at m = 4), matches the same subdomains at a tenth of the step within 1 %.

use cosim_tests::*;
use std::path::{Path, PathBuf};

/// Runs `case` with `--variant variant` (if any) and `sets`; returns the output directory.
fn run(case: &str, tag: &str, variant: Option<&str>, sets: &[String]) -> PathBuf {
    let (dir, id) = scratch(tag);
    let out = dir.join("out");
    let mut extra: Vec<&str> = Vec::new();
    if let Some(v) = variant {
        extra.extend(["--variant", v]);
    }
    for s in sets {
        extra.extend(["--set", s.as_str()]);
    }
    let case = workspace_root().join("examples").join(case);
    let o = run_case(&case, &out, &id, &extra);
    assert!(
        o.status.success(),
        "{tag}: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    nothing_left(&id);
    out
}

fn series(out: &Path, node: &str, key: &str) -> Vec<(f64, f64)> {
    node_series(&out.join("run.mcap"), node, key)
}

/// Largest difference between `a` and the samples of `reference` at the same times (the
/// reference samples `ratio` times as often), relative to the reference's largest magnitude;
/// and the samples compared.
fn history_error(a: &[(f64, f64)], reference: &[(f64, f64)], ratio: usize) -> (f64, usize) {
    let scale = reference.iter().fold(0.0f64, |m, &(_, x)| m.max(x.abs()));
    let mut e = 0.0f64;
    let mut n = 0;
    for (k, &(t, x)) in a.iter().enumerate() {
        let Some(&(tr, y)) = reference.get((k + 1) * ratio - 1) else {
            break;
        };
        assert!(
            (t - tr).abs() <= 1e-9 * t.abs().max(1e-12),
            "sample {k}: times {t} and {tr} differ"
        );
        e = e.max((x - y).abs() / scale);
        n += 1;
    }
    (e, n)
}

/// The audit of a coupled run from summary.json: (momentum residual relative to the run's
/// impulse scale, energy residual relative to its energy scale, ΔE_Γ of the first coupling).
fn audit(out: &Path) -> (f64, f64, f64) {
    let s = summary(out);
    let b = &s["balance"];
    let f = |k: &str| b[k].as_f64().unwrap_or(f64::NAN);
    let de = s["couplings"][0]["interface_energy"]
        .as_f64()
        .unwrap_or(f64::NAN);
    (
        f("max_momentum_residual_relative"),
        f("max_energy_residual_relative"),
        de,
    )
}

/// (node of the coupled run, point) pairs compared with the monolithic node.
type Points<'a> = &'a [(&'a str, &'a str)];

/// Compares every point's displacement component `comp` ("ux" or "uy") of a coupled run with
/// the reference run's node `mono` (None: the same node as the coupled run's); returns the
/// largest error and asserts the count.
fn compare(
    coupled: &Path,
    reference: &Path,
    mono: Option<&str>,
    points: Points,
    comp: &str,
) -> f64 {
    let windows = summary(coupled)["windows"].as_u64().unwrap_or(0) as usize;
    assert!(windows > 0, "no windows");
    let mut worst = 0.0f64;
    for (node, point) in points {
        let key = format!("{point}_{comp}");
        let a = series(coupled, node, &key);
        let r = series(reference, mono.unwrap_or(node), &key);
        let ratio = r.len() / a.len().max(1);
        let (e, n) = history_error(&a, &r, ratio.max(1));
        println!("{point} ({node}.{key}): {e:.3e} of its largest value over {n} samples");
        assert_eq!(n, windows, "{point}: samples compared");
        worst = worst.max(e);
    }
    worst
}

fn check_audit(tag: &str, out: &Path) {
    let (p, e, de) = audit(out);
    println!(
        "{tag}: momentum residual {p:.3e}, energy residual {e:+.3e} (relative), ΔE_Γ {de:e} J"
    );
    assert!(p < 1e-9, "{tag}: momentum residual {p:e}");
    assert!(
        p.is_finite() && e.is_finite() && de.is_finite(),
        "{tag}: audit {p} {e} {de}"
    );
}

const IMPLICIT: &str = "{ scheme = \"gs4\", design = \"U0(1,1,0)\", implicit = true }";

#[test]
fn wave_bar_in_two_subdomains_matches_the_monolithic_mesh() {
    let reference = run("seed003_wave.toml", "s3w-ref", Some("small-reference"), &[]);
    let points: Points = &[("left", "A"), ("right", "B")];
    for (tag, sets) in [
        ("s3w-ex-im", vec![]),
        ("s3w-im-im", vec![format!("left.integrator={IMPLICIT}")]),
    ] {
        let out = run("seed003_wave_split.toml", tag, Some("small"), &sets);
        let e = compare(&out, &reference, Some("bar"), points, "ux");
        println!("{tag}: largest error {e:.3e}");
        assert!(e < 0.01, "{tag}: {e:e}");
        check_audit(tag, &out);
    }
}

#[test]
fn cantilever_in_two_subdomains_matches_the_monolithic_mesh() {
    let reference = run(
        "seed003_cantilever.toml",
        "s3c-ref",
        Some("small-reference"),
        &[],
    );
    let points: Points = &[("left", "A"), ("right", "B")];
    for (tag, sets) in [
        ("s3c-im-im", vec![]),
        (
            "s3c-im-ex",
            vec![
                "right.integrator={ scheme = \"gs4\", design = \"U0(1,1,0)\", implicit = false }"
                    .to_string(),
                "right.substeps=".to_string(),
            ],
        ),
    ] {
        let out = run("seed003_cantilever_split.toml", tag, Some("small"), &sets);
        let e = compare(&out, &reference, Some("beam"), points, "uy");
        println!("{tag}: largest error {e:.3e}");
        assert!(e < 0.01, "{tag}: {e:e}");
        check_audit(tag, &out);
    }
}

/// The three-subdomain cantilever's load ramped over 0.1 s (C³), 0.2 s long: a smooth
/// response with free vibration after the ramp, for the order study.
const STUDY_LOAD: &str =
    "loads=[{ edge = \"right\", traction = [0.0, -100000.0], ramp = \"septic\", ramp_time = 0.1 }]";
const STUDY_END: f64 = 0.2;
/// Coarsest system step of the study per method (s); the levels halve it three times. gc's
/// start finer: its error holds a second-order part that hides the first order above 1 ms
/// (measured orders 0.38, 1.04, 1.45 from 4 ms; 1.45, 1.23, 1.07 from 1 ms).
const STUDY_DT0: [(&str, f64); 2] = [("gs4", 4e-3), ("gc", 1e-3)];
/// The reference's sampling interval: gc's finest system step (s).
const STUDY_SAMPLE: f64 = 1.25e-4;

fn orders(e: &[f64]) -> Vec<f64> {
    e.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

#[test]
fn three_subdomains_match_the_monolithic_mesh_and_gs4_is_second_order() {
    let points: Points = &[("one", "C"), ("two", "A"), ("three", "B")];
    // Seed 003 §5.3: the small variant against the monolithic mesh, within 1 %.
    let reference = run(
        "seed003_cantilever.toml",
        "s3t-ref",
        Some("small-reference"),
        &[],
    );
    let out = run("seed003_three.toml", "s3t", Some("small"), &[]);
    let e = compare(&out, &reference, Some("beam"), points, "uy");
    println!("three subdomains: largest error {e:.3e}");
    assert!(e < 0.01, "three subdomains: {e:e}");
    check_audit("s3t", &out);
    let s = summary(&out);
    assert_eq!(
        s["couplings"][0]["sides"].as_array().map_or(0, |a| a.len()),
        3,
        "one coupling of three sides"
    );

    // Order study: ΔT₀ … ΔT₀/8 against the monolithic mesh at 1/64 of the finest step of
    // either method (average acceleration), sampled at that finest step.
    let finest = STUDY_SAMPLE;
    let reference = run(
        "seed003_cantilever.toml",
        "s3t-oref",
        Some("small-reference"),
        &[
            format!("beam.{STUDY_LOAD}"),
            format!("run.end_time={STUDY_END:e}"),
            format!("run.window={finest:e}"),
            format!("beam.dt={:e}", finest / 64.0),
        ],
    );
    let mut measured = 0;
    let mut energy = Vec::new();
    for (method, dt0) in STUDY_DT0 {
        let mut errors = vec![Vec::new(); points.len()];
        let mut de = Vec::new();
        let mut residuals = Vec::new();
        for level in 0..4 {
            let dt = dt0 / (1 << level) as f64;
            let ratio = (dt / finest).round() as usize;
            let tag = format!("s3t-{method}-{level}");
            let out = run(
                "seed003_three.toml",
                &tag,
                Some("small"),
                &[
                    format!("three.{STUDY_LOAD}"),
                    format!("run.end_time={STUDY_END:e}"),
                    format!("run.window={dt:e}"),
                    format!("couplings.cuts.method={method}"),
                ],
            );
            let windows = (STUDY_END / dt).round() as usize;
            for (p, (node, point)) in points.iter().enumerate() {
                let key = format!("{point}_uy");
                let a = series(&out, node, &key);
                let r = series(&reference, "beam", &key);
                let (e, n) = history_error(&a, &r, ratio);
                assert_eq!(n, windows, "{tag} {point}: samples compared");
                errors[p].push(e);
            }
            check_audit(&tag, &out);
            let (_, residual, interface) = audit(&out);
            de.push(interface);
            residuals.push(residual.abs());
        }
        // The audit's energy residual is a discretisation error too: it falls at every
        // halving (measured: gs4 5.3e-2 to 4.2e-5, gc 2.6e-2 to 2.0e-3 of the largest energy).
        assert!(
            residuals.windows(2).all(|w| w[1] < w[0]),
            "{method}: energy residuals {residuals:?} do not fall with the step"
        );
        for (p, (_, point)) in points.iter().enumerate() {
            let o = orders(&errors[p]);
            println!("{method} {point}: errors {:?}, orders {o:.3?}", errors[p]);
            for (l, x) in o.iter().enumerate() {
                // gs4 is second order; gc first, approached from above (measured 1.45-1.59,
                // 1.23-1.29, 1.07-1.08): every halving is checked, not only the last.
                let least = if method == "gs4" { 1.9 } else { 0.9 };
                assert!(*x >= least, "{method} {point} halving {l}: order {x:.3}");
                measured += 1;
            }
            if method == "gc" {
                let last = o[o.len() - 1];
                assert!(
                    (0.7..=1.3).contains(&last),
                    "gc {point}: last order {last:.3}"
                );
            }
        }
        println!("{method}: ΔE_Γ {de:?} J");
        energy.push(de);
    }
    assert_eq!(measured, 2 * 3 * 3);
    // ΔE_Γ: gc dissipates (≥ 0) and halves it with the step; gs4's falls four times a halving.
    let (gs4, gc) = (&energy[0], &energy[1]);
    assert!(gc.iter().all(|&e| e >= 0.0), "gc ΔE_Γ {gc:?}");
    let gc_order = orders(gc);
    let gs4_order = orders(&gs4.iter().map(|e| e.abs()).collect::<Vec<_>>());
    println!("ΔE_Γ orders: gc {gc_order:.3?}, gs4 {gs4_order:.3?}");
    assert!(
        (0.7..=1.3).contains(&gc_order[2]),
        "gc ΔE_Γ order {gc_order:?}"
    );
    assert!(gs4_order[2] >= 1.9, "gs4 ΔE_Γ order {gs4_order:?}");
}

/// On seed 003 §5.1: subdomain 1 in central differences exactly at its
/// critical step bound (two steps of the bound per window), subdomain 2 in average
/// acceleration at the window (m = 2), runs stable for gs4 and gc and stays close to the
/// monolithic mesh, gs4 closer than gc. The load rises over 1 ms (C³): a step load on this
/// coarse mesh at these steps is a few per cent off the reference whatever the coupling.
#[test]
fn explicit_side_at_its_critical_step_is_stable() {
    let params: toml::Table = toml::from_str(
        "length = 5.0\nheight = 1.0\nnx = 10\nny = 2\nyoung = 72e9\npoisson = 0.3\n\
         density = 2700.0\nfixed = [\"left\"]\ninterfaces = { cut = \"right\" }\n",
    )
    .expect("params");
    let critical = solid_node::fem2d::Fem2d::from_params(&params)
        .expect("the left half")
        .critical_step();
    let window = 2.0 * critical;
    let windows = (7.8e-3 / window).round() as usize;
    let end = window * windows as f64;
    println!("critical step bound {critical:e} s, window {window:e} s, {windows} windows");
    let load = "loads=[{ edge = \"right\", traction = [-10000.0, 0.0], ramp = \"septic\", ramp_time = 1.0e-3 }]";
    let reference = run(
        "seed003_wave.toml",
        "s3w-cref",
        Some("small-reference"),
        &[
            format!("run.window={window:e}"),
            format!("run.end_time={end:e}"),
            format!("bar.dt={:e}", critical / 100.0),
            format!("bar.{load}"),
        ],
    );
    let points: Points = &[("left", "A"), ("right", "B")];
    let mut worst = Vec::new();
    // Measured: gs4 2.1e-2, gc 5.1e-2 of the largest displacement.
    for (method, bound) in [("gs4", 0.03), ("gc", 0.07)] {
        let tag = format!("s3w-courant-{method}");
        let out = run(
            "seed003_wave_split.toml",
            &tag,
            Some("small"),
            &[
                format!("run.window={window:e}"),
                format!("run.end_time={end:e}"),
                "left.substeps=2".into(),
                "right.substeps=1".into(),
                format!("right.{load}"),
                format!("couplings.cut.method={method}"),
            ],
        );
        let e = compare(&out, &reference, Some("bar"), points, "ux");
        println!("{tag}: largest error {e:.3e}");
        assert!(e < bound, "{tag}: {e:e}");
        check_audit(&tag, &out);
        worst.push(e);
    }
    assert!(worst[0] < worst[1], "gs4 {:e}, gc {:e}", worst[0], worst[1]);
}

/// Seed 003 §5.4: the notched specimen, fem-2d | pd-correspondence |
/// pd-correspondence in one coupling, small variant (load ramped over 4 ms, 8 ms), against
/// the same three subdomains at a tenth of the step (m = 1 everywhere): within 1 % in uy at A,
/// B and C, for gs4 (every side at the system step) and for gc with the particles at four
/// steps per system step; momentum closes to round-off and the energy residual is small.
#[test]
fn notched_specimen_fem_pd_pd_matches_its_reference() {
    let reference = run(
        "seed003_notch.toml",
        "s3n-ref",
        Some("small-reference"),
        &[],
    );
    let points: Points = &[("fem", "A"), ("notch", "B"), ("right", "C")];
    let multirate: Vec<String> = [
        "run.window=6.4e-5",
        "notch.substeps=4",
        "right.substeps=4",
        "couplings.cuts.method=gc",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    // Measured bounds: see the report printed.
    for (tag, sets, bound) in [("s3n-gs4", vec![], 0.01), ("s3n-gc4", multirate, 0.01)] {
        let out = run("seed003_notch.toml", tag, Some("small"), &sets);
        let e = compare(&out, &reference, None, points, "uy");
        println!("{tag}: largest error {e:.3e}");
        assert!(e < bound, "{tag}: {e:e}");
        check_audit(tag, &out);
        let (_, energy, de) = audit(&out);
        println!("{tag}: energy residual {energy:+.3e} of the largest energy, ΔE_Γ {de:.3e} J");
        assert!(energy.abs() < 1e-2, "{tag}: energy residual {energy:e}");
        let s = summary(&out);
        assert_eq!(
            s["couplings"][0]["sides"].as_array().map_or(0, |a| a.len()),
            3,
            "one coupling of three sides"
        );
    }
}

/// The notched specimen's gs4 coupling (every side at one step per system step, the particle
/// side exact for its nonlinear force) is second order in time: uy at A, B and C at ΔT, ΔT/2
/// and ΔT/4 (ΔT = 16 µs, the particles' stable step) against ΔT/40, over the small variant's
/// C³ load ramp (4 ms).
#[test]
fn notched_specimen_gs4_is_second_order() {
    let end = "run.end_time=4.0e-3".to_string();
    let reference = run(
        "seed003_notch.toml",
        "s3n-oref",
        Some("small"),
        &[end.clone(), "run.window=4.0e-7".into()],
    );
    let points: Points = &[("fem", "A"), ("notch", "B"), ("right", "C")];
    let mut errors = vec![Vec::new(); points.len()];
    for (level, ratio) in [40usize, 20, 10].into_iter().enumerate() {
        let dt = 4.0e-7 * ratio as f64;
        let tag = format!("s3n-o{level}");
        let out = run(
            "seed003_notch.toml",
            &tag,
            Some("small"),
            &[end.clone(), format!("run.window={dt:e}")],
        );
        let windows = (4.0e-3 / dt).round() as usize;
        for (p, (node, point)) in points.iter().enumerate() {
            let key = format!("{point}_uy");
            let (e, n) = history_error(
                &series(&out, node, &key),
                &series(&reference, node, &key),
                ratio,
            );
            assert_eq!(n, windows, "{tag} {point}: samples compared");
            errors[p].push(e);
        }
        check_audit(&tag, &out);
    }
    let mut measured = 0;
    for (p, (_, point)) in points.iter().enumerate() {
        let o = orders(&errors[p]);
        println!("notch gs4 {point}: errors {:?}, orders {o:.3?}", errors[p]);
        for x in o {
            assert!(x >= 1.9, "{point}: order {x:.3}");
            measured += 1;
        }
    }
    assert_eq!(measured, 6);
}
