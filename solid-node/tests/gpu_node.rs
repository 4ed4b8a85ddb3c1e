//! `device = "gpu"` through the node's `Solver` trait (the PD bar wave
//! on GPU and CPU within 1e-10 relative). A plane-strain steel bar (60 × 6 particles, Δx 1 mm,
//! δ 3.015 Δx) with its left quarter launched at 5 m/s against a held right end (prescribed
//! velocity 0: a compression wave that reflects), an immersed interface on every particle
//! receiving a different, non-uniform force each window (as from a gas), advanced over 6
//! windows by the factory-built node on "cpu" and on "gpu"; the interface outputs (positions
//! as displacements, velocities) and the report (momentum, kinetic energy, interface work and
//! impulse, support impulse, centre-of-mass displacement, von Mises stress, and
//! the strain energy, plastic work and the residual of the node's energy balance) must agree
//! within 1e-10 of their magnitude, for pd-bond and pd-correspondence; a yielding
//! pd-correspondence bar within 10× the CPU's own one-ulp sensitivity. The CPU path itself is
//! verified by pd_verification.rs (wave speed, patch test) and pd_solver.rs (impulse balance).
//! What the device path does not implement is refused at set-up naming `device`. Without an
//! adapter with f64 kernels the comparisons print why they were skipped and pass outside CI;
//! under `CI=true` they fail.

use mechanics::gpu::GpuContext;
use protocol::{
    Binding, CouplingKind, Inbox, Outbox, Role, Solver, SolverError, StepReport, Window,
};

/// Some(()) when an adapter with f64 kernels exists; prints why not otherwise.
fn adapter(test: &str) -> Option<()> {
    mechanics::gpu::f64_context_or_skip(test).map(|_| ())
}

fn table(model: &str, device: &str) -> toml::Table {
    let poisson = if model == "pd-bond" { 0.25 } else { 0.3 };
    let mut t: toml::Table = toml::from_str(
        r#"
dimension = "plane_strain"
thickness = 1e-3
spacing = 1e-3
horizon = 3.015e-3
density = 7850.0
young = 200e9
bodies = [{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.06, 0.006, 0.001] }]
initial_velocity = [{ region = { shape = "box", min = [0.0, 0.0, 0.0], max = [0.015, 0.006, 0.001] }, velocity = [5.0, 0.0, 0.0] }]
prescribed_velocity = [{ region = { shape = "box", min = [0.0575, 0.0, 0.0], max = [0.06, 0.006, 0.001] }, velocity = [0.0, 0.0, 0.0] }]
interfaces = [{ name = "all", select = "all" }]
points = { mid = [0.0305, 0.0035] }
"#,
    )
    .expect("params");
    t.insert("poisson".into(), toml::Value::Float(poisson));
    t.insert("device".into(), toml::Value::String(device.into()));
    t
}

fn binding(kind: CouplingKind, role: Role) -> Binding {
    Binding {
        coupling: "c".into(),
        kind,
        interface: "all".into(),
        role,
        peer: "gas".into(),
        peer_interface: "particles".into(),
        sends: vec![],
        receives: vec![],
        input_lag: 1,
    }
}

fn build(model: &str, t: &toml::Table) -> Result<Box<dyn Solver>, SolverError> {
    match solid_node::factory(model, t) {
        Ok(s) => Ok(s),
        Err(e) => Err(e),
    }
}

/// (initial positions, final positions, final velocities, reports: the initial report, then
/// one per window) of 6 windows of 2 µs, and the full state (displacements, velocities, forces) from the node's checkpoint at the end:
/// on the device path read from the device in full only there (per window only the report
/// crosses).
type Run = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<StepReport>, [Vec<f64>; 3]);

/// Displacements, velocities and forces from a checkpoint.
fn full_state(bytes: &[u8]) -> [Vec<f64>; 3] {
    let s: solid_node::pd::solver::BodyState =
        protocol::checkpoint::decode_state(bytes).expect("a peridynamic node's state");
    [&s.disp, &s.vel, &s.force].map(|v| v.iter().flatten().copied().collect())
}

fn run_with(model: &str, device: &str, density: f64, yield_stress: Option<f64>) -> Run {
    let mut t = table(model, device);
    t.insert("density".into(), toml::Value::Float(density));
    if let Some(y) = yield_stress {
        t.insert("yield_stress".into(), toml::Value::Float(y));
    }
    let mut s = build(model, &t).expect("the bar must build");
    let mut out = Outbox::new();
    s.setup(
        &[binding(CouplingKind::Immersed, Role::Driver)],
        &Inbox::new(),
        &mut out,
    )
    .expect("setup");
    let n = s.interface("all").expect("interface").len();
    let x0 = out.require("all", "position", 3 * n).expect("x0").to_vec();
    let mut reports = vec![s.initial_report().expect("initial report")];
    for w in 1..=6u64 {
        // A force up to ~1 N per particle (particle mass 7.85e-6 kg), different each window,
        // zero on every fifth particle.
        let mut inbox = Inbox::new();
        let f = inbox.put("all", "force", 3, n);
        for k in 0..n {
            if k % 5 == 0 {
                continue;
            }
            let a = (k as f64 * 0.37 + w as f64).sin();
            f[3 * k] = a;
            f[3 * k + 1] = 0.5 * (k as f64 * 0.11 - w as f64).cos();
        }
        let win = Window {
            index: w,
            t0: (w - 1) as f64 * 2e-6,
            t1: w as f64 * 2e-6,
            write_output: false,
        };
        reports.push(s.advance(&win, &inbox, &mut out).expect("advance"));
    }
    let x = out.require("all", "position", 3 * n).expect("x").to_vec();
    let v = out.require("all", "velocity", 3 * n).expect("v").to_vec();
    // an output frame from the (device) state
    let dir = std::env::temp_dir().join(format!(
        "solid-gpu-node-{}-{model}-{device}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).expect("scratch dir");
    s.write_output(12e-6, 6, &dir).expect("output frame");
    let frames = std::fs::read_dir(&dir).expect("frames").count();
    assert!(frames > 0, "no output frame written");
    let _ = std::fs::remove_dir_all(&dir);
    let full = full_state(&s.save_state().expect("checkpoint"));
    (x0, x, v, reports, full)
}

use mechanics::gpu::max_rel_diff as rel;

fn scalar(r: &StepReport, name: &str) -> Option<f64> {
    r.scalars.iter().find(|(k, _)| k == name).map(|(_, v)| *v)
}

/// Per window: strain energy, plastic work, and the energy residual of the node's own
/// balance, KE + U + W_p − (KE + U)(t = 0) − W_interface (the support is held at rest and
/// does no work), from the initial report and the window reports.
fn energy_series(first: &StepReport, reports: &[StepReport]) -> [Vec<f64>; 3] {
    let plastic = |r: &StepReport| scalar(r, "plastic_work").expect("plastic_work reported");
    let e0 = first.kinetic_energy + first.internal_energy + plastic(first);
    [
        reports.iter().map(|r| r.internal_energy).collect(),
        reports.iter().map(plastic).collect(),
        reports
            .iter()
            .map(|r| r.kinetic_energy + r.internal_energy + plastic(r) - e0 - r.interface_work)
            .collect(),
    ]
}

/// Largest differences of run `a` against run `b` (relative to `b`'s magnitudes, see
/// [`rel`]): interface outputs, full state, every report quantity window by window, and the
/// energies (strain energy and plastic work as series over the windows; the residual of the
/// node's own energy balance relative to the largest energy KE + U + W_p of `b`).
fn differences(a: &Run, b: &Run) -> Vec<(&'static str, f64)> {
    let (x0, xa, va, ra, fa) = a;
    let (_, xb, vb, rb, fb) = b;
    assert_eq!((ra.len(), rb.len()), (7, 7), "initial and 6 window reports");
    let disp = |x: &[f64]| -> Vec<f64> { x.iter().zip(x0).map(|(p, q)| p - q).collect() };
    let (ea, eb) = (
        energy_series(&ra[0], &ra[1..]),
        energy_series(&rb[0], &rb[1..]),
    );
    let scale = rb[1..]
        .iter()
        .map(|r| r.kinetic_energy + r.internal_energy + scalar(r, "plastic_work").unwrap_or(0.0))
        .fold(0.0_f64, f64::max);
    let residual = ea[2]
        .iter()
        .zip(&eb[2])
        .map(|(p, q)| (p - q).abs())
        .fold(0.0_f64, f64::max)
        / scale;
    let mut worst = vec![
        ("displacement", rel(&disp(xa), &disp(xb))),
        ("velocity", rel(va, vb)),
        ("full-state displacement", rel(&fa[0], &fb[0])),
        ("full-state velocity", rel(&fa[1], &fb[1])),
        ("full-state force", rel(&fa[2], &fb[2])),
        ("strain energy", rel(&ea[0], &eb[0])),
        ("plastic work", rel(&ea[1], &eb[1])),
        ("energy residual (of the largest energy)", residual),
    ];
    let (mut p, mut ke, mut wk, mut ii, mut ei, mut com, mut vm, mut pt) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (g, c) in ra[1..].iter().zip(&rb[1..]) {
        assert_eq!(c.substeps, g.substeps);
        p = f64::max(p, rel(&g.momentum, &c.momentum));
        ke = f64::max(ke, rel(&[g.kinetic_energy], &[c.kinetic_energy]));
        wk = f64::max(wk, rel(&[g.interface_work], &[c.interface_work]));
        ii = f64::max(ii, rel(&g.interface_impulse, &c.interface_impulse));
        ei = f64::max(ei, rel(&g.external_impulse, &c.external_impulse));
        let cx = scalar(c, "com_displacement_x").expect("com");
        com = f64::max(
            com,
            rel(&[scalar(g, "com_displacement_x").expect("com")], &[cx]),
        );
        // a reported point: on the device path its displacement comes from the gathered
        // position (to round-off of the position's size, 3 cm here)
        let ux = |r: &StepReport| scalar(r, "mid_ux").expect("mid_ux");
        pt = f64::max(pt, rel(&[ux(g)], &[ux(c)]));
        if let Some(s) = scalar(c, "max_von_mises") {
            vm = f64::max(vm, rel(&[scalar(g, "max_von_mises").expect("vm")], &[s]));
        }
    }
    worst.extend([
        ("momentum", p),
        ("kinetic energy", ke),
        ("interface work", wk),
        ("interface impulse", ii),
        ("support impulse", ei),
        ("com displacement", com),
        ("max von Mises", vm),
        ("point displacement", pt),
    ]);
    worst
}

/// The bar through the node on "cpu" and "gpu" (see the module doc); with `yield_stress`
/// the bar yields (pd-correspondence) and its plastic work is compared too.
fn compare(model: &str, yield_stress: Option<f64>) {
    let test = format!("{model} bar wave through the node (yield stress {yield_stress:?})");
    if adapter(&test).is_none() {
        return;
    }
    let cpu = run_with(model, "cpu", 7850.0, yield_stress);
    let gpu = run_with(model, "gpu", 7850.0, yield_stress);
    assert_eq!(cpu.0, gpu.0);
    for r in &gpu.3[1..] {
        assert_eq!(scalar(r, "gpu_precision_bits"), Some(64.0));
    }
    // For scale: the CPU against itself with the density one ulp larger, the round-off
    // sensitivity of the case.
    let ulp = run_with(
        model,
        "cpu",
        f64::from_bits(7850.0f64.to_bits() + 1),
        yield_stress,
    );
    let worst = differences(&gpu, &cpu);
    let control = differences(&ulp, &cpu);
    let rc = &cpu.3;
    let last = rc.last().expect("reports");
    let [strain, plastic, residual] = energy_series(&rc[0], &rc[1..]);
    let [_, _, residual_gpu] = energy_series(&gpu.3[0], &gpu.3[1..]);
    let peak = |v: &[f64]| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    println!(
        "{test}: {} substeps in 6 windows; final KE {:.4e} J, strain energy {:.4e} J, plastic work {:.4e} J, support impulse x {:.4e} N s, interface work {:.4e} J; largest energy residual CPU {:.4e} J, GPU {:.4e} J",
        rc[1..].iter().map(|r| r.substeps).sum::<u64>(),
        last.kinetic_energy,
        last.internal_energy,
        plastic.last().copied().unwrap_or(0.0),
        last.external_impulse[0],
        last.interface_work,
        peak(&residual),
        peak(&residual_gpu),
    );
    for ((name, e), (_, c)) in worst.iter().zip(&control) {
        println!(
            "  {name}: max relative difference GPU vs CPU {e:.3e} (one-ulp CPU control {c:.3e})"
        );
    }
    // the case is not trivial: the support held, the wave moved, the forces did work, the
    // bar stores strain energy
    assert!(last.external_impulse[0].abs() > 0.0 && last.interface_work.abs() > 0.0);
    assert!(strain.iter().all(|&u| u > 0.0), "strain energy {strain:?}");
    match yield_stress {
        None => {
            assert!(plastic.iter().all(|&w| w == 0.0), "{plastic:?}");
            // The bound asked of the device path is 1e-10. With displacement-based kinematics (session 4) the worst
            // measured on lavapipe is 2.4e-13 (pd-correspondence displacement; velocity was
            // 6.5e-11 before): held to 1e-11, the energies too.
            assert!(worst.iter().all(|(_, e)| *e <= 1e-11), "{worst:?}");
        }
        Some(_) => {
            assert!(
                plastic.last().is_some_and(|&w| w > 0.0),
                "the case must yield: {plastic:?}"
            );
            // The radial return makes a yielding case sensitive to round-off (a particle a
            // hair above or below the yield surface in a step): each quantity is held to 10×
            // the one-ulp control's difference, and to 1e-11 at least.
            for ((name, e), (_, c)) in worst.iter().zip(&control) {
                let env = c.max(1e-12);
                assert!(
                    *e <= 10.0 * env,
                    "{name}: GPU differs by {e:e}, the one-ulp control by {c:e}"
                );
            }
        }
    }
}

#[test]
fn bond_bar_wave_gpu_matches_cpu_through_the_node() {
    compare("pd-bond", None);
}

#[test]
fn correspondence_bar_wave_gpu_matches_cpu_through_the_node() {
    compare("pd-correspondence", None);
}

/// the plastic work accumulated on the device per step, and the strain energy of a
/// yielded bar, equal the CPU path's.
#[test]
fn plastic_correspondence_bar_energies_gpu_match_cpu_through_the_node() {
    // the launched quarter meets the held end at ≈ ρ c v/2 ≈ 115 MPa against 40 MPa
    compare("pd-correspondence", Some(40e6));
}

fn refusal(model: &str, t: &toml::Table) -> (String, String) {
    match build(model, t) {
        Err(SolverError::Config { key, reason }) => (key, reason),
        Err(e) => (format!("other error: {e}"), String::new()),
        Ok(_) => ("accepted".into(), String::new()),
    }
}

/// What the device kernels do not implement is refused at set-up with the key `device` and
/// the reason; nothing falls back to the CPU. These refusals come before any adapter is
/// looked for, so they run everywhere.
#[test]
fn unsupported_gpu_configurations_are_refused_naming_device() {
    let damage = |kind: &str| -> toml::Value {
        let d: toml::Table = match kind {
            "critical_stretch" => {
                toml::from_str("kind = \"critical_stretch\"\ncritical_stretch = 0.01")
            }
            _ => toml::from_str("kind = \"von_mises\"\ncritical_stress = 1e9"),
        }
        .expect("damage");
        toml::Value::Table(d)
    };
    // pd-bond breaks bonds at the critical stretch on the device (tests/gpu_fracture.rs):
    // accepted (checked without opening a device)
    let mut t = table("pd-bond", "gpu");
    t.insert("damage".into(), damage("critical_stretch"));
    assert!(
        solid_node::build("pd-bond", &t, &protocol::BuildOptions::DESCRIBE).is_ok(),
        "pd-bond + critical_stretch on the gpu must be accepted"
    );
    for (model, kind) in [
        ("pd-bond", "von_mises"),
        ("pd-correspondence", "critical_stretch"),
        ("pd-correspondence", "von_mises"),
    ] {
        let mut t = table(model, "gpu");
        t.insert("damage".into(), damage(kind));
        let (key, reason) = refusal(model, &t);
        println!("{model} + damage {kind}: {key}: {reason}");
        assert_eq!(key, "device");
        assert!(
            reason.contains("damage") && reason.contains(kind),
            "{reason}"
        );
        // the same on the CPU is accepted (pd-bond breaks by critical stretch only)
        let mut t = table(model, "cpu");
        t.insert("damage".into(), damage(kind));
        if model != "pd-bond" {
            assert_eq!(refusal(model, &t).0, "accepted");
        }
    }
    let mut t = table("pd-correspondence", "gpu");
    t.insert(
        "dimension".into(),
        toml::Value::String("plane_stress".into()),
    );
    let (key, reason) = refusal("pd-correspondence", &t);
    println!("pd-correspondence + plane_stress: {key}: {reason}");
    assert_eq!(key, "device");
    assert!(reason.contains("plane_stress"), "{reason}");
    let mut t = table("pd-correspondence", "gpu");
    t.insert("rk_order".into(), toml::Value::Integer(2));
    let (key, reason) = refusal("pd-rk-ba", &t);
    println!("pd-rk-ba: {key}: {reason}");
    assert_eq!(key, "device");
    assert!(reason.contains("pd-rk-ba"), "{reason}");
    let mut t = table("pd-correspondence", "gpu");
    let pp: toml::Table = toml::from_str(
        "center = [0.03, 0.003, 0.0]\ninner_radius = 0.001\npeak = 1e6\nduration = 1e-6",
    )
    .expect("pulse");
    t.insert("pressure_pulse".into(), toml::Value::Table(pp));
    let (key, reason) = refusal("pd-correspondence", &t);
    println!("pressure_pulse: {key}: {reason}");
    assert_eq!(key, "device");
    assert!(reason.contains("pressure_pulse"), "{reason}");
    let (key, reason) = refusal("pd-bond", &table("pd-bond", "tpu"));
    assert_eq!(key, "device");
    assert!(reason.contains("tpu"), "{reason}");
}

/// A kinematic responder moves its particles every substep: refused at set-up on "gpu".
#[test]
fn kinematic_responder_on_gpu_is_refused_at_setup() {
    if adapter("kinematic responder on gpu").is_none() {
        return;
    }
    let model = "pd-correspondence";
    let mut s = build(model, &table(model, "gpu")).expect("builds");
    let e = s.setup(
        &[binding(CouplingKind::Kinematic, Role::Responder)],
        &Inbox::new(),
        &mut Outbox::new(),
    );
    match e {
        Err(SolverError::Config { key, reason }) => {
            println!("kinematic responder: {key}: {reason}");
            assert_eq!(key, "device");
            assert!(reason.contains("kinematic responder"), "{reason}");
        }
        other => panic!("expected a config error, got {other:?}"),
    }
}

/// Without an adapter, "gpu" is a config error naming `device` (never a panic). Run on every
/// machine: the test runs its inner half in a child process of this test binary with the
/// Vulkan driver hidden (`VK_ICD_FILENAMES` pointing nowhere, `WGPU_BACKEND=vulkan`), where
/// no adapter can be found, and requires the child to pass.
#[test]
fn no_adapter_is_a_config_error() {
    let exe = std::env::current_exe().expect("test binary path");
    let o = std::process::Command::new(exe)
        .args([
            "--exact",
            "gpu_node::no_adapter_inner",
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        // VK_DRIVER_FILES overrides VK_ICD_FILENAMES in current loaders (the NVIDIA driver is
        // often named through it), so both point nowhere and no driver is added.
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .env_remove("VK_ADD_DRIVER_FILES")
        .env("WGPU_BACKEND", "vulkan")
        .output()
        .expect("the test binary runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    println!("{text}");
    assert!(o.status.success(), "inner test failed:\n{text}");
    assert!(
        text.contains("1 passed"),
        "the inner test did not run:\n{text}"
    );
}

/// The inner half of [`no_adapter_is_a_config_error`], run by it with the driver hidden.
#[test]
#[ignore = "run by no_adapter_is_a_config_error with the Vulkan driver hidden"]
fn no_adapter_inner() {
    let e = match GpuContext::new() {
        Err(e) => e,
        Ok(c) => panic!(
            "an adapter was found with the Vulkan driver hidden: {}",
            c.describe()
        ),
    };
    let (key, reason) = refusal("pd-bond", &table("pd-bond", "gpu"));
    println!("no adapter ({e}): {key}: {reason}");
    assert_eq!(key, "device");
    assert!(reason.contains("no GPU adapter"), "{reason}");
}

/// Checkpoint on the device path: 3 windows, `save_state`, then a fresh "gpu" node that
/// `load_state`s the blob and runs windows 4–6 ends bit-identical to the uninterrupted run
/// (the device body is rebuilt from the restored host state and J2 states).
#[test]
fn gpu_checkpoint_restart_is_bit_identical() {
    if adapter("gpu checkpoint").is_none() {
        return;
    }
    let model = "pd-correspondence";
    let force = |w: u64, n: usize| -> Inbox {
        let mut inbox = Inbox::new();
        let f = inbox.put("all", "force", 3, n);
        for k in 0..n {
            f[3 * k + 1] = (k as f64 * 0.23 + w as f64).sin();
        }
        inbox
    };
    let win = |w: u64| Window {
        index: w,
        t0: (w - 1) as f64 * 2e-6,
        t1: w as f64 * 2e-6,
        write_output: false,
    };
    let b = [binding(CouplingKind::Immersed, Role::Driver)];
    let mut a = build(model, &table(model, "gpu")).expect("builds");
    let mut out = Outbox::new();
    a.setup(&b, &Inbox::new(), &mut out).expect("setup");
    let n = a.interface("all").expect("interface").len();
    for w in 1..=3 {
        a.advance(&win(w), &force(w, n), &mut out).expect("advance");
    }
    let blob = a.save_state().expect("save");
    let mut c = build(model, &table(model, "gpu")).expect("builds");
    let mut out_c = Outbox::new();
    c.setup(&b, &Inbox::new(), &mut out_c).expect("setup");
    c.load_state(&blob).expect("load");
    let (mut ra, mut rc) = (None, None);
    for w in 4..=6 {
        ra = Some(a.advance(&win(w), &force(w, n), &mut out).expect("advance"));
        rc = Some(
            c.advance(&win(w), &force(w, n), &mut out_c)
                .expect("advance"),
        );
    }
    let (ra, rc) = (ra.expect("report"), rc.expect("report"));
    for f in ["position", "velocity"] {
        assert_eq!(
            out.require("all", f, 3 * n).expect("a"),
            out_c.require("all", f, 3 * n).expect("c"),
            "{f}"
        );
    }
    assert_eq!(ra.momentum, rc.momentum);
    assert_eq!(ra.interface_work, rc.interface_work);
    assert_eq!(scalar(&ra, "max_von_mises"), scalar(&rc, "max_von_mises"));
    println!(
        "gpu checkpoint: restart after window 3 matches the uninterrupted run bit for bit (KE {:.6e} J)",
        ra.kinetic_energy
    );
}
