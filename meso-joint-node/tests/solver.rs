//! The `mc-spg` Solver: bad input refused with the key named (must-show 6), and the
//! responder side of the kinematic coupling driven by an in-process stand-in shell driver
//! (seed 004 eq. 29–33): set-up mass mapped with Wᵀ, constraint forces equal to the reactions
//! of the same motion imposed as velocity supports, interface power identical on both sides.

#![allow(clippy::needless_range_loop)]

use meso_joint_node::factory;
use protocol::{Field, FieldSet, SolverError, Window};

fn base() -> toml::Table {
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

fn key_of(r: Result<Box<dyn protocol::Solver>, SolverError>) -> String {
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
    assert_eq!(key_of(factory("mc-spg", &t)), "params");
    assert_eq!(key_of(factory("nope", &base())), "model");
    assert!(factory("mc-spg", &base()).is_ok());
}

/// Two shell strips (one quad each) over the ends of the block, mid-surface z = 1 mm.
fn shell_nodes() -> Vec<[f64; 3]> {
    let z = 1e-3;
    vec![
        [0.0, 0.0, z],
        [1e-3, 0.0, z],
        [1e-3, 2e-3, z],
        [0.0, 2e-3, z],
        [5e-3, 0.0, z],
        [6e-3, 0.0, z],
        [6e-3, 2e-3, z],
        [5e-3, 2e-3, z],
    ]
}

fn flat(v: &[[f64; 3]]) -> Vec<f64> {
    v.iter().flatten().copied().collect()
}

#[test]
fn stand_in_driver_gets_the_support_reactions_and_the_power_balances() {
    let v = 0.5;
    // Responder: coupling particles in the two end regions.
    let mut tc = base();
    let c: toml::Table = toml::from_str(
        "interface = \"shell\"\ncells = [[0, 1, 2, 3], [4, 5, 6, 7]]\nregions = [{ lo = [-1.0, -1.0, -1.0], hi = [1e-3, 1.0, 1.0] }, { lo = [5e-3, -1.0, -1.0], hi = [1.0, 1.0, 1.0] }]",
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

    let mut x = shell_nodes();
    let mut setup_in = FieldSet::new();
    setup_in.insert(
        "shell",
        Field {
            name: "position".into(),
            components: 3,
            values: flat(&x),
        },
    );
    let mut out = FieldSet::new();
    coupled.setup(&[], &setup_in, &mut out).unwrap();
    let mass = out.require("shell", "mass", 8).unwrap().to_vec();
    let stiff = out.require("shell", "stiffness", 8).unwrap().to_vec();
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
    for w in 1..=20u64 {
        for (k, p) in x.iter_mut().enumerate() {
            p[0] += window * node_v[k][0];
        }
        let mut inbox = FieldSet::new();
        inbox.insert(
            "shell",
            Field {
                name: "position".into(),
                components: 3,
                values: flat(&x),
            },
        );
        let win = Window {
            index: w,
            t0: (w - 1) as f64 * window,
            t1: w as f64 * window,
            write_output: false,
        };
        let rc = coupled.advance(&win, &inbox, &mut out).unwrap();
        let rs = supported
            .advance(&win, &FieldSet::new(), &mut sup_out)
            .unwrap();
        let f = out.require("shell", "force", 24).unwrap().to_vec();
        let right: f64 = (4..8).map(|k| f[3 * k]).sum();
        let reaction = rs
            .scalars
            .iter()
            .find(|(n, _)| n == "force_right_x")
            .unwrap()
            .1;
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

#[test]
fn bolted_plate_geometry_builds_and_steps() {
    let t: toml::Table = toml::from_str(
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
    .unwrap();
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
