//! GPU path of `pd-bond` against the CPU path: the free-free bar of
//! pd_verification.rs's long-wave test (plane-stress strip, fundamental mode v = V cos(πx/L)),
//! advanced by `Body::step` on the CPU and by `GpuBondBody::steps` on the device with the
//! same dt; displacements, velocities and forces must agree within 1e-10 of their largest
//! magnitude (f64 kernels). A second run with a critical stretch small enough for bonds to
//! break checks that the same bonds break. The CPU path is verified against √(E/ρ) by
//! pd_verification.rs. Without an adapter the tests print why they were skipped and pass.

use mechanics::gpu::GpuContext;
use solid_node::pd::bond::BondModel;
use solid_node::pd::family::Bonds;
use solid_node::pd::geometry::{Shape, lattice};
use solid_node::pd::gpu::GpuBondBody;
use solid_node::pd::integrate::Body;
use solid_node::pd::model::{Dim, Kinematics};
use std::sync::Arc;
use std::time::Instant;

fn context(test: &str) -> Option<Arc<GpuContext>> {
    mechanics::gpu::f64_context_or_skip(test).map(Arc::new)
}

/// Plane-stress steel strip nx × ny (Δx 1 mm, δ 3.015 Δx) in its fundamental mode.
fn bar(nx: usize, ny: usize, amp: f64, s0: Option<f64>) -> (Body, BondModel) {
    let (e, rho, dx) = (200e9, 7850.0, 1e-3);
    let x0 = lattice(
        &[Shape::Box {
            min: [0.0; 3],
            max: [nx as f64 * dx, ny as f64 * dx, dx],
        }],
        &[],
        dx,
        false,
    );
    let vol = vec![dx * dx * dx; x0.len()];
    let delta = 3.015 * dx;
    let bonds = Bonds::build(&x0, delta);
    let v = vec![[0.0; 3]; x0.len()];
    let k = Kinematics {
        x0: &x0,
        pos: &x0,
        disp: &displacements(&x0, &x0),
        vel: &v,
        vol: &vol,
    };
    let m = BondModel::new(Dim::PlaneStress, e, delta, dx, s0, &k, &bonds);
    let mut b = Body::new(
        Dim::PlaneStress,
        dx,
        delta,
        rho,
        x0,
        vol,
        bonds,
        Box::new(m.clone()),
    );
    let length = nx as f64 * dx;
    for i in 0..b.len() {
        b.vel[i][0] = amp * (std::f64::consts::PI * b.x0[i][0] / length).cos();
    }
    (b, m)
}

fn max_rel(a: &[[f64; 3]], b: &[[f64; 3]], x0: Option<&[[f64; 3]]>) -> f64 {
    let val = |v: &[[f64; 3]], i: usize, d: usize| v[i][d] - x0.map_or(0.0, |x| x[i][d]);
    let mut scale = 0.0_f64;
    let mut diff = 0.0_f64;
    for i in 0..a.len() {
        for d in 0..3 {
            scale = scale.max(val(b, i, d).abs());
            let e = (val(a, i, d) - val(b, i, d)).abs();
            diff = if e.is_nan() {
                f64::INFINITY
            } else {
                diff.max(e)
            };
        }
    }
    if scale > 0.0 { diff / scale } else { diff }
}

/// Runs `steps` on both paths; returns (rel. displacement, velocity, force differences,
/// broken bonds CPU, broken bonds GPU).
fn compare(
    ctx: Arc<GpuContext>,
    nx: usize,
    ny: usize,
    amp: f64,
    s0: Option<f64>,
    steps: u64,
) -> [f64; 5] {
    let (mut cpu, model) = bar(nx, ny, amp, s0);
    let dt = 0.5 * cpu.stable_dt();
    let mut gpu = GpuBondBody::new(ctx, &cpu, &model, s0).expect("GPU body");
    let t = Instant::now();
    for _ in 0..steps {
        cpu.step(dt);
    }
    let t_cpu = t.elapsed().as_secs_f64();
    let t = Instant::now();
    gpu.steps(steps, dt).expect("GPU steps");
    let (mut out, _) = bar(nx, ny, amp, s0);
    let mut coef = vec![0.0; cpu.bonds.len()];
    gpu.download(&mut out, &mut coef).expect("download");
    let t_gpu = t.elapsed().as_secs_f64();
    let bu = (cpu.bonds.len() as u64 * steps) as f64;
    println!(
        "  {} particles, {} bonds, {steps} steps: CPU {t_cpu:.3} s ({:.3e} bond-updates/s), GPU {t_gpu:.3} s ({:.3e} bond-updates/s)",
        cpu.len(),
        cpu.bonds.len(),
        bu / t_cpu,
        bu / t_gpu
    );
    assert_eq!(out.time, cpu.time);
    cpu.model.sync_bonds(&mut cpu.bonds);
    let broken_cpu = cpu.bonds.intact.iter().filter(|&&w| w == 0.0).count();
    let broken_gpu = coef.iter().filter(|&&c| c == 0.0).count();
    // the same bonds, not only as many
    let same = cpu
        .bonds
        .intact
        .iter()
        .zip(&coef)
        .all(|(&w, &c)| (w == 0.0) == (c == 0.0));
    assert!(same, "different bonds broke");
    // the energy the broken bonds released, booked per particle on both paths
    let released: f64 = gpu.released().expect("released").iter().sum();
    let e = (released - cpu.model.fracture_energy()).abs();
    assert!(
        e <= 1e-10 * cpu.model.fracture_energy().abs(),
        "released energy: GPU {released:e}, CPU {:e}",
        cpu.model.fracture_energy()
    );
    if broken_cpu > 0 {
        assert!(released > 0.0);
        println!(
            "  released energy: GPU {released:.6e} J, CPU {:.6e} J",
            cpu.model.fracture_energy()
        );
    }
    // the packed intact flags are the coefficients' (zero = broken)
    let bits = gpu.intact_bits().expect("intact bits");
    assert!((0..coef.len()).all(|b| solid_node::pd::gpu::bit(&bits, b) == (coef[b] != 0.0)));
    [
        max_rel(&out.pos, &cpu.pos, Some(&cpu.x0)),
        max_rel(&out.vel, &cpu.vel, None),
        max_rel(&out.force, &cpu.force, None),
        broken_cpu as f64,
        broken_gpu as f64,
    ]
}

#[test]
fn bar_wave_gpu_matches_cpu() {
    let Some(ctx) = context("pd-bond bar 120x8") else {
        return;
    };
    // about a quarter of the fundamental period (T/2 = L/c ≈ 24 µs; dt ≈ 0.08 µs)
    let r = compare(ctx, 120, 8, 0.01, None, 150);
    println!(
        "pd-bond bar: max relative difference GPU vs CPU: displacement {:.3e}, velocity {:.3e}, force {:.3e}",
        r[0], r[1], r[2]
    );
    assert!(r[0] <= 1e-10 && r[1] <= 1e-10 && r[2] <= 1e-10, "{r:?}");
}

#[test]
fn breaking_bonds_match_cpu() {
    let Some(ctx) = context("pd-bond bar with s0") else {
        return;
    };
    // peak modal strain ≈ V/c = 2/5048 ≈ 4e-4 at the centre against s0 = 2e-4: bonds in
    // the middle break (about a quarter of all), those near the free ends stay intact
    let r = compare(ctx, 60, 6, 2.0, Some(2e-4), 300);
    println!(
        "pd-bond breaking: differences {:.3e} {:.3e} {:.3e}; broken bonds CPU {}, GPU {}",
        r[0], r[1], r[2], r[3], r[4]
    );
    assert!(r[3] > 0.0, "the case must break bonds");
    assert!(
        r[3] < 0.5 * 7740.0,
        "only the middle should break: {}",
        r[3]
    );
    assert_eq!(r[3], r[4]);
    assert!(r[0] <= 1e-10 && r[1] <= 1e-10, "{r:?}");
}

/// u = x − X per particle (the models read displacements; see `Kinematics::disp`).
fn displacements(pos: &[[f64; 3]], x0: &[[f64; 3]]) -> Vec<[f64; 3]> {
    pos.iter()
        .zip(x0)
        .map(|(p, q)| std::array::from_fn(|d| p[d] - q[d]))
        .collect()
}
