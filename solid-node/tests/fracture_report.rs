//! The per-window fracture scalars of the peridynamic node (damaged particle count,
//! fragments, where damage first appeared, largest von Mises stress): checked against
//! closed forms (von Mises of simple stress states, distances on the lattice) and against
//! the node's own independent measurements (damage indices, connected components).

use mechanics::j2::von_mises;
use protocol::{Inbox, Outbox, Solver, Window};
use solid_node::pd::geometry::{Shape, lattice};
use solid_node::pd::solver::{DAMAGED_INDEX, PdSolver, first_damage_of};

#[test]
fn von_mises_of_simple_stress_states() {
    let s = 3.0e8;
    // Uniaxial: σ; pure shear: √3 τ; hydrostatic: 0.
    assert!((von_mises(&[s, 0.0, 0.0, 0.0, 0.0, 0.0]) - s).abs() < 1e-6);
    assert!((von_mises(&[0.0, 0.0, 0.0, 0.0, 0.0, s]) - 3f64.sqrt() * s).abs() < 1e-6);
    assert!((von_mises(&[0.0, 0.0, 0.0, s, 0.0, 0.0]) - 3f64.sqrt() * s).abs() < 1e-6);
    assert!(von_mises(&[-s, -s, -s, 0.0, 0.0, 0.0]).abs() < 1e-6);
}

#[test]
fn first_damage_near_the_inner_corners_of_a_hollow_square() {
    // Hole 10 cm, outside 16 cm, Δx 5 mm: lattice points at cell centres, so the three
    // particles around a re-entrant corner (the fourth cell is in the hole) are Δx/√2 from it.
    let dx = 5e-3;
    let sq = Shape::HollowSquare {
        center: [0.2, 0.2, 0.0],
        inner_half: 0.05,
        outer_half: 0.08,
        height: 0.0,
    };
    let x0 = lattice(std::slice::from_ref(&sq), &[], dx, false);
    assert_eq!(x0.len(), 32 * 32 - 20 * 20);
    let corners = [(0.15, 0.15), (0.25, 0.15), (0.15, 0.25), (0.25, 0.25)];
    let mut d = vec![0.0; x0.len()];
    for (i, p) in x0.iter().enumerate() {
        for (k, c) in corners.iter().enumerate() {
            if (p[0] - c.0).hypot(p[1] - c.1) < 0.75 * dx {
                d[i] = 0.1 + 0.1 * k as f64;
            }
        }
    }
    let f = first_damage_of(std::slice::from_ref(&sq), &x0, &d, 7e-5);
    assert_eq!(f.count, 12);
    assert!(
        (f.corner_distance - dx / 2f64.sqrt()).abs() < 1e-12,
        "{f:?}"
    );
    // The most damaged are at the last corner; of equals, the first in lattice order (rows
    // of increasing y).
    assert!((f.position[0] - 0.2525).abs() < 1e-12 && (f.position[1] - 0.2475).abs() < 1e-12);
    assert_eq!(f.radius, [-1.0, -1.0]);
    assert_eq!(f.time, 7e-5);
    // One particle next to the middle of the upper side, half a spacing right of it: nearest
    // corner (0.25, 0.25), 47.5 mm along x and 2.5 mm along y.
    let mut d = vec![0.0; x0.len()];
    let mid = x0
        .iter()
        .position(|p| (p[0] - 0.2025).abs() < 1e-9 && (p[1] - 0.2525).abs() < 1e-9)
        .expect("a particle next to the middle of the upper inner side");
    d[mid] = 0.3;
    let f = first_damage_of(std::slice::from_ref(&sq), &x0, &d, 1.0);
    let want = (0.25f64 - 0.2025).hypot(0.0025);
    assert!((f.corner_distance - want).abs() < 1e-12, "{f:?}");
}

/// A coarse brittle ring (Δx 5 mm, 648 particles) under a 2 GPa internal pressure pulse:
/// the report's `damaged_particles` and `fragments` are what the damage indices and the
/// connected components say, the first damage is on the inner face, and the largest von Mises
/// stress passed σcr = 3 GPa before bonds broke.
#[test]
fn the_report_counts_what_the_body_shows() {
    let text = r#"
dimension = "plane_strain"
thickness = 0.01
spacing = 5e-3
horizon = 1.5075e-2
density = 7870.0
young = 200e9
poisson = 0.29
damage = { kind = "von_mises", critical_stress = 3e9 }
bodies = [{ shape = "hollow_cylinder", center = [0.0, 0.0, 0.0], inner_radius = 0.07, outer_radius = 0.1 }]
pressure_pulse = { surface = "inner", center = [0.0, 0.0, 0.0], inner_radius = 0.07, peak = 2e9, rise = 5e-6, duration = 60e-6 }
fragment_min_size = 10
"#;
    let table: toml::Table = toml::from_str(text).expect("params");
    let mut s = PdSolver::from_table("pd-correspondence", &table).expect("solver");
    s.setup(&[], &Inbox::new(), &mut Outbox::new())
        .expect("setup");
    let (inbox, mut out) = (Inbox::new(), Outbox::new());
    let mut peak_vm: f64 = 0.0;
    let mut first: Option<f64> = None;
    let mut last = None;
    for w in 0..120u64 {
        let win = Window {
            index: w + 1,
            t0: w as f64 * 1e-6,
            t1: (w + 1) as f64 * 1e-6,
            write_output: false,
        };
        let r = s.advance(&win, &inbox, &mut out).expect("advance");
        let get = |k: &str| r.scalars.iter().find(|(n, _)| n == k).map(|(_, v)| *v);
        if first.is_none() && get("cracked_particles").unwrap_or(0.0) > 0.0 {
            first = Some(win.t1);
            // Stress crossed σcr at the latest in the window the first bond broke.
            assert!(peak_vm.max(get("max_von_mises").unwrap_or(0.0)) >= 3e9 * 0.9);
        }
        peak_vm = peak_vm.max(get("max_von_mises").expect("max_von_mises"));
        last = Some(r);
    }
    let r = last.expect("windows ran");
    let get = |k: &str| {
        r.scalars
            .iter()
            .find(|(n, _)| n == k)
            .map(|(_, v)| *v)
            .unwrap_or_else(|| panic!("{k} not reported"))
    };
    let d = s.body.damage();
    let damaged = d.iter().filter(|&&x| x >= DAMAGED_INDEX).count();
    let (frags, debris) = s.fragments(10);
    println!(
        "first damage by {:?} s; {damaged} damaged, fragments {frags:?}, debris {debris}",
        first
    );
    assert_eq!(get("damaged_particles"), damaged as f64);
    assert_eq!(get("fragments"), frags.len() as f64);
    assert_eq!(get("debris_particles"), debris as f64);
    assert!(damaged > 0 && frags.len() >= 2, "{damaged} {frags:?}");
    let fd = s.first_damage().expect("first damage recorded");
    assert_eq!(Some(fd.time), first);
    assert_eq!(get("first_damage_time"), fd.time);
    assert!(fd.radius[0] < 0.07 + 5e-3, "{fd:?}");
    assert!(fd.radius[1] < 0.085, "{fd:?}");
}
