//! Seed 004's shell–joint cases end to end through `cosim run`: a
//! `macro-shell-node` (model `blt-shell`) drives `meso-joint-node`s (model `mc-spg`) through
//! the kinematic coupling (docs/architecture.md, serial schedule), at the small variants of
//! `examples/coupon_*.toml`, `examples/single_joint.toml` and `examples/crash_tube.toml`.
//!
//! * Coupon (seed 004 §4.1): the two-scale force on the pulled end
//!   agrees with the single-scale (all-SPG) one to 5 % of the peak at every window up to the
//!   single-scale peak; both peaks are the net-section yield force σy·A = 1 GPa × 32 mm² =
//!   32 kN within 4 % (with E_t = 1 GPa the engineering force peaks at ~0.5 % plastic strain,
//!   F/σy·A = (1 + H εp) e^(−ε) < 1.006); both runs add mass by mass scaling and stay
//!   quasi-static at the peak (kinetic ≪ internal energy); `cosim plot` puts both curves in one
//!   PNG. Pulled on to rupture, the two-scale coupon and the seed's single-scale model
//!   (hexahedra with an SPG centre) neck alike in width and thickness, carry the same force
//!   to within 5 % of the peak until the middle breaks, and break at the same elongation
//!   within 10 %.
//! * Single joint (seed 004 §4.2): the joint force rises, peaks and falls after the plate
//!   material around the bolt fails (broken bonds).
//! * Every recording passes `tools/check_mcap.py`.

use cosim_tests::*;
use std::path::{Path, PathBuf};

/// Runs `examples/<case>.toml --variant small` into a scratch directory named `label`
/// (the label is what `cosim plot` prints in the legend).
fn run_small(case: &str, label: &str, extra: &[&str]) -> PathBuf {
    run_variant(case, "small", label, extra)
}

fn run_variant(case: &str, variant: &str, label: &str, extra: &[&str]) -> PathBuf {
    let (dir, id) = scratch(label);
    let out = dir.join(label);
    let path = workspace_root().join(format!("examples/{case}.toml"));
    let mut args = vec!["--variant", variant];
    args.extend_from_slice(extra);
    let o = run_case(&path, &out, &id, &args);
    assert!(
        o.status.success(),
        "{case}: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let (ok, text) = check_mcap(&out.join("run.mcap"), "--require-json");
    assert!(ok, "{case}: check_mcap failed: {text}");
    momentum_balances(&out, case);
    out
}

/// Every window, the nodes' momentum is what their supports, prescribed-velocity regions
/// and coupling impulses explain, to round-off of the run's gross momentum Σ m|v| (or its
/// largest impulse, if larger): the supports' reactions include the momentum it takes to
/// hold the prescribed velocity, and a rigid bolt keeps what its neighbours push into it.
fn momentum_balances(out: &Path, case: &str) {
    let b = &summary(out)["balance"];
    let get = |k: &str| b[k].as_f64().unwrap_or_else(|| panic!("balance.{k}"));
    let (resid, rel) = (
        get("max_momentum_residual"),
        get("max_momentum_residual_relative"),
    );
    println!(
        "{case}: momentum residual {resid:.3e} N s, {rel:.3e} of the gross momentum {:.3e} \
         or largest impulse {:.3e}",
        get("momentum_scale"),
        get("impulse_scale")
    );
    assert!(get("momentum_scale") > 0.0, "{case}: nothing moved");
    assert!(rel <= 1e-12, "{case}: momentum residual {rel:e}");
}

fn series(out: &Path, node: &str, key: &str) -> Vec<(f64, f64)> {
    let s = node_series(&out.join("run.mcap"), node, key);
    assert!(!s.is_empty(), "no {node}.{key} in {}", out.display());
    s
}

fn peak(s: &[(f64, f64)]) -> (usize, f64) {
    s.iter().enumerate().fold(
        (0, f64::NEG_INFINITY),
        |a, (i, &(_, v))| {
            if v > a.1 { (i, v) } else { a }
        },
    )
}

/// The seed's own single-scale coupon — hexahedra with an SPG centre (`--variant solid`) —
/// against the all-particle one: the same force through the pulled end within 5 % of the
/// peak at every window up to it (measured 2.5 % over 136 windows at the test size) and the same peak
/// within 2 % (measured 0.2 %), momentum to round-off in both.
#[test]
fn coupon_with_solid_elements_matches_the_all_particle_coupon() {
    let to_peak = ["--set", "run.end_time=0.01"];
    let particles = run_small("coupon_single_scale", "coupon_particles", &to_peak);
    let solid = run_variant(
        "coupon_single_scale",
        "solid-small",
        "coupon_solid",
        &to_peak,
    );
    let fp = series(&particles, "coupon", "force_right_x");
    let fs = series(&solid, "coupon", "force_right_x");
    assert_eq!(fp.len(), fs.len(), "both runs have the same windows");
    let (ip, f_peak) = peak(&fp);
    let (_, f_peak_solid) = peak(&fs);
    let mut worst: f64 = 0.0;
    for (a, b) in fp.iter().zip(&fs).take(ip + 1) {
        worst = worst.max((a.1 - b.1).abs() / f_peak);
    }
    println!(
        "peaks: all particles {f_peak:.1} N, hexahedra with an SPG centre {f_peak_solid:.1} N; largest difference up to the peak {:.2} % of it over {} windows",
        100.0 * worst,
        ip + 1
    );
    assert!(ip + 1 >= 100, "only {} windows up to the peak", ip + 1);
    assert!(
        worst < 0.05,
        "forces differ by {:.2} % of the peak",
        100.0 * worst
    );
    assert!(
        (f_peak_solid / f_peak - 1.0).abs() < 0.02,
        "peaks {f_peak} and {f_peak_solid}"
    );
}

#[test]
fn coupon_two_scale_matches_single_scale_up_to_the_peak() {
    let to_peak = ["--set", "run.end_time=0.01"];
    let single = run_small("coupon_single_scale", "single_scale", &to_peak);
    let two = run_small("coupon_two_scale", "two_scale", &to_peak);
    let fs = series(&single, "coupon", "force_right_x");
    let ft = series(&two, "coupon", "force_right_x");
    assert_eq!(fs.len(), ft.len(), "both runs have the same windows");
    let (ip, f_peak) = peak(&fs);
    let t_peak = fs[ip].0;
    // Net-section yield force of the 8 × 4 mm section at σy = 1 GPa.
    let f_yield = 1e9 * 8e-3 * 4e-3;
    let (_, f_peak_two) = peak(&ft);
    println!(
        "single-scale peak {f_peak:.1} N at t = {t_peak:.3e} s, two-scale peak {f_peak_two:.1} N, σy·A = {f_yield:.1} N"
    );
    // Quasi-statically F/σy·A < 1.006; the two-scale force overshoots that where the
    // velocity ramp ends (4 ms), by the inertia of its shells, mass-scaled to the seed's
    // step (measured 3.3 % at this size, 2.7 % at the case's).
    for f in [f_peak, f_peak_two] {
        assert!(
            (f / f_yield - 1.0).abs() < 0.04,
            "peak {f} vs σy·A {f_yield}"
        );
    }
    let mut worst: f64 = 0.0;
    let mut at = 0.0;
    for (a, b) in fs.iter().zip(&ft).take(ip + 1) {
        assert!((a.0 - b.0).abs() < 1e-12, "window times differ");
        let d = (a.1 - b.1).abs() / f_peak;
        if d > worst {
            (worst, at) = (d, a.0);
        }
    }
    println!(
        "largest |F_two − F_single| / F_peak up to the peak: {:.2} % (t = {at:.3e} s)",
        100.0 * worst
    );
    assert!(worst < 0.05, "{worst}");
    // The displacement of the pulled end is the same prescribed motion in both runs.
    let us = series(&single, "coupon", "displacement_right_x");
    let ut = series(&two, "coupon", "displacement_right_x");
    let (u_end, u_two) = (us[us.len() - 1].1, ut[ut.len() - 1].1);
    println!("end displacement: single {u_end:.6e} m, two-scale {u_two:.6e} m");
    // Same ramped velocity; the ramp is sampled at each node's own step midpoints.
    assert!(u_end > 0.0 && (u_two / u_end - 1.0).abs() < 1e-3);
    // Mass scaling to the seed's steps added mass, reported by every node; each run is
    // quasi-static at the peak: its kinetic energy, all nodes together, is below 5 % of their
    // internal energy.
    for (out, node) in [(&single, "coupon"), (&two, "coupon"), (&two, "centre")] {
        let m = series(out, node, "added_mass");
        assert!(m[0].1 > 0.0, "{node}: no added mass reported");
        println!("{}: {node} added mass {:.3e} kg", out.display(), m[0].1);
    }
    for (out, nodes) in [
        (&single, &["coupon"][..]),
        (&two, &["coupon", "centre"][..]),
    ] {
        let at_peak = |key: &str| -> f64 {
            nodes
                .iter()
                .map(|node| {
                    let s = series(out, node, key);
                    let k = s.iter().position(|p| p.0 >= t_peak).unwrap_or(s.len() - 1);
                    s[k].1
                })
                .sum()
        };
        let ratio = at_peak("kinetic_energy") / at_peak("internal_energy");
        println!(
            "{}: kinetic/internal at the peak {ratio:.3e}",
            out.display()
        );
        assert!(
            ratio < 0.05,
            "{nodes:?}: kinetic/internal {ratio} at the peak"
        );
    }
    // Both force curves on one chart.
    let (dir, _) = scratch("coupon-plot");
    let o = cosim(&[
        "plot",
        two.to_str().expect("utf-8"),
        single.to_str().expect("utf-8"),
        "--series",
        "coupon.force_right_x",
        "--x",
        "coupon.displacement_right_x",
        "-o",
        dir.to_str().expect("utf-8"),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let png = std::fs::read(dir.join("coupon_force_right_x_vs_coupon_displacement_right_x.png"))
        .expect("force–displacement plot written");
    assert!(png.len() > 1000 && png.starts_with(b"\x89PNG"));
    // Both as figures: the shells' mid-surface stress drawn as von Mises, the particles'
    // velocity as its magnitude, each named on its colour bar.
    for (out, field, measure) in [
        (&two, "coupon.stress_mid", "coupon: stress_mid (von Mises"),
        (
            &single,
            "coupon.velocity",
            "coupon: velocity (magnitude) [m/s]",
        ),
    ] {
        let p = paper_picture(out, Some(field));
        assert!(
            p.scales.iter().any(|s| s.label.starts_with(measure)),
            "{:?}",
            p.scales
        );
    }
    for out in [&single, &two] {
        // Every VTK file of both runs (shell elements, SPG particles) opens with meshio.
        let (ok, text) = check_vtk(out, &[]);
        assert!(ok, "check_vtk {}: {text}", out.display());
        // The force on the pulled end is among the default charts (the coupon's, and in
        // the two-scale run the SPG centre's too).
        let plots = summary(out)["plots"].clone();
        let drawn: Vec<&str> = plots
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|p| p.as_str())
            .filter(|p| {
                p.contains("force_right") && std::fs::metadata(p).is_ok_and(|m| m.len() > 1000)
            })
            .collect();
        assert!(!drawn.is_empty(), "{plots}");
    }
}

/// Seed 004 §4.1 to the end: the two-scale coupon (shell ends, SPG middle) against the
/// seed's single-scale model (hexahedra with an SPG centre), both pulled until the middle
/// breaks. The tear starts at the first window after the peak where the force on the pulled
/// end is below 90 % of the peak, and the coupon has parted at the first below 10 % (the
/// joint report's failure). Up to the earlier start the forces agree within 5 % of the peak
/// at every window; the pulled end's displacement at the start and at parting agree within
/// 10 %; and both coupons have necked in width and in thickness alike (the VTK frame just
/// before the tear: the narrowest section of the particles against its own reference size).
#[test]
fn coupon_pulled_to_rupture_necks_and_breaks_alike_in_both_models() {
    let frames = [
        "--set",
        "run.end_time=0.115",
        "--set",
        "run.output_every=100",
    ];
    let two = run_small("coupon_two_scale", "two_scale_rupture", &frames);
    let single = run_variant(
        "coupon_single_scale",
        "solid-small",
        "single_rupture",
        &frames,
    );
    let fs = series(&single, "coupon", "force_right_x");
    let ft = series(&two, "coupon", "force_right_x");
    let us = series(&single, "coupon", "displacement_right_x");
    let ut = series(&two, "coupon", "displacement_right_x");
    assert_eq!(fs.len(), ft.len(), "both runs have the same windows");
    // (window the tear starts, window the coupon has parted, peak)
    let rupture = |f: &[(f64, f64)]| {
        let (ip, f_peak) = peak(f);
        let below = |share: f64| {
            (ip..f.len())
                .find(|&k| f[k].1 < share * f_peak)
                .unwrap_or_else(|| {
                    panic!(
                        "the force stays above {share} of its peak {f_peak} N to {} s",
                        f[f.len() - 1].0
                    )
                })
        };
        (below(0.9), below(0.1), f_peak)
    };
    let ((starts_s, parts_s, peak_s), (starts_t, parts_t, peak_t)) = (rupture(&fs), rupture(&ft));
    let before = starts_s.min(starts_t);
    let worst = fs[..before]
        .iter()
        .zip(&ft[..before])
        .map(|(a, b)| (a.1 - b.1).abs() / peak_s)
        .fold(0.0f64, f64::max);
    let mm = |u: &[(f64, f64)], k: usize| 1e3 * u[k].1;
    println!(
        "single-scale: peak {peak_s:.1} N, tear from {:.4} s ({:.4} mm), parted at {:.4} s ({:.4} mm); two-scale: peak {peak_t:.1} N, tear from {:.4} s ({:.4} mm), parted at {:.4} s ({:.4} mm); largest force difference over the {before} windows before the tear {:.2} % of the peak",
        fs[starts_s].0,
        mm(&us, starts_s),
        fs[parts_s].0,
        mm(&us, parts_s),
        ft[starts_t].0,
        mm(&ut, starts_t),
        ft[parts_t].0,
        mm(&ut, parts_t),
        100.0 * worst
    );
    // The tear comes well past the peak (a neck has to form first).
    assert!(before >= 2000, "only {before} windows before the tear");
    assert!(
        worst < 0.05,
        "forces differ by {:.2} % of the peak",
        100.0 * worst
    );
    for (what, ks, kt) in [("starts", starts_s, starts_t), ("parts", parts_s, parts_t)] {
        let (a, b) = (us[ks].1, ut[kt].1);
        assert!(
            a > 1e-3 && (b / a - 1.0).abs() < 0.10,
            "the coupon {what} at {b} m (two-scale) against {a} m (single-scale)"
        );
    }
    // The neck in the last frame before the earlier tear, in both models' particles.
    // the window of series entry `before − 1` (the series holds windows 1, 2, ...)
    let window = before as f64;
    let necks: Vec<Neck> = [(&single, "coupon"), (&two, "centre")]
        .iter()
        .map(|(out, node)| {
            let (_, frame) = last_frame_before(&out.join(node), window.round() as u64);
            let n = neck(&frame);
            println!(
                "{}: {} columns of particles; the narrowest at reference x = {:.2} mm is {:.3} of its width and {:.3} of its thickness, the widest {:.3} and {:.3}",
                frame.display(),
                n.columns,
                1e3 * n.x,
                n.width,
                n.thickness,
                n.widest.0,
                n.widest.1
            );
            n
        })
        .collect();
    for n in &necks {
        assert!(n.columns >= 9, "{} columns", n.columns);
        // Necked: the narrowest section has lost more than a tenth of its width and of its
        // thickness, in the middle of the coupon, and the widest has lost a tenth less (a
        // neck, not a uniform thinning).
        assert!(n.width < 0.9 && n.thickness < 0.9, "{n:?}");
        assert!((n.x - 12e-3).abs() < 1.5e-3, "{n:?}");
        assert!(
            n.widest.0 - n.width > 0.1 && n.widest.1 - n.thickness > 0.1,
            "{n:?}"
        );
    }
    // Alike in both models, width and thickness (within 5 % of the size).
    assert!(
        (necks[0].width - necks[1].width).abs() < 0.05
            && (necks[0].thickness - necks[1].thickness).abs() < 0.05,
        "{necks:?}"
    );
    // The single-scale picture of the neck: hexahedra and SPG particles of one node coloured
    // by the same field share one colour bar, from the hexahedra's least plastic strain (at
    // the grips, none) to the particles' largest.
    let (k, _) = last_frame_before(&single.join("coupon"), window.round() as u64);
    let choice = coordinator::fields::Choice::parse("coupon.eq_plastic_strain").expect("choice");
    let png = single.join("neck.png");
    let p = coordinator::fields::render(
        &single,
        Some(fs[k as usize - 1].0),
        &png,
        Some(choice),
        None,
        Default::default(),
    )
    .expect("a picture");
    let largest = series(&single, "coupon", "max_eq_plastic_strain")[k as usize - 1].1;
    println!(
        "{}: colour bars {:?}, largest plastic strain {largest}",
        png.display(),
        p.scales
    );
    assert_eq!(p.scales.len(), 1, "{:?}", p.scales);
    let s = &p.scales[0];
    assert!(
        s.label.starts_with("coupon: eq_plastic_strain"),
        "{}",
        s.label
    );
    assert!(
        s.lo <= 1e-3 && s.hi >= largest * (1.0 - 1e-9) && largest > 0.3,
        "{s:?}"
    );
}

/// The narrowest section of a frame's particles, as fractions of its reference size.
#[derive(Debug)]
struct Neck {
    /// Columns of particles along x (one reference x each).
    columns: usize,
    /// Reference x of the narrowest column (m), its width and thickness over their reference.
    x: f64,
    width: f64,
    thickness: f64,
    /// Width and thickness over their reference of the widest column.
    widest: (f64, f64),
}

/// The particles' VTK file (`joint_<window>.vtu`) of the latest window at or before `window`,
/// and its window.
fn last_frame_before(dir: &Path, window: u64) -> (u64, PathBuf) {
    let mut best: Option<(u64, PathBuf)> = None;
    for e in std::fs::read_dir(dir).expect("node output").flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        let Some(k) = name
            .strip_prefix("joint_")
            .and_then(|s| s.strip_suffix(".vtu"))
            .and_then(|s| s.parse::<u64>().ok())
        else {
            continue;
        };
        if k <= window && best.as_ref().is_none_or(|b| k > b.0) {
            best = Some((k, e.path()));
        }
    }
    let (k, path) = best.unwrap_or_else(|| panic!("no frame before window {window}"));
    assert!(window - k <= 100, "frame {k} is far before window {window}");
    (k, path)
}

/// Groups the particles of `vtu` by reference x (position − displacement) and measures each
/// column's extent in y (width) and z (thickness), now and in the reference.
fn neck(vtu: &Path) -> Neck {
    let p = vtu_piece(vtu);
    let x: Vec<f64> = p.points.cast_into::<f64>().expect("points");
    let u = vtu_array(p.data.point, "displacement").expect("displacement");
    assert_eq!(x.len(), u.len());
    // column key: reference x in micrometres
    let mut cols: std::collections::BTreeMap<i64, [[f64; 2]; 4]> = Default::default();
    let empty = [[f64::INFINITY, f64::NEG_INFINITY]; 4];
    for (p, d) in x.chunks_exact(3).zip(u.chunks_exact(3)) {
        let r: [f64; 3] = std::array::from_fn(|k| p[k] - d[k]);
        let c = cols.entry((r[0] * 1e6).round() as i64).or_insert(empty);
        // current y, z, reference y, z
        for (k, v) in [p[1], p[2], r[1], r[2]].into_iter().enumerate() {
            c[k] = [c[k][0].min(v), c[k][1].max(v)];
        }
    }
    let ratio = |c: &[[f64; 2]; 4]| {
        let ext = |k: usize| c[k][1] - c[k][0];
        (ext(0) / ext(2), ext(1) / ext(3))
    };
    let (kn, cn) = cols
        .iter()
        .min_by(|a, b| ratio(a.1).0.total_cmp(&ratio(b.1).0))
        .expect("particles");
    let widest = cols
        .values()
        .map(ratio)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .expect("particles");
    let (width, thickness) = ratio(cn);
    Neck {
        columns: cols.len(),
        x: *kn as f64 * 1e-6,
        width,
        thickness,
        widest,
    }
}

#[test]
fn single_joint_force_rises_then_drops_after_failure() {
    let out = run_small("single_joint", "single_joint", &[]);
    single_joint_fails(&out);
}

/// The same joint as seed 004 §4.2 meshes it — hexahedra for the plates, SPG particles
/// around the bolt and at the coupled ends (`--variant solid-small`): the force rises, the
/// shell's reaction carries it, and it drops once the plate tears out (measured peak 8.21 kN
/// against the all-particle joint's 8.52 kN); the run creates no energy to speak of (its
/// balance is checked with every run's momentum here, and its warning thresholds in the
/// run itself).
#[test]
fn single_joint_with_solid_elements_rises_then_drops_after_failure() {
    let out = run_variant("single_joint", "solid-small", "single_joint_solid", &[]);
    single_joint_fails(&out);
    let s = summary(&out);
    assert_eq!(s["warnings"].as_array().map(|w| w.len()), Some(0), "{s:#}");
}

/// The single joint's force history: rises, carried by the shell's reaction, drops after
/// bonds break.
fn single_joint_fails(out: &Path) {
    let f = series(out, "joint", "force_a_x");
    let broken = series(out, "joint", "broken_bonds");
    let reaction = series(out, "plates", "force_right_x");
    let (ip, f_peak) = peak(&f);
    let t_peak = f[ip].0;
    let f_end = f[f.len() - 1].1;
    let first_break = broken
        .iter()
        .find(|p| p.1 > 0.0)
        .map(|p| p.0)
        .unwrap_or(f64::INFINITY);
    println!(
        "joint force peak {f_peak:.1} N at t = {t_peak:.4e} s, first broken bond at {first_break:.4e} s, final {f_end:.1} N, broken bonds {}",
        broken[broken.len() - 1].1
    );
    // Rises: monotone to within dynamic noise over the first half of the loading.
    assert!(f_peak > 0.0 && f[ip / 2].1 > 0.2 * f_peak && f[ip / 2].1 < 0.9 * f_peak);
    // Before failure the shell's reaction on the pulled edge carries the same force: the
    // joint is the only load path between the plates (quasi-static, 5 %).
    let k = ip * 3 / 4;
    assert!(
        (reaction[k].1 - f[k].1).abs() < 0.05 * f_peak,
        "reaction {} vs joint force {} at t = {}",
        reaction[k].1,
        f[k].1,
        f[k].0
    );
    // Drops after failure: the peak comes when bonds start to break, the force then falls
    // to a small fraction of the peak (the plate tears out around the bolt).
    assert!(first_break <= t_peak + 5e-3, "peak long before failure");
    assert!(f_end.abs() < 0.2 * f_peak, "{f_end} of {f_peak}");
    assert!(broken[broken.len() - 1].1 > 100.0);
    joint_report_matches_the_force_history(out);
}

/// The joint report the run wrote (`joint_report.csv`, joined from the joint node's own)
/// against the force history recorded window by window: the peak of the fastener's force and
/// its time, the first window after it below a tenth of the peak with bonds broken, and the
/// mode the seed finds for this joint, pull-out (the plate tears around the fastener). The
/// fastener's force (summed over the plates) is the force the shell puts through the two
/// coupled ends (summed over the rings) while the joint holds: within 2 % of the peak at
/// every window from a fifth to 95 % of the peak's time (measured 1.47 %; as the loading
/// starts the plates' inertia shows, 5.9 % at 1 ms).
fn joint_report_matches_the_force_history(out: &Path) {
    let force = series(out, "joint", "fastener_force_magnitude");
    let a = series(out, "joint", "force_a_magnitude");
    let b = series(out, "joint", "force_b_magnitude");
    let broken = series(out, "joint", "broken_bonds");
    assert_eq!(a.len(), b.len());
    assert_eq!(a.len(), force.len());
    assert!(a.len() > 100, "{} windows", a.len());
    let (ip, f_peak) = peak(&force);
    let t_peak = force[ip].0;
    let holding: Vec<usize> = (0..force.len())
        .filter(|&k| (0.2 * t_peak..=0.95 * t_peak).contains(&force[k].0))
        .collect();
    let worst = holding
        .iter()
        .map(|&k| (force[k].1 - a[k].1).abs().max((force[k].1 - b[k].1).abs()))
        .fold(0.0f64, f64::max);
    let holding = holding.len();
    println!(
        "fastener force against the coupled ends' over {holding} windows: within {:.3} % of the peak",
        100.0 * worst / f_peak
    );
    assert!(holding >= 50, "{holding} windows");
    assert!(worst <= 0.02 * f_peak, "{worst} N of {f_peak} N");
    let k_failed = (ip..force.len())
        .find(|&k| force[k].1 < 0.1 * f_peak && broken[k].1 > 0.0)
        .expect("the force falls below a tenth of its peak");
    let failed = force[k_failed].0;
    // and never carries half its peak again (else the report takes the failure back)
    assert!(force[k_failed..].iter().all(|p| p.1 <= 0.5 * f_peak));
    let text = std::fs::read_to_string(out.join("joint_report.csv")).expect("joint_report.csv");
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 2, "{text}");
    assert!(
        lines[0].starts_with("node,joint,peak_force_N,peak_time_s,failure_time_s,failure_mode,")
    );
    let f: Vec<&str> = lines[1].split(',').collect();
    assert_eq!(&f[..2], &["joint", "joint"], "{text}");
    let num = |k: usize| f[k].parse::<f64>().unwrap();
    assert!(
        (num(2) - f_peak).abs() <= 1e-12 * f_peak,
        "{} vs {f_peak}",
        num(2)
    );
    assert_eq!(num(3), force[ip].0);
    assert_eq!(num(4), failed);
    assert_eq!(f[5], "pull-out", "{text}");
    assert!(num(6) > num(7), "{text}");
}

#[test]
fn crash_tube_runs_one_process_per_joint_and_grouped_alike() {
    // 5 ms of crush loading: short, but every joint is loaded through the shell.
    let end = ["--set", "run.end_time=5e-3"];
    let separate = run_small("crash_tube", "crash_tube", &end);
    // The same case with the ten joints in one node (`--variant grouped`).
    let out = run_variant("crash_tube", "grouped", "crash_grouped", &end);
    let mut largest: f64 = 0.0;
    let mut worst: f64 = 0.0;
    for k in 1..=5 {
        for j in [format!("j{k}"), format!("j{k}p")] {
            let q = format!("fastener_force_{j}_magnitude");
            let a = series(&separate, &j, &q);
            let b = series(&out, "joints", &q);
            assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(&b) {
                largest = largest.max(x.1.abs());
                worst = worst.max((x.1 - y.1).abs());
            }
        }
    }
    println!(
        "joint forces: largest {largest:.3e} N, separate vs grouped differ by ≤ {worst:.3e} N"
    );
    assert!(largest > 1.0, "the joints carry no load ({largest} N)");
    // Same physics and mapping; what differs is round-off: the placement transforms, and
    // the order in which the shell adds the coupling loads (ten interfaces vs one).
    assert!(worst <= 1e-4 * largest, "{worst:e} vs {largest:e}");
}

/// Seed 004 Fig. 14: with joints 3–3' as thread-bonded screws (case II) instead of bolts that
/// bear on their holes (case I), joint 3's fastener carries a higher peak force over the first
/// 25 ms of crush (measured 641 N against 191 N); `tests/tests/crash_tube.rs` crushes both to
/// half the tube's length.
#[test]
fn crash_tube_screws_at_joint_3_peak_higher_than_bolts() {
    let end = ["--set", "run.end_time=2.5e-2"];
    let case1 = run_variant("crash_tube", "small", "crash_case1", &end);
    let case2 = run_variant("crash_tube", "small2", "crash_case2", &end);
    let peak = |out: &Path, j: &str| {
        series(out, j, &format!("fastener_force_{j}_magnitude"))
            .iter()
            .map(|p| p.1.abs())
            .fold(0.0f64, nan_max)
    };
    let mut rows = Vec::new();
    for k in 1..=5 {
        for j in [format!("j{k}"), format!("j{k}p")] {
            rows.push((j.clone(), peak(&case1, &j), peak(&case2, &j)));
        }
    }
    for (j, a, b) in &rows {
        println!("{j}: peak joint force case I {a:.1} N, case II {b:.1} N");
    }
    let (_, j3_i, j3_ii) = rows.iter().find(|r| r.0 == "j3").cloned().expect("j3");
    assert!(j3_i > 10.0, "joint 3 carries no load in case I ({j3_i} N)");
    assert!(j3_ii > 1.5 * j3_i, "case II {j3_ii} N vs case I {j3_i} N");
    tube_picture(&case1);
    shapes_side_by_side(&case1, &case2);
    charts_of_eleven_nodes(&case1, &case2);
    paper_picture(&case1, None);
}

/// What the small crash tube (eleven nodes) draws: at most 25 PNGs, every axis with a unit;
/// and `cosim plot` puts two series of one run, or one series of two runs, on one chart.
fn charts_of_eleven_nodes(case1: &Path, case2: &Path) {
    let pngs: Vec<PathBuf> = files_under(case1, &[])
        .into_keys()
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    println!("{} PNGs: {pngs:?}", pngs.len());
    assert!(
        (5..=25).contains(&pngs.len()),
        "{} PNGs: {pngs:?}",
        pngs.len()
    );
    let listed = summary(case1)["plots"].as_array().unwrap().len();
    assert_eq!(listed + 1, pngs.len(), "the plots and fields.png");
    // The same charts from the recording: every axis carries a unit.
    let charts = coordinator::charts::default_charts(case1).unwrap();
    assert_eq!(charts.len(), listed);
    let mut panels = 0;
    for c in &charts {
        for p in &c.panels {
            panels += 1;
            assert!(
                coordinator::plot::unit_of(&p.y_label).is_some(),
                "{}: {} has no unit",
                c.file,
                p.y_label
            );
        }
    }
    // the energy chart has a panel per node: eleven, at least
    assert!(panels >= charts.len() + 10, "{panels} panels");
    let (dir, _) = scratch("crash-plots");
    let plot = |runs: &[&Path], series: &[&str]| {
        let mut args = vec!["plot".to_string()];
        args.extend(runs.iter().map(|r| r.display().to_string()));
        for s in series {
            args.extend(["--series".into(), s.to_string()]);
        }
        args.push("-o".into());
        args.push(dir.display().to_string());
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = cosim(&a);
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).to_string(),
            err,
        )
    };
    // Pixels of the first two line colours (matplotlib's blue and orange): a line over the
    // run's 250 windows covers hundreds, a legend's swatch about forty.
    let two_lines = |png: &str| {
        let (_, _, px) = png_pixels(Path::new(png.trim()));
        let count = |c: [u8; 3]| px.iter().filter(|p| **p == c).count();
        let (blue, orange) = (count([31, 119, 180]), count([255, 127, 14]));
        println!("{}: {blue} blue and {orange} orange pixels", png.trim());
        assert!(
            blue > 300 && orange > 300,
            "{png}: {blue} blue, {orange} orange"
        );
    };
    // A glob over nodes and quantities (joints 3 and 3'), one chart. The two mirror each
    // other across the tube's symmetry plane, so their lines coincide: the drawing is
    // checked with two joints that differ, below.
    let (ok, listed, err) = plot(&[case1], &["j3*.force_j3*_a_magnitude"]);
    assert!(ok, "{err}");
    assert_eq!(listed.lines().count(), 1, "{listed}");
    // Two series of one run, joints 1 and 3, one chart with both lines.
    let (ok, listed, err) = plot(
        &[case1],
        &["j1.force_j1_a_magnitude", "j3.force_j3_a_magnitude"],
    );
    assert!(ok, "{err}");
    assert_eq!(listed.lines().count(), 1, "{listed}");
    two_lines(&listed);
    // One series of two runs, one chart.
    let (ok, listed, err) = plot(&[case1, case2], &["j3.force_j3_a_magnitude"]);
    assert!(ok, "{err}");
    assert_eq!(
        listed.trim(),
        dir.join("j3_force_j3_a_magnitude.png").to_str().unwrap()
    );
    two_lines(&listed);
    // A misspelt quantity is named, with the nearest one.
    let (ok, _, e) = plot(&[case1], &["j3.force_j3_a_magnitde"]);
    assert!(!ok);
    assert!(e.contains("did you mean j3.force_j3_a_magnitude?"), "{e}");
}

/// Both cases' tubes side by side as `cosim plot --field tube.mises_top --alone --up z`
/// draws them: the shells alone, upright, on one colour range — the union of the two runs'
/// own ranges — so that the panels compare by colour. (The stress: at 25 ms of crush the
/// tubes have not yielded yet.)
fn shapes_side_by_side(case1: &Path, case2: &Path) {
    use coordinator::fields::{Camera, Choice, render, render_runs};
    let choice = Choice::parse("tube.mises_top").expect("choice");
    let camera = Camera::from_args(Some("z"), Some(45.0), Some(25.0)).expect("camera");
    let (dir, _) = scratch("shapes");
    let own: Vec<(f64, f64)> = [case1, case2]
        .iter()
        .enumerate()
        .map(|(k, run)| {
            let p = render(
                run,
                None,
                &dir.join(format!("{k}.png")),
                Some(choice),
                Some("tube"),
                camera,
            )
            .expect("a picture");
            assert_eq!(p.scales.len(), 1, "the shells alone: {:?}", p.scales);
            (p.scales[0].lo, p.scales[0].hi)
        })
        .collect();
    let runs = [
        ("I".to_string(), case1.to_path_buf()),
        ("II".to_string(), case2.to_path_buf()),
    ];
    let panels = render_runs(
        &runs,
        None,
        &dir.join("both.png"),
        choice,
        Some("tube"),
        camera,
    )
    .expect("the runs side by side");
    let union = (own[0].0.min(own[1].0), own[0].1.max(own[1].1));
    println!("von Mises stress ranges {own:?}, side by side {union:?}");
    assert!(own[0] != own[1], "the runs differ: {own:?}");
    for p in &panels {
        assert_eq!(p.scales.len(), 1, "{:?}", p.scales);
        assert_eq!((p.scales[0].lo, p.scales[0].hi), union);
    }
}

/// `fields.png` of a crash-tube run: the tube drawn across the picture (its longest axis
/// spans the 1000 px plot area's width), solid, shaded and coloured by plastic strain.
fn tube_picture(out: &Path) {
    let png = out.join("fields.png");
    assert_eq!(
        summary(out)["fields"].as_str(),
        Some(png.to_str().unwrap()),
        "summary.json names the picture"
    );
    let (w, h, px) = png_pixels(&png);
    assert_eq!((w, h), (1200, 800));
    let (mut drawn, mut x_min, mut x_max) = (0usize, u32::MAX, 0);
    let mut colours = std::collections::HashSet::new();
    for (k, p) in px.iter().enumerate() {
        let (x, y) = (k as u32 % w, k as u32 / w);
        if !(40..1040).contains(&x) || !(60..760).contains(&y) || *p == [255, 255, 255] {
            continue;
        }
        drawn += 1;
        x_min = x_min.min(x);
        x_max = x_max.max(x);
        colours.insert(*p);
    }
    println!(
        "{}: {drawn} pixels drawn, x {x_min}..{x_max}, {} colours",
        png.display(),
        colours.len()
    );
    assert!(x_max - x_min >= 950, "the tube spans {x_min}..{x_max}");
    assert!(drawn >= 150_000, "{drawn} pixels");
    assert!(colours.len() >= 50, "{} colours", colours.len());
}
