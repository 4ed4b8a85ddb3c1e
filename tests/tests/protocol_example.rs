//! PROTOCOL.md's worked example of a kinematic coupling (section 4.7), run through the
//! participant runtime and the built-in bar: every number the example gives — the set-up
//! fields, the fields of windows 1 and 2, both reports — is worked out there by hand from the
//! two one-element bars, and must be what the runtime sends and reports.

use protocol::participant::NodeEngine;
use protocol::*;

fn bar(params: &str) -> Box<dyn Solver> {
    let t: toml::Table = toml::from_str(params).unwrap();
    solid_node::factory("bar-1d", &t).unwrap()
}

fn binding(role: Role, interface: &str, peer: &str, peer_interface: &str, lag: u64) -> Binding {
    Binding {
        coupling: "mid".into(),
        kind: CouplingKind::Kinematic,
        interface: interface.into(),
        role,
        peer: peer.into(),
        peer_interface: peer_interface.into(),
        sends: vec![],
        receives: vec![],
        input_lag: lag,
    }
}

/// The one message of `out` (on coupling "mid"), with its fields as (name, components, values).
fn fields(out: &[Fields]) -> Vec<(String, u32, Vec<f64>)> {
    assert_eq!(out.len(), 1, "{out:?}");
    assert_eq!(out[0].coupling, "mid");
    out[0]
        .fields
        .iter()
        .map(|f| (f.name.clone(), f.components, f.values.clone()))
        .collect()
}

fn field<'a>(f: &'a [(String, u32, Vec<f64>)], name: &str) -> (u32, &'a [f64]) {
    let (_, c, v) = f
        .iter()
        .find(|(n, _, _)| n == name)
        .unwrap_or_else(|| panic!("no '{name}' in {f:?}"));
    (*c, v)
}

fn close(got: f64, want: f64, what: &str) {
    assert!(
        (got - want).abs() <= 1e-12,
        "{what}: got {got}, want {want}"
    );
}

#[test]
fn the_worked_kinematic_example_is_what_the_runtime_sends_and_reports() {
    // Unit bars: E = ρ = A = 1, one element of 1 m: k = EA/h = 1 N/m, node masses ρAh/2 = 0.5 kg.
    let left = bar(
        "length = 1.0\nelements = 1\nyoung = 1.0\ndensity = 1.0\narea = 1.0\n\
         load_end = \"none\"\ninterfaces = { tip = \"right\" }",
    );
    let right = bar(
        "length = 1.0\nx0 = 1.0\nelements = 1\nyoung = 1.0\ndensity = 1.0\n\
         area = 1.0\nfixed = \"none\"\ntip_force = 1.0\ncourant = 0.5\n\
         interfaces = { root = \"left\" }",
    );
    let mut l = NodeEngine::new(left, &[binding(Role::Driver, "tip", "right", "root", 1)]);
    let mut r = NodeEngine::new(right, &[binding(Role::Responder, "root", "left", "tip", 0)]);
    for m in l.own_meshes().unwrap() {
        r.peer_mesh(&m).unwrap();
    }
    for m in r.own_meshes().unwrap() {
        l.peer_mesh(&m).unwrap();
    }

    // Set-up: the responder sends its interface node's mass, its stiffness and its force.
    assert!(
        r.ready(0) && !l.ready(0),
        "the driver waits for its responder's set-up"
    );
    let setup = r.setup().unwrap();
    let f = fields(&setup);
    assert_eq!(field(&f, "mass"), (1, &[0.5][..]));
    assert_eq!(field(&f, "stiffness"), (1, &[1.0][..]));
    assert_eq!(field(&f, "force"), (3, &[0.0, 0.0, 0.0][..]));
    assert_eq!(f.len(), 3, "{f:?}");
    for m in setup {
        l.receive(m).unwrap();
    }
    assert!(l.ready(0));
    // The driver's set-up message on the coupling carries no field.
    assert!(fields(&l.setup().unwrap()).is_empty());

    let window = |k: u64| Window {
        index: k,
        t0: (k - 1) as f64 * 0.5,
        t1: k as f64 * 0.5,
        write_output: false,
    };
    // Each row: driver (position, velocity, momentum, KE, IE, interface impulse and work),
    // then responder (force, momentum, KE, IE, external work and impulse, interface impulse
    // and work), after windows 1 and 2.
    #[rustfmt::skip]
    let want = [
        ([1.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0],
         0.5, [0.5, 0.25, 0.125, 0.5, 0.5, 0.0, 0.0]),
        ([1.125, 0.25], [0.25, 0.03125, 0.0078125, 0.25, 0.0625],
         1.125, [0.75, 0.5625, 0.6328125, 1.25, 1.0, -0.25, -0.0625]),
    ];
    let mut checked = 0;
    for (k, (motion, driver, force, responder)) in (1..=2).zip(want) {
        let w = window(k);
        assert!(l.ready(k));
        let (rl, out) = l.advance(&w).unwrap();
        let f = fields(&out);
        assert_eq!(out[0].window, k);
        close(out[0].time, w.t1, "the driver's fields are of t1");
        assert_eq!(f.len(), 2, "{f:?}");
        let (c, x) = field(&f, "position");
        assert_eq!(c, 3);
        close(x[0], motion[0], &format!("window {k}: position"));
        let (c, v) = field(&f, "velocity");
        assert_eq!(c, 3);
        close(v[0], motion[1], &format!("window {k}: velocity"));
        for (got, want, what) in [
            (rl.momentum[0], driver[0], "driver momentum"),
            (rl.kinetic_energy, driver[1], "driver kinetic energy"),
            (rl.internal_energy, driver[2], "driver internal energy"),
            (
                rl.interface_impulse[0],
                driver[3],
                "driver interface impulse",
            ),
            (rl.interface_work, driver[4], "driver interface work"),
        ] {
            close(got, want, &format!("window {k}: {what}"));
            checked += 1;
        }
        for m in out {
            r.receive(m).unwrap();
        }
        assert!(r.ready(k));
        let (rr, out) = r.advance(&w).unwrap();
        let f = fields(&out);
        assert_eq!(f.len(), 1, "{f:?}");
        let (c, v) = field(&f, "force");
        assert_eq!(c, 3);
        close(v[0], force, &format!("window {k}: force"));
        for (got, want, what) in [
            (rr.momentum[0], responder[0], "responder momentum"),
            (rr.kinetic_energy, responder[1], "responder kinetic energy"),
            (
                rr.internal_energy,
                responder[2],
                "responder internal energy",
            ),
            (rr.external_work, responder[3], "responder external work"),
            (
                rr.external_impulse[0],
                responder[4],
                "responder external impulse",
            ),
            (
                rr.interface_impulse[0],
                responder[5],
                "responder interface impulse",
            ),
            (rr.interface_work, responder[6], "responder interface work"),
        ] {
            close(got, want, &format!("window {k}: {what}"));
            checked += 1;
        }
        // The audit's balance: momentum equals the external impulse, the interface impulses
        // cancel, and so does the interface work of a window.
        close(
            rl.momentum[0] + rr.momentum[0],
            rl.external_impulse[0] + rr.external_impulse[0],
            &format!("window {k}: momentum balance"),
        );
        close(
            rl.interface_impulse[0] + rr.interface_impulse[0],
            0.0,
            &format!("window {k}: interface impulses"),
        );
        close(
            rl.interface_work + rr.interface_work,
            0.0,
            &format!("window {k}: interface work"),
        );
        for m in out {
            l.receive(m).unwrap();
        }
    }
    assert_eq!(checked, 2 * (5 + 7));
}
