//! pd-correspondence with the blast solid (Johnson–Cook strength with adiabatic heating,
//! Mie–Grüneisen pressure, Johnson–Cook failure): two halves of a free steel block driven
//! into each other, and apart, conserve momentum to round-off; the energy of the impact
//! (kinetic + stored + plastic) is conserved to the integrator's error, which falls with the
//! step; the parameters are refused by key.

use protocol::SolverError;
use solid_node::pd::solver::PdSolver;

/// 4340 steel (Johnson & Cook 1983 strength; the steel Us–up set of Steinberg for the
/// pressure), with the failure constants of Johnson & Cook 1985.
const STEEL: &str = r#"
dimension = "3d"
spacing = 1e-3
horizon = 3.015e-3
density = 7830.0
young = 205e9
poisson = 0.29
yield_stress = 792e6
bodies = [{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.010, 0.006, 0.006] }]
johnson_cook = { hardening_modulus = 510e6, hardening_exponent = 0.26, rate_coefficient = 0.014, thermal_exponent = 1.03, room_temperature = 273.0, melt_temperature = 1793.0, specific_heat = 477.0, initial_temperature = 293.0 }
eos = { kind = "mie_gruneisen", sound_speed = 4569.0, s1 = 1.49, gamma0 = 2.17, volume_correction = 0.46 }
"#;

const FAILURE: &str = r#"damage = { kind = "johnson_cook", d1 = -0.80, d2 = 2.10, d3 = -0.5, d4 = 0.002, d5 = 0.61 }"#;

fn solver(model: &str, extra: &str) -> PdSolver {
    let t: toml::Table = toml::from_str(&format!("{STEEL}\n{extra}")).expect("test table");
    PdSolver::from_table(model, &t).expect("the blast solid builds")
}

/// What a run of the two halves measured.
struct Run {
    /// Largest |Σ m v| over the run, over Σ m |v| at the start.
    momentum: f64,
    /// Largest |E − E₀|/E₀, E = kinetic + stored + plastic + released.
    energy: f64,
    /// Plastic work and released energy at the end over E₀.
    plastic: f64,
    released: f64,
    /// Broken bond copies at the end.
    broken: usize,
    /// Highest temperature at the end (K).
    hottest: f64,
    samples: usize,
}

/// The block's halves (x below and above its middle) at ∓`speed` along x (m/s: negative
/// drives them into each other), over `time` (s) of Verlet steps at `cfl`.
fn halves(model: &str, extra: &str, speed: f64, cfl: f64, time: f64) -> Run {
    let mut s = solver(model, &format!("cfl = {cfl}\n{extra}"));
    let dt = s.dt();
    let steps = (time / dt).ceil() as usize;
    let dt = time / steps as f64;
    let b = &mut s.body;
    for i in 0..b.len() {
        let side = if b.x0[i][0] > 0.005 { 1.0 } else { -1.0 };
        b.vel[i] = [
            side * speed,
            0.2 * speed * (b.x0[i][1] - 0.003) / 0.003,
            0.0,
        ];
    }
    let gross = b.momentum_gross();
    let total = |s: &mut PdSolver| {
        let (u, wp, wf) = s.energies();
        (s.body.kinetic_energy() + u + wp + wf, wp, wf)
    };
    let (e0, _, _) = total(&mut s);
    let mut run = Run {
        momentum: 0.0,
        energy: 0.0,
        plastic: 0.0,
        released: 0.0,
        broken: 0,
        hottest: 0.0,
        samples: 0,
    };
    for _ in 0..steps {
        s.body.step(dt);
        let p = s.body.momentum();
        let m = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        run.momentum = run.momentum.max(m / gross);
        let (e, wp, wf) = total(&mut s);
        run.energy = run.energy.max(((e - e0) / e0).abs());
        (run.plastic, run.released) = (wp / e0, wf / e0);
        run.samples += 1;
    }
    let mut bonds = s.body.bonds.clone();
    s.body.model.sync_bonds(&mut bonds);
    run.broken = bonds.intact.iter().filter(|&&w| w == 0.0).count();
    let scalars = s.body.model.point_scalars();
    let (name, t) = &scalars[0];
    assert_eq!(*name, "temperature");
    run.hottest = t.iter().cloned().fold(0.0, f64::max);
    run
}

#[test]
fn an_impact_conserves_momentum_to_round_off_and_energy_to_the_integrators_error() {
    // The halves meet at 2 × 150 m/s: about 5 GPa of shock pressure, past the 792 MPa
    // yield; 4 µs is about four times the time a wave takes to cross the block.
    let time = 4e-6;
    for model in ["pd-correspondence", "pd-rk-ba"] {
        let coarse = halves(model, "", -150.0, 0.4, time);
        let fine = halves(model, "", -150.0, 0.1, time);
        eprintln!(
            "{model} impact: momentum {:.1e} / {:.1e} of Σ m|v|, largest |E − E₀|/E₀ {:.2e} → {:.2e} (cfl 0.4 → 0.1), plastic work {:.3} of E₀, hottest {:.1} K, {} / {} steps",
            coarse.momentum,
            fine.momentum,
            coarse.energy,
            fine.energy,
            fine.plastic,
            fine.hottest,
            coarse.samples,
            fine.samples
        );
        assert!(coarse.samples >= 50 && fine.samples >= 4 * coarse.samples - 4);
        // first order: the shock's plastic flow is not smooth in time
        for r in [&coarse, &fine] {
            assert!(r.momentum < 1e-13, "{model}: momentum {:e}", r.momentum);
            assert_eq!(r.broken, 0);
        }
        assert!(
            fine.plastic > 0.01,
            "{model}: plastic work {:e} of E₀",
            fine.plastic
        );
        assert!(
            fine.hottest > 293.5,
            "{model}: no heating: {} K",
            fine.hottest
        );
        assert!(
            fine.energy < coarse.energy / 2.5,
            "{model}: the energy error must fall with the step: {:e} → {:e}",
            coarse.energy,
            fine.energy
        );
        assert!(
            fine.energy < 1e-2,
            "{model}: energy error {:e}",
            fine.energy
        );
    }
}

#[test]
fn a_block_torn_apart_by_johnson_cook_failure_conserves_momentum() {
    // The halves fly apart at 2 × 200 m/s: the tension across the middle drives plastic
    // flow at high triaxiality, whose failure strain is small, until the bonds there break.
    for model in ["pd-correspondence", "pd-rk-ba"] {
        let r = halves(model, FAILURE, 200.0, 0.4, 4e-6);
        eprintln!(
            "{model} torn: momentum {:.1e} of Σ m|v|, {} bond copies broken, released {:.3e} and plastic {:.3e} of E₀, largest |E − E₀|/E₀ {:.2e}, {} steps",
            r.momentum, r.broken, r.released, r.plastic, r.energy, r.samples
        );
        assert!(r.samples >= 50, "{} steps", r.samples);
        assert!(r.momentum < 1e-13, "{model}: momentum {:e}", r.momentum);
        assert!(r.broken > 100, "{model}: {} bond copies broken", r.broken);
        assert!(r.plastic > 0.0);
        // Mott's scatter of the failure strain: applied (other bonds break), the same draw
        // for the same seed, another for another seed; momentum still to round-off
        let mott = |seed: u64| {
            let f = FAILURE.replace(
                "d5 = 0.61",
                &format!("d5 = 0.61, mott = {{ gamma = 5.0, seed = {seed} }}"),
            );
            halves(model, &f, 200.0, 0.4, 4e-6)
        };
        // without the failure law no bond breaks: those above broke by Johnson–Cook failure
        assert_eq!(halves(model, "", 200.0, 0.4, 4e-6).broken, 0, "{model}");
        let (a, b, c) = (mott(1), mott(1), mott(2));
        eprintln!(
            "{model} torn with Mott's scatter (γ 5): {} / {} bond copies broken (seeds 1, 2), momentum {:.1e}",
            a.broken, c.broken, a.momentum
        );
        assert!(a.momentum < 1e-13, "{model}: momentum {:e}", a.momentum);
        assert_eq!(
            a.broken, b.broken,
            "{model}: the same seed drew differently"
        );
        if model == "pd-correspondence" {
            // (pd-rk-ba's bonds across the split reach D ≫ 1 in a step at this speed whatever
            // the scatter: the same 3,816 break; its draw is checked bond by bond below)
            assert_ne!(a.broken, r.broken, "{model}: the scatter changed nothing");
            assert_ne!(a.broken, c.broken, "{model}: two seeds drew alike");
        }
    }
}

/// The key and message of the error building `model` with the steel and `extra` gives,
/// after `edit` of its table; "accepted" when it builds.
fn refusal(model: &str, extra: &str, edit: impl Fn(&mut toml::Table)) -> (String, String) {
    let mut t: toml::Table = toml::from_str(&format!("{STEEL}\n{extra}")).expect("test table");
    edit(&mut t);
    match solid_node::pd::factory(model, &t) {
        Some(Err(SolverError::Config { key, reason })) => (key, reason),
        Some(Err(e)) => ("other error".into(), e.to_string()),
        Some(Ok(_)) => ("accepted".into(), String::new()),
        None => ("not a pd model".into(), String::new()),
    }
}

fn key_of(model: &str, extra: &str) -> String {
    refusal(model, extra, |_| {}).0
}

/// Sets `key` of the `johnson_cook` table.
fn strength(key: &'static str, v: f64) -> impl Fn(&mut toml::Table) {
    move |t| {
        if let Some(jc) = t.get_mut("johnson_cook").and_then(|j| j.as_table_mut()) {
            jc.insert(key.into(), toml::Value::Float(v));
        }
    }
}

#[test]
fn the_blast_solids_parameters_are_refused_by_key() {
    assert_eq!(key_of("pd-bond", ""), "johnson_cook");
    for model in ["pd-correspondence", "pd-rk-ba"] {
        assert_eq!(key_of(model, FAILURE), "accepted", "{model}");
        assert_eq!(key_of(model, "iso_hardening = 1e9"), "iso_hardening");
        let no_a = |t: &mut toml::Table| {
            t.remove("yield_stress");
        };
        assert_eq!(refusal(model, "", no_a).0, "yield_stress");
        let no_strength = |t: &mut toml::Table| {
            t.remove("johnson_cook");
            t.remove("eos");
        };
        assert_eq!(refusal(model, FAILURE, no_strength).0, "damage.kind");
        let eos_alone = |t: &mut toml::Table| {
            t.remove("johnson_cook");
        };
        assert_eq!(refusal(model, "", eos_alone).0, "eos");
        for (k, v) in [
            ("hardening_exponent", 1.5),
            ("melt_temperature", 200.0),
            ("taylor_quinney", 2.0),
        ] {
            let key = refusal(model, "", strength(k, v)).0;
            assert_eq!(key, format!("johnson_cook.{k}"));
        }
        let bad_eos = |t: &mut toml::Table| {
            if let Some(e) = t.get_mut("eos").and_then(|e| e.as_table_mut()) {
                e.insert("sound_speed".into(), toml::Value::Float(-1.0));
            }
        };
        assert_eq!(refusal(model, "", bad_eos).0, "eos.sound_speed");
        let bad_failure = FAILURE.replace("d1 = -0.80", "d1 = nan");
        assert_eq!(key_of(model, &bad_failure), "damage.d1");
        for (mott, key) in [
            ("mott = { gamma = 0.0 }", "damage.mott.gamma"),
            (
                "mott = { gamma = 10.0, min_fraction = 1.5 }",
                "damage.mott.min_fraction",
            ),
            ("mott = { gamma = 10.0, sigma = 1.0 }", "damage"),
        ] {
            let scattered = FAILURE.replace("d5 = 0.61", &format!("d5 = 0.61, {mott}"));
            let k = key_of(model, &scattered);
            assert!(k.starts_with(key), "{model} {mott}: {k}");
        }
    }
    let plane = |t: &mut toml::Table| {
        t.insert("dimension".into(), "plane_stress".into());
        t.insert("thickness".into(), toml::Value::Float(1e-3));
    };
    assert_eq!(refusal("pd-correspondence", "", plane).0, "johnson_cook");
    let (key, why) = refusal("pd-correspondence", "device = \"gpu\"", |_| {});
    assert_eq!(key, "device");
    assert!(why.contains("johnson_cook"), "{why}");
}

/// Mott's factors reach pd-rk-ba's bonds: each copy of bond (i, j) fails at the mean of its
/// particles' factors, ½(f_i + f_j), both copies alike, drawn from the seed and the index.
#[test]
fn mott_factors_reach_every_bond_of_pd_rk_ba() {
    use mechanics::johnson_cook::MottScatter;
    use solid_node::pd::model::PdModel;
    let s = solver("pd-rk-ba", "");
    let mut bonds = s.body.bonds.clone();
    let solid = s
        .params
        .blast_solid()
        .expect("valid")
        .expect("a blast solid");
    let mut m = solid_node::pd::rk_ba::RkBa::new(
        solid_node::pd::model::Dim::Three,
        2,
        s.params.horizon,
        solid,
        mechanics::damage::NoDamage,
        &bonds,
    );
    let mott = MottScatter {
        gamma: 10.0,
        seed: 3,
        min_fraction: 0.1,
    };
    let f: Vec<f64> = (0..s.body.len()).map(|i| mott.factor(i as u64)).collect();
    m.set_failure_factors(&f);
    m.sync_bonds(&mut bonds);
    let mut checked = 0;
    for i in 0..s.body.len() {
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            let shift = m.bond_state(b).failure_shift;
            assert_eq!(shift, 0.5 * (f[i] + f[j]) - 1.0, "bond {i}–{j}");
            checked += 1;
        }
    }
    assert_eq!(checked, bonds.len());
    assert!(checked > 10_000, "{checked} bonds");
    // the draw spreads: the factors differ from one particle to the next
    assert!(f.windows(2).all(|w| w[0] != w[1]));
}
