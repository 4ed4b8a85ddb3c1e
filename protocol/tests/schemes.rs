//! The coupling schemes' contracts (docs/architecture.md): each kind's input lags and serial order,
//! and the sync-force node side's mapping (`v_r = W v_d`, `f_d = Wᵀ f_r`) against values worked
//! out by hand for a responder point halfway along the driver's one-cell line, and the
//! responder's following of the driver's motion through a window (`kinematic::Follow`)
//! against positions and velocities worked out by hand.

use protocol::mapping::Mapping;
use protocol::scheme::kinematic::{Follow, Path};
use protocol::scheme::{self, driver_responder_input};
use protocol::{CellKind, Cells, CouplingKind, Field, FieldSet, InterfaceMesh, Role};

fn field(name: &str, values: Vec<f64>) -> Field {
    Field {
        name: name.into(),
        components: 3,
        values,
    }
}

/// The driver: one line cell from (0,0,0) to (2,0,0); the responder: one point at (1,0,0).
fn meshes() -> (InterfaceMesh, InterfaceMesh) {
    let mut d = InterfaceMesh::points(vec![[0.0; 3], [2.0, 0.0, 0.0]]);
    d.cells = Some(Cells {
        kind: CellKind::Line,
        connectivity: vec![0, 1],
    });
    (d, InterfaceMesh::points(vec![[1.0, 0.0, 0.0]]))
}

#[test]
fn lags_and_serial_order_follow_each_scheme() {
    for kind in [CouplingKind::Kinematic, CouplingKind::Immersed] {
        let s = scheme::of(kind);
        // The driver's loads arrive at the next sync time; the responder follows the
        // driver's motion in the same window when serial, a window later when parallel.
        assert_eq!(s.input_lag(Role::Driver, true), 1, "{kind:?}");
        assert_eq!(s.input_lag(Role::Driver, false), 1, "{kind:?}");
        assert_eq!(s.input_lag(Role::Responder, true), 0, "{kind:?}");
        assert_eq!(s.input_lag(Role::Responder, false), 1, "{kind:?}");
        assert!(s.responder_after_driver(true), "{kind:?}");
        assert!(!s.responder_after_driver(false), "{kind:?}");
        assert!(!s.coordinator_solved(), "{kind:?}");
    }
    assert!(
        scheme::of(CouplingKind::Kinematic)
            .parallel_refusal()
            .is_some()
    );
    assert!(
        scheme::of(CouplingKind::Immersed)
            .parallel_refusal()
            .is_none()
    );
    assert!(scheme::of(CouplingKind::Immersed).decouples());
    assert!(!scheme::of(CouplingKind::Kinematic).decouples());
    let l = scheme::of(CouplingKind::Lagrange);
    assert_eq!(l.input_lag(Role::Driver, true), 0);
    assert!(!l.responder_after_driver(true));
    assert!(l.coordinator_solved());
    // A lagrange side takes the set-up request only; in a window it sends step by step.
    assert_eq!(l.input_window(Role::Driver, 0, None, 0), Some(0));
    assert_eq!(l.input_window(Role::Driver, 0, None, 3), None);
    assert!(l.sends_at_window_end(0) && !l.sends_at_window_end(3));
}

#[test]
fn the_driver_responder_input_rule() {
    // Set-up: the driver waits for its responder's set-up fields, the responder for nothing.
    assert_eq!(driver_responder_input(Role::Driver, 1, None, 0), Some(0));
    assert_eq!(driver_responder_input(Role::Responder, 0, None, 0), None);
    assert_eq!(driver_responder_input(Role::Driver, 1, None, 7), Some(6));
    assert_eq!(driver_responder_input(Role::Responder, 0, None, 7), Some(7));
    // Decoupled before window 5: the peer's window 4 is still consumed, window 5 is not.
    assert_eq!(driver_responder_input(Role::Driver, 1, Some(5), 5), Some(4));
    assert_eq!(driver_responder_input(Role::Driver, 1, Some(5), 6), None);
    assert_eq!(driver_responder_input(Role::Responder, 0, Some(5), 5), None);
}

#[test]
fn kinematic_maps_motion_and_loads_and_refuses_the_wrong_direction() {
    let s = scheme::of(CouplingKind::Kinematic);
    let (driver, own) = meshes();
    assert!(s.needs_peer_mesh());
    assert!(
        s.responder_map(&driver, &driver)
            .expect("same mesh")
            .is_none()
    );
    let m: Mapping = s
        .responder_map(&driver, &own)
        .expect("a mapping")
        .expect("different meshes are mapped");
    assert_eq!((m.n_driver(), m.n_responder()), (2, 1));

    // Motion in: the midpoint takes the mean of the two driver points.
    let mut inbox = FieldSet::new();
    let v = field("velocity", vec![1.0, 0.0, 2.0, 3.0, 0.0, -2.0]);
    s.receive(Role::Responder, Some(&m), "root", &v, &mut inbox)
        .expect("motion is mapped");
    assert_eq!(
        inbox.get("root", "velocity").map(|f| f.values.clone()),
        Some(vec![2.0, 0.0, 0.0])
    );
    let err = s
        .receive(
            Role::Responder,
            Some(&m),
            "root",
            &field("force", vec![0.0; 6]),
            &mut inbox,
        )
        .expect_err("a responder receives no loads");
    assert!(err.contains("motion only"), "{err}");

    // Loads out: half of the point's force goes to each driver point.
    let mut scratch = Vec::new();
    let f = s
        .send(
            Role::Responder,
            Some(&m),
            &field("force", vec![4.0, -2.0, 0.0]),
            &mut scratch,
        )
        .expect("a load is mapped");
    assert_eq!(f.values, vec![2.0, -1.0, 0.0, 2.0, -1.0, 0.0]);
    let err = s
        .send(
            Role::Responder,
            Some(&m),
            &field("velocity", vec![0.0; 3]),
            &mut scratch,
        )
        .expect_err("a responder sends no motion");
    assert!(err.contains("loads only"), "{err}");
}

#[test]
fn immersed_fields_travel_unmapped() {
    let s = scheme::of(CouplingKind::Immersed);
    let (driver, own) = meshes();
    assert!(!s.needs_peer_mesh());
    assert!(
        s.responder_map(&driver, &own)
            .expect("no mapping")
            .is_none()
    );
    let (d, r) = s.default_fields();
    assert_eq!(
        (d, r),
        (&["position", "velocity", "volume"][..], &["force"][..])
    );
    let mut inbox = FieldSet::new();
    let p = field("position", vec![0.5, 0.25, 0.0]);
    s.receive(Role::Responder, None, "particles", &p, &mut inbox)
        .expect("taken as it is");
    assert_eq!(inbox.get("particles", "position"), Some(&p));
}

#[test]
fn each_side_follows_or_takes_loads_as_its_scheme_says() {
    let k = scheme::of(CouplingKind::Kinematic);
    // The sync-force responder follows its driver and sends its coupling mass and stiffness
    // at set-up, which its driver receives; the driver takes loads, which always come.
    assert!(k.follows(Role::Responder) && !k.follows(Role::Driver));
    assert_eq!(k.setup_sends(Role::Responder), ["mass", "stiffness"]);
    assert!(k.setup_sends(Role::Driver).is_empty());
    assert_eq!(k.setup_receives(Role::Driver), ["mass", "stiffness"]);
    assert!(k.setup_receives(Role::Responder).is_empty());
    assert!(!k.loads_may_be_absent());
    assert_eq!(k.sends(Role::Driver), ["position", "velocity"]);
    assert_eq!(k.sends(Role::Responder), ["force"]);
    // Immersed: nobody follows (the fluid immerses the particles), nothing extra at set-up,
    // and the solid's loads are absent before the fluid's first output and after a decoupling.
    let i = scheme::of(CouplingKind::Immersed);
    assert!(!i.follows(Role::Responder) && !i.follows(Role::Driver));
    assert!(i.setup_sends(Role::Driver).is_empty() && i.setup_sends(Role::Responder).is_empty());
    assert!(i.loads_may_be_absent());
    assert_eq!(i.sends(Role::Driver), ["position", "velocity", "volume"]);
    assert_eq!(i.sends(Role::Responder), ["force"]);
    let l = scheme::of(CouplingKind::Lagrange);
    assert!(!l.follows(Role::Responder) && !l.follows(Role::Driver));
}

/// A held path: one point, one component, at 2 at the window start, the driver's velocity 3,
/// a window of 1 in 4 sub-steps of 0.25: after sub-step k it is at 2 + (k+1)·0.25·3.
#[test]
fn a_held_path_integrates_the_drivers_velocity_from_the_window_start() {
    let mut f = Follow::new(Path::Held, 1, 1);
    assert_eq!((f.len(), f.path()), (1, Path::Held));
    f.set_start(0, &[2.0]);
    f.set_end(0, &[3.0]);
    let want = [2.75, 3.5, 4.25, 5.0];
    for (k, w) in want.iter().enumerate() {
        assert_eq!(f.position(0, 0, k as u64, 4, 0.25), *w, "sub-step {k}");
        // The velocity is the driver's, whatever the point's position.
        assert_eq!(
            f.velocity(0, 0, -7.0, k as u64, 4, 0.25),
            3.0,
            "sub-step {k}"
        );
    }
    // The next window starts from the node's state: nothing carries over.
    f.next_window();
    f.set_start(0, &[5.0]);
    f.set_end(0, &[-1.0]);
    assert_eq!(f.position(0, 0, 1, 4, 0.25), 4.5);
}

/// A linear path: two points of three components, 4 sub-steps of 0.5. Point 0 goes from the
/// origin to (4, 8, −4): after sub-step k (s = (k+1)/4) at s·(4, 8, −4); point 1 stays at
/// (1, 2, 3). The velocity lands a point from where it is on the next target in one step.
#[test]
fn a_linear_path_interpolates_between_the_sync_positions() {
    let mut f = Follow::new(Path::Linear, 2, 3);
    assert_eq!(f.len(), 2);
    f.set_start(1, &[1.0, 2.0, 3.0]);
    f.set_end(0, &[4.0, 8.0, -4.0]);
    f.set_end(1, &[1.0, 2.0, 3.0]);
    let want0 = [
        [1.0, 2.0, -1.0],
        [2.0, 4.0, -2.0],
        [3.0, 6.0, -3.0],
        [4.0, 8.0, -4.0],
    ];
    for (k, w) in want0.iter().enumerate() {
        for d in 0..3 {
            assert_eq!(
                f.position(0, d, k as u64, 4, 0.5),
                w[d],
                "sub-step {k}, {d}"
            );
            assert_eq!(f.position(1, d, k as u64, 4, 0.5), [1.0, 2.0, 3.0][d]);
        }
    }
    // From x = 0.5 the first target 1 is 0.5 away: 1 per unit time over a step of 0.5.
    assert_eq!(f.velocity(0, 0, 0.5, 0, 4, 0.5), 1.0);
    // From x = 4 the last target 8 (component 1) is 4 away: 8.
    assert_eq!(f.velocity(0, 1, 4.0, 3, 4, 0.5), 8.0);
    assert_eq!(f.velocity(1, 2, 3.0, 2, 4, 0.5), 0.0);
    // The next window starts at this one's sync positions: halfway to (8, 8, 8) after two
    // of four sub-steps is (6, 8, 2).
    f.next_window();
    f.set_end(0, &[8.0, 8.0, 8.0]);
    for (d, w) in [6.0, 8.0, 2.0].iter().enumerate() {
        assert_eq!(f.position(0, d, 1, 4, 0.5), *w);
    }
}
