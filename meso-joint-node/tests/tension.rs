//! Must-show 3: uniaxial tension of a bar follows the J2 kinematic-hardening law within 2 %
//! before necking. The material is seed 004 §4.2's (E 210 GPa, σy 0.2 GPa, E_t 20 GPa): with
//! §4.1's E_t = 1 GPa < σy, Considère's criterion (dσ/dε = σ) puts necking at yield, so
//! there would be no hardening range to compare. Bond failure (eq. 15–17) starts when the
//! plastic strain reaches ε_crit, and never under compression.

#![allow(clippy::needless_range_loop)]

use mechanics::j2::J2Material;
use mechanics::tensor::{self, vec3};
use meso_joint_node::config::Smoothing;
use meso_joint_node::geometry::block;
use meso_joint_node::model::{Model, ModelParams};

pub(crate) const E: f64 = 210e9;
pub(crate) const SY: f64 = 0.2e9;
pub(crate) const ET: f64 = 20e9;
pub(crate) const L: f64 = 8e-3;

fn bar(eps_crit: f64, v_end: f64) -> Model {
    bar_r(eps_crit, v_end, 2000)
}

fn bar_r(eps_crit: f64, v_end: f64, reanchor_every: u64) -> Model {
    let h = 0.5e-3;
    let s = block([0.0; 3], [L, 3e-3, 3e-3], h);
    let p = ModelParams {
        blast: None,
        material: J2Material {
            young: E,
            poisson: 0.3,
            yield_stress: SY,
            iso_hardening: 0.0,
            kin_hardening: E * ET / (E - ET),
        },
        density: 7850.0,
        spacing: h,
        support: 2.0 * h,
        eps_crit,
        e_crit: 1.0,
        reanchor_every,
        smoothing: Smoothing::Consistent,
        cfl: 0.4,
        bearing: None,
    };
    let mut m = Model::new(p, s.x, s.vol, s.part, &s.rigid_parts).unwrap();
    // Grips two particle layers deep: with one layer, direct nodal integration lets the odd
    // and even particle layers decouple (each held at one end only).
    m.add_velocity_bc("left", [-v_end, 0.0, 0.0], 2e-5, |x| x[0] < 2.0 * h);
    m.add_velocity_bc("right", [v_end, 0.0, 0.0], 2e-5, |x| x[0] > L - 2.0 * h);
    m.initial_forces();
    m
}

/// Mean axial log strain and true axial stress over the central half of the bar; the stress
/// is taken relative to the mean lateral stress, σ_xx − (σ_yy + σ_zz)/2 (J2 is pressure
/// insensitive, and the DNI surface leaves a small lateral stress in a 6-particle section).
fn gauge(m: &Model) -> (f64, f64, f64) {
    let (mut e, mut s, mut ep, mut n) = (0.0, 0.0, 0.0, 0.0);
    for i in 0..m.len() {
        if (m.x0[i][0] - 0.5 * L).abs() < 0.25 * L {
            let f = tensor::rows(&(tensor::mat(&m.fhat[i]) * tensor::mat(&m.ftot_a[i])));
            e += f[0][0].ln();
            let st = m.mat[i].stress();
            s += st[0] - 0.5 * (st[1] + st[2]);
            ep += m.mat[i].eq_plastic_strain();
            n += 1.0;
        }
    }
    (e / n, s / n, ep / n)
}

/// The J2 law in uniaxial stress: E ε, then σy + E_t (ε − σy/E).
pub(crate) fn j2_uniaxial(eps: f64) -> f64 {
    let ey = SY / E;
    if eps <= ey {
        E * eps
    } else {
        SY + ET * (eps - ey)
    }
}

#[test]
fn uniaxial_tension_follows_the_kinematic_hardening_law() {
    tension_run(2000);
}

/// Re-anchoring the adaptive Lagrangian kernel (eq. 12–14) every 25 steps must not disturb
/// the curve either (it did, by up to 19 %, with the affine kernel argument `F_J⁻¹ d`).
#[test]
fn uniaxial_tension_with_frequent_reanchoring() {
    tension_run(25);
}

fn tension_run(reanchor_every: u64) {
    let mut m = bar_r(10.0, 1.0, reanchor_every);
    let dt = m.stable_dt();
    let mut worst: f64 = 0.0;
    let mut worst_at = 0.0;
    let mut samples = 0;
    let mut last = (0.0, 0.0, 0.0);
    let mut k = 0;
    while last.0 < 0.02 && k < 20000 {
        m.step(dt).unwrap();
        k += 1;
        last = gauge(&m);
        if k % 500 == 0 {
            eprintln!(
                "step {k} t {:.3e} gauge ε {:.5} σ {:.4e} ε̄ᵖ {:.4}",
                m.time, last.0, last.1, last.2
            );
        }
        let (eps, sig, _) = last;
        if eps > 0.004 {
            let exact = j2_uniaxial(eps);
            let e = (sig - exact).abs() / exact;
            if e > worst {
                worst = e;
                worst_at = eps;
            }
            samples += 1;
        }
    }
    eprintln!(
        "tension (re-anchor every {reanchor_every}): {samples} samples to ε = {:.4}, worst |σ − σ_J2|/σ_J2 = {:.3} % at ε = {worst_at:.4}, mean ε̄ᵖ = {:.4} (1-D law {:.4}), KE/IE = {:.2e}",
        last.0,
        100.0 * worst,
        last.2,
        last.0 - j2_uniaxial(last.0) / E,
        m.kinetic_energy() / m.internal_energy()
    );
    // The run must reach the end strain and compare the law along the way (about 1,490
    // samples past ε = 0.004 were measured): an error over no sample would be 0.
    assert!(last.0 >= 0.02, "the run stopped at ε = {} < 0.02", last.0);
    assert!(samples >= 1000, "only {samples} samples past ε = 0.004");
    // The bound: 2 % (measured 0.17 % re-anchoring at step 2000 and 0.03 % every 25
    // steps; before the material-distance kernel of shape.rs, 4.4 % and 19 %).
    assert!(
        worst < 0.02,
        "stress–strain off the J2 law by {:.2} %",
        100.0 * worst
    );
    assert!(m.broken_bonds == 0);
}

#[test]
fn failure_starts_at_eps_crit_in_tension_and_never_in_compression() {
    let eps_crit = 0.01;
    // Tension: record the pair-averaged plastic strain when the first bond breaks.
    let mut m = bar(eps_crit, 2.0);
    let dt = m.stable_dt();
    // Largest pair-averaged plastic strain over intact bonds in tension (eq. 15, 17).
    let pair_max = |m: &Model| -> f64 {
        let mut e: f64 = 0.0;
        for p in 0..m.rows.cols.len() {
            let (i, j) = (m.rows.row_of[p] as usize, m.rows.cols[p] as usize);
            let x = (vec3(&m.x[i]) - vec3(&m.x[j])).norm();
            if i != j && m.rows.alive[p] && x > m.rows.len0[p] {
                e = e.max(0.5 * (m.mat[i].eq_plastic_strain() + m.mat[j].eq_plastic_strain()));
            }
        }
        e
    };
    let mut before = 0.0;
    for _ in 0..20000 {
        before = pair_max(&m);
        m.step(dt).unwrap();
        if m.broken_bonds > 0 {
            break;
        }
    }
    assert!(m.broken_bonds > 0, "no bond broke");
    // The per-part counts kept as bonds break are the bonds' own count (the joint report's).
    assert_eq!(m.broken_by_part, m.count_broken_by_part());
    let kept: u64 = m.broken_by_part.iter().map(|n| n[0] + n[1]).sum();
    assert_eq!(kept, m.broken_bonds as u64);
    eprintln!(
        "first failure: pair-averaged ε̄ᵖ of stretched bonds before the step {before:.5} (ε_crit {eps_crit}), {} bonds broke",
        m.broken_bonds
    );
    // No bond broke while every stretched pair was below ε_crit, and the first break came
    // in the step the pair average crossed it (its increment per step is < 1 % of ε_crit).
    assert!(
        before < eps_crit && before > 0.99 * eps_crit,
        "failure not at ε_crit: {before}"
    );

    // Compression to several times ε_crit: no bond may break while compressed (eq. 17 needs
    // e_IJ > e_crit). Checked for every bond in the step it breaks.
    let mut c = bar(eps_crit, -1.0);
    let mut peak: f64 = 0.0;
    let mut alive = c.rows.alive.clone();
    let mut broke_compressed = 0;
    let mut broke_axial = 0;
    for _ in 0..3000 {
        c.step(dt).unwrap();
        for p in 0..alive.len() {
            if alive[p] && !c.rows.alive[p] {
                let (i, j) = (c.rows.row_of[p] as usize, c.rows.cols[p] as usize);
                let e = (vec3(&c.x[i]) - vec3(&c.x[j])).norm() / c.rows.len0[p];
                if e <= c.p.e_crit {
                    broke_compressed += 1;
                }
                if (c.x0[j][0] - c.x0[i][0]).abs() > 0.9 * c.rows.len0[p] {
                    broke_axial += 1;
                }
                alive[p] = false;
            }
        }
        peak = c
            .mat
            .iter()
            .map(|s| s.eq_plastic_strain())
            .fold(peak, f64::max);
        if peak > 3.0 * eps_crit {
            break;
        }
    }
    // Most bonds along the load axis stay compressed (e < 1) and never break. Lateral bonds
    // are stretched by the Poisson bulge and fail by eq. 17; once the corner particles have
    // lost their lateral bonds, the loose corner columns wobble and a few axial bonds there
    // are locally stretched (e ≈ 1 + 1e-5) and may break too: that is tension, and counted.
    let mut axial_broken = 0;
    let mut axial_total = 0;
    for p in 0..c.rows.cols.len() {
        let (i, j) = (c.rows.row_of[p] as usize, c.rows.cols[p] as usize);
        if i == j {
            continue;
        }
        let dx = (c.x0[j][0] - c.x0[i][0]).abs();
        if dx > 0.9 * c.rows.len0[p] {
            axial_total += 1;
            if !c.rows.alive[p] {
                axial_broken += 1;
            }
        }
    }
    eprintln!(
        "compression: max ε̄ᵖ {peak:.4}, axial bonds broken {axial_broken}/{axial_total} ({broke_axial} counted at breaking, all stretched), broken while compressed {broke_compressed}, all broken {}",
        c.broken_bonds
    );
    assert!(
        peak > 2.0 * eps_crit,
        "compression did not plastify enough: {peak}"
    );
    assert!(axial_total > 0);
    assert_eq!(broke_compressed, 0, "bonds broke under compression");
    assert!(
        axial_broken * 50 < axial_total,
        "axial bonds broke: {axial_broken}/{axial_total}"
    );
}
