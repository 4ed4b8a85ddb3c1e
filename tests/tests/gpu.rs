//! The GPU path in a coupled run: the small variant of
//! `examples/chamber_detonation.toml` with the bar as `pd-correspondence` (a gas node and a
//! peridynamic bar node as real processes,
//! immersed coupling) run with the gas on `device = "cpu"` and on `device = "gpu"`
//! (`--set gas.device="gpu"`), and compared field by field, window by window: every field of
//! every recorded `Fields` message on the data topics (the gas's forces on the particles; the
//! bar's particle positions, velocities and volumes), relative to the field's largest
//! magnitude in that window.
//!
//! Every field must agree within 1e-10 in every window, relative to the run's largest
//! |value| of that field (sender/field over all windows of the CPU run): gas forces, bar
//! positions, velocities and volumes; and the gas's reported interface impulse likewise.
//! Until session 3 the bar's strains (~1e-6) were formed from absolute positions (0.3 m) and
//! kept ~8 digits, so any two differently rounded runs drifted apart by ~1e-7 in the bar's
//! velocities; the solid node now forms bond deformations from displacements. A third,
//! CPU-only run whose initial air temperature differs by one ulp (the control) is printed
//! for scale (the coupled system's own round-off sensitivity), not asserted.
//! Measured (lavapipe, session 4, 80 windows): bar positions 1.9e-16, bar velocities 1.3e-13
//! (control 1.1e-13), gas forces 1.6e-15 of their largest values; the gas's interface
//! impulse 1.3e-18 of 2.55e-3 N s.
//!
//! The CPU run itself is checked against momentum conservation by immersed.rs, and the GPU
//! immersed kernels against the CPU ones in process (fluid-node/tests/gpu_immersed.rs: ≤ 4e-15).
//! Without an adapter (or with f32-only kernels) the test prints why it was skipped and
//! passes outside CI; under `CI=true` it fails.

use cosim_tests::*;
use protocol::{Message, codec};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// (coupling, sender, window, field) → values of every recorded `Fields` message.
/// (sender, coupling, window, field).
type FieldKey = (String, String, u64, String);
type Traffic = BTreeMap<FieldKey, Vec<f64>>;

fn traffic(mcap: &Path) -> Traffic {
    let (msgs, complete) = coordinator::record::read_all(mcap).expect("readable recording");
    assert!(complete, "{} is incomplete", mcap.display());
    let mut out = Traffic::new();
    for m in msgs.iter().filter(|m| !m.json) {
        let Ok(env) = codec::decode(&m.data) else {
            continue;
        };
        if let Message::Fields(f) = env.message {
            // topic cosim/<run>/<coupling>/<from>: the sender without the run id
            let from = m.topic.rsplit('/').next().unwrap_or("").to_string();
            for fld in f.fields {
                out.insert(
                    (f.coupling.clone(), from.clone(), f.window, fld.name),
                    fld.values,
                );
            }
        }
    }
    out
}

/// Largest |a − b| per recorded field, window by window: (key, difference, scale), with the
/// scale the largest |value| of that sender/field in `a` over all windows.
fn compare(a: &Traffic, b: &Traffic) -> Vec<(FieldKey, f64, f64)> {
    assert_eq!(
        a.keys().collect::<Vec<_>>(),
        b.keys().collect::<Vec<_>>(),
        "the runs exchanged different messages"
    );
    let mut scale: BTreeMap<(String, String), f64> = BTreeMap::new();
    for (k, x) in a {
        let m = scale.entry((k.1.clone(), k.3.clone())).or_default();
        *m = x.iter().fold(*m, |m, v| m.max(v.abs()));
    }
    a.iter()
        .map(|(k, x)| {
            let y = &b[k];
            assert_eq!(x.len(), y.len(), "{k:?}: lengths");
            let diff = x
                .iter()
                .zip(y)
                .map(|(p, q)| (p - q).abs())
                .fold(
                    0.0_f64,
                    |m, e| {
                        if e.is_nan() { f64::INFINITY } else { m.max(e) }
                    },
                );
            (k.clone(), diff, scale[&(k.1.clone(), k.3.clone())])
        })
        .collect()
}

fn run(case: &Path, out: &Path, id: &str, sets: &[&str]) -> (std::process::Output, f64) {
    // The default timeouts: a node beats from its Welcome on, while it builds its solver
    // (on the GPU path it compiles the WGSL pipelines, seconds on lavapipe under load).
    // The bar as pd-correspondence, the model with device kernels (the case's own,
    // pd-rk-ba, has none), on the CPU and on the GPU alike.
    let mut args = vec!["--variant", "small", "--set", "bar.model=pd-correspondence"];
    for s in sets {
        args.extend_from_slice(&["--set", s]);
    }
    let t = Instant::now();
    let o = run_case(case, out, id, &args);
    (o, t.elapsed().as_secs_f64())
}

/// The run's stdout and stderr, or `None` when it found no GPU adapter: the test is then
/// skipped outside CI and fails under `CI=true`.
fn output_unless_no_adapter(test: &str, o: &std::process::Output) -> Option<String> {
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    if !o.status.success() && text.contains("no GPU adapter") {
        skip_or_fail(test, &format!("the GPU run found no adapter:\n{text}"));
        return None;
    }
    Some(text)
}

fn ok(o: &std::process::Output, what: &str) {
    assert!(
        o.status.success(),
        "{what}: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn chamber_with_the_gas_on_the_gpu_sends_the_same_coupling_traffic() {
    // the control: the CPU run with the initial air temperature one ulp higher
    let one_ulp = format!(
        "gas.regions=[{{ shape = \"all\", material = \"air\", temperature = {:?}, pressure = 1.0e5 }}, {{ shape = \"sphere\", center = [0.0, 0.2, 0.0], radius = 0.0061, material = \"air\", temperature = 1465.0, pressure = 6.75e6 }}]",
        f64::from_bits(290.0f64.to_bits() + 1)
    );
    same_traffic(
        "chamber_with_the_gas_on_the_gpu_sends_the_same_coupling_traffic",
        &[],
        &one_ulp,
        false,
    );
}

/// TNT detonation products (JWL, the constants of examples/steel_tube.toml) as a material of
/// the chamber's gas.
const TNT: &str = "gas.materials.tnt={ eos = \"jwl\", rho0 = 1630.0, a = 3.712e11, b = 3.21e9, r1 = 4.15, r2 = 0.95, omega = 0.3, e0 = 6.9927e9 }";

/// The chamber's gas with a 2 cm TNT charge (JWL products at their loading density and JWL
/// pressure) instead of the hot air: two materials, one of them JWL, on the GPU in a coupled
/// run. This blast amplifies round-off (in process, fluid-node/tests/gpu.rs measures a 2e-16
/// change of the initial state growing to 8e-5), so each field may differ from the CPU run by
/// ten times what the one-ulp control run differs, or 1e-10, whichever is larger.
#[test]
fn chamber_with_a_jwl_charge_on_the_gpu_sends_the_same_coupling_traffic() {
    let regions = |t_air: f64| {
        format!(
            "gas.regions=[{{ shape = \"all\", material = \"air\", temperature = {t_air:?}, pressure = 1.0e5 }}, {{ shape = \"sphere\", center = [0.0, 0.2, 0.0], radius = 0.02, material = \"tnt\", density = 1630.0, pressure = 8.3759e9 }}]"
        )
    };
    let one_ulp = regions(f64::from_bits(290.0f64.to_bits() + 1));
    same_traffic(
        "chamber_with_a_jwl_charge_on_the_gpu_sends_the_same_coupling_traffic",
        &[TNT.to_string(), regions(290.0)],
        &one_ulp,
        true,
    );
}

/// The small chamber with `sets` run with the gas on the GPU and on the CPU, and on the CPU
/// again with `control` set too: every exchanged field must agree within 1e-10 of its
/// largest |value| (or, when `by_control`, within ten times the control's difference where
/// that is larger), and so must the gas's interface impulse.
fn same_traffic(test: &str, sets: &[String], control: &str, by_control: bool) {
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let (dir, id) = scratch("gpu-chamber");
    let mut gsets: Vec<&str> = sets.iter().map(String::as_str).collect();
    gsets.push("gas.device=\"gpu\"");
    let (o, t_gpu) = run(&case, &dir.join("gpu"), &format!("{id}g"), &gsets);
    if output_unless_no_adapter(test, &o).is_none() {
        return;
    }
    ok(&o, "GPU run");
    let gmcap = dir.join("gpu/run.mcap");
    let bits = node_series(&gmcap, "gas", "gpu_precision_bits");
    assert!(!bits.is_empty(), "the GPU run must report its precision");
    if bits.iter().any(|&(_, b)| b != 64.0) {
        skip_or_fail(
            test,
            "the 1e-10 agreement needs f64 kernels (the adapter has no SHADER_F64)",
        );
        return;
    }
    let csets: Vec<&str> = sets.iter().map(String::as_str).collect();
    let (o, t_cpu) = run(&case, &dir.join("cpu"), &format!("{id}c"), &csets);
    ok(&o, "CPU run");
    let mut usets = csets.clone();
    usets.push(control);
    let (o, _) = run(&case, &dir.join("ulp"), &format!("{id}u"), &usets);
    ok(&o, "perturbed CPU run");
    println!("wall time of the run: gas on the CPU {t_cpu:.2} s, on the GPU {t_gpu:.2} s");
    let cpu = traffic(&dir.join("cpu/run.mcap"));
    let gpu = compare(&cpu, &traffic(&gmcap));
    let ulp = compare(&cpu, &traffic(&dir.join("ulp/run.mcap")));
    let mut worst_gpu: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    let mut worst_ulp: BTreeMap<String, f64> = BTreeMap::new();
    for ((k, dg, sc), (_, du, _)) in gpu.iter().zip(&ulp) {
        let name = format!("{}/{}", k.1, k.3);
        let w = worst_gpu.entry(name.clone()).or_default();
        *w = (w.0.max(dg / sc.max(f64::MIN_POSITIVE)), *sc);
        let w = worst_ulp.entry(name).or_default();
        *w = w.max(du / sc.max(f64::MIN_POSITIVE));
    }
    let windows = cpu.keys().map(|k| k.2).max().unwrap_or(0);
    println!("{} fields over {windows} windows", cpu.len());
    for (name, (r, sc)) in &worst_gpu {
        println!(
            "  {name}: largest |value| {sc:.4e}; max difference GPU vs CPU {r:.3e} of it; one-ulp CPU control {:.3e}",
            worst_ulp[name]
        );
    }
    let peak_force = cpu
        .iter()
        .filter(|(k, _)| k.3 == "force")
        .flat_map(|(_, v)| v.iter().map(|x| x.abs()))
        .fold(0.0_f64, nan_max);
    // not trivially 0 = 0: the blast reached the bar
    assert!(peak_force > 0.0, "no force crossed the interface");
    for q in ["gas/force", "bar/velocity", "bar/position"] {
        assert!(worst_gpu.contains_key(q), "{q} was not exchanged");
    }
    for (k, d, sc) in &gpu {
        assert!(*sc > 0.0 || k.3 != "force", "{k:?}: no scale");
        let control = if by_control {
            worst_ulp[&format!("{}/{}", k.1, k.3)]
        } else {
            0.0
        };
        let allowed = 1e-10_f64.max(10.0 * control);
        assert!(
            *d <= allowed * sc,
            "{k:?}: GPU differs from CPU by {d:e}, {:e} of the run's largest |value| {sc:e} (allowed {allowed:e})",
            d / sc
        );
    }
    // the gas's reported interface impulse, window by window
    let ic = node_vectors(&dir.join("cpu/run.mcap"), "gas", "interface_impulse");
    let ig = node_vectors(&gmcap, "gas", "interface_impulse");
    assert_eq!(ic.len(), ig.len());
    let scale = ic
        .iter()
        .flat_map(|(_, j)| j.iter().map(|x| x.abs()))
        .fold(0.0_f64, nan_max);
    assert!(scale > 0.0);
    let diff = ic
        .iter()
        .zip(&ig)
        .flat_map(|((_, a), (_, b))| (0..3).map(move |d| (a[d] - b[d]).abs()))
        .fold(0.0_f64, nan_max);
    let iu = node_vectors(&dir.join("ulp/run.mcap"), "gas", "interface_impulse");
    let diff_ulp = ic
        .iter()
        .zip(&iu)
        .flat_map(|((_, a), (_, b))| (0..3).map(move |d| (a[d] - b[d]).abs()))
        .fold(0.0_f64, nan_max);
    println!(
        "gas interface impulse: largest difference {diff:.3e} of {scale:.3e} N s (control {diff_ulp:.3e})"
    );
    let allowed = if by_control {
        (1e-10 * scale).max(10.0 * diff_ulp)
    } else {
        1e-10 * scale
    };
    assert!(diff <= allowed, "{diff:e} vs {scale:e}");
}

/// `precision = "f32"` on both GPU nodes (for consumer GPUs, whose f64 rate is a small
/// fraction of f32): each node warns, the warning reaches the log and `summary.json`
/// (per node and in the run's `warnings`), and the f32 run still tracks the f64 CPU run.
#[test]
fn f32_on_request_warns_in_the_summary_and_tracks_the_cpu_run() {
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let (dir, id) = scratch("gpu-f32");
    let short = "run.end_time=1.5e-4";
    let (o, _) = run(
        &case,
        &dir.join("f32"),
        &format!("{id}f"),
        &[
            short,
            "gas.device=\"gpu\"",
            "gas.precision=\"f32\"",
            "bar.device=\"gpu\"",
            "bar.precision=\"f32\"",
        ],
    );
    let Some(text) = output_unless_no_adapter("f32_on_request_warns", &o) else {
        return;
    };
    ok(&o, "f32 GPU run");
    let s = summary(&dir.join("f32"));
    let all: Vec<&str> = s["warnings"]
        .as_array()
        .expect("warnings in summary.json")
        .iter()
        .filter_map(|w| w.as_str())
        .collect();
    println!("summary.json warnings: {all:#?}");
    for node in ["gas", "bar"] {
        assert!(
            all.iter()
                .any(|w| w.starts_with(&format!("{node}: ")) && w.contains("f32")),
            "{node}: no f32 warning in {all:?}"
        );
        let own = s["nodes"][node]["warnings"]
            .as_array()
            .expect("node warnings");
        // only the f32 warning: the bar's GPU path reports its energies
        assert_eq!(own.len(), 1, "{node}: {own:?}");
    }
    assert!(
        text.contains("f32"),
        "the warning is not in the log:\n{text}"
    );
    let (o, _) = run(&case, &dir.join("cpu"), &format!("{id}c"), &[short]);
    ok(&o, "CPU run");
    assert_eq!(
        summary(&dir.join("cpu"))["warnings"]
            .as_array()
            .map(Vec::len),
        Some(0)
    );
    // The bar's centre-of-mass displacement, f32 GPU against f64 CPU.
    let a = node_series(&dir.join("cpu/run.mcap"), "bar", "com_displacement_x");
    let b = node_series(&dir.join("f32/run.mcap"), "bar", "com_displacement_x");
    assert_eq!(a.len(), b.len());
    let peak = a.iter().map(|p| p.1.abs()).fold(0.0f64, nan_max);
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x.1 - y.1).abs())
        .fold(0.0f64, nan_max);
    println!(
        "bar centre of mass: largest displacement {peak:.4e} m, f32 GPU vs f64 CPU differ by \
         {worst:.3e} m ({:.2e} of it)",
        worst / peak
    );
    assert!(peak > 0.0, "the bar did not move");
    assert!(worst <= 1e-4 * peak, "{worst:e} of {peak:e}");
}

/// Per-window values of a key of the `/cosim/balance` channel: (window, value).
fn balance_series(mcap: &Path, key: &str) -> Vec<(u64, f64)> {
    let (msgs, _) = coordinator::record::read_json(mcap).expect("readable recording");
    msgs.iter()
        .filter(|m| m.topic == "/cosim/balance")
        .filter_map(|m| {
            let v: serde_json::Value = serde_json::from_slice(&m.data).ok()?;
            Some((v["window"].as_u64()?, v[key].as_f64()?))
        })
        .collect()
}

/// the bar's energies on the GPU path (strain energy reduced on the device each
/// window) close the run's energy balance as the CPU path's do. The small chamber with the
/// bar (pd-correspondence) on `device = "gpu"` against the all-CPU run: the bar's strain
/// energy and plastic work window by window within 1e-10 of the run's largest strain
/// energy, the balance's energy residual window by window within 1e-10 of the run's energy
/// scale, and the summary's largest residual in the CPU run's bounds (immersed.rs).
#[test]
fn chamber_with_the_bar_on_the_gpu_closes_the_energy_balance_like_the_cpu() {
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let (dir, id) = scratch("gpu-bar-energy");
    let (o, _) = run(
        &case,
        &dir.join("gpu"),
        &format!("{id}g"),
        &["bar.device=\"gpu\""],
    );
    if output_unless_no_adapter("chamber_with_the_bar_on_the_gpu", &o).is_none() {
        return;
    }
    ok(&o, "GPU run");
    let gmcap = dir.join("gpu/run.mcap");
    let bits = node_series(&gmcap, "bar", "gpu_precision_bits");
    assert!(!bits.is_empty(), "the GPU run must report its precision");
    if bits.iter().any(|&(_, b)| b != 64.0) {
        skip_or_fail(
            "chamber_with_the_bar_on_the_gpu_closes_the_energy_balance_like_the_cpu",
            "the 1e-10 agreement needs f64 kernels (the adapter has no SHADER_F64)",
        );
        return;
    }
    let (o, _) = run(&case, &dir.join("cpu"), &format!("{id}c"), &[]);
    ok(&o, "CPU run");
    let cmcap = dir.join("cpu/run.mcap");
    let worst = |a: &[(f64, f64)], b: &[(f64, f64)]| {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .map(|(p, q)| {
                assert_eq!(p.0, q.0, "the same windows");
                (p.1 - q.1).abs()
            })
            .fold(0.0_f64, nan_max)
    };
    let (uc, ug) = (
        node_series(&cmcap, "bar", "internal_energy"),
        node_series(&gmcap, "bar", "internal_energy"),
    );
    let (wc, wg) = (
        node_series(&cmcap, "bar", "plastic_work"),
        node_series(&gmcap, "bar", "plastic_work"),
    );
    assert!(uc.len() >= 80, "{} windows of the bar", uc.len());
    let u_max = uc.iter().map(|p| p.1).fold(0.0_f64, nan_max);
    let (du, dw) = (worst(&ug, &uc), worst(&wg, &wc));
    let (rc, rg) = (
        balance_series(&cmcap, "energy_residual"),
        balance_series(&gmcap, "energy_residual"),
    );
    assert_eq!(rc.len(), uc.len(), "a balance row per window");
    assert_eq!(
        rc.iter().map(|r| r.0).collect::<Vec<_>>(),
        rg.iter().map(|r| r.0).collect::<Vec<_>>()
    );
    let dr = rc
        .iter()
        .zip(&rg)
        .map(|(p, q)| (p.1 - q.1).abs())
        .fold(0.0_f64, nan_max);
    let (sc, sg) = (summary(&dir.join("cpu")), summary(&dir.join("gpu")));
    let scale = sc["balance"]["energy_scale"]
        .as_f64()
        .expect("energy scale");
    let (r_cpu, r_gpu) = (
        sc["balance"]["max_energy_residual_relative"]
            .as_f64()
            .expect("residual"),
        sg["balance"]["max_energy_residual_relative"]
            .as_f64()
            .expect("residual"),
    );
    println!(
        "bar strain energy: largest {u_max:.4e} J over {} windows, GPU vs CPU differ by {du:.3e} J; plastic work differs by {dw:.3e} J",
        uc.len()
    );
    println!(
        "energy residual per window: GPU vs CPU differ by {dr:.3e} J of the energy scale {scale:.4e} J; largest residual CPU {r_cpu:.6e}, GPU {r_gpu:.6e} of it"
    );
    assert!(u_max > 0.0, "the bar stores no strain energy");
    assert!(
        du <= 1e-10 * u_max && dw <= 1e-10 * u_max,
        "{du:e} {dw:e} of {u_max:e}"
    );
    assert!(scale > 0.0);
    assert!(dr <= 1e-10 * scale, "{dr:e} of {scale:e}");
    for r in [r_cpu, r_gpu] {
        assert!(r < 0.0 && r > -1e-3, "energy residual {r:e}");
    }
}

/// The shock–bubble case's edge line through `cosim run` with the gas on the device: the
/// node reads the line's cells back every window, records the edges and their speeds, and
/// the run prints the speeds, as on the CPU. At 2 mm cells to 0.2 ms (both edges move 8 to
/// 20 mm); the GPU and CPU edges differ by the flow's own round-off amplification
/// (fluid-node/tests/gpu.rs: about 1e-5 m, as much as the CPU from a state changed by
/// 2e-16), so the speeds are held within 1 % here, and the positions within 0.1 mm.
#[test]
fn shock_bubble_edges_on_the_gpu_track_the_cpu_run() {
    let test = "shock_bubble_edges_on_the_gpu_track_the_cpu_run";
    let case = workspace_root().join("examples/shock_bubble.toml");
    let mut runs = Vec::new();
    for device in ["cpu", "gpu"] {
        let (dir, id) = scratch(&format!("bubble-edges-{device}"));
        let out = dir.join("out");
        let set = format!("gas.device=\"{device}\"");
        let o = run_case(
            &case,
            &out,
            &id,
            &[
                "--variant",
                "small",
                "--set",
                "gas.grid.cells=[163, 23, 1]",
                "--set",
                "run.end_time=2.0e-4",
                "--set",
                "run.pictures=none",
                "--set",
                &set,
            ],
        );
        let Some(text) = output_unless_no_adapter(test, &o) else {
            return;
        };
        assert!(o.status.success(), "{device}: {text}");
        let printed = |name: &str| -> f64 {
            let line = text
                .lines()
                .find(|l| l.starts_with(&format!("cosim: gas.bubble.{name} = ")))
                .unwrap_or_else(|| panic!("{device}: no {name} line in:\n{text}"));
            line.rsplit(' ').next().unwrap().parse().expect("a number")
        };
        let speeds = [printed("first_speed"), printed("last_speed")];
        let mcap = out.join("run.mcap");
        let series = [
            node_series(&mcap, "gas", "bubble.first"),
            node_series(&mcap, "gas", "bubble.last"),
        ];
        runs.push((speeds, series));
    }
    let ((cpu_v, cpu_x), (gpu_v, gpu_x)) = (&runs[0], &runs[1]);
    println!("edge speeds (m/s): CPU {cpu_v:?}, GPU {gpu_v:?}");
    for side in 0..2 {
        assert!(
            cpu_v[side] > 50.0,
            "the CPU edge {side} hardly moved: {cpu_v:?}"
        );
        assert!(
            (gpu_v[side] - cpu_v[side]).abs() <= 0.01 * cpu_v[side],
            "edge {side}: GPU {} m/s, CPU {} m/s",
            gpu_v[side],
            cpu_v[side]
        );
        assert_eq!(cpu_x[side].len(), 40, "CPU windows of edge {side}");
        assert_eq!(gpu_x[side].len(), 40, "GPU windows of edge {side}");
        let worst = cpu_x[side]
            .iter()
            .zip(&gpu_x[side])
            .map(|(a, b)| {
                assert_eq!(a.0, b.0, "window times");
                (a.1 - b.1).abs()
            })
            .fold(0.0, f64::max);
        println!("edge {side}: GPU against CPU at most {worst:.2e} m over 40 windows");
        assert!(worst < 1e-4, "edge {side}: {worst:e} m");
    }
}
