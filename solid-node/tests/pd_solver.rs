//! The peridynamic `Solver`: config validation names the key, and the
//! coupling sides against an in-process stand-in peer (immersed provider, kinematic
//! responder and driver), checkpoints, and the VTK frame read back.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use mechanics::j2::to_matrix;
use protocol::{Binding, CouplingKind, Inbox, Outbox, Role, Solver, SolverError, Window};
use solid_node::pd::solver::PdSolver;
use vtkio::model::{Attribute, DataSet, IOBuffer, Piece};

fn base() -> toml::Table {
    toml::from_str(
        r#"
dimension = "3d"
spacing = 1e-3
horizon = 3.015e-3
density = 7850.0
young = 200e9
poisson = 0.25
bodies = [{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.008, 0.006, 0.006] }]
interfaces = [{ name = "surface", select = "surface" }, { name = "left", select = "all", region = { shape = "box", min = [0.0, 0.0, 0.0], max = [0.0021, 0.006, 0.006] } }]
"#,
    )
    .unwrap_or_default()
}

/// The parameter lines of a 12 × 6 mm glass plate, 1 mm thick (E 74 GPa, ρ 2480 kg/m³),
/// with the lattice `spacing`, `horizon` and `poisson` (pd-bond's own in its `dimension`).
pub fn glass_strip(dimension: &str, spacing: f64, horizon: f64, poisson: f64) -> String {
    format!(
        r#"
dimension = "{dimension}"
thickness = 1e-3
spacing = {spacing:e}
horizon = {horizon:e}
density = 2480.0
young = 74e9
poisson = {poisson:?}
bodies = [{{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.012, 0.006, 0.0] }}]"#
    )
}

/// The key a config error names, or "accepted" (shared with the other files' refusal tests).
pub fn key_of(model: &str, t: &toml::Table) -> String {
    match solid_node::pd::factory(model, t) {
        Some(Err(SolverError::Config { key, .. })) => key,
        Some(Err(e)) => format!("other error: {e}"),
        Some(Ok(_)) => "accepted".into(),
        None => "not a pd model".into(),
    }
}

#[test]
fn bad_input_is_refused_with_the_key() {
    let ok = base();
    assert_eq!(key_of("pd-bond", &ok), "accepted");
    // A fragment axis that is not a point.
    let mut t = base();
    t.insert(
        "fragment_axis".into(),
        toml::Value::Array(vec![toml::Value::Float(0.0)]),
    );
    assert_eq!(key_of("pd-bond", &t), "fragment_axis");
    t.insert(
        "fragment_axis".into(),
        toml::Value::Array(vec![toml::Value::Float(0.0), toml::Value::Float(0.1)]),
    );
    assert_eq!(key_of("pd-bond", &t), "accepted");
    // Horizon smaller than the spacing.
    let mut t = base();
    t.insert("horizon".into(), toml::Value::Float(0.5e-3));
    assert_eq!(key_of("pd-bond", &t), "horizon");
    // ν out of range for the chosen model: bond-based 3-D fixes 1/4; correspondence (−1, ½).
    let mut t = base();
    t.insert("poisson".into(), toml::Value::Float(0.3));
    assert_eq!(key_of("pd-bond", &t), "poisson");
    assert_eq!(key_of("pd-correspondence", &t), "accepted");
    t.insert("poisson".into(), toml::Value::Float(0.5));
    assert_eq!(key_of("pd-correspondence", &t), "poisson");
    assert_eq!(key_of("pd-rk-ba", &t), "poisson");
    t.insert("poisson".into(), toml::Value::Float(-1.0));
    assert_eq!(key_of("pd-rk-ba", &t), "poisson");
    // bond-based plane stress fixes 1/3 (1/4 is the 3-D value), plane strain 1/4
    let mut t = base();
    for (k, v) in [
        ("dimension", toml::Value::String("plane_stress".into())),
        ("thickness", toml::Value::Float(1e-3)),
    ] {
        t.insert(k.into(), v);
    }
    assert_eq!(key_of("pd-bond", &t), "poisson");
    t.insert("poisson".into(), toml::Value::Float(1.0 / 3.0));
    assert_eq!(key_of("pd-bond", &t), "accepted");
    t.insert(
        "dimension".into(),
        toml::Value::String("plane_strain".into()),
    );
    assert_eq!(key_of("pd-bond", &t), "poisson");
    // Damage threshold above the failure value.
    let mut t = base();
    t.insert("yield_stress".into(), toml::Value::Float(300e6));
    let d: toml::Table =
        toml::from_str("kind = \"plastic_strain\"\neps_threshold = 0.3\neps_critical = 0.2")
            .unwrap_or_default();
    t.insert("damage".into(), toml::Value::Table(d));
    assert_eq!(key_of("pd-correspondence", &t), "damage.eps_threshold");
    // An empty body: no shapes, or shapes with no lattice point.
    let mut t = base();
    t.insert("bodies".into(), toml::Value::Array(vec![]));
    assert_eq!(key_of("pd-bond", &t), "bodies");
    let mut t = base();
    let tiny: toml::Table =
        toml::from_str("shape = \"box\"\nmin = [0.0, 0.0, 0.0]\nmax = [1e-4, 1e-4, 1e-4]")
            .unwrap_or_default();
    t.insert(
        "bodies".into(),
        toml::Value::Array(vec![toml::Value::Table(tiny)]),
    );
    assert_eq!(key_of("pd-bond", &t), "bodies");
    // Unknown keys are refused.
    let mut t = base();
    t.insert("horizn".into(), toml::Value::Float(1.0));
    assert_eq!(key_of("pd-bond", &t), "horizn");
}

fn binding(kind: CouplingKind, role: Role, iface: &str) -> Binding {
    Binding {
        coupling: "c".into(),
        kind,
        interface: iface.into(),
        role,
        peer: "peer".into(),
        peer_interface: "x".into(),
        sends: vec![],
        receives: vec![],
        input_lag: 1,
    }
}

/// Window `index` of 2 µs.
fn window(index: u64) -> Window {
    window_of(index, 2e-6)
}

/// Window `index` (from 1) of windows `len` seconds long, without output.
pub fn window_of(index: u64, len: f64) -> Window {
    Window {
        index,
        t0: (index - 1) as f64 * len,
        t1: index as f64 * len,
        write_output: false,
    }
}

/// From rest, a per-particle force summing to `fsum` held over the first 2 µs window: the
/// body's momentum and the interface impulse both equal Σ F · window. Relative to the
/// impulse's largest component: a zero component carries only the round-off of the internal
/// forces' sum (1.6e-21 N s measured against 2.4e-6 N s since the bond stretch is formed from
/// displacements).
fn assert_impulse(rep: &protocol::StepReport, fsum: [f64; 3]) {
    let scale = (0..3).map(|d| (fsum[d] * 2e-6).abs()).fold(0.0, f64::max);
    for d in 0..3 {
        let expect = fsum[d] * 2e-6;
        assert!(
            (rep.momentum[d] - expect).abs() <= 1e-12 * scale,
            "d={d}: {} vs {expect}",
            rep.momentum[d]
        );
        assert!(
            (rep.interface_impulse[d] - expect).abs() <= 1e-12 * scale,
            "d={d}: {} vs {expect}",
            rep.interface_impulse[d]
        );
    }
}

/// Immersed provider (the driver, as the scheme has the solid): sends position/velocity/volume
/// at set-up and each window; a received per-particle force F held over the window changes
/// the momentum by Σ F · window exactly.
#[test]
fn immersed_provider_applies_forces_and_conserves_impulse() {
    let mut s = match solid_node::pd::factory("pd-bond", &base()) {
        Some(Ok(s)) => s,
        _ => panic!("base config must build"),
    };
    let b = [binding(CouplingKind::Immersed, Role::Driver, "surface")];
    let mut out = Outbox::new();
    s.setup(&b, &Inbox::new(), &mut out).expect("setup");
    let n = s.interface("surface").expect("iface").len();
    assert_eq!(
        out.require("surface", "position", 3 * n)
            .map(|v| v.len())
            .ok(),
        Some(3 * n)
    );
    assert!(out.require("surface", "volume", n).is_ok());
    let mut inbox = Inbox::new();
    let f = inbox.put("surface", "force", 3, n);
    for k in 0..n {
        f[3 * k] = 1.0 + 0.01 * k as f64;
        f[3 * k + 2] = -0.5;
    }
    let fsum: [f64; 3] = std::array::from_fn(|d| f.chunks(3).map(|c| c[d]).sum());
    let rep = s.advance(&window(1), &inbox, &mut out).expect("advance");
    assert_impulse(&rep, fsum);
    assert!(out.require("surface", "velocity", 3 * n).is_ok());
}

/// Kinematic responder: the boundary layer follows the driver's motion and lands on its
/// positions; set-up sends mass, stiffness and force; each window the force at t1.
#[test]
fn kinematic_responder_follows_the_driver() {
    let mut s = match solid_node::pd::factory("pd-correspondence", &{
        let mut t = base();
        t.insert("poisson".into(), toml::Value::Float(0.3));
        t
    }) {
        Some(Ok(s)) => s,
        _ => panic!("config must build"),
    };
    let b = [binding(CouplingKind::Kinematic, Role::Responder, "left")];
    let mut out = Outbox::new();
    s.setup(&b, &Inbox::new(), &mut out).expect("setup");
    let mesh = s.interface("left").expect("iface");
    let n = mesh.len();
    let m = out.require("left", "mass", n).expect("mass").to_vec();
    assert!((m[0] - 7850.0 * 1e-9).abs() < 1e-15);
    assert!(
        out.require("left", "stiffness", n)
            .expect("k")
            .iter()
            .all(|&k| k > 0.0)
    );
    assert!(out.require("left", "force", 3 * n).is_ok());
    // Driver pulls the layer in −x at 2 m/s for one window.
    let span = 2e-7; // the wave crosses 1 mm: the rest of the body still lags
    let mut inbox = Inbox::new();
    let v = inbox.put("left", "velocity", 3, n);
    for k in 0..n {
        v[3 * k] = -2.0;
    }
    let x = inbox.put("left", "position", 3, n);
    for k in 0..n {
        x[3 * k] = mesh.positions[k][0] - 2.0 * span;
        x[3 * k + 1] = mesh.positions[k][1];
        x[3 * k + 2] = mesh.positions[k][2];
    }
    let w = Window {
        index: 1,
        t0: 0.0,
        t1: span,
        write_output: false,
    };
    s.advance(&w, &inbox, &mut out).expect("advance");
    let after = s.interface("left").expect("iface");
    for k in 0..n {
        assert!((after.positions[k][0] - (mesh.positions[k][0] - 2.0 * span)).abs() < 1e-15);
    }
    // The rest of the body pulls the layer back: net constraint force on it is +x.
    let f = out.require("left", "force", 3 * n).expect("force");
    let fx: f64 = f.chunks(3).map(|c| c[0]).sum();
    assert!(fx > 0.0, "the body must resist being pulled: {fx}");
}

/// Kinematic driver (the PD body drives a responder's boundary layer): set-up sends the
/// interface's positions and velocities; each window the responder's constraint force is
/// applied over the window (momentum and interface impulse change by Σ F · window), and the
/// motion at t1 goes out, equal to the body's interface state. A non-physical set-up mass
/// and a missing force are refused, naming the interface.
#[test]
fn kinematic_driver_sends_motion_and_applies_the_force() {
    let build = || match solid_node::pd::factory("pd-bond", &base()) {
        Some(Ok(s)) => s,
        _ => panic!("base config must build"),
    };
    let b = [binding(CouplingKind::Kinematic, Role::Driver, "left")];
    let mut s = build();
    // the responder's set-up masses, one per interface particle, one of them NaN
    let n_left = s.interface("left").expect("iface").len();
    let mut set_up = Inbox::new();
    let m = set_up.put("left", "mass", 1, n_left);
    m.fill(1e-6);
    m[n_left / 2] = f64::NAN;
    match build().setup(&b, &set_up, &mut Outbox::new()) {
        Err(e) => assert!(
            e.to_string().contains("left") && e.to_string().contains("mass"),
            "{e}"
        ),
        Ok(()) => panic!("a NaN set-up mass must be refused"),
    }
    let mut out = Outbox::new();
    s.setup(&b, &Inbox::new(), &mut out).expect("setup");
    let mesh = s.interface("left").expect("iface");
    let n = mesh.len();
    assert!(n > 0);
    let x = out.require("left", "position", 3 * n).expect("position");
    for k in 0..n {
        assert_eq!(&x[3 * k..3 * k + 3], &mesh.positions[k][..]);
    }
    assert!(
        out.require("left", "velocity", 3 * n)
            .expect("velocity")
            .iter()
            .all(|&v| v == 0.0)
    );
    // The responder's constraint force: pulls the layer in −x, a little shear in z.
    let mut inbox = Inbox::new();
    let f = inbox.put("left", "force", 3, n);
    for k in 0..n {
        f[3 * k] = -2.0 - 0.01 * k as f64;
        f[3 * k + 2] = 0.25;
    }
    let fsum: [f64; 3] = std::array::from_fn(|d| f.chunks(3).map(|c| c[d]).sum());
    let rep = s.advance(&window(1), &inbox, &mut out).expect("advance");
    assert_impulse(&rep, fsum);
    // The motion at t1 is the body's interface state, and the layer moved in −x.
    let after = s.interface("left").expect("iface");
    let x = out.require("left", "position", 3 * n).expect("position");
    let v = out.require("left", "velocity", 3 * n).expect("velocity");
    let mut vx = 0.0;
    for k in 0..n {
        assert_eq!(&x[3 * k..3 * k + 3], &after.positions[k][..]);
        vx += v[3 * k];
    }
    assert!(vx < 0.0, "the pulled layer must move in −x: Σ vx = {vx}");
    // A driver needs the responder's force every window.
    match s.advance(&window(2), &Inbox::new(), &mut out) {
        Err(e) => assert!(e.to_string().contains("left"), "{e}"),
        Ok(_) => panic!("a window without the responder's force must be refused"),
    }
}

/// A Johnson–Cook solid softer than 4340 (A = 300 MPa, so that the block's 40 m/s flows;
/// 4340's B, n, C, m and thermal constants), the steel Mie–Grüneisen pressure, and a failure
/// strain of 0.002 (D1 alone) so that bonds break within the test's eight windows.
const JOHNSON_COOK: &str = r#"poisson = 0.29
yield_stress = 300e6
johnson_cook = { hardening_modulus = 510e6, hardening_exponent = 0.26, rate_coefficient = 0.014, thermal_exponent = 1.03, room_temperature = 273.0, melt_temperature = 1793.0, specific_heat = 477.0 }
eos = { kind = "mie_gruneisen", sound_speed = 4569.0, s1 = 1.49, gamma0 = 2.17, volume_correction = 0.46 }
damage = { kind = "johnson_cook", d1 = 0.002, d2 = 0.0, d3 = 0.0, d4 = 0.0, d5 = 0.0 }"#;

/// Checkpoint: `save_state` after some windows, then (a) keep running and (b) a fresh node
/// built from the same parameters that `load_state`s the blob and runs the same windows give
/// bit-identical positions, velocities, damage and reports, for every model (with plasticity
/// and bond breaking under way). A truncated blob is refused.
#[test]
fn checkpoint_restart_is_bit_identical() {
    let extra = [
        (
            "pd-bond",
            "damage = { kind = \"critical_stretch\", critical_stretch = 0.004 }",
        ),
        (
            "pd-correspondence",
            "poisson = 0.3\nyield_stress = 300e6\niso_hardening = 1e9\ndamage = { kind = \"plastic_strain\", eps_threshold = 0.002, eps_critical = 0.01 }",
        ),
        (
            "pd-rk-ba",
            "poisson = 0.3\nyield_stress = 150e6\nkin_hardening = 20e9\ndamage = { kind = \"von_mises\", critical_stress = 250e6 }",
        ),
        // the Johnson–Cook solid with its temperature, pressure work and failure indicator
        // (a failure strain of 0.2 % so that bonds break within the run)
        ("pd-correspondence", JOHNSON_COOK),
    ];
    for (model, ex) in extra {
        let mut t = base();
        t.remove("poisson");
        let e: toml::Table = toml::from_str(&format!(
            "{ex}\ninitial_velocity = [{{ region = {{ shape = \"box\", min = [0.0, 0.0, 0.0], max = [0.003, 0.006, 0.006] }}, velocity = [-40.0, 15.0, 0.0] }}]"
        ))
        .unwrap_or_default();
        for (k, v) in e {
            t.insert(k, v);
        }
        if !t.contains_key("poisson") {
            t.insert("poisson".into(), toml::Value::Float(0.25));
        }
        let build = || match solid_node::pd::factory(model, &t) {
            Some(Ok(s)) => s,
            Some(Err(e)) => panic!("{model}: {e}"),
            None => panic!("{model}: unknown"),
        };
        let win = |k: u64| Window {
            index: k,
            t0: (k - 1) as f64 * 0.5e-6,
            t1: k as f64 * 0.5e-6,
            write_output: false,
        };
        let (inbox, mut out) = (Inbox::new(), Outbox::new());
        let mut a = build();
        a.setup(&[], &inbox, &mut out).expect("setup");
        for k in 1..=4 {
            a.advance(&win(k), &inbox, &mut out).expect("advance");
        }
        let blob = a.save_state().expect("save");
        let mut reports_a = Vec::new();
        for k in 5..=8 {
            reports_a.push(a.advance(&win(k), &inbox, &mut out).expect("advance"));
        }
        let mut b = build();
        b.setup(&[], &inbox, &mut out).expect("setup");
        assert!(
            b.load_state(&blob[..blob.len() - 3]).is_err(),
            "{model}: truncated blob accepted"
        );
        b.load_state(&blob).expect("load");
        let mut reports_b = Vec::new();
        for k in 5..=8 {
            reports_b.push(b.advance(&win(k), &inbox, &mut out).expect("advance"));
        }
        let sa = a.save_state().expect("save a");
        let sb = b.save_state().expect("save b");
        let damaged = reports_a
            .last()
            .and_then(|r| r.scalars.iter().find(|(n, _)| n == "max_damage"))
            .map(|s| s.1)
            .unwrap_or(0.0);
        println!(
            "{model}: checkpoint {} bytes, max damage at the end {damaged:.3}",
            blob.len()
        );
        assert!(damaged > 0.0, "{model}: the run should break bonds");
        assert!(sa == sb, "{model}: restarted state differs");
        for (ra, rb) in reports_a.iter().zip(&reports_b) {
            assert_eq!(ra.momentum, rb.momentum);
            assert_eq!(
                ra.kinetic_energy.to_bits(),
                rb.kinetic_energy.to_bits(),
                "{model}"
            );
        }
    }
}

/// Point arrays read back: (name, components, values).
type Arrays = Vec<(String, usize, Vec<f64>)>;

/// The points and point arrays of a `.vtu`.
fn read_vtu(path: &std::path::Path) -> (Vec<f64>, Arrays) {
    let vtk = vtkio::Vtk::import(path).expect("vtkio reads the file back");
    let DataSet::UnstructuredGrid { pieces, .. } = vtk.data else {
        panic!("not an unstructured grid")
    };
    assert_eq!(pieces.len(), 1);
    let Piece::Inline(piece) = pieces.into_iter().next().expect("one piece") else {
        panic!("piece not inline")
    };
    let f64s = |b: IOBuffer| b.cast_into::<f64>().expect("numeric buffer");
    let mut arrays = Vec::new();
    for a in piece.data.point {
        match a {
            Attribute::DataArray(d) => {
                let comps = d.num_comp();
                arrays.push((d.name.clone(), comps, f64s(d.data)));
            }
            Attribute::Field { name, .. } => panic!("unexpected field attribute {name}"),
        }
    }
    (f64s(piece.points), arrays)
}

/// The node's VTK frame ("VTK output of displacement, velocity, stress, plastic
/// strain and damage per particle"), read back with vtkio: every array equals the solver's
/// state bit for bit, for a correspondence body that is yielding and breaking bonds.
#[test]
fn vtk_frame_reads_back_equal_to_the_state() {
    // the base block, J2 with ductile damage, one end thrown out: it yields and tears
    let mut t = base();
    let extra: toml::Table = toml::from_str(
        r#"
poisson = 0.3
yield_stress = 300e6
iso_hardening = 1e9
damage = { kind = "plastic_strain", eps_threshold = 0.002, eps_critical = 0.01 }
initial_velocity = [{ region = { shape = "box", min = [0.0, 0.0, 0.0], max = [0.003, 0.006, 0.006] }, velocity = [-40.0, 15.0, 0.0] }]
"#,
    )
    .expect("toml");
    t.extend(extra);
    let mut s = PdSolver::from_table("pd-correspondence", &t).expect("config builds");
    let (inbox, mut out) = (Inbox::new(), Outbox::new());
    s.setup(&[], &inbox, &mut out).expect("setup");
    for k in 1..=6u64 {
        let w = Window {
            index: k,
            t0: (k - 1) as f64 * 0.5e-6,
            t1: k as f64 * 0.5e-6,
            write_output: false,
        };
        s.advance(&w, &inbox, &mut out).expect("advance");
    }
    let dir = std::env::temp_dir().join(format!("pd_output_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    s.write_output(3e-6, 6, &dir).expect("write");
    let (points, arrays) = read_vtu(&dir.join("pd_000006.vtu"));
    let pvd = std::fs::read_to_string(dir.join("pd.pvd")).expect("pvd");
    assert!(pvd.contains("file=\"pd_000006.vtu\""), "{pvd}");
    let _ = std::fs::remove_dir_all(&dir);

    let b = &mut s.body;
    let n = b.len();
    let get = |name: &str, comps: usize| -> Vec<f64> {
        let (_, c, v) = arrays
            .iter()
            .find(|(a, _, _)| a == name)
            .unwrap_or_else(|| panic!("no array {name}"));
        assert_eq!((*c, v.len()), (comps, comps * n), "{name}");
        v.clone()
    };
    let x: Vec<f64> = (0..n)
        .flat_map(|i| (0..3).map(move |d| (i, d)))
        .map(|(i, d)| b.x0[i][d] + b.disp[i][d])
        .collect();
    assert_eq!(points, x, "points");
    assert_eq!(
        get("displacement", 3),
        b.disp.as_flattened(),
        "displacement"
    );
    assert_eq!(get("velocity", 3), b.vel.as_flattened(), "velocity");
    let stress: Vec<f64> = b
        .model
        .stress()
        .expect("correspondence has stress")
        .iter()
        .flat_map(|s| to_matrix(s).into_iter().flatten())
        .collect();
    assert_eq!(get("stress", 9), stress, "stress");
    let plastic = b.model.plastic_strain().expect("J2 has plastic strain");
    assert!(
        plastic.iter().cloned().fold(0.0, f64::max) > 0.0,
        "the case must yield"
    );
    assert_eq!(get("plastic_strain", 1), plastic, "plastic strain");
    let damage = b.damage();
    assert!(
        damage.iter().cloned().fold(0.0, f64::max) > 0.0,
        "the case must break bonds"
    );
    assert_eq!(get("damage", 1), damage, "damage");
}

/// A support that holds one component (`components = "y"`): the plate's bottom row slides
/// in x under a load that pulls the whole plate along x and down, and stays at y = 0; the
/// body's momentum is the load's impulse less the support's, component by component, to
/// round-off. A bad letter is refused by its key.
#[test]
fn a_support_can_hold_one_component() {
    let table = |components: &str| -> toml::Table {
        toml::from_str(&format!(
            r#"{}
prescribed_velocity = [{{ region = {{ shape = "box", min = [-1.0, -1.0, -1.0], max = [1.0, 0.001, 1.0] }}, velocity = [0.0, 0.0, 0.0], components = "{components}" }}]
loads = [{{ region = {{ shape = "box", min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] }}, force = [50.0, -80.0, 0.0] }}]
"#,
            glass_strip("plane_stress", 1e-3, 2e-3, 0.22)
        ))
        .expect("toml")
    };
    let mut s = PdSolver::from_table("pd-correspondence", &table("y")).expect("builds");
    let bottom: Vec<usize> = (0..s.body.len())
        .filter(|&i| s.body.x0[i][1] < 0.001)
        .collect();
    assert_eq!(bottom.len(), 12);
    s.setup(&[], &Inbox::new(), &mut Outbox::new())
        .expect("set-up");
    let mut rep = None;
    for k in 1..=5 {
        rep = Some(
            s.advance(&window(k), &Inbox::new(), &mut Outbox::new())
                .expect("advance"),
        );
    }
    let rep = rep.expect("a report");
    for &i in &bottom {
        assert_eq!(s.body.vel[i][1], 0.0);
        assert_eq!(s.body.disp[i][1], 0.0);
        assert!(s.body.vel[i][0] > 0.0, "the bottom row slides in x");
    }
    // the load's x impulse: 50 N over 10 µs, all of it momentum
    let jx = 50.0 * 1e-5;
    assert!(
        (rep.momentum[0] - jx).abs() < 1e-12 * jx,
        "{:?}",
        rep.momentum
    );
    assert!((rep.external_impulse[0] - jx).abs() < 1e-12 * jx);
    let py = rep.momentum[1] - rep.external_impulse[1];
    assert!(py.abs() < 1e-12 * 80.0 * 1e-5, "{py:e}");
    assert!(
        rep.external_impulse[1] > -80.0 * 1e-5,
        "the support took part of the y load"
    );
    match PdSolver::from_table("pd-correspondence", &table("yw")) {
        Err(SolverError::Config { key, .. }) => {
            assert_eq!(key, "prescribed_velocity[0].components")
        }
        Err(e) => panic!("expected a config error, got {e}"),
        Ok(_) => panic!("\"yw\" must be refused"),
    }
}
