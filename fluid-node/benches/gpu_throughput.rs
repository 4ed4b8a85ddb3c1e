//! GPU throughput of the fluid step: cell-updates per second (one full SSP-RK3 step
//! of one cell = one update) on the 2-D cylindrical blast — p 10 in r < 0.1, 0.1 outside,
//! ρ 1, γ 1.4, unit square, outflow — at several grid sizes, on the device the environment
//! gives (`WGPU_BACKEND=vulkan` → lavapipe here), next to the CPU path on the same problem
//! at 1 and 2 rayon threads. Each iteration is `STEPS` steps from the same advanced state;
//! the GPU timing includes one control readback per batch (no field readback).
//! The group `fluid_blast_2d_immersed` runs the same blast with an immersed disc of particles
//! at rest (radius 0.15 about (0.7, 0.5), two particles per cell and direction; seed 002 §3):
//! the step plus the immersed kernels (solid-cell fill, moving-wall fluxes, projection,
//! impulses), the cost of the coupling on each path.
//! Run: `WGPU_BACKEND=vulkan cargo bench -p fluid-node --features criterion-bench --bench gpu_throughput`
//! (optional filter, e.g. `-- gpu/256`). Without an adapter only the CPU rows run.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use fluid_node::gpu::GpuEuler;
use fluid_node::model::Fluid;
use fluid_node::{setup, step};
use mechanics::gpu::GpuContext;
use std::sync::Arc;
use std::time::Duration;

const SIZES: [usize; 4] = [64, 128, 256, 512];
const STEPS: u64 = 10;

fn case(n: usize) -> Fluid {
    let text = fluid_node::setup::benchmark_blast_case(n);
    match setup::from_toml_str(&text) {
        Ok(f) => f,
        Err(e) => panic!("benchmark case is invalid: {e}"),
    }
}

fn bench(c: &mut Criterion) {
    let ctx = match GpuContext::new() {
        Ok(c) => {
            println!("GPU: {}", c.describe());
            if let Some(w) = &c.warning {
                println!("warning: {w}");
            }
            Some(Arc::new(c))
        }
        Err(e) => {
            println!("GPU rows skipped: {e}");
            None
        }
    };
    let mut g = c.benchmark_group("fluid_blast_2d");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for n in SIZES {
        let f0 = case(n);
        g.throughput(Throughput::Elements((n * n) as u64 * STEPS));
        if let Some(ctx) = &ctx {
            let mut gpu = match GpuEuler::with_context(ctx.clone(), &f0) {
                Ok(s) => s,
                Err(e) => panic!("GPU solver: {e}"),
            };
            g.bench_with_input(BenchmarkId::new("gpu", n), &n, |b, _| {
                b.iter(|| {
                    if let Err(e) = gpu.steps_n(STEPS, f64::INFINITY) {
                        panic!("GPU step: {e}");
                    }
                })
            });
        }
        for threads in [1, 2] {
            let pool = match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
                Ok(p) => p,
                Err(e) => panic!("rayon pool: {e}"),
            };
            let mut f = f0.clone();
            g.bench_with_input(
                BenchmarkId::new(format!("cpu_{threads}t"), n),
                &n,
                |b, _| {
                    b.iter(|| {
                        pool.install(|| {
                            for _ in 0..STEPS {
                                if let Err(e) = step::step(&mut f, f64::INFINITY) {
                                    panic!("CPU step: {e}");
                                }
                            }
                        })
                    })
                },
            );
        }
    }
    g.finish();
}

/// The disc of particles at rest: (positions, velocities, volumes), flat.
fn disc(n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let sp = 0.5 / n as f64;
    let m = (0.3 / sp).ceil() as i64;
    let mut pos = Vec::new();
    for a in -m..=m {
        for b in -m..=m {
            let (x, y) = ((a as f64 + 0.5) * sp, (b as f64 + 0.5) * sp);
            if x * x + y * y <= 0.15 * 0.15 {
                pos.extend_from_slice(&[0.7 + x, 0.5 + y, 0.5]);
            }
        }
    }
    let np = pos.len() / 3;
    (pos, vec![0.0; 3 * np], vec![sp * sp; np])
}

fn bench_immersed(c: &mut Criterion) {
    let ctx = GpuContext::new().ok().map(Arc::new);
    let mut g = c.benchmark_group("fluid_blast_2d_immersed");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    for n in [64, 256] {
        let text = format!(
            "{}\n[immersed]\ninterface = \"particles\"\n",
            fluid_node::setup::benchmark_blast_case(n)
        );
        let f0 = match setup::from_toml_str(&text) {
            Ok(f) => f,
            Err(e) => panic!("benchmark case is invalid: {e}"),
        };
        let (pos, vel, vol) = disc(n);
        g.throughput(Throughput::Elements((n * n) as u64 * STEPS));
        if let Some(ctx) = &ctx {
            let mut f = f0.clone();
            let mut gpu = match GpuEuler::with_context(ctx.clone(), &f) {
                Ok(s) => s,
                Err(e) => panic!("GPU solver: {e}"),
            };
            let mut im = f.immersed.take().expect("immersed");
            if let Err(e) = gpu.set_particles(&mut im, &mut f, &pos, &vel, &vol) {
                panic!("GPU particles: {e}");
            }
            g.bench_with_input(BenchmarkId::new("gpu", n), &n, |b, _| {
                b.iter(|| {
                    if let Err(e) = gpu.steps_n(STEPS, f64::INFINITY) {
                        panic!("GPU step: {e}");
                    }
                })
            });
        }
        for threads in [1, 2] {
            let pool = match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
                Ok(p) => p,
                Err(e) => panic!("rayon pool: {e}"),
            };
            let mut f = f0.clone();
            let mut im = f.immersed.take().expect("immersed");
            im.set_particles(&mut f, &pos, &vel, &vol);
            f.immersed = Some(im);
            g.bench_with_input(
                BenchmarkId::new(format!("cpu_{threads}t"), n),
                &n,
                |b, _| {
                    b.iter(|| {
                        pool.install(|| {
                            for _ in 0..STEPS {
                                if let Err(e) = step::step(&mut f, f64::INFINITY) {
                                    panic!("CPU step: {e}");
                                }
                            }
                        })
                    })
                },
            );
        }
    }
    g.finish();
}

criterion_group!(benches, bench, bench_immersed);
criterion_main!(benches);
