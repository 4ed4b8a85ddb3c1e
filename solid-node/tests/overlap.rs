//! The peridynamic side of an overlap coupling: the boundary layer's particles carry no mass
//! of the patch's, the patch's pull on them balances the layer's forces on the patch pair by
//! pair, and a linear field across the layer leaves the patch's own particles without force
//! (no ghost force at the coupling layer). A model whose force does not split by bond is
//! refused by its key.

use protocol::{Binding, CouplingKind, Inbox, Outbox, Role, Solver, SolverError};
use solid_node::pd::solver::PdSolver;

/// A 24 × 24 plate of 1 mm particles, δ = 2Δp as the glass plate's, its outer four rows and
/// columns (two horizons) the layer.
fn plate(model: &str, poisson: f64) -> Result<PdSolver, SolverError> {
    let t: toml::Table = toml::from_str(&format!(
        r#"
dimension = "plane_stress"
thickness = 1e-3
spacing = 1e-3
horizon = 2e-3
density = 2480.0
young = 74e9
poisson = {poisson}
stabilization = 0.5
bodies = [{{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.024, 0.024, 0.0] }}]
interfaces = [{{ name = "layer", select = "all", regions = [
  {{ shape = "box", min = [-1.0, -1.0, -1.0], max = [0.004, 1.0, 1.0] }},
  {{ shape = "box", min = [0.020, -1.0, -1.0], max = [1.0, 1.0, 1.0] }},
  {{ shape = "box", min = [-1.0, -1.0, -1.0], max = [1.0, 0.004, 1.0] }},
  {{ shape = "box", min = [-1.0, 0.020, -1.0], max = [1.0, 1.0, 1.0] }},
] }}]
"#
    ))
    .expect("toml");
    PdSolver::from_table(model, &t)
}

fn layer_binding() -> Binding {
    Binding {
        coupling: "c".into(),
        kind: CouplingKind::Overlap,
        interface: "layer".into(),
        role: Role::Responder,
        peer: "mesh".into(),
        peer_interface: "region".into(),
        sends: vec![],
        receives: vec![],
        input_lag: 0,
    }
}

/// The patch's pull on every particle of the layer, and the force on every own particle, for
/// the displacement `u(X)` of every particle (N), reached from rest in one step of 1 s at
/// the velocity `u` (the stress law is a rate form: its stress is the integral of the rate).
fn forces(s: &mut PdSolver, layer: &[bool], u: impl Fn([f64; 3]) -> [f64; 3]) -> Vec<[f64; 3]> {
    let b = &mut s.body;
    for i in 0..b.len() {
        let d = u(b.x0[i]);
        b.set_disp(i, d);
        b.vel[i] = d;
    }
    b.eval_forces(1.0);
    let own: Vec<u8> = layer.iter().map(|&l| u8::from(!l)).collect();
    let k = b.kinematics();
    (0..b.len())
        .map(|i| {
            let f = if layer[i] {
                b.model
                    .partial_force(&k, &b.bonds, i, &own)
                    .expect("pd-correspondence splits its force")
            } else {
                b.force[i]
            };
            f.map(|x| x * b.vol[i])
        })
        .collect()
}

#[test]
fn the_layer_pulls_as_much_as_it_is_pulled_and_a_linear_field_leaves_no_ghost_force() {
    let mut s = plate("pd-correspondence", 0.22).expect("builds");
    let pts = s.interface_points("layer");
    let mut out = Outbox::new();
    s.setup(&[layer_binding()], &Inbox::new(), &mut out)
        .expect("set-up");
    let n = pts.len();
    // the reference state pulls nothing
    let f0 = out
        .require("layer", "force", 3 * n)
        .expect("the set-up force");
    assert!(f0.iter().all(|&f| f == 0.0));
    let s = &mut s;
    let total = s.body.len();
    assert_eq!(total, 576);
    assert_eq!(n, 576 - 16 * 16);
    let mut layer = vec![false; total];
    for &i in &pts {
        layer[i] = true;
    }
    // The layer's mass is the driver's: moving it alone moves no momentum of the patch.
    for &i in &pts {
        s.body.vel[i] = [3.0, -2.0, 0.0];
    }
    assert_eq!(s.body.momentum(), [0.0; 3]);
    assert_eq!(s.body.kinetic_energy(), 0.0);
    for &i in &pts {
        s.body.vel[i] = [0.0; 3];
    }
    // A linear field (stretch, shear and a rotation): the patch's own particles feel nothing,
    // the layer next to them is pulled.
    let linear = |x: [f64; 3]| [1e-4 * x[0] + 4e-5 * x[1], -2e-5 * x[0] - 3e-5 * x[1], 0.0];
    let f = forces(s, &layer, linear);
    let norm = |v: &[f64; 3]| v[0].hypot(v[1]);
    let pull = pts.iter().map(|&i| norm(&f[i])).fold(0.0, f64::max);
    let ghost = (0..total)
        .filter(|&i| !layer[i])
        .map(|i| norm(&f[i]))
        .fold(0.0, f64::max);
    println!("largest pull {pull:e} N, largest force on the patch {ghost:e} N");
    assert!(pull > 1e-3, "the layer must be pulled: {pull}");
    assert!(
        ghost < 1e-10 * pull,
        "ghost force {ghost:e} against {pull:e}"
    );
    // A quadratic field: the patch is loaded, and its forces and the pull sum to zero pair
    // by pair.
    let quadratic = |x: [f64; 3]| {
        [
            0.02 * x[0] * x[1] + 1e-4 * x[0],
            0.03 * x[0] * x[0] - 0.01 * x[1] * x[1],
            0.0,
        ]
    };
    let mut s = plate("pd-correspondence", 0.22).expect("builds");
    s.setup(&[layer_binding()], &Inbox::new(), &mut Outbox::new())
        .expect("set-up");
    let f = forces(&mut s, &layer, quadratic);
    let (mut sum, mut gross) = ([0.0; 2], 0.0);
    for v in &f {
        for c in 0..2 {
            sum[c] += v[c];
        }
        gross += norm(v);
    }
    println!("quadratic field: Σ f = {sum:?} against Σ |f| = {gross:e}");
    assert!(gross > 1e-3);
    assert!(sum[0].hypot(sum[1]) < 1e-13 * gross, "{sum:?} vs {gross:e}");
    // The pull is the patch's own bonds only, not the layer particle's whole force: a layer
    // particle beyond a horizon (2 mm) of every own particle is pulled by nothing, though its
    // neighbours in the layer push on it.
    let b = &s.body;
    let (mut far, mut pushed) = (0, 0);
    for &i in &pts {
        let reach = (0..total)
            .filter(|&j| !layer[j])
            .map(|j| (b.x0[i][0] - b.x0[j][0]).hypot(b.x0[i][1] - b.x0[j][1]))
            .fold(f64::INFINITY, f64::min);
        if reach > 2e-3 * (1.0 + 1e-9) {
            far += 1;
            assert_eq!(f[i], [0.0; 3], "particle {i}, {reach} m from the patch");
            let whole = b.force[i].map(|x| x * b.vol[i]);
            if norm(&whole) > 1e-6 * gross {
                pushed += 1;
            }
        }
    }
    // the two outer rows and columns of the 24 × 24 plate (176), and three at each inner
    // corner of the layer, more than a horizon diagonally from the patch's corner particle
    assert_eq!(far, 24 * 24 - 20 * 20 + 4 * 3);
    assert!(
        pushed > 0,
        "no far layer particle carries a force of its own"
    );
}

#[test]
fn a_model_that_does_not_split_its_force_is_refused() {
    let mut s = plate("pd-bond", 1.0 / 3.0).expect("builds");
    let e = s
        .setup(&[layer_binding()], &Inbox::new(), &mut Outbox::new())
        .unwrap_err();
    match e {
        SolverError::Config { key, reason } => {
            assert_eq!(key, "model");
            assert!(reason.contains("pd-correspondence"), "{reason}");
        }
        other => panic!("expected a config error, got {other}"),
    }
}
