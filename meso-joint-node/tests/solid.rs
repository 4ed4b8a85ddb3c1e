//! Solid elements around an SPG core (seed 004 §4.2): the split of the lattice into cells of
//! particles and hexahedra, the patch test across the boundary they share, a bar of
//! hexahedra with an SPG middle in tension (both follow the J2 law and carry one force;
//! momentum to round-off), bad `solid` tables refused by key, and a bolted joint with
//! solid elements restarted bit for bit.

#![allow(clippy::needless_range_loop)]

use mechanics::hex8::HexParams;
use mechanics::j2::J2Material;
use meso_joint_node::config::Smoothing;
use meso_joint_node::geometry::{block, split_solid};
use meso_joint_node::model::{Model, ModelParams};
use meso_joint_node::solid::Solid;

// the tension test's bar and material
use crate::tension::{E, ET, L, SY, j2_uniaxial};
const H: f64 = 0.5e-3;

fn material() -> J2Material {
    J2Material {
        young: E,
        poisson: 0.3,
        yield_stress: SY,
        iso_hardening: 0.0,
        kin_hardening: E * ET / (E - ET),
    }
}

/// The 8 × 3 × 3 mm bar of seed 004 §4.2's steel at 0.5 mm, pulled at 1 m/s by two-layer
/// grips at each end; `core`: the x-range kept as SPG particles, the rest hexahedra (none:
/// all particles).
fn bar(core: Option<[f64; 2]>) -> Model {
    let s = block([0.0; 3], [L, 3e-3, 3e-3], H);
    let p = ModelParams {
        blast: None,
        material: material(),
        density: 7850.0,
        spacing: H,
        support: 2.0 * H,
        eps_crit: 10.0,
        e_crit: 1.0,
        reanchor_every: 2000,
        smoothing: Smoothing::Consistent,
        cfl: 0.4,
        bearing: None,
    };
    let mut m = match core {
        None => Model::new(p, s.x, s.vol, s.part, &s.rigid_parts).unwrap(),
        Some([a, b]) => {
            let split = split_solid(&s, |x| x[0] > a && x[0] < b);
            let hp = HexParams {
                material: material(),
                density: 7850.0,
                hourglass: 1.0,
            };
            let solid = Solid::new(
                split.nodes,
                split.node_particle,
                split.elements,
                split.element_part,
                hp,
            )
            .unwrap();
            let ps = split.particles;
            let kv = Some(split.kernel_vol);
            Model::with_solid(p, ps.x, ps.vol, ps.part, &ps.rigid_parts, Some(solid), kv).unwrap()
        }
    };
    m.add_velocity_bc("left", [-1.0, 0.0, 0.0], 2e-5, |x| x[0] < 2.0 * H);
    m.add_velocity_bc("right", [1.0, 0.0, 0.0], 2e-5, |x| x[0] > L - 2.0 * H);
    m.initial_forces();
    m
}

/// The force the right grip pulls with (N, x): minus the body's force on its particles and
/// nodes (the grip's velocity is constant by then).
fn grip_force(m: &Model) -> f64 {
    let g = &m.bcs[1];
    let mut f: f64 = g.particles.iter().map(|&i| -m.f[i as usize][0]).sum();
    if let Some(sd) = &m.solid {
        f += g.nodes.iter().map(|&k| -sd.f[k as usize][0]).sum::<f64>();
    }
    f
}

fn total_mass(m: &Model) -> f64 {
    let nodes: f64 = m
        .solid
        .as_ref()
        .map_or(0.0, |sd| sd.own_nodes().map(|k| sd.mass[k]).sum());
    // the inertial masses: the particles' own and the elements' share on the shared nodes
    m.mh.iter().sum::<f64>() + nodes
}

#[test]
fn the_split_puts_each_cell_in_one_of_the_two_and_shares_the_boundary_nodes() {
    let m = bar(Some([3e-3, 5e-3]));
    let sd = m.solid.as_ref().unwrap();
    // 16 × 6 × 6 cells, 4 of the 16 along x in the core
    assert_eq!(sd.part.elements.len(), 12 * 36);
    // the core's corners: 5 × 7 × 7 particles; two planes of 7 × 7 shared with elements
    assert_eq!(m.len(), 5 * 49);
    let shared = sd.node_particle.iter().filter(|&&i| i != u32::MAX).count();
    assert_eq!(shared, 2 * 49);
    // the material's mass is all there once: the bar's 8 × 3 × 3 mm of steel
    let want = 7850.0 * L * 3e-3 * 3e-3;
    let got = total_mass(&m);
    assert!(
        (got - want).abs() < 1e-12 * want,
        "{got} kg against {want} kg"
    );
    // the particles' volumes are the core's
    let core: f64 = m.vol.iter().sum();
    assert!(
        (core - 2e-3 * 9e-6).abs() < 1e-12 * core,
        "core volume {core}"
    );
}

/// The particles' gauge: volume-weighted mean axial log strain and axial stress less the
/// mean lateral one over the core (J2 is pressure insensitive).
fn core_gauge(m: &Model) -> (f64, f64) {
    let (mut e, mut s, mut v) = (0.0, 0.0, 0.0);
    for i in 0..m.len() {
        let f = mechanics::tensor::mat(&m.fhat[i]) * mechanics::tensor::mat(&m.ftot_a[i]);
        e += m.vol0[i] * f[(0, 0)].ln();
        let st = m.mat[i].stress();
        s += m.vol0[i] * (st[0] - 0.5 * (st[1] + st[2]));
        v += m.vol0[i];
    }
    (e / v, s / v)
}

/// The elements' gauge between the material planes x = 1.5 and 2.5 mm (between a grip and
/// the core): log strain of the planes' mean distance, and the elements' mean axial stress
/// less their lateral one.
fn element_gauge(m: &Model) -> (f64, f64) {
    let sd = m.solid.as_ref().unwrap();
    let plane = |x0: f64| {
        let on: Vec<usize> = (0..sd.len())
            .filter(|&k| (sd.x0[k][0] - x0).abs() < 1e-9)
            .collect();
        on.iter().map(|&k| sd.x[k][0]).sum::<f64>() / on.len() as f64
    };
    let e = ((plane(2.5e-3) - plane(1.5e-3)) / 1e-3).ln();
    let (mut s, mut n) = (0.0, 0.0);
    for (el, st) in sd.part.elements.iter().zip(sd.part.state.iter()) {
        let xc = el.iter().map(|&k| sd.x0[k as usize][0]).sum::<f64>() / 8.0;
        if xc > 1.5e-3 && xc < 2.5e-3 {
            let t = st.mat.stress;
            s += t[0] - 0.5 * (t[1] + t[2]);
            n += 1.0;
        }
    }
    (e, s / n)
}

/// The axial force through the core and through the elements between x = 2 and 2.5 mm
/// (N): `Σ V σ_xx` over each, divided by its current length.
fn section_forces(m: &Model) -> (f64, f64) {
    let span = |xs: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
        hi - lo
    };
    let core: f64 = (0..m.len()).map(|i| m.vol[i] * m.mat[i].stress()[0]).sum();
    let core_len = span(&mut m.x.iter().map(|x| x[0]));
    let sd = m.solid.as_ref().unwrap();
    let on = |x0: f64| (0..sd.len()).filter(move |&k| (sd.x0[k][0] - x0).abs() < 1e-9);
    let plane = |x0: f64| on(x0).map(|k| sd.x[k][0]).sum::<f64>() / on(x0).count() as f64;
    let mut el = 0.0;
    for (e, st) in sd.part.elements.iter().zip(sd.part.state.iter()) {
        let xc = e.iter().map(|&k| sd.x0[k as usize][0]).sum::<f64>() / 8.0;
        if xc > 2.0e-3 && xc < 2.5e-3 {
            el += st.volume * st.mat.stress[0];
        }
    }
    (core / core_len, el / (plane(2.5e-3) - plane(2.0e-3)))
}

/// Pulled to 1.5 % strain, the bar of hexahedra with a 2 mm SPG core in its middle follows
/// the J2 kinematic-hardening law in both (within 2 % past 0.4 % strain, as the
/// all-particle bar does; measured 0.03 % and 0.29 %), carries one force through the core,
/// the elements and the grip (within 1 %; measured 0.63 %, the largest early on), and keeps its momentum: what it
/// holds equals the grips' booked impulse to round-off. The elements' gauge strains less
/// than the core at one force: it is 1 mm from a grip, which holds the section's lateral
/// contraction.
#[test]
fn hexahedra_and_their_spg_core_both_follow_the_j2_law_in_tension() {
    let mut m = bar(Some([3e-3, 5e-3]));
    let dt = m.stable_dt();
    let (mut worst_core, mut worst_el, mut samples) = (0.0f64, 0.0f64, 0);
    let mut worst_force = 0.0f64;
    let mut last = (0.0, 0.0);
    let mut step = 0;
    while last.0 < 0.015 && step < 20000 {
        m.step(dt).unwrap();
        step += 1;
        let (ec, sc) = core_gauge(&m);
        let (ee, se) = element_gauge(&m);
        last = (ec, ee);
        if ec > 0.004 && ee > 0.004 {
            worst_core = worst_core.max((sc - j2_uniaxial(ec)).abs() / j2_uniaxial(ec));
            worst_el = worst_el.max((se - j2_uniaxial(ee)).abs() / j2_uniaxial(ee));
            let (fc, fe) = section_forces(&m);
            let fg = grip_force(&m);
            worst_force = worst_force.max(((fc - fg).abs()).max((fe - fg).abs()) / fg);
            samples += 1;
        }
        if step % 300 == 0 {
            eprintln!(
                "t {:.3e} s: core ε {ec:.5} σ {sc:.4e}, elements ε {ee:.5} σ {se:.4e}, grip {:.1} N",
                m.time,
                grip_force(&m)
            );
        }
    }
    let p = m.momentum();
    let scale = total_mass(&m) * 1.0;
    for d in 0..3 {
        let off = p[d] - m.bc_impulse[d];
        assert!(
            off.abs() < 1e-12 * scale,
            "momentum {d} off the grips' impulse by {off:e}"
        );
    }
    eprintln!(
        "{samples} samples over {step} steps: worst |σ − σ_J2|/σ_J2 {:.3} % in the core, {:.3} % in the elements; section forces off the grip's by {:.3} %",
        100.0 * worst_core,
        100.0 * worst_el,
        100.0 * worst_force
    );
    assert!(last.0 >= 0.015, "the core reached only ε = {}", last.0);
    assert!(samples >= 500, "only {samples} samples past ε = 0.004");
    assert!(
        worst_core < 0.02,
        "core off the J2 law by {:.2} %",
        100.0 * worst_core
    );
    assert!(
        worst_el < 0.02,
        "elements off the J2 law by {:.2} %",
        100.0 * worst_el
    );
}

/// Patch test across the shared boundary: a uniform stretch (1e-8, elastic) leaves no force
/// on any particle or element node away from the bar's outer surfaces — at the boundary
/// the elements' share and the particles' share of each shared node cancel, and the core's
/// particles on its free sides weigh as whole cells in their neighbours' shapes (with their
/// partial volumes as weights, forces of 0.13 σh² were left there).
#[test]
fn a_uniform_stretch_crosses_the_shared_boundary_without_ghost_forces() {
    let mut m = bar(Some([3e-3, 5e-3]));
    m.bcs.clear();
    let rate = 1e-8; // over dt = 1 s
    for i in 0..m.len() {
        m.kind[i] = meso_joint_node::model::Kind::Free;
        m.v[i] = [rate * m.x[i][0], 0.0, 0.0];
        m.vh[i] = m.v[i];
    }
    let sd = m.solid.as_mut().unwrap();
    sd.held.fill(false);
    for k in 0..sd.len() {
        sd.v[k] = [rate * sd.x[k][0], 0.0, 0.0];
    }
    m.position_phase(1.0).unwrap();
    let sigma = m.mat[0].stress()[0];
    assert!(sigma > 0.0);
    let unit = sigma * H * H;
    // more than a kernel support from the outer surfaces, the grips' planes included
    let interior = |x: &[f64; 3]| {
        (x[1] > 0.9e-3 && x[1] < 2.1e-3)
            && (x[2] > 0.9e-3 && x[2] < 2.1e-3)
            && (x[0] > 1.2e-3 && x[0] < L - 1.2e-3)
    };
    let norm = |f: &[f64; 3]| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let (mut worst, mut checked, mut boundary) = (0.0f64, 0, 0);
    for i in (0..m.len()).filter(|&i| interior(&m.x0[i])) {
        worst = worst.max(norm(&m.f[i]) / unit);
        checked += 1;
        if (m.x0[i][0] - 3e-3).abs() < 1e-9 || (m.x0[i][0] - 5e-3).abs() < 1e-9 {
            boundary += 1;
        }
    }
    let sd = m.solid.as_ref().unwrap();
    for k in sd.own_nodes().filter(|&k| interior(&sd.x0[k])) {
        worst = worst.max(norm(&sd.f[k]) / unit);
        checked += 1;
    }
    eprintln!(
        "{checked} particles and nodes ({boundary} on the shared boundary): largest force {worst:.3e} σh²"
    );
    assert_eq!(boundary, 2 * 9);
    assert!(checked >= 9 * 11, "only {checked} checked");
    assert!(worst < 1e-6, "a force of {worst:e} σh²");
}

fn joint_with_solid() -> toml::Table {
    // the bolted plates, pulled at 0.5 m/s, with elements outside a core around the bolt
    let mut t = crate::solver::bolted_plates();
    let extra: toml::Table = toml::from_str(
        r#"
        velocity_bc = [
          { name = "left", velocity = [-0.5, 0.0, 0.0], ramp = 1e-6, region = { lo = [-1.0, -1.0, -1.0], hi = [1.0e-3, 1.0, 1.0] } },
          { name = "right", velocity = [0.5, 0.0, 0.0], ramp = 1e-6, region = { lo = [13.0e-3, -1.0, -1.0], hi = [1.0, 1.0, 1.0] } },
        ]
        [solid]
        core = [{ lo = [4.0e-3, -2.5e-3, -1.0], hi = [10.0e-3, 2.5e-3, 1.0] }]
        "#,
    )
    .unwrap();
    t.extend(extra);
    t
}

/// A bad `solid` table is refused by its key before anything runs.
#[test]
fn a_bad_solid_table_is_refused_by_its_key() {
    use crate::solver::key_of;
    use meso_joint_node::factory;
    let with = |f: &dyn Fn(&mut toml::Table)| {
        let mut t = joint_with_solid();
        f(&mut t);
        key_of(factory("mc-spg", &t))
    };
    let solid = |t: &mut toml::Table| t["solid"].as_table_mut().unwrap().clone();
    assert_eq!(
        with(&|t| {
            let mut s = solid(t);
            s.insert("core".into(), toml::Value::Array(vec![]));
            t.insert("solid".into(), toml::Value::Table(s));
        }),
        "solid.core"
    );
    assert_eq!(
        with(&|t| {
            let mut s = solid(t);
            s.insert("hourglass".into(), toml::Value::Float(-1.0));
            t.insert("solid".into(), toml::Value::Table(s));
        }),
        "solid.hourglass"
    );
    assert_eq!(
        with(&|t| {
            let mut s = solid(t);
            let all: toml::Table =
                toml::from_str("lo = [-1.0, -1.0, -1.0]\nhi = [1.0, 1.0, 1.0]").unwrap();
            s.insert(
                "core".into(),
                toml::Value::Array(vec![toml::Value::Table(all)]),
            );
            t.insert("solid".into(), toml::Value::Table(s));
        }),
        "solid.core"
    );
    // a kinematic coupling drives particles: its regions may not hold element nodes
    assert_eq!(
        with(&|t| {
            let c: toml::Table = toml::from_str(
                "interface = \"shell\"\nregions = [{ lo = [-1.0, -1.0, -1.0], hi = [1.0e-3, 1.0, 1.0] }]",
            )
            .unwrap();
            t.insert("coupling".into(), toml::Value::Table(c));
            t.remove("velocity_bc");
        }),
        "coupling.regions"
    );
    assert!(meso_joint_node::factory("mc-spg", &joint_with_solid()).is_ok());
}

/// The bolted joint with hexahedra around an SPG core at the bolt steps, and its state read
/// back into a fresh node continues bit for bit.
#[test]
fn a_joint_with_solid_elements_restarts_bit_identically() {
    use meso_joint_node::factory;
    use protocol::{FieldSet, Window};
    let mut a = factory("mc-spg", &joint_with_solid()).unwrap();
    let dt = a.stable_dt();
    let win = |index: u64| Window {
        index,
        t0: (index - 1) as f64 * 20.0 * dt,
        t1: index as f64 * 20.0 * dt,
        write_output: false,
    };
    for k in 1..=3 {
        a.advance(&win(k), &FieldSet::new(), &mut FieldSet::new())
            .unwrap();
    }
    let state = a.save_state().unwrap();
    let mut b = factory("mc-spg", &joint_with_solid()).unwrap();
    b.load_state(&state).unwrap();
    for k in 4..=6 {
        let mut ra = a
            .advance(&win(k), &FieldSet::new(), &mut FieldSet::new())
            .unwrap();
        let mut rb = b
            .advance(&win(k), &FieldSet::new(), &mut FieldSet::new())
            .unwrap();
        // the wall-clock time is not physics
        (ra.wall_s, rb.wall_s) = (0.0, 0.0);
        assert_eq!(ra, rb, "window {k}");
        assert!(ra.kinetic_energy > 0.0 && ra.internal_energy > 0.0);
    }
    assert_eq!(a.save_state().unwrap(), b.save_state().unwrap());
}

/// Mass scaling reaches the elements too: with a target of 5e-7 s (about 25 times the
/// steel's step at 0.5 mm) the joint's step is the target, its elements and particles took
/// added mass, and it steps.
#[test]
fn mass_scaling_raises_the_elements_step_with_the_particles() {
    use protocol::{FieldSet, Window};
    let mut t = joint_with_solid();
    let plain = meso_joint_node::factory("mc-spg", &t).unwrap().stable_dt();
    let target = 5e-7;
    assert!(plain < target / 10.0, "the unscaled step {plain} s");
    t.insert("mass_scaling_dt".into(), toml::Value::Float(target));
    let mut s = meso_joint_node::factory("mc-spg", &t).unwrap();
    let dt = s.stable_dt();
    assert!(
        dt >= 0.999 * target,
        "scaled step {dt} s against the target {target} s"
    );
    let r = s
        .advance(
            &Window {
                index: 1,
                t0: 0.0,
                t1: 20.0 * dt,
                write_output: false,
            },
            &FieldSet::new(),
            &mut FieldSet::new(),
        )
        .unwrap();
    let added = r.scalars.iter().find(|(n, _)| n == "added_mass").unwrap().1;
    assert!(added > 0.0, "no mass added");
    assert!(r.substeps <= 21, "{} substeps for 20 steps", r.substeps);
}
