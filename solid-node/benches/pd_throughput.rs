//! Throughput benchmark: bond-updates per second for pd-bond and
//! pd-correspondence on a 31 × 31 × 31 cubic block (29,791 particles), δ = 3.015 Δx
//! (122-member interior families, 3,244,494 bonds), 100 full time steps (forces, damage
//! check, velocity-Verlet integration); pd-rk-ba (order 2) on the same block for reference.
//! Select models by naming them after `--`, and cap the instruction set of the bond kernels
//! with `base`, `avx2` or `avx512` (the same bits, except correspondence's AVX-512 lane sums). Run with RAYON_NUM_THREADS=1 and 2:
//! `RAYON_NUM_THREADS=1 cargo bench -p solid-node --bench pd_throughput`.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use mechanics::simd::Simd;
use solid_node::pd::cases::benchmark_block;
use solid_node::pd::integrate::Body;
use std::time::Instant;

fn block(model: &str) -> Body {
    // PD_BENCH_N: another block edge (e.g. a small block that fits in cache, to separate
    // memory traffic from arithmetic); the block is 31.
    let n = std::env::var("PD_BENCH_N")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(31);
    match benchmark_block(n, model) {
        Ok(b) => b.body,
        Err(e) => panic!("{e}"),
    }
}

fn main() {
    let threads = rayon::current_num_threads();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let which: Vec<&String> = args.iter().filter(|a| a.starts_with("pd-")).collect();
    // `base`, `avx2` or `avx512` caps the instruction set of the bond kernels
    let simd = args.iter().find_map(|a| match a.as_str() {
        "base" => Some(Simd::Base),
        "avx2" => Some(Simd::Avx2),
        "avx512" => Some(Simd::Avx512),
        _ => None,
    });
    for model in ["pd-bond", "pd-correspondence", "pd-rk-ba"] {
        if !which.is_empty() && !which.iter().any(|w| w.as_str() == model) {
            continue;
        }
        let mut b = block(model);
        if let Some(s) = simd {
            b.model.set_simd(s);
        }
        let bonds = b.bonds.len();
        let dt = 0.5 * b.stable_dt();
        b.step(dt); // warm-up
        // pd-rk-ba (bond-level J2) is ~20× slower: fewer steps, same per-step measure.
        let steps = std::env::var("PD_BENCH_STEPS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(if model == "pd-rk-ba" { 10 } else { 100 });
        let t = Instant::now();
        for _ in 0..steps {
            b.step(dt);
        }
        let s = t.elapsed().as_secs_f64();
        let rate = bonds as f64 * steps as f64 / s;
        println!(
            "{model:>18}: {} particles, {bonds} bonds, {steps} steps in {s:.3} s at {threads} thread(s): {:.1} M bond-updates/s",
            b.len(),
            rate / 1e6
        );
    }
}
