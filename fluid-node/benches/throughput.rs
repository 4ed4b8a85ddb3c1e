//! Solver-only throughput: cell-updates per second (one full SSP-RK3
//! step of one cell = one update) on the 2-D cylindrical blast — p 10 in r < 0.1, 0.1
//! outside, ρ 1, γ 1.4, unit square, 400×400 — at 1 and 2 threads (rayon pools built here;
//! `RAYON_NUM_THREADS` is not needed). Also checks the two runs are bit-identical.
//! Run: `cargo bench -p fluid-node --bench throughput` (optional arguments: grid size;
//! `base`, `avx2` or `avx512` to cap the instruction set of the row kernels, which changes
//! the speed, never the values; `3d` for the spherical blast on a cube (default 54³);
//! `unfused` for the unfused stages, which give the same values).

use fluid_node::{EulerSolver, setup, simd::Simd};
use std::time::Instant;

fn case(n: usize, three_d: bool) -> String {
    if three_d {
        setup::benchmark_blast_case_3d(n)
    } else {
        setup::benchmark_blast_case(n)
    }
}

fn run(
    n: usize,
    three_d: bool,
    fused: bool,
    threads: usize,
    steps: usize,
    simd: Simd,
) -> anyhow::Result<(f64, Vec<f64>)> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    pool.install(|| {
        let mut s = EulerSolver::from_fluid(setup::from_toml_str(&case(n, three_d))?);
        s.fluid.simd = simd;
        s.fluid.fused = fused;
        // warm-up step (first touch of the buffers)
        fluid_node::step::step(&mut s.fluid, f64::INFINITY)?;
        let t0 = Instant::now();
        for _ in 0..steps {
            fluid_node::step::step(&mut s.fluid, f64::INFINITY)?;
        }
        let el = t0.elapsed().as_secs_f64();
        let cells = s.fluid.grid.cells();
        Ok(((cells * steps) as f64 / el, s.fluid.cons.clone()))
    })
}

fn main() -> anyhow::Result<()> {
    let has = |w: &str| std::env::args().skip(1).any(|a| a == w);
    let (three_d, fused) = (has("3d"), !has("unfused"));
    let n: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(if three_d { 54 } else { 400 });
    let simd = std::env::args()
        .skip(1)
        .find_map(|a| match a.as_str() {
            "base" => Some(Simd::Base),
            "avx2" => Some(Simd::Avx2),
            "avx512" => Some(Simd::Avx512),
            _ => None,
        })
        .unwrap_or_else(Simd::detect);
    let steps = 40;
    let mut best = [0.0_f64; 2];
    let mut states: Vec<Vec<f64>> = Vec::new();
    for rep in 0..3 {
        for (k, th) in [1usize, 2].iter().enumerate() {
            let (rate, st) = run(n, three_d, fused, *th, steps, simd)?;
            best[k] = best[k].max(rate);
            if rep == 0 {
                states.push(st);
            }
        }
    }
    let same = states[0] == states[1];
    println!(
        "{} blast {n}^{}, {steps} SSP-RK3 steps, best of 3 ({simd:?} kernels, {:?} detected, {}):",
        if three_d { "spherical" } else { "cylindrical" },
        if three_d { 3 } else { 2 },
        Simd::detect(),
        if fused {
            "fused stages"
        } else {
            "unfused stages"
        }
    );
    println!("  1 thread : {:.3} M cell-updates/s", best[0] / 1e6);
    println!(
        "  2 threads: {:.3} M cell-updates/s (speed-up {:.2})",
        best[1] / 1e6,
        best[1] / best[0]
    );
    println!("  1-thread and 2-thread states bit-identical: {same}");
    if !same {
        anyhow::bail!("results differ between thread counts");
    }
    Ok(())
}
