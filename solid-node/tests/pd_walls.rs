//! Rigid walls (`walls`): an elastic bar that strikes one rebounds as the one-dimensional
//! theory says (contact for 2L/c₀ under the force ρc₀Av, leaving at the speed it came), the
//! momentum it loses is exactly the impulse the node books for the wall, its energy is the
//! start's plus the wall's work to the integrator's error, and bad walls are refused by key.

use super::pd_solver::key_of;
use protocol::{Inbox, Outbox, Solver, StepReport, Window};
use solid_node::pd::solver::PdSolver;

const E: f64 = 200e9;
const RHO: f64 = 7850.0;
/// The bar: 4 × 4 particles across, 40 along z, Δx = 1 mm, its end face on the wall (z = 0).
const LENGTH: f64 = 0.040;
const AREA: f64 = 16e-6;
const SPEED: f64 = 10.0;

fn bar(extra: &str) -> toml::Table {
    toml::from_str(&format!(
        r#"
dimension = "3d"
spacing = 1e-3
horizon = 3.015e-3
density = {RHO}
young = {E}
poisson = 0.25
bodies = [{{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.004, 0.004, {LENGTH}] }}]
initial_velocity = [{{ region = {{ shape = "box", min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] }}, velocity = [0.0, 0.0, -{SPEED}] }}]
walls = [{{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 2.0] }}]
{extra}
"#
    ))
    .expect("test table")
}

/// Window `k` of `w` seconds through `s`.
fn window<S: Solver + ?Sized>(s: &mut S, k: u64, w: f64) -> StepReport {
    let win = Window {
        index: k,
        t0: (k - 1) as f64 * w,
        t1: k as f64 * w,
        write_output: false,
    };
    s.advance(&win, &Inbox::new(), &mut Outbox::new())
        .expect("advance")
}

fn scalar(r: &StepReport, name: &str) -> f64 {
    r.scalars
        .iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no scalar {name}"))
        .1
}

#[test]
fn an_elastic_bar_rebounds_from_a_wall_as_the_one_dimensional_theory_says() {
    for model in ["pd-bond", "pd-correspondence"] {
        let mut s = match solid_node::pd::factory(model, &bar("")) {
            Some(Ok(s)) => s,
            _ => panic!("{model}: the bar must build"),
        };
        s.setup(&[], &Inbox::new(), &mut Outbox::new())
            .expect("setup");
        let mass = RHO * AREA * LENGTH;
        let p0 = -mass * SPEED;
        let e0 = 0.5 * mass * SPEED * SPEED;
        let c0 = (E / RHO).sqrt();
        let contact = 2.0 * LENGTH / c0; // 15.85 µs
        let w = 0.25e-6;
        let (mut touching, mut last_touch, mut pushed) = (0usize, 0.0f64, 0.0f64);
        let (mut worst_p, mut worst_e) = (0.0f64, 0.0f64);
        let mut rep = None;
        for k in 1..=120u64 {
            let r = window(&mut *s, k, w);
            // The body's momentum is the start's plus the wall's impulse, to round-off.
            let p = r.momentum[2];
            worst_p = worst_p.max((p - p0 - r.external_impulse[2]).abs() / p0.abs());
            for d in 0..2 {
                assert!(r.momentum[d].abs() < 1e-15 && r.external_impulse[d] == 0.0);
            }
            // Kinetic plus strain energy: the start's plus the wall's (negative) work.
            let e = r.kinetic_energy + r.internal_energy;
            assert!(
                r.external_work <= 0.0,
                "the wall gave energy: {:e}",
                r.external_work
            );
            worst_e = worst_e.max((e - e0 - r.external_work).abs() / e0);
            let f = scalar(&r, "wall_force_z");
            assert!(f >= 0.0, "a wall pulls: {f} N");
            if f > 0.0 {
                touching += 1;
                last_touch = k as f64 * w;
                pushed += f * w;
            }
            rep = Some(r);
        }
        let r = rep.expect("120 windows");
        let rebound = r.momentum[2] / mass;
        let mean_force = pushed / last_touch;
        eprintln!(
            "{model}: contact {:.2} µs (2L/c₀ {:.2}), mean force {:.0} N (ρc₀Av {:.0}), rebound {rebound:.3} m/s of {SPEED}, wall work {:.3e} J of {e0:.3e}; momentum {worst_p:.1e}, energy {worst_e:.1e} of the start's; {touching} windows touching",
            last_touch * 1e6,
            contact * 1e6,
            mean_force,
            RHO * c0 * AREA * SPEED,
            r.external_work,
        );
        assert!(
            worst_p < 1e-12,
            "{model}: momentum off the wall's impulse by {worst_p:e}"
        );
        assert!(
            worst_e < 0.02,
            "{model}: energy off its books by {worst_e:e}"
        );
        // It left the wall (the last 40 windows, 10 µs, without a touch) at about the speed
        // it came, after touching it for 2L/c₀.
        assert!(
            last_touch < 80.0 * w,
            "{model}: still touching at {last_touch:e} s"
        );
        assert!(
            (last_touch - contact).abs() < 0.1 * contact,
            "{model}: contact {last_touch:e} s against 2L/c0 = {contact:e} s"
        );
        assert!(
            rebound > 0.9 * SPEED && rebound <= SPEED,
            "{model}: rebound {rebound} m/s"
        );
        // Its impulse spread over the contact: the force of the one-dimensional theory.
        let theory = RHO * c0 * AREA * SPEED;
        assert!(
            (mean_force - theory).abs() < 0.1 * theory,
            "{model}: mean force {mean_force} N against {theory} N"
        );
    }
}

#[test]
fn a_bad_wall_is_refused_by_its_key() {
    assert_eq!(key_of("pd-bond", &bar("")), "accepted");
    let zero = "walls = [{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 0.0] }]";
    let behind = "walls = [{ point = [0.0, 0.0, 0.01], normal = [0.0, 0.0, 1.0] }]";
    let reversed = "walls = [{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, -1.0] }]";
    let nan = "walls = [{ point = [0.0, nan, 0.0], normal = [0.0, 0.0, 1.0] }]";
    for (wall, key) in [
        (zero, "walls[0].normal"),
        (behind, "walls[0].point"),
        (reversed, "walls[0].point"),
        (nan, "walls[0].point"),
    ] {
        let mut t = bar("");
        let w: toml::Table = toml::from_str(wall).expect("wall");
        t.insert("walls".into(), w["walls"].clone());
        assert_eq!(key_of("pd-bond", &t), key, "{wall}");
    }
    // out of the plane in 2-D
    let flat: toml::Table = toml::from_str(
        r#"
dimension = "plane_strain"
spacing = 1e-3
horizon = 3.015e-3
density = 7850.0
young = 200e9
poisson = 0.25
bodies = [{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.004, 0.01, 0.0] }]
walls = [{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.5] }]
"#,
    )
    .expect("table");
    assert_eq!(key_of("pd-bond", &flat), "walls[0].normal");
    // the device path holds no walls
    let t = bar("device = \"gpu\"");
    assert_eq!(key_of("pd-bond", &t), "device");
}

/// A 4340 steel cube (Johnson–Cook strength, Mie–Grüneisen pressure), 12 particles a side,
/// crushed at 20 m/s between a wall under it and a grip on its top layer held only along z
/// (both ends frictionless), to about 0.4 of true strain: it stays a uniform block, its
/// particles' plastic strain is the block's log strain less the elastic part, its stress the
/// Johnson–Cook law's there, the wall carries that stress over the block's current area
/// (less than the surface layers add), and the grip's work is booked: the energy closes.
#[test]
fn a_block_crushed_on_a_wall_by_a_driven_grip_flows_uniformly_and_keeps_its_books() {
    let t: toml::Table = toml::from_str(
        r#"
dimension = "3d"
spacing = 5e-4
horizon = 1.5075e-3
density = 7830.0
young = 205e9
poisson = 0.29
yield_stress = 792e6
johnson_cook = { hardening_modulus = 510e6, hardening_exponent = 0.26, rate_coefficient = 0.014, thermal_exponent = 1.03, room_temperature = 294.0, melt_temperature = 1793.0, specific_heat = 477.0 }
eos = { kind = "mie_gruneisen", sound_speed = 4569.0, s1 = 1.49, gamma0 = 2.17, volume_correction = 0.46 }
bodies = [{ shape = "box", min = [-0.003, -0.003, 0.0], max = [0.003, 0.003, 0.006] }]
prescribed_velocity = [{ region = { shape = "box", min = [-1.0, -1.0, 0.0055], max = [1.0, 1.0, 1.0] }, velocity = [0.0, 0.0, -20.0], components = "z" }]
walls = [{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }]
"#,
    )
    .expect("cube");
    let mut s = PdSolver::from_table("pd-correspondence", &t).expect("the cube builds");
    s.setup(&[], &Inbox::new(), &mut Outbox::new())
        .expect("setup");
    let w = 1e-6;
    let (mut worst_e, mut windows, mut last) = (0.0f64, 0, None);
    for k in 1..=90u64 {
        let r = window(&mut s, k, w);
        // Against the grip's work so far (the block starts at rest, unstressed): judged
        // below against the whole work, as the run's balance is.
        let e = r.kinetic_energy + r.internal_energy + scalar(&r, "plastic_work");
        worst_e = worst_e.max((e - r.external_work).abs());
        windows += 1;
        last = Some(r);
    }
    let r = last.expect("90 windows");
    let worst_e = worst_e / r.external_work;
    let b = &s.body;
    // The inner particles (two spacings and more from every face at the start).
    let inner: Vec<usize> = (0..b.len())
        .filter(|&i| {
            let x = b.x0[i];
            x[0].abs() < 0.0015 && x[1].abs() < 0.0015 && x[2] > 0.0015 && x[2] < 0.0045
        })
        .collect();
    // Their deformation: the least-squares affine map from the start to now, along z and x.
    let mean =
        |f: &dyn Fn(usize) -> f64| inner.iter().map(|&i| f(i)).sum::<f64>() / inner.len() as f64;
    let stretch = |d: usize| {
        let (cx0, cx) = (mean(&|i| b.x0[i][d]), mean(&|i| b.pos[i][d]));
        let num = mean(&|i| (b.x0[i][d] - cx0) * (b.pos[i][d] - cx));
        let den = mean(&|i| (b.x0[i][d] - cx0).powi(2));
        num / den
    };
    let (fz, fx) = (stretch(2), stretch(0));
    let ep = b.model.plastic_strain().expect("plastic strain");
    let stress = b.model.stress().expect("stress");
    let temp = &b.model.point_scalars()[0].1;
    let ep_in = mean(&|i| ep[i]);
    let szz = mean(&|i| stress[i][2]);
    let vm = mean(&|i| mechanics::j2::von_mises(&stress[i]));
    let t_in = mean(&|i| temp[i]);
    // Johnson–Cook at the inner particles' state: ε̄ᵖ, the rate 20 m/s over the particles'
    // span now (centre to centre, 11 spacings at the start), the temperature they reached.
    let rate = 20.0 / (11.0 * 5e-4 * fz);
    let tstar = (t_in - 294.0) / (1793.0 - 294.0);
    let flow =
        (792e6 + 510e6 * ep_in.powf(0.26)) * (1.0 + 0.014 * rate.ln()) * (1.0 - tstar.powf(1.03));
    let area = (12.0 * 5e-4 * fx).powi(2);
    let carried = scalar(&r, "wall_force_z") / area;
    eprintln!(
        "crushed block: F_zz {fz:.4}, F_xx {fx:.4} (ln {:.4}); inner ε̄ᵖ {ep_in:.4}, σ_zz {:.1} MPa, von Mises {:.1} MPa, Johnson–Cook {:.1} MPa at {t_in:.0} K and {rate:.0}/s; wall {:.1} MPa on the current area; energy off its books by {worst_e:.1e} over {windows} windows (grip work {:.2} J)",
        -fz.ln(),
        szz / 1e6,
        vm / 1e6,
        flow / 1e6,
        carried / 1e6,
        r.external_work
    );
    assert_eq!(windows, 90);
    assert!(fz < 0.7, "crushed only to {fz}");
    // Uniform and nearly incompressible: F_xx² F_zz ≈ 1.
    assert!((fx * fx * fz - 1.0).abs() < 0.01, "J = {}", fx * fx * fz);
    for &i in &inner {
        assert!((ep[i] - ep_in).abs() < 0.01 * ep_in, "not uniform");
    }
    // ε̄ᵖ is the log strain less the elastic strain (σ/E, under 1 %).
    assert!(
        (ep_in - (-fz.ln() - flow / 205e9)).abs() < 0.01 * ep_in,
        "ε̄ᵖ {ep_in} against ln(1/F_zz) − σ/E = {}",
        -fz.ln() - flow / 205e9
    );
    assert!(
        (vm - flow).abs() < 1e-3 * flow,
        "von Mises {vm} against {flow}"
    );
    assert!(
        carried > -szz && carried < 1.08 * -szz,
        "wall {carried} against {szz}"
    );
    assert!(r.external_work > 100.0, "grip work {}", r.external_work);
    assert!(worst_e < 0.01, "energy off its books by {worst_e:e}");
}
