//! No-fail zones (`no_fail`): a bond with either end in one never breaks, in every model's
//! damage test and on every instruction set the CPU has; everything else is untouched.
//!
//! A plate is torn at two lines by its initial velocities (the left third moving left, the
//! right third moving right), so bonds break at both within a few steps. Then:
//! * with a zone over the whole plate, the run is bit for bit the run without damage (the
//!   kept bonds' forces are those of live bonds, not recomputed differently);
//! * with a zone over the right tear, no particle in it is damaged, while the left tear
//!   still breaks, as it does without the zone;
//! * a zone that holds no particle, and a zone on the device, are refused with the key.

use crate::pd_solver::{glass_strip, window_of};
use mechanics::simd::Simd;
use protocol::{Inbox, Outbox, Solver, SolverError};
use solid_node::pd::solver::PdSolver;

const MODELS: [&str; 3] = ["pd-bond", "pd-correspondence", "pd-rk-ba"];

/// The zone over the right tear (x ≥ 7.5 mm), and the whole plate.
const RIGHT: &str = r#"{ shape = "box", min = [0.0075, -1.0, -1.0], max = [1.0, 1.0, 1.0] }"#;
const ALL: &str = r#"{ shape = "box", min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] }"#;

/// A 12 × 6 mm plate (24 × 12 particles, δ = 3.03 Δx) whose left third (x < 4 mm) moves left and right
/// third (x > 8 mm) right at 20 m/s; `damage` a critical stretch of 1e-3 or none; `zones` the
/// `no_fail` list; `extra` more keys.
fn table(damage: bool, zones: &[&str], extra: &str) -> toml::Table {
    table_at(1.515e-3, damage, zones, extra)
}

/// [`table`] with horizon `delta`.
fn table_at(delta: f64, damage: bool, zones: &[&str], extra: &str) -> toml::Table {
    let damage = if damage {
        r#"damage = { kind = "critical_stretch", critical_stretch = 1e-3 }"#
    } else {
        ""
    };
    toml::from_str(&format!(
        r#"{}
initial_velocity = [{{ region = {{ shape = "box", min = [-1.0, -1.0, -1.0], max = [0.004, 1.0, 1.0] }}, velocity = [-20.0, 0.0, 0.0] }}, {{ region = {{ shape = "box", min = [0.008, -1.0, -1.0], max = [1.0, 1.0, 1.0] }}, velocity = [20.0, 0.0, 0.0] }}]
no_fail = [{}]
{damage}
{extra}
"#,
        glass_strip("plane_strain", 5e-4, delta, 0.25),
        zones.join(", ")
    ))
    .expect("toml")
}

/// The solver of `model` from `t`, on instruction set `simd`, after three windows of 1 µs
/// (about ten particle steps each).
fn run(model: &str, t: &toml::Table, simd: Simd) -> PdSolver {
    let mut s = PdSolver::from_table(model, t).expect("builds");
    s.body.model.set_simd(simd);
    s.setup(&[], &Inbox::new(), &mut Outbox::new())
        .expect("set-up");
    for k in 1..=3 {
        s.advance(&window_of(k, 1e-6), &Inbox::new(), &mut Outbox::new())
            .expect("advance");
    }
    s
}

fn bits(v: &[[f64; 3]]) -> Vec<[u64; 3]> {
    v.iter().map(|p| p.map(f64::to_bits)).collect()
}

#[test]
fn no_fail_zones_keep_their_bonds_in_every_model() {
    for model in MODELS {
        for simd in Simd::available() {
            let tag = format!("{model} on {simd:?}");
            // Without a zone the plate tears at both lines.
            let mut free = run(model, &table(true, &[], ""), simd);
            let x0 = free.body.x0.clone();
            let right = |i: usize| x0[i][0] >= 0.0075;
            let d = free.body.damage();
            let torn_right = (0..d.len()).filter(|&i| right(i) && d[i] > 0.0).count();
            let torn_left = (0..d.len()).filter(|&i| !right(i) && d[i] > 0.0).count();
            assert!(
                torn_right >= 12,
                "{tag}: {torn_right} damaged at the right tear"
            );
            assert!(torn_left >= 12, "{tag}: {torn_left} damaged elsewhere");

            // A zone over everything: the run without damage, bit for bit.
            let mut kept = run(model, &table(true, &[ALL], ""), simd);
            let mut elastic = run(model, &table(false, &[], ""), simd);
            assert!(elastic.body.damage().iter().all(|&d| d == 0.0), "{tag}");
            let differ = |a: &[[f64; 3]], b: &[[f64; 3]]| {
                bits(a).iter().zip(bits(b)).filter(|(p, q)| *p != q).count()
            };
            let n = differ(&kept.body.pos, &elastic.body.pos);
            assert_eq!(
                n, 0,
                "{tag}: {n} positions differ from the run without damage"
            );
            let n = differ(&kept.body.vel, &elastic.body.vel);
            assert_eq!(
                n, 0,
                "{tag}: {n} velocities differ from the run without damage"
            );
            assert!(kept.body.damage().iter().all(|&d| d == 0.0), "{tag}");

            // A zone over the right tear: nothing in it is damaged, and the left tear still
            // breaks.
            let mut part = run(model, &table(true, &[RIGHT], ""), simd);
            let d = part.body.damage();
            let inside = (0..d.len()).filter(|&i| right(i)).count();
            // nine columns (x = 7.75 … 11.75 mm) of twelve
            assert_eq!(inside, 9 * 12, "{tag}: particles in the zone");
            for i in (0..d.len()).filter(|&i| right(i)) {
                assert_eq!(d[i], 0.0, "{tag}: particle {i} at {:?}", x0[i]);
            }
            let left = (0..d.len()).filter(|&i| !right(i) && d[i] > 0.0).count();
            assert!(left >= 12, "{tag}: {left} damaged at the left tear");
            eprintln!(
                "{tag}: {torn_right} + {torn_left} damaged without a zone, {left} with the \
                 right one"
            );
        }
    }
}

#[test]
fn bad_no_fail_zones_are_refused_with_the_key() {
    let key = |model: &str, t: &toml::Table| match PdSolver::from_table(model, t) {
        Err(SolverError::Config { key, reason }) => format!("{key}: {reason}"),
        Err(e) => format!("other error: {e}"),
        Ok(_) => "accepted".into(),
    };
    let away = r#"{ shape = "box", min = [0.5, 0.5, -1.0], max = [0.6, 0.6, 1.0] }"#;
    let k = key("pd-correspondence", &table(true, &[RIGHT, away], ""));
    assert!(k.starts_with("no_fail[1]: holds no particle"), "{k}");
    let bad = r#"{ shape = "box", min = [0.5, 0.5, -1.0], max = [0.4, 0.6, 1.0] }"#;
    let k = key("pd-bond", &table(true, &[bad], ""));
    assert!(k.starts_with("no_fail[0]:"), "{k}");
    // refused on the device before any adapter is looked for
    let k = key("pd-bond", &table(true, &[RIGHT], r#"device = "gpu""#));
    assert!(k.starts_with("device:") && k.contains("no_fail"), "{k}");
}

/// pd-bond's bonds exactly a horizon long (δ = 3 Δx) have influence 1 − |ξ|/δ = 0: they carry
/// no force from the start, and are not damage. The torn plate without a damage law reads
/// damage 0 everywhere, and with one the same as at δ = 3.03 Δx in kind: both tears break.
#[test]
fn a_bond_a_horizon_long_is_not_damage() {
    let mut s = run("pd-bond", &table_at(1.5e-3, false, &[], ""), Simd::detect());
    let d = s.body.damage();
    let n = d.iter().filter(|&&x| x > 0.0).count();
    assert_eq!(n, 0, "{n} particles read damaged without a damage law");
    let mut s = run("pd-bond", &table_at(1.5e-3, true, &[], ""), Simd::detect());
    let d = s.body.damage();
    let right = (0..d.len())
        .filter(|&i| s.body.x0[i][0] >= 0.0075 && d[i] > 0.0)
        .count();
    let left = (0..d.len())
        .filter(|&i| s.body.x0[i][0] < 0.0075 && d[i] > 0.0)
        .count();
    assert!(right >= 12 && left >= 12, "{right} and {left} damaged");
    assert!(
        left + right < d.len(),
        "every particle damaged: {left} + {right}"
    );
}
