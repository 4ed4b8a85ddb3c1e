//! The `fem-2d` node in process: its report balances (the momentum of the bar equals the
//! impulse of its load and support; kinetic plus strain energy equals the work of the load),
//! a checkpoint restarts bit-identically, and its parameters are refused with their keys.

use protocol::{Binding, CouplingKind, Inbox, Outbox, Role, Solver, StepReport, Window};
use solid_node::fem2d::Fem2d;

/// The seed 003 §5.1 bar, 20 × 2, with a step load and `extra` keys.
fn bar(extra: &str) -> Fem2d {
    bar_with("", extra)
}

/// The same bar with `history` keys for its load.
fn bar_with(history: &str, extra: &str) -> Fem2d {
    let text = format!(
        "length = 10.0\nheight = 1.0\nnx = 20\nny = 2\nyoung = 72e9\npoisson = 0.3\n\
         density = 2700.0\nfixed = [\"left\"]\n\
         loads = [{{ edge = \"right\", traction = [-1e4, 0.0] {history} }}]\n\
         points = {{ B = [10.0, 0.5] }}\n{extra}"
    );
    let table = match text.parse::<toml::Table>() {
        Ok(t) => t,
        Err(e) => panic!("{e}"),
    };
    match Fem2d::from_params(&table) {
        Ok(m) => m,
        Err(e) => panic!("{e}"),
    }
}

fn window(k: u64, w: f64) -> Window {
    Window {
        index: k + 1,
        t0: k as f64 * w,
        t1: (k + 1) as f64 * w,
        write_output: false,
    }
}

fn run(node: &mut Fem2d, from: u64, to: u64, w: f64) -> Vec<StepReport> {
    let mut out = Outbox::new();
    (from..to)
        .map(
            |k| match node.advance(&window(k, w), &Inbox::new(), &mut out) {
                Ok(r) => r,
                Err(e) => panic!("{e}"),
            },
        )
        .collect()
}

#[test]
fn momentum_and_energy_balance_the_load_and_support() {
    // Over two transits of the wave (3.9 ms): the loaded end pushes, the reflection reaches
    // the support. The load ramps up over one transit (C³ ramp), so that the modes near the
    // mesh's highest frequency, where central differences' energy differs most from ½vᵀMv +
    // ½uᵀKu, stay quiet. Implicit Newmark conserves that energy exactly (with the
    // trapezoidal work of the load); central differences to O((ωΔt)²) of the modes excited.
    let ramp = ", history = \"ramp\", ramp_time = 1.94e-3";
    for (extra, energy_tol) in [
        ("", 1e-2),
        // An edge crack from the top, through the upper row of elements at mid-length and
        // ending in the lower one: the balance holds across its split elements too.
        ("crack = [[5.25, 1.2], [5.25, 0.3]]", 1e-2),
        (
            "crack = [[5.25, 1.2], [5.25, 0.3]]\n\
             integrator = { scheme = \"gs4\", design = \"U0(1,1,0)\", implicit = true }\ndt = 2e-5",
            1e-9,
        ),
        (
            "integrator = { scheme = \"gs4\", design = \"U0(1,1,0)\", implicit = true }\ndt = 2e-5",
            1e-9,
        ),
    ] {
        let mut node = bar_with(ramp, extra);
        let reports = run(&mut node, 0, 80, 5e-5);
        assert_eq!(reports.len(), 80);
        let scale = reports
            .iter()
            .fold(0.0f64, |m, r| m.max(r.external_work.abs()));
        assert!(scale > 0.0);
        let mut checked = 0;
        for r in &reports {
            // Momentum: P = ∫ (load + support reaction) dt, to the trapezoid rule's accuracy
            // (the support force varies within a step).
            for c in 0..2 {
                let d = (r.momentum[c] - r.external_impulse[c]).abs();
                assert!(
                    d <= 1e-3 * r.applied_impulse.max(1e-30),
                    "{extra}: {c}: {d} of {}",
                    r.applied_impulse
                );
            }
            let e = r.kinetic_energy + r.internal_energy;
            assert!(
                (e - r.external_work).abs() <= energy_tol * scale,
                "{extra}: energy {e} vs work {}",
                r.external_work
            );
            checked += 1;
        }
        assert_eq!(checked, 80);
    }
}

#[test]
fn checkpoint_restarts_bit_identically() {
    let extra =
        "integrator = { scheme = \"gs4\", design = \"U0(0,0,0)\", implicit = true }\ndt = 2e-5";
    let mut whole = bar(extra);
    let all = run(&mut whole, 0, 40, 5e-5);
    let mut first = bar(extra);
    run(&mut first, 0, 20, 5e-5);
    let state = match first.save_state() {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    };
    let mut second = bar(extra);
    if let Err(e) = second.load_state(&state) {
        panic!("{e}");
    }
    let rest = run(&mut second, 20, 40, 5e-5);
    assert_eq!(rest.len(), 20);
    for (a, b) in all[20..].iter().zip(&rest) {
        assert_eq!(a.scalars, b.scalars);
        assert_eq!(a.kinetic_energy.to_bits(), b.kinetic_energy.to_bits());
        assert_eq!(a.external_work.to_bits(), b.external_work.to_bits());
    }
    // A state of another mesh is refused.
    let other = bar("").save_state().unwrap_or_default();
    let mut coarse = {
        let text = "length = 10.0\nheight = 1.0\nnx = 10\nny = 2\nyoung = 72e9\npoisson = 0.3\n\
                    density = 2700.0\nfixed = [\"left\"]\n";
        Fem2d::from_params(&text.parse::<toml::Table>().unwrap_or_default())
    };
    if let Ok(c) = coarse.as_mut() {
        assert!(c.load_state(&other).is_err());
    } else {
        panic!("coarse bar refused");
    }
}

#[test]
fn bad_parameters_name_their_key() {
    let base = "length = 10.0\nheight = 1.0\nnx = 4\nny = 2\nyoung = 72e9\npoisson = 0.3\n\
                density = 2700.0\n";
    for (extra, key) in [
        ("fixed = [\"north\"]", "fixed[0]"),
        ("plane = \"strain\"\nthickness = -1.0", "thickness"),
        (
            "loads = [{ edge = \"top\", traction = [0.0, 1.0], history = \"step\", ramp_time = 1.0 }]",
            "loads[0].ramp_time",
        ),
        (
            "loads = [{ edge = \"top\", traction = [0.0, 1.0], history = \"sine\" }]",
            "loads[0].history",
        ),
        (
            "loads = [{ edge = \"top\", traction = [0.0] }]",
            "loads[0].traction",
        ),
        ("interfaces = { cut = \"middle\" }", "interfaces.cut"),
        ("courant = 1.5", "courant"),
        ("crack = [[1.0, 0.5]]", "crack"),
        ("crack = [[1.0, 0.25], [1.0, 0.25]]", "crack[1]"),
        // Along a row of nodes.
        ("crack = [[-1.0, 0.5], [20.0, 0.5]]", "crack"),
        // Off the mesh.
        ("crack = [[11.0, 0.25], [12.0, 0.25]]", "crack"),
        // An overlap region whose side is off the mesh lines, one with nothing inside, one
        // with everything, and two regions.
        (
            "interfaces = { p = { overlap = [[2.5, 0.0], [6.0, 1.0]] } }",
            "interfaces.p.overlap",
        ),
        (
            "interfaces = { p = { overlap = [[2.5, 0.0], [2.5, 1.0]] } }",
            "interfaces.p.overlap",
        ),
        (
            "interfaces = { p = { overlap = [[-1.0, -1.0], [11.0, 2.0]] } }",
            "interfaces.p.overlap",
        ),
        (
            "interfaces = { p = { overlap = [[0.0, 0.0], [2.5, 1.0]] }, q = { overlap = [[5.0, 0.0], [7.5, 1.0]] } }",
            "interfaces.q",
        ),
    ] {
        let text = format!("{base}{extra}\n");
        let table = match text.parse::<toml::Table>() {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        let e = Fem2d::from_params(&table)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.starts_with(&format!("{key}:")), "{extra}: {e}");
    }
}

/// A mesh that hands a region to a finer model leaves the region's elements out, so it is
/// refused when no overlap coupling takes the region (it would run with a hole in it).
#[test]
fn an_overlap_region_without_its_coupling_is_refused() {
    let mut m = bar("interfaces = { p = { overlap = [[4.0, 0.0], [6.0, 1.0]] } }");
    let e = m
        .setup(&[], &Inbox::new(), &mut Outbox::new())
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(e.starts_with("interfaces.p.overlap:"), "{e}");
    // the region's elements are out: the bar of 20 × 2 keeps 16 × 2 of them
    let active = m.model().active.iter().filter(|a| **a).count();
    assert_eq!(active, 32);
}

/// The finer model's force on an overlap interface node that a support holds goes to the
/// support: the mesh reports as interface impulse all the force it received, the held nodes'
/// included (so the impulse handed across matches what the finer model sent), the support's
/// reaction takes that share, and the mesh's momentum still balances. Here the top edge is
/// held in y, and the ring of a region spanning the bar's height has nodes on it.
#[test]
fn an_overlap_force_on_a_held_node_goes_to_its_support() {
    let text = "length = 10.0\nheight = 1.0\nnx = 20\nny = 2\nyoung = 72e9\npoisson = 0.3\n\
                density = 2700.0\nfixed = [\"left\", \"top.y\"]\n\
                interfaces = { p = { overlap = [[4.0, 0.0], [6.0, 1.0]] } }\n";
    let binding = [Binding {
        coupling: "c".into(),
        kind: CouplingKind::Overlap,
        interface: "p".into(),
        role: Role::Driver,
        peer: "patch".into(),
        peer_interface: "layer".into(),
        sends: vec![],
        receives: vec![],
        input_lag: 1,
    }];
    // The same forces on every node, with (`all`) and without the y force on the held ones:
    // the x impulse fixes the time the force acted for, the y impulse must be the force
    // received times it.
    let run_with = |all: bool| -> (StepReport, [f64; 2]) {
        let table = match text.parse::<toml::Table>() {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        let mut m = match Fem2d::from_params(&table) {
            Ok(m) => m,
            Err(e) => panic!("{e}"),
        };
        let mut out = Outbox::new();
        m.setup(&binding, &Inbox::new(), &mut out).expect("set-up");
        let nodes = m.interface("p").expect("interface").positions;
        let held = nodes.iter().filter(|p| p[1] == 1.0).count();
        assert_eq!(held, 4, "ring nodes on the held top edge");
        let mut inbox = Inbox::new();
        let f = inbox.put("p", "force", 3, nodes.len());
        let mut sum = [0.0; 2];
        for (k, p) in nodes.iter().enumerate() {
            f[3 * k] = 0.5 + 0.1 * k as f64;
            f[3 * k + 1] = if all || p[1] != 1.0 {
                -1.0 - 0.2 * k as f64
            } else {
                0.0
            };
            sum[0] += f[3 * k];
            sum[1] += f[3 * k + 1];
        }
        let mut rep = None;
        for k in 0..3 {
            rep = Some(
                m.advance(&window(k, 1e-5), &inbox, &mut out)
                    .expect("advance"),
            );
        }
        (rep.expect("a report"), sum)
    };
    for all in [false, true] {
        let (rep, sum) = run_with(all);
        let tau = rep.interface_impulse[0] / sum[0];
        assert!(tau > 2e-5 && tau <= 3e-5, "{tau}");
        let iy = rep.interface_impulse[1];
        assert!(
            (iy - sum[1] * tau).abs() <= 1e-12 * iy.abs(),
            "held forces {all}: y impulse {iy:e} against {:e} received",
            sum[1] * tau
        );
        for c in 0..2 {
            let r = rep.momentum[c] - rep.external_impulse[c] - rep.interface_impulse[c];
            assert!(
                r.abs() <= 1e-12 * rep.momentum_gross.max(iy.abs()),
                "momentum {c}: {r:e}"
            );
        }
    }
}
