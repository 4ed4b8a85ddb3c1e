//! The coupling schemes' contracts (ARCHITECTURE §5): each kind's input lags and serial order,
//! and the sync-force node side's mapping (`v_r = W v_d`, `f_d = Wᵀ f_r`) against values worked
//! out by hand for a responder point halfway along the driver's one-cell line.

use protocol::mapping::Mapping;
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
fn sync_force_maps_motion_and_loads_and_refuses_the_wrong_direction() {
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
