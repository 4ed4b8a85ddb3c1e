//! The `mc-spg` Solver: bad input refused with the key named, and the
//! responder side of the kinematic coupling driven by an in-process stand-in shell driver
//! (seed 004 eq. 29–33): set-up mass mapped with Wᵀ, constraint forces equal to the reactions
//! of the same motion imposed as velocity supports, interface power identical on both sides.

#![allow(clippy::needless_range_loop)]

use meso_joint_node::factory;
use protocol::mapping::Mapping;
use protocol::{CellKind, Cells, Field, FieldSet, InterfaceMesh, SolverError, Window};

pub(crate) fn base() -> toml::Table {
    toml::from_str(
        r#"
        spacing = 0.5e-3
        kernel_support = 1.0e-3
        density = 7850.0
        young = 210e9
        poisson = 0.3
        yield_stress = 0.2e9
        tangent_modulus = 20e9
        eps_crit = 0.1
        [geometry]
        kind = "block"
        origin = [0.0, 0.0, 0.0]
        size = [6e-3, 2e-3, 2e-3]
        "#,
    )
    .unwrap()
}

pub(crate) fn key_of(r: Result<Box<dyn protocol::Solver>, SolverError>) -> String {
    match r {
        Err(SolverError::Config { key, .. }) => key,
        Err(e) => panic!("wrong error kind: {e}"),
        Ok(_) => panic!("bad input accepted"),
    }
}

#[test]
fn bad_input_is_refused_with_the_key_named() {
    let mut t = base();
    t.insert("kernel_support".into(), toml::Value::Float(0.4e-3));
    assert_eq!(key_of(factory("mc-spg", &t)), "kernel_support");
    let mut t = base();
    t.insert("kernel_support".into(), toml::Value::Float(0.5e-3));
    assert_eq!(key_of(factory("mc-spg", &t)), "kernel_support");
    for bad in [0.0, -0.1] {
        let mut t = base();
        t.insert("eps_crit".into(), toml::Value::Float(bad));
        assert_eq!(key_of(factory("mc-spg", &t)), "eps_crit");
    }
    let mut t = base();
    let c: toml::Table = toml::from_str(
        "interface = \"shell\"\nregions = [{ lo = [1.0, 1.0, 1.0], hi = [2.0, 2.0, 2.0] }]",
    )
    .unwrap();
    t.insert("coupling".into(), toml::Value::Table(c));
    assert_eq!(key_of(factory("mc-spg", &t)), "coupling.regions");
    let mut t = base();
    t.insert("horizon".into(), toml::Value::Float(1.0));
    assert_eq!(key_of(factory("mc-spg", &t)), "horizon");
    assert_eq!(key_of(factory("nope", &base())), "model");
    assert!(factory("mc-spg", &base()).is_ok());
}

/// Two shell strips (one quad each) over the ends of the block, mid-surface z = 1 mm.
fn shell_mesh() -> InterfaceMesh {
    let z = 1e-3;
    let positions = vec![
        [0.0, 0.0, z],
        [1e-3, 0.0, z],
        [1e-3, 2e-3, z],
        [0.0, 2e-3, z],
        [5e-3, 0.0, z],
        [6e-3, 0.0, z],
        [6e-3, 2e-3, z],
        [5e-3, 2e-3, z],
    ];
    InterfaceMesh {
        ids: (0..8).collect(),
        normals: vec![[0.0, 0.0, 1.0]; 8],
        weights: vec![0.5e-6; 8],
        positions,
        cells: Some(Cells {
            kind: CellKind::Quad,
            connectivity: vec![0, 1, 2, 3, 4, 5, 6, 7],
        }),
    }
}

fn flat(v: &[[f64; 3]]) -> Vec<f64> {
    v.iter().flatten().copied().collect()
}

/// The driver's node field `name` mapped onto the particles with `W`, as the participant
/// runtime does (`v_r = W v_d`).
fn motion(w: &Mapping, name: &str, nodes: &[f64]) -> Field {
    let mut values = vec![0.0; 3 * w.n_responder()];
    w.map_motion(nodes, 3, &mut values).unwrap();
    Field {
        name: name.into(),
        components: 3,
        values,
    }
}

/// A particle load field mapped back onto the shell nodes with `Wᵀ`.
fn load(w: &Mapping, out: &FieldSet, name: &str, c: usize) -> Vec<f64> {
    let f = out.require("shell", name, c * w.n_responder()).unwrap();
    let mut d = vec![0.0; c * w.n_driver()];
    w.map_load(f, c, &mut d).unwrap();
    d
}

#[test]
fn stand_in_driver_gets_the_support_reactions_and_the_power_balances() {
    let v = 0.5;
    // Responder: coupling particles in the two end regions.
    let mut tc = base();
    let c: toml::Table = toml::from_str(
        "interface = \"shell\"\nregions = [{ name = \"left\", lo = [-1.0, -1.0, -1.0], hi = [1e-3, 1.0, 1.0] }, { name = \"right\", lo = [5e-3, -1.0, -1.0], hi = [1.0, 1.0, 1.0] }]",
    )
    .unwrap();
    tc.insert("coupling".into(), toml::Value::Table(c));
    let mut coupled = factory("mc-spg", &tc).unwrap();
    // Reference: the same motion as velocity supports.
    let mut tb = base();
    let b: toml::Table = toml::from_str(
        "velocity_bc = [{ name = \"left\", velocity = [-0.5, 0.0, 0.0], region = { lo = [-1.0, -1.0, -1.0], hi = [1e-3, 1.0, 1.0] } }, { name = \"right\", velocity = [0.5, 0.0, 0.0], region = { lo = [5e-3, -1.0, -1.0], hi = [1.0, 1.0, 1.0] } }]",
    )
    .unwrap();
    for (k, val) in b {
        tb.insert(k, val);
    }
    let mut supported = factory("mc-spg", &tb).unwrap();

    // The mapping the runtime builds: particles projected onto the shell quads (eq. 29).
    let mesh = shell_mesh();
    let own = coupled.interface("shell").unwrap();
    let w = Mapping::consistent(&mesh, &own.positions).unwrap();
    let mut x = mesh.positions.clone();
    let mut out = FieldSet::new();
    coupled.setup(&[], &FieldSet::new(), &mut out).unwrap();
    let mass = load(&w, &out, "mass", 1);
    let stiff = load(&w, &out, "stiffness", 1);
    // 2 end layers × 4 × 4 particles at each end, 0.5 mm lattice, ρ 7850.
    let m_expected = 2.0 * 32.0 * 0.125e-9 * 7850.0;
    let m_sum: f64 = mass.iter().sum();
    assert!(
        (m_sum - m_expected).abs() < 1e-12 * m_expected,
        "{m_sum} vs {m_expected}"
    );
    assert!(stiff.iter().all(|k| *k > 0.0));

    let window = 2e-7;
    let node_v: Vec<[f64; 3]> = (0..8)
        .map(|k| [if k < 4 { -v } else { v }, 0.0, 0.0])
        .collect();
    let mut worst: f64 = 0.0;
    let mut f_prev = vec![0.0; 24];
    let (mut p_driver, mut p_resp) = (0.0, 0.0);
    let mut sup_out = FieldSet::new();
    for k in 1..=20u64 {
        for (i, p) in x.iter_mut().enumerate() {
            p[0] += window * node_v[i][0];
        }
        let mut inbox = FieldSet::new();
        inbox.insert("shell", motion(&w, "position", &flat(&x)));
        inbox.insert("shell", motion(&w, "velocity", &flat(&node_v)));
        inbox.insert("shell", motion(&w, "normal", &flat(&mesh.normals)));
        let win = Window {
            index: k,
            t0: (k - 1) as f64 * window,
            t1: k as f64 * window,
            write_output: false,
        };
        let rc = coupled.advance(&win, &inbox, &mut out).unwrap();
        let rs = supported
            .advance(&win, &FieldSet::new(), &mut sup_out)
            .unwrap();
        let f = load(&w, &out, "force", 3);
        let right: f64 = (4..8).map(|k| f[3 * k]).sum();
        let scalar =
            |r: &protocol::StepReport, n: &str| r.scalars.iter().find(|(m, _)| m == n).unwrap().1;
        let reaction = scalar(&rs, "force_right_x");
        // The region sum reported by the coupled node is the same force before the mapping.
        assert!((scalar(&rc, "force_right_x") - right).abs() <= 1e-9 * right.abs());
        worst = worst.max((right + reaction).abs() / reaction.abs().max(1e-30));
        // Interface power: driver side uses the nodal forces and velocities; the responder
        // side its own interface work (Σ f·v of its coupling particles), both trapezoidal.
        p_driver += 0.5
            * window
            * (0..8)
                .map(|k| (f[3 * k] + f_prev[3 * k]) * node_v[k][0])
                .sum::<f64>();
        f_prev = f;
        p_resp = rc.interface_work;
    }
    eprintln!(
        "coupled vs supported: worst |F_coupled + R_support|/|R| = {worst:e}; interface work driver {p_driver:e} J vs responder {p_resp:e} J"
    );
    assert!(worst < 1e-9, "{worst:e}");
    // The work the shell does on the joint is minus the work of the joint's force on the shell.
    // Both come from the same forces; the sampling differs (per window vs per substep), so
    // compare at 2 % rather than round-off.
    assert!(
        ((-p_driver) - p_resp).abs() < 0.02 * p_resp.abs(),
        "{p_driver:e} {p_resp:e}"
    );
}

/// Two plates around a bonded rigid bolt, pulled apart at 0.01 m/s (shared with the solid
/// elements' tests).
pub(crate) fn bolted_plates() -> toml::Table {
    toml::from_str(
        r#"
        spacing = 0.5e-3
        kernel_support = 1.0e-3
        density = 7850.0
        young = 210e9
        poisson = 0.3
        yield_stress = 0.2e9
        tangent_modulus = 20e9
        eps_crit = 0.1
        velocity_bc = [
          { name = "left", velocity = [-0.01, 0.0, 0.0], region = { lo = [-1.0, -1.0, -1.0], hi = [1.0e-3, 1.0, 1.0] } },
          { name = "right", velocity = [0.01, 0.0, 0.0], region = { lo = [13.0e-3, -1.0, -1.0], hi = [1.0, 1.0, 1.0] } },
        ]
        [geometry]
        kind = "bolted-plates"
        width = 8e-3
        length = 10e-3
        overlap = 6e-3
        bolt_radius = 1.5e-3
        head_radius = 2.5e-3
        head_height = 1e-3
        "#,
    )
    .unwrap()
}

#[test]
fn bolted_plate_geometry_builds_and_steps() {
    let t = bolted_plates();
    let mut s = factory("mc-spg", &t).unwrap();
    let dt = s.stable_dt();
    let win = Window {
        index: 1,
        t0: 0.0,
        t1: 10.0 * dt,
        write_output: false,
    };
    let r = s
        .advance(&win, &FieldSet::new(), &mut FieldSet::new())
        .unwrap();
    assert!(r.substeps >= 10);
    assert!(r.kinetic_energy.is_finite() && r.internal_energy >= 0.0);
}

/// Several joints in one node (`placements`): each copy is the local geometry moved rigidly
/// into its frame, the copies never bond to each other, coupling regions apply in the local
/// frame of every copy and are reported per copy; a bad placement is refused by name.
#[test]
fn placements_copy_the_joint_rigidly_and_report_per_copy() {
    let base = r#"
        spacing = 0.5e-3
        kernel_support = 1.0e-3
        density = 7850.0
        young = 210e9
        poisson = 0.3
        yield_stress = 0.2e9
        tangent_modulus = 20e9
        eps_crit = 0.1
        geometry = { kind = "bolted-plates", width = 6e-3, length = 6e-3, overlap = 6e-3, bolt_radius = 1e-3, head_radius = 2e-3, head_height = 1e-3 }
        coupling = { regions = [{ name = "a", lo = [-1.0, -1.0, -1.0], hi = [0.5e-3, 1.0, 1.0e-3] }] }
        "#;
    let one: toml::Table = toml::from_str(base).unwrap();
    let mut two: toml::Table = toml::from_str(base).unwrap();
    let pl: toml::Value = toml::from_str::<toml::Table>(
        r#"p = [
          { name = "p", origin = [0.0, 0.0, 0.0] },
          { name = "q", origin = [0.1, 0.2, 0.3], x_axis = [0.0, 0.0, 1.0], z_axis = [0.0, -1.0, 0.0], bolt_radius = 1.5e-3 },
        ]"#,
    )
    .unwrap()["p"]
        .clone();
    two.insert("placements".into(), pl);
    let s1 = meso_joint_node::solver::SpgSolver::new(
        meso_joint_node::config::Params::from_table(&one).unwrap(),
    )
    .unwrap();
    let s2 = meso_joint_node::solver::SpgSolver::new(
        meso_joint_node::config::Params::from_table(&two).unwrap(),
    )
    .unwrap();
    let n1 = s1.model.len();
    // Copy "q" has a wider shank: fewer plate particles, more bolt particles.
    assert!(s2.model.len() > n1 && s2.model.len() < 2 * n1 + n1 / 2);
    // Copy "p" is the unplaced geometry, particle for particle.
    for i in 0..n1 {
        assert_eq!(s2.model.x0[i], s1.model.x0[i]);
    }
    // Copy "q": local (x, y, z) ↦ origin + x ẑ + y (−ŷ × ẑ = −x̂) + z (−ŷ).
    let q0 = s2.model.x0[n1];
    let l0 = s1.model.x0[0];
    let want = [0.1 - l0[1], 0.2 - l0[2], 0.3 + l0[0]];
    for d in 0..3 {
        assert!((q0[d] - want[d]).abs() < 1e-15, "{q0:?} vs {want:?}");
    }
    // No bond between the copies (they are 0.37 m apart anyway; parts differ).
    let rows = &s2.model.rows;
    for i in 0..s2.model.len() {
        for p in rows.range(i) {
            let j = rows.cols[p] as usize;
            assert_eq!(i < n1, j < n1, "bond {i}–{j} across copies");
        }
    }
    // Both copies couple the same local region; region forces are named per copy.
    assert_eq!(s2.coupling_points(), 2 * s1.coupling_points());
    let d = protocol::Solver::describe(&s2);
    assert_eq!(d.interfaces[0].points, s2.coupling_points());
    let mut bad = two.clone();
    bad["placements"].as_array_mut().unwrap()[1]
        .as_table_mut()
        .unwrap()
        .insert("name".into(), "p".into());
    assert_eq!(key_of(factory("mc-spg", &bad)), "placements[1].name");
    let mut bad = two.clone();
    bad["placements"].as_array_mut().unwrap()[1]
        .as_table_mut()
        .unwrap()
        .insert(
            "x_axis".into(),
            toml::Value::try_from([0.0, 2.0, 0.0]).unwrap(),
        );
    assert_eq!(key_of(factory("mc-spg", &bad)), "placements[1]");
}

/// Tearing through (bond failure, eq. 15–17, with `separation_weight`): a bar pulled apart
/// with a small ε_crit runs through separation without diverging, and its end force drops
/// from its peak to a small fraction once it has torn.
#[test]
fn a_bar_pulled_apart_tears_and_its_force_drops() {
    let mut t = base();
    let extra: toml::Table = toml::from_str(
        r#"
        eps_crit = 0.02
        separation_weight = 0.9
        velocity_bc = [
          { name = "left", velocity = [-0.5, 0.0, 0.0], region = { lo = [-1.0, -1.0, -1.0], hi = [1e-3, 1.0, 1.0] } },
          { name = "right", velocity = [0.5, 0.0, 0.0], region = { lo = [5e-3, -1.0, -1.0], hi = [1.0, 1.0, 1.0] } },
        ]
        "#,
    )
    .unwrap();
    for (k, v) in extra {
        t.insert(k, v);
    }
    let mut s = factory("mc-spg", &t).unwrap();
    let (inbox, mut out) = (FieldSet::new(), FieldSet::new());
    let (mut peak, mut last, mut broken) = (0.0f64, 0.0, 0.0);
    let w = 2e-6;
    for k in 1..=250u64 {
        let win = Window {
            index: k,
            t0: (k - 1) as f64 * w,
            t1: k as f64 * w,
            write_output: false,
        };
        let r = s.advance(&win, &inbox, &mut out).unwrap();
        let get = |n: &str| r.scalars.iter().find(|(m, _)| m == n).unwrap().1;
        last = get("force_right_x");
        peak = peak.max(last);
        broken = get("broken_bonds");
    }
    eprintln!("tearing: peak {peak:.2} N, final {last:.3} N, {broken} bonds broken");
    assert!(peak > 0.0 && broken > 0.0);
    assert!(last.abs() < 0.1 * peak, "{last} of {peak}");
}

/// `fastener = "bearing"` (a bolt in a hole): no kernel row pairs the rigid bolt with plate
/// material, the bearing contact is at rest in the reference state (the initial forces are
/// those of the unloaded body: zero), and pushing the plate against the shank gives equal and
/// opposite contact forces. `contact_stiffness` is checked and needs "bearing".
#[test]
fn a_bearing_bolt_is_not_bonded_and_pushes_back_by_contact() {
    let text = r#"
        spacing = 0.5e-3
        kernel_support = 1.0e-3
        density = 7850.0
        young = 210e9
        poisson = 0.3
        yield_stress = 0.2e9
        tangent_modulus = 20e9
        eps_crit = 0.1
        geometry = { kind = "bolted-plates", width = 6e-3, length = 6e-3, overlap = 6e-3, bolt_radius = 1e-3, head_radius = 2e-3, head_height = 1e-3 }
        "#;
    let build = |extra: &str| {
        let t: toml::Table = toml::from_str(&format!("{text}\n{extra}")).unwrap();
        meso_joint_node::solver::SpgSolver::new(
            meso_joint_node::config::Params::from_table(&t).unwrap(),
        )
        .unwrap()
    };
    let rigid_plate_pairs = |s: &meso_joint_node::solver::SpgSolver| {
        let m = &s.model;
        let rigid = |i: usize| m.kind[i] == meso_joint_node::model::Kind::Rigid;
        (0..m.len())
            .flat_map(|i| m.rows.range(i).map(move |p| (i, p)))
            .filter(|&(i, p)| rigid(i) != rigid(m.rows.cols[p] as usize))
            .count()
    };
    let bonded = build("");
    let mut bearing = build("fastener = \"bearing\"");
    assert!(
        rigid_plate_pairs(&bonded) > 0,
        "a bonded fastener shares rows"
    );
    assert_eq!(rigid_plate_pairs(&bearing), 0);
    let m = &mut bearing.model;
    let fmax =
        m.f.iter()
            .flat_map(|f| f.iter())
            .fold(0.0f64, |a, &b| a.max(b.abs()));
    assert_eq!(fmax, 0.0, "contact not at rest in the reference state");
    // Push the plate particles next to the shank on its +x side 1 % of a spacing towards
    // the bolt axis: the shank must push them back, and be pushed towards −x.
    let h = 0.5e-3;
    let axis = m.rigid[0].com;
    let mut moved = 0;
    // plate particles beside the shank on its +x side: their unit direction from the axis
    let beside = |m: &meso_joint_node::model::Model, i: usize| -> Option<[f64; 2]> {
        let r = [m.x[i][0] - axis[0], m.x[i][1] - axis[1]];
        let d = (r[0] * r[0] + r[1] * r[1]).sqrt();
        (m.kind[i] != meso_joint_node::model::Kind::Rigid
            && r[0] > 0.0
            && d < 1e-3 + 1.5 * h
            && m.x[i][2] > 0.0
            && m.x[i][2] < 2e-3)
            .then_some([r[0] / d, r[1] / d])
    };
    for i in 0..m.len() {
        if let Some(n) = beside(m, i) {
            m.x[i][0] -= 0.01 * h * n[0];
            m.x[i][1] -= 0.01 * h * n[1];
            moved += 1;
        }
    }
    assert!(moved > 10, "{moved}");
    m.contact_pairs.clear();
    m.initial_forces();
    let mut total = [0.0f64; 3];
    let mut on_bolt = [0.0f64; 3];
    let mut gross = 0.0f64;
    for i in 0..m.len() {
        for a in 0..3 {
            total[a] += m.f[i][a];
            gross += m.f[i][a].abs();
            if m.kind[i] == meso_joint_node::model::Kind::Rigid {
                on_bolt[a] += m.f[i][a];
            }
        }
    }
    println!("contact: gross force {gross:.3e} N, net {total:?}, on the bolt {on_bolt:?}");
    // k = E h = 1.05e8 N/m, penetration up to 0.01 h = 5 µm: ~500 N per pair.
    assert!(
        on_bolt[0] < -100.0,
        "the shank is not pushed back: {on_bolt:?}"
    );
    assert!(
        on_bolt[1].abs() <= 1e-9 * gross,
        "{on_bolt:?} (symmetric about y = 0)"
    );
    for a in 0..3 {
        assert!(total[a].abs() <= 1e-12 * gross, "{total:?}");
    }
    // The contact's energy is in the internal energy and is the potential of its forces:
    // pushing the same particles a further 0.1 % of a spacing changes it by the work of the
    // contact forces, −½ Σ (f_before + f_after)·Δx (trapezoid rule).
    let e1 = m.internal_energy();
    assert!(
        m.contact_energy > 0.0 && e1 >= m.contact_energy,
        "{e1} vs {}",
        m.contact_energy
    );
    let f1 = m.f.clone();
    let mut dx = vec![[0.0f64; 3]; m.len()];
    for i in 0..m.len() {
        if let Some(n) = beside(m, i) {
            dx[i] = [-0.001 * h * n[0], -0.001 * h * n[1], 0.0];
            m.x[i][0] += dx[i][0];
            m.x[i][1] += dx[i][1];
        }
    }
    m.initial_forces();
    let e2 = m.internal_energy();
    let work: f64 = (0..m.len())
        .map(|i| {
            (0..3)
                .map(|a| 0.5 * (f1[i][a] + m.f[i][a]) * dx[i][a])
                .sum::<f64>()
        })
        .sum();
    println!("contact energy {e1:.6e} -> {e2:.6e} J, work of the contact forces {work:.6e} J");
    assert!(e2 > e1, "pushing further must store energy");
    assert!(
        ((e2 - e1) + work).abs() <= 1e-3 * (e2 - e1),
        "energy change {} vs −work {}",
        e2 - e1,
        -work
    );
    let bad: toml::Table = toml::from_str(&format!("{text}\ncontact_stiffness = 1e8")).unwrap();
    assert_eq!(key_of(factory("mc-spg", &bad)), "contact_stiffness");
    let bad: toml::Table = toml::from_str(&format!(
        "{text}\nfastener = \"bearing\"\ncontact_stiffness = -1.0"
    ))
    .unwrap();
    assert_eq!(key_of(factory("mc-spg", &bad)), "contact_stiffness");
}
