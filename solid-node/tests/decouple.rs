//! Decoupling of the immersed coupling (seed 000 §4, docs/architecture.md): after the coordinator
//! ends the coupling the body applies the force still in flight (sent by the gas before the
//! end, arriving one window late), sends nothing more, and goes on as a free body whose
//! momentum no longer changes. A kinematic coupling cannot be ended this way.

use protocol::{Binding, CouplingKind, Inbox, Outbox, Role, Window};

fn table() -> toml::Table {
    toml::from_str(
        r#"
dimension = "plane_strain"
thickness = 0.01
spacing = 5e-3
horizon = 1.5075e-2
density = 7870.0
young = 200e9
poisson = 0.29
bodies = [{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.05, 0.03, 0.01] }]
interfaces = [{ name = "particles", select = "all" }]
"#,
    )
    .expect("params")
}

fn binding(kind: CouplingKind, role: Role) -> Binding {
    Binding {
        coupling: "blast".into(),
        kind,
        interface: "particles".into(),
        role,
        peer: "gas".into(),
        peer_interface: "particles".into(),
        sends: vec![],
        receives: vec![],
        input_lag: 1,
    }
}

fn window(k: u64) -> Window {
    Window {
        index: k,
        t0: (k - 1) as f64 * 1e-6,
        t1: k as f64 * 1e-6,
        write_output: false,
    }
}

#[test]
fn after_decoupling_the_force_in_flight_is_applied_and_nothing_more_is_sent() {
    let mut s = match solid_node::pd::factory("pd-correspondence", &table()) {
        Some(Ok(s)) => s,
        _ => panic!("config must build"),
    };
    let b = [binding(CouplingKind::Immersed, Role::Driver)];
    s.setup(&b, &Inbox::new(), &mut Outbox::new())
        .expect("setup");
    let n = s.interface("particles").expect("interface").len();
    // A non-uniform force, so the body deforms and its internal forces are not trivially 0.
    let mut inbox = Inbox::new();
    let f = inbox.put("particles", "force", 3, n);
    for k in 0..n {
        f[3 * k] = 10.0 + k as f64;
        f[3 * k + 1] = -3.0 * (k % 7) as f64;
    }
    let fsum: [f64; 3] = std::array::from_fn(|d| f.chunks(3).map(|c| c[d]).sum());
    let mut out = Outbox::new();
    let r1 = s.advance(&window(1), &inbox, &mut out).expect("window 1");
    assert!(out.get("particles", "position").is_some());
    s.decouple("particles").expect("an immersed coupling ends");
    // Window 2: the gas's force of window 1, in flight, still arrives and is applied.
    let mut out = Outbox::new();
    let r2 = s.advance(&window(2), &inbox, &mut out).expect("window 2");
    assert!(out.get("particles", "position").is_none());
    assert!(out.get("particles", "velocity").is_none());
    for d in 0..3 {
        let want = 2.0 * fsum[d] * 1e-6;
        let scale = fsum[0].abs() * 1e-6;
        assert!((r2.interface_impulse[d] - want).abs() <= 1e-12 * scale);
        assert!((r2.momentum[d] - want).abs() <= 1e-12 * scale, "{r2:?}");
    }
    // Afterwards nothing arrives: a free body, momentum and received impulse constant.
    let empty = Inbox::new();
    let mut last = r2;
    for k in 3..40 {
        let mut out = Outbox::new();
        let r = s
            .advance(&window(k), &empty, &mut out)
            .expect("free window");
        assert!(out.get("particles", "position").is_none());
        assert_eq!(r.interface_impulse, last.interface_impulse);
        for d in 0..3 {
            assert!(
                (r.momentum[d] - last.momentum[d]).abs() <= 1e-12 * fsum[0].abs() * 1e-6,
                "window {k}: {:?} vs {:?}",
                r.momentum,
                last.momentum
            );
        }
        last = r;
    }
    assert!(last.kinetic_energy > 0.0 && r1.kinetic_energy > 0.0);
}

#[test]
fn a_kinematic_coupling_cannot_be_decoupled() {
    let mut s = match solid_node::pd::factory("pd-correspondence", &table()) {
        Some(Ok(s)) => s,
        _ => panic!("config must build"),
    };
    let b = [binding(CouplingKind::Kinematic, Role::Driver)];
    s.setup(&b, &Inbox::new(), &mut Outbox::new())
        .expect("setup");
    assert!(s.decouple("particles").is_err());
}
