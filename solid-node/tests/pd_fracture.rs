//! Fracture checks at test resolution: the Kalthoff–Winkler crack angle
//! (experiment ≈ 70°, accepted 65–72°) and the seed 000 §3.2 brittle hollow
//! cylinder under an internal pressure pulse (must-show 6: cracks start at the inner face,
//! the ring breaks into fragments). Full resolution: `examples/kalthoff_winkler.rs`,
//! `examples/hollow_cylinder.rs`.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use solid_node::pd::cases::{HollowCylinder, KalthoffWinkler};
use solid_node::pd::fracture::components;

/// Kalthoff–Winkler at Δx = 1 mm (19,800 particles, 90 µs): the cracks from both notch
/// tips, fitted by a line through the tip over 3δ–40 mm, run at 65–72° to the notch.
/// (At Δx = 0.5 mm the example measures 68.0°; coarser than 1 mm the crack is not resolved.)
#[test]
fn kalthoff_winkler_crack_angle() {
    let kw = KalthoffWinkler::default();
    let (mut b, s0) = kw.build();
    // s0 calibrated to G0 on the lattice, near the closed form √(4πG0/(9Eδ)) of ω = 1.
    let closed = (4.0 * std::f64::consts::PI * kw.g0 / (9.0 * 191e9 * 3.015 * kw.dx)).sqrt();
    assert!((s0 / closed - 1.0).abs() < 0.3, "s0 {s0} vs {closed}");
    kw.run(&mut b);
    let d = b.damage();
    for (name, f) in ["upper", "lower"].iter().zip(kw.measure(&b.x0, &d, 0.04)) {
        let f = f.unwrap_or_else(|| panic!("{name}: no crack"));
        println!("{name}: {f:?}");
        assert!(f.reach > 0.035, "{name}: crack too short ({} m)", f.reach);
        assert!(
            f.angle_deg >= 65.0 && f.angle_deg <= 72.0,
            "{name}: angle {}",
            f.angle_deg
        );
    }
}

/// Brittle hollow cylinder (r 7–10 cm, σ_cr 3 GPa) at Δx = 2 mm under a 2 GPa internal
/// pulse (rise 5 µs, 60 µs long), through the node's `pressure_pulse` parameter: the first
/// broken bonds lie within one horizon of the inner face, and after 150 µs the ring is in at
/// least 2 fragments of ≥ 20 particles.
#[test]
fn hollow_cylinder_cracks_from_inside_and_fragments() {
    let c = HollowCylinder {
        dx: 2e-3,
        ..Default::default()
    };
    let (s, r) = match c.run(150, 1e-6, 20, None) {
        Ok(x) => x,
        Err(e) => panic!("run failed: {e}"),
    };
    let (t, radii) = r
        .first_break
        .clone()
        .unwrap_or_else(|| panic!("no bond broke"));
    let rmax = radii.iter().cloned().fold(0.0, f64::max);
    println!(
        "{} particles; first break by {:.1} µs at {} particles, r ≤ {:.1} mm; fragments {:?}, debris {}",
        s.body.len(),
        t * 1e6,
        radii.len(),
        rmax * 1e3,
        r.fragments,
        r.debris
    );
    let delta = 3.015 * c.dx;
    assert!(rmax <= 0.07 + delta, "first damage at r = {rmax}");
    assert!(r.fragments.len() >= 2, "fragments: {:?}", r.fragments);
    // Fragments separate: most of the mass is in fragments, not dust ...
    let in_frag: usize = r.fragments.iter().sum();
    assert!(in_frag > s.body.len() / 2);
    // ... every fragment flies outward, and every pair moves apart: with centroids c and
    // mean velocities v (volume-weighted), c·v > 0 and (c_a − c_b)·(v_a − v_b) > 0.
    let mut s = s;
    let _ = s.body.damage(); // brings the model's bond damage into `bonds`
    let b = &s.body;
    let (label, sizes) = components(&b.bonds, &b.bonds.intact);
    let mut frags: Vec<([f64; 2], [f64; 2])> = Vec::new();
    for (l, &size) in sizes.iter().enumerate() {
        if size < 20 {
            continue;
        }
        let (mut c, mut v, mut w) = ([0.0; 2], [0.0; 2], 0.0);
        for i in (0..b.len()).filter(|&i| label[i] as usize == l) {
            for d in 0..2 {
                c[d] += b.vol[i] * b.pos[i][d];
                v[d] += b.vol[i] * b.vel[i][d];
            }
            w += b.vol[i];
        }
        frags.push((c.map(|x| x / w), v.map(|x| x / w)));
    }
    assert_eq!(frags.len(), r.fragments.len());
    for (a, (ca, va)) in frags.iter().enumerate() {
        assert!(
            ca[0] * va[0] + ca[1] * va[1] > 0.0,
            "fragment {a} moves inward"
        );
        for (cb, vb) in &frags[a + 1..] {
            let sep = (ca[0] - cb[0]) * (va[0] - vb[0]) + (ca[1] - cb[1]) * (va[1] - vb[1]);
            assert!(sep > 0.0, "two fragments approach each other");
        }
    }
}
