//! Verification of pd-rk-ba (seed 000 App. A): RK gradient patch tests of order 1
//! and 2 (A.1–A.8) on regular and jittered particle sets, interior and boundary; long-wave
//! speed of a free bar against √(E/ρ); linear momentum of a free, fracturing body; thread-
//! count independence; selection by name through the node factory.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use mechanics::damage::{CriticalStretch, NoDamage};
use mechanics::j2::J2Material;
use solid_node::pd::family::Bonds;
use solid_node::pd::geometry::{Shape, lattice};
use solid_node::pd::integrate::Body;
use solid_node::pd::model::{Dim, PdModel};
use solid_node::pd::rk_ba::{RkBa, rk_gradient};

fn block(n: [usize; 3], dx: f64, three_d: bool) -> Vec<[f64; 3]> {
    lattice(
        &[Shape::Box {
            min: [0.0; 3],
            max: [n[0] as f64 * dx, n[1] as f64 * dx, n[2] as f64 * dx],
        }],
        &[],
        dx,
        three_d,
    )
}

fn steel() -> J2Material {
    J2Material {
        young: 200e9,
        poisson: 0.3,
        yield_stress: f64::MAX,
        iso_hardening: 0.0,
        kin_hardening: 0.0,
    }
}

/// Deterministic pseudo-random numbers in [−½, ½).
fn lcg(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

/// Must-show 1 for pd-rk-ba: the RK gradient of a linear field is exact (order 1 and 2), and
/// of a quadratic field exact for order 2, at every particle — interior and boundary — on a
/// lattice and on a jittered particle set, to 1e-12 relative to the gradient's size.
#[test]
fn rk_gradient_patch_tests() {
    let dx = 1e-3;
    let h: [[f64; 3]; 3] = [[0.3, -0.2, 0.15], [0.1, 0.25, -0.4], [-0.05, 0.35, 0.2]];
    // Quadratic field u_a = Σ_b H_ab x_b + Σ_bc Q_abc x_b x_c (x in mm for O(1) terms).
    let q = |a: usize, b: usize, c: usize| 0.1 * ((a + 2 * b + 3 * c) as f64 - 4.0);
    for three_d in [false, true] {
        let dim = if three_d {
            Dim::Three
        } else {
            Dim::PlaneStrain
        };
        let dims = if three_d { 3 } else { 2 };
        let n = if three_d { [7, 6, 6] } else { [14, 12, 1] };
        for jitter in [0.0, 0.2] {
            let mut st = 7u64;
            let x0: Vec<[f64; 3]> = block(n, dx, three_d)
                .into_iter()
                .map(|p| {
                    std::array::from_fn(|d| {
                        if d < dims {
                            p[d] + jitter * dx * lcg(&mut st)
                        } else {
                            p[d]
                        }
                    })
                })
                .collect();
            let vol = vec![dx.powi(dims as i32); x0.len()];
            for order in [1usize, 2] {
                let delta = (order as f64 + 1.015) * dx;
                let bonds = Bonds::build(&x0, delta);
                let s = 1.0 / dx;
                let lin: Vec<[f64; 3]> = x0
                    .iter()
                    .map(|p| std::array::from_fn(|a| (0..dims).map(|b| h[a][b] * p[b]).sum()))
                    .collect();
                let quad: Vec<[f64; 3]> = x0
                    .iter()
                    .map(|p| {
                        std::array::from_fn(|a| {
                            let mut v = 0.0;
                            for b in 0..dims {
                                v += h[a][b] * p[b];
                                for c in 0..dims {
                                    v += q(a, b, c) * p[b] * p[c] * s;
                                }
                            }
                            v
                        })
                    })
                    .collect();
                let gl = rk_gradient(dim, order, delta, &x0, &vol, &bonds, &lin);
                let mut worst_l: f64 = 0.0;
                for g in &gl {
                    for a in 0..3 {
                        for b in 0..dims {
                            worst_l = worst_l.max((g[a][b] - h[a][b]).abs());
                        }
                    }
                }
                let gq = rk_gradient(dim, order, delta, &x0, &vol, &bonds, &quad);
                let mut worst_q: f64 = 0.0;
                for (i, g) in gq.iter().enumerate() {
                    let p = x0[i];
                    for a in 0..3 {
                        for b in 0..dims {
                            let mut exact = h[a][b];
                            for c in 0..dims {
                                exact += (q(a, b, c) + q(a, c, b)) * p[c] * s;
                            }
                            worst_q = worst_q.max((g[a][b] - exact).abs());
                        }
                    }
                }
                println!(
                    "{}-D jitter {jitter} order {order}: linear error {worst_l:.2e}, quadratic error {worst_q:.2e}",
                    dims
                );
                assert!(worst_l < 1e-12, "linear field, order {order}: {worst_l:e}");
                if order == 2 {
                    assert!(worst_q < 1e-12, "quadratic field, order 2: {worst_q:e}");
                } else {
                    // Order 1 is not exact for a quadratic field (shows the test can fail).
                    assert!(worst_q > 1e-6, "order 1 should miss the quadratic term");
                }
            }
        }
    }
}

/// A block of pd-rk-ba without damage, with or without the bond-associative stabilization.
fn rk_body_ba(n: [usize; 3], order: usize, ba: bool) -> Body {
    let dx = 1e-3;
    let x0 = block(n, dx, true);
    let vol = vec![dx * dx * dx; x0.len()];
    let delta = (order as f64 + 1.015) * dx;
    let bonds = Bonds::build(&x0, delta);
    let mut m = RkBa::new(Dim::Three, order, delta, steel(), NoDamage, &bonds);
    m.set_bond_associative(ba);
    Body::new(Dim::Three, dx, delta, 7850.0, x0, vol, bonds, Box::new(m))
}

fn rk_body(n: [usize; 3], order: usize, s0: Option<f64>) -> Body {
    let dx = 1e-3;
    let x0 = block(n, dx, true);
    let vol = vec![dx * dx * dx; x0.len()];
    let delta = (order as f64 + 1.015) * dx;
    let bonds = Bonds::build(&x0, delta);
    let m: Box<dyn PdModel> = match s0 {
        Some(s) => Box::new(RkBa::new(
            Dim::Three,
            order,
            delta,
            steel(),
            CriticalStretch {
                critical_stretch: s,
            },
            &bonds,
        )),
        None => Box::new(RkBa::new(
            Dim::Three,
            order,
            delta,
            steel(),
            NoDamage,
            &bonds,
        )),
    };
    Body::new(Dim::Three, dx, delta, 7850.0, x0, vol, bonds, m)
}

/// Must-show 2 for pd-rk-ba: the fundamental mode of a free 3-D bar (120 × 4 × 4 particles)
/// gives the long-wave speed √(E/ρ) within 1 % (half period = L/c), at RK order 1 and 2.
#[test]
fn rk_ba_long_wave_speed() {
    let (e, rho): (f64, f64) = (200e9, 7850.0);
    let c_exact = (e / rho).sqrt();
    let len = 120.0 * 1e-3;
    for order in [1, 2] {
        let mut b = rk_body([120, 4, 4], order, None);
        let dt = 0.5 * b.stable_dt();
        let amp = 0.01;
        let x0 = b.x0.clone();
        let shape = |x: f64| (std::f64::consts::PI * x / len).cos();
        for (v, q) in b.vel.iter_mut().zip(&x0) {
            v[0] = amp * shape(q[0]);
        }
        let modal = |b: &Body| -> f64 {
            (0..b.len())
                .map(|i| (b.pos[i][0] - b.x0[i][0]) * shape(b.x0[i][0]))
                .sum()
        };
        let (mut prev, mut t_prev) = (0.0, 0.0);
        let c = loop {
            b.step(dt);
            let m = modal(&b);
            if prev > 0.0 && m <= 0.0 {
                let tz = t_prev + dt * prev / (prev - m);
                break len / tz;
            }
            assert!(m.is_finite() && b.steps < 5000, "no zero crossing: {m}");
            prev = m;
            t_prev = b.time;
        };
        println!(
            "pd-rk-ba 3-D order {order}: c = {c:.2}, √(E/ρ) = {c_exact:.2}, error {:.3} %",
            100.0 * (c - c_exact) / c_exact
        );
        assert!(
            (c - c_exact).abs() / c_exact < 0.01,
            "order {order}: c = {c}"
        );
    }
}

fn randomize(b: &mut Body, amp: f64) {
    let mut st: u64 = 12345;
    for v in b.vel.iter_mut() {
        for c in v.iter_mut() {
            *c = amp * lcg(&mut st);
        }
    }
}

/// Gives `b` random velocities (up to ±30 m/s), takes 150 steps at half the stable step and
/// returns the largest change of a momentum component relative to Σ m |v|.
fn random_momentum_drift(b: &mut Body) -> f64 {
    randomize(b, 60.0);
    let p0 = b.momentum();
    let scale: f64 = (0..b.len())
        .map(|i| b.density * b.vol[i] * b.vel[i].iter().map(|c| c.abs()).sum::<f64>())
        .sum();
    let dt = 0.5 * b.stable_dt();
    for _ in 0..150 {
        b.step(dt);
    }
    let p1 = b.momentum();
    (0..3).map(|d| (p1[d] - p0[d]).abs()).fold(0.0, f64::max) / scale
}

/// Must-show 4 for pd-rk-ba: linear momentum of a free body with random velocities is
/// conserved to round-off while bonds break (order 1 and 2).
#[test]
fn rk_ba_momentum_conserved_in_free_body() {
    for order in [1usize, 2] {
        let mut b = rk_body([8, 7, 6], order, Some(0.002));
        let err = random_momentum_drift(&mut b);
        let broken = b.damage().iter().filter(|&&d| d > 0.0).count();
        println!("order {order}: relative momentum drift {err:e}, {broken} damaged particles");
        assert!(broken > 0, "the test must break bonds");
        // Round-off: 150 steps of sums over ~100 bonds per particle. Measured 1.6e-14
        // (order 1) and 1.13e-13 (order 2) since positions are x = X + u (session 4); the
        // earlier x += v dt rounding gave < 1e-13. 150 steps × ~1e-15 per step = 1.5e-13.
        assert!(err < 2e-13, "order {order}: {err:e}");
        assert!(b.vel.iter().all(|v| v.iter().all(|c| c.is_finite())));
    }
}

/// Stretches block `b` at a uniform rate (every particle held at v = (ε̇ x, 0, 0)) for five
/// steps and returns, over the interior particles (more than 3.5 spacings from the faces),
/// how many there are, the largest stress error relative to the classical σ = C : D t
/// (elastic, small strain) and the largest force relative to σ/Δx (a stress difference
/// across one spacing).
fn uniform_rate(mut b: Body) -> (usize, f64, f64) {
    let dx = 1e-3;
    let rate = 10.0; // 1/s
    let x0 = b.x0.clone();
    for (v, p) in b.vel.iter_mut().zip(&x0) {
        *v = [rate * p[0], 0.0, 0.0];
    }
    b.prescribed.iter_mut().for_each(|p| *p = 1);
    b.vpres = b.vel.clone();
    let dt = 1e-8;
    for _ in 0..5 {
        b.step(dt);
    }
    let m = steel();
    let (e, nu) = (m.young, m.poisson);
    let lam = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    let mu = e / (2.0 * (1.0 + nu));
    let eps = rate * 5.0 * dt;
    let (s_xx, s_yy) = ((lam + 2.0 * mu) * eps, lam * eps);
    let stress = b.model.stress().unwrap_or_default();
    let interior: Vec<usize> = (0..b.len())
        .filter(|&i| x0[i].iter().all(|&c| c > 3.5 * dx && c < 5.5 * dx))
        .collect();
    let (mut worst, mut fmax) = (0.0f64, 0.0f64);
    for &i in &interior {
        worst = worst.max((stress[i][0] - s_xx).abs() / s_xx);
        worst = worst.max((stress[i][1] - s_yy).abs() / s_xx);
        fmax = fmax.max(b.force[i].iter().map(|f| f.abs()).fold(0.0, f64::max));
    }
    (interior.len(), worst, fmax * dx / s_xx)
}

/// A homogeneous deformation rate in the bulk produces the classical stress: stretching a
/// block at a uniform rate gives, at interior bonds, σ = C : D t (elastic, small strain), and
/// no force on interior particles.
#[test]
fn rk_ba_uniform_rate_gives_classical_stress_and_no_interior_force() {
    let (n, worst, force) = uniform_rate(rk_body([9, 9, 9], 2, None));
    println!(
        "uniform rate: {n} interior particles, stress error {worst:.2e} (relative, small-strain C:ε), interior force {force:.2e} of σ/Δx"
    );
    assert!(n > 0);
    assert!(worst < 1e-6, "{worst:e}");
    assert!(force < 1e-9, "{force:e}");
}

/// Without the bond-associative stabilization the model is still consistent: a uniform
/// deformation rate gives the classical stress at the particles and no interior force, and
/// a free body with random velocities keeps its momentum to round-off (order 1 and 2).
#[test]
fn without_ba_a_uniform_rate_gives_classical_stress_and_momentum_is_kept() {
    for order in [1usize, 2] {
        let (n, worst, force) = uniform_rate(rk_body_ba([9, 9, 9], order, false));
        println!(
            "without BA, order {order}: {n} interior particles, stress error {worst:.2e}, interior force {force:.2e} of σ/Δx"
        );
        assert!(n > 0);
        assert!(worst < 1e-6, "order {order}: {worst:e}");
        assert!(force < 1e-9, "order {order}: {force:e}");

        let err = random_momentum_drift(&mut rk_body_ba([8, 7, 6], order, false));
        println!("without BA, order {order}: relative momentum drift {err:e}");
        assert!(err < 2e-13, "order {order}: {err:e}");
    }
}

/// The zero-energy mode that the bond-associative stabilization removes: velocities that
/// alternate in sign from one lattice plane to the next, v = a (−1)^k e_x, have a zero point
/// gradient at every particle whose family is symmetric (the odd neighbours cancel in
/// pairs), so without BA the interior particles feel no force at all; with BA the bond
/// gradient v_ij x_ijᵀ/|x_ij|² sees the mode and resists it (f · v < 0 at every interior
/// particle).
#[test]
fn the_alternating_mode_has_no_stiffness_without_ba_and_is_resisted_with_it() {
    let dx = 1e-3;
    let n = [14usize, 14, 14];
    for order in [1usize, 2] {
        let delta = (order as f64 + 1.015) * dx;
        let run = |ba: bool| {
            let mut b = rk_body_ba(n, order, ba);
            let x0 = b.x0.clone();
            for (v, p) in b.vel.iter_mut().zip(&x0) {
                let k = (p[0] / dx).floor() as i64;
                *v = [if k % 2 == 0 { 1.0 } else { -1.0 }, 0.0, 0.0];
            }
            b.step(1e-9);
            // interior: the whole family (and its families) away from the surface
            let lo = 2.0 * delta;
            let hi = n[0] as f64 * dx - 2.0 * delta;
            let inner: Vec<usize> = (0..b.len())
                .filter(|&i| x0[i].iter().all(|&c| c > lo && c < hi))
                .collect();
            let power: Vec<f64> = inner
                .iter()
                .map(|&i| (0..3).map(|d| b.force[i][d] * b.vel[i][d]).sum())
                .collect();
            let fmax = inner
                .iter()
                .map(|&i| b.force[i].iter().map(|f| f.abs()).fold(0.0, f64::max))
                .fold(0.0, f64::max);
            (inner.len(), power, fmax)
        };
        let (n_ba, power_ba, f_ba) = run(true);
        let (n_point, _, f_point) = run(false);
        println!(
            "order {order}: {n_ba} interior particles; largest interior force with BA {f_ba:.3e} N, without {f_point:.3e} N"
        );
        assert_eq!(n_ba, n_point);
        assert!(n_ba >= 8, "order {order}: only {n_ba} interior particles");
        assert!(
            power_ba.iter().all(|&p| p < 0.0),
            "order {order}: BA does not resist the mode everywhere"
        );
        assert!(
            f_point < 1e-9 * f_ba,
            "order {order}: {f_point:e} vs {f_ba:e}"
        );
    }
}

/// Determinism: bit-identical state for 1 and 2 threads.
#[test]
fn rk_ba_is_thread_count_independent() {
    let run = |threads: usize| {
        let go = || {
            let mut b = rk_body([8, 7, 6], 2, Some(0.002));
            randomize(&mut b, 60.0);
            let dt = 0.5 * b.stable_dt();
            for _ in 0..30 {
                b.step(dt);
            }
            (b.pos.clone(), b.vel.clone())
        };
        match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
            Ok(p) => p.install(go),
            Err(_) => go(),
        }
    };
    assert!(run(1) == run(2), "results differ between 1 and 2 threads");
}

/// The model is chosen by name in the node config; a horizon too small for the order and
/// plane stress are refused with the key named.
#[test]
fn rk_ba_by_name_and_bad_input() {
    let t = |extra: &str| -> toml::Table {
        toml::from_str(&format!(
            r#"
dimension = "3d"
spacing = 1e-3
horizon = 3.015e-3
density = 7850.0
young = 200e9
poisson = 0.3
bodies = [{{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.006, 0.005, 0.005] }}]
{extra}
"#
        ))
        .unwrap_or_default()
    };
    let key = |tab: &toml::Table| match solid_node::pd::factory("pd-rk-ba", tab) {
        Some(Ok(s)) => format!("accepted {}", s.describe().model),
        Some(Err(protocol::SolverError::Config { key, .. })) => key,
        Some(Err(e)) => format!("other: {e}"),
        None => "unknown".into(),
    };
    assert_eq!(key(&t("")), "accepted pd-rk-ba");
    assert_eq!(key(&t("rk_order = 3")), "rk_order");
    assert_eq!(key(&t("rk_condition_floor = 0.01")), "accepted pd-rk-ba");
    for bad in ["0.0", "1.0", "-1e-3", "nan"] {
        assert_eq!(
            key(&t(&format!("rk_condition_floor = {bad}"))),
            "rk_condition_floor",
            "{bad}"
        );
    }
    let mut small = t("rk_order = 2");
    small.insert("horizon".into(), toml::Value::Float(1.2e-3));
    assert_eq!(key(&small), "horizon");
    let mut ps = t("");
    ps.insert(
        "dimension".into(),
        toml::Value::String("plane_stress".into()),
    );
    assert_eq!(key(&ps), "dimension");
    assert_eq!(key(&t("bond_associative = false")), "accepted pd-rk-ba");
    let damaged = "bond_associative = false\ndamage = { kind = \"critical_stretch\", critical_stretch = 0.01 }";
    assert_eq!(key(&t(damaged)), "bond_associative");
    let other = |model: &str| match solid_node::pd::factory(model, &t("bond_associative = true")) {
        Some(Err(protocol::SolverError::Config { key, .. })) => key,
        _ => "accepted".into(),
    };
    assert_eq!(other("pd-correspondence"), "bond_associative");
    assert_eq!(other("pd-bond"), "bond_associative");
    for model in ["pd-correspondence", "pd-bond"] {
        let floor = solid_node::pd::factory(model, &t("rk_condition_floor = 0.01"));
        assert!(
            matches!(floor, Some(Err(protocol::SolverError::Config { ref key, .. })) if key == "rk_condition_floor"),
            "{model}"
        );
    }
}

/// A damaged family keeps the gradient it can support: along a straight crack every
/// particle keeps the quadratic gradient (a half family is as well conditioned as the
/// body's own edge); a particle left with bonds along one line and one off it falls back to
/// the linear gradient (no quadratic field is determined by two directions); one left with
/// bonds along a single line carries none. The counts reach the report.
#[test]
fn a_damaged_family_falls_back_to_the_gradient_it_supports() {
    let dx = 1e-3;
    let n = [14, 12, 1];
    let x0 = block(n, dx, false);
    let vol = vec![dx * dx * dx; x0.len()];
    let delta = 3.015 * dx;
    let mut bonds = Bonds::build(&x0, delta);
    let mut m = RkBa::new(Dim::PlaneStrain, 2, delta, steel(), NoDamage, &bonds);
    let zero = vec![[0.0; 3]; x0.len()];
    let k = solid_node::pd::model::Kinematics {
        x0: &x0,
        pos: &x0,
        disp: &zero,
        vel: &zero,
        vol: &vol,
    };
    assert_eq!(m.singular_particle(&k, &bonds), None);
    let mut f = vec![[0.0; 3]; x0.len()];
    let break_bond = |m: &mut RkBa<NoDamage>, b: usize| {
        m.hist[b].wd = 0.0;
        let t = m.rev[b] as usize;
        m.hist[t].wd = 0.0;
    };
    // A crack along y = 5.5 dx through the whole block (every bond across it broken).
    let yc = 5.5 * dx;
    for i in 0..x0.len() {
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            if (x0[i][1] - yc) * (x0[j][1] - yc) < 0.0 {
                break_bond(&mut m, b);
            }
        }
    }
    m.force_density(&k, &mut bonds, 0.0, &mut f);
    let degree: Vec<u8> = m.point.iter().map(|p| p.degree).collect();
    assert!(
        degree.iter().all(|&d| d == 2),
        "a straight crack reduced {} of {} gradients",
        degree.iter().filter(|&&d| d != 2).count(),
        degree.len()
    );
    assert_eq!(m.reduced_gradients(), (0, 0));
    // The floor is the case's (`rk_condition_floor`): above the share a half family keeps
    // (about 0.87 of its reference determinant), the particles beside the crack drop to the
    // linear gradient, and only they.
    let mut strict = RkBa::new(Dim::PlaneStrain, 2, delta, steel(), NoDamage, &bonds);
    strict.set_condition_floor(0.95);
    for b in 0..m.hist.len() {
        strict.hist[b].wd = m.hist[b].wd;
    }
    strict.force_density(&k, &mut bonds, 0.0, &mut f);
    let reduced: Vec<usize> = (0..x0.len())
        .filter(|&i| strict.point[i].degree != 2)
        .collect();
    println!(
        "floor 0.95: {} of {} gradients reduced to linear",
        reduced.len(),
        x0.len()
    );
    assert!(
        reduced.len() >= 10,
        "a floor of 0.95 reduced only {} gradients",
        reduced.len()
    );
    for &i in &reduced {
        assert_eq!(strict.point[i].degree, 1, "particle {i}");
        assert!(
            (x0[i][1] - yc).abs() < delta,
            "particle {i} at y {} reduced, a horizon or more from the crack",
            x0[i][1]
        );
    }
    // Two interior particles away from the crack (row 9, columns 4 and 10): the first keeps
    // its bonds along x and one to the particle above it; the second only those along x.
    let at = |c: usize, r: usize| {
        x0.iter()
            .position(|p| {
                (p[0] - (c as f64 + 0.5) * dx).abs() < 1e-9
                    && (p[1] - (r as f64 + 0.5) * dx).abs() < 1e-9
            })
            .expect("a lattice particle")
    };
    let (a, c) = (at(4, 9), at(10, 9));
    for (i, keep_above) in [(a, true), (c, false)] {
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            let d = [x0[j][0] - x0[i][0], x0[j][1] - x0[i][1]];
            let on_line = d[1].abs() < 1e-9;
            let above = keep_above && d[0].abs() < 1e-9 && (d[1] - dx).abs() < 1e-9;
            if !(on_line || above) {
                break_bond(&mut m, b);
            }
        }
    }
    m.force_density(&k, &mut bonds, 0.0, &mut f);
    assert_eq!(m.point[a].degree, 1, "bonds along x and one above");
    assert_eq!(m.point[c].degree, 0, "bonds along x only");
    assert_eq!(m.reduced_gradients(), (1, 1));
    let scalars = m.damage_scalars();
    assert_eq!(
        scalars,
        vec![
            ("reduced_gradient_particles", 1.0),
            ("gradient_free_particles", 1.0)
        ]
    );
    // The linear fall-back is the linear RK gradient: exact for a linear field.
    let h = [[0.3, -0.2], [0.1, 0.25]];
    let v: Vec<[f64; 3]> = x0
        .iter()
        .map(|p| {
            [
                h[0][0] * p[0] + h[0][1] * p[1],
                h[1][0] * p[0] + h[1][1] * p[1],
                0.0,
            ]
        })
        .collect();
    let kv = solid_node::pd::model::Kinematics { vel: &v, ..k };
    m.force_density(&kv, &mut bonds, 0.0, &mut f);
    let l = m.point[a].l;
    for r in 0..2 {
        for s in 0..2 {
            assert!(
                (l[r][s] - h[r][s]).abs() < 1e-12,
                "linear gradient at the reduced particle: L[{r}][{s}] = {} against {}",
                l[r][s],
                h[r][s]
            );
        }
    }
}

/// The kernel is evaluated on the current bond, so a bond stretched to the horizon carries no
/// force: two halves of a block pulled apart by more than the horizon are two fragments
/// although no bond between them is damaged; pulled apart by less, they are one.
#[test]
fn halves_pulled_apart_past_the_horizon_are_two_fragments() {
    let dx = 1e-3;
    let x0 = block([12, 6, 1], dx, false);
    let delta = 3.015 * dx;
    let mut bonds = Bonds::build(&x0, delta);
    let m = RkBa::new(Dim::PlaneStrain, 2, delta, steel(), NoDamage, &bonds);
    let split = |gap: f64| -> Vec<[f64; 3]> {
        x0.iter()
            .map(|p| {
                let shift = if p[0] > 6.0 * dx { gap } else { 0.0 };
                [p[0] + shift, p[1], p[2]]
            })
            .collect()
    };
    let count = |bonds: &Bonds| {
        solid_node::pd::fracture::components(bonds, &bonds.intact)
            .1
            .iter()
            .filter(|&&s| s >= 10)
            .count()
    };
    m.fragment_links(&split(0.5 * delta), &mut bonds);
    assert_eq!(count(&bonds), 1, "a gap of half a horizon");
    m.fragment_links(&split(delta), &mut bonds);
    assert_eq!(count(&bonds), 2, "a gap of a horizon");
    // damage is read from the bonds' own state: none broke
    m.sync_bonds(&mut bonds);
    assert!(bonds.intact.iter().all(|&w| w == 1.0));
}
