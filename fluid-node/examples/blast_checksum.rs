//! Bit-level fingerprint of the benchmark case (2-D cylindrical blast)
//! after a number of SSP-RK3 steps: prints an FNV-1a hash of every conserved value's bits, so
//! two builds of the kernels can be compared for bit-identical results, plus the run time.
//! Run: `cargo run --release -p fluid-node --example blast_checksum -- [n] [steps]
//! [base|avx2|avx512] [3d] [unfused]` (`base`… caps the instruction set of the row kernels;
//! `3d`: the spherical blast on n³ cells; `unfused`: the unfused RK stages — neither
//! changes the checksum of a case).

use fluid_node::{setup, simd::Simd};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let n = args.first().copied().unwrap_or(100);
    let steps = args.get(1).copied().unwrap_or(20);
    let three_d = std::env::args().skip(1).any(|a| a == "3d");
    let text = if three_d {
        setup::benchmark_blast_case_3d(n)
    } else {
        setup::benchmark_blast_case(n)
    };
    let mut f = setup::from_toml_str(&text)?;
    for a in std::env::args().skip(1) {
        match a.as_str() {
            "base" => f.simd = Simd::Base,
            "avx2" => f.simd = Simd::Avx2,
            "avx512" => f.simd = Simd::Avx512,
            "unfused" => f.fused = false,
            _ => {}
        }
    }
    let t0 = Instant::now();
    for _ in 0..steps {
        fluid_node::step::step(&mut f, f64::INFINITY)?;
    }
    let el = t0.elapsed().as_secs_f64();
    let mut h: u64 = 0xcbf29ce484222325;
    for x in &f.cons {
        for b in x.to_bits().to_le_bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x100000001b3);
        }
    }
    println!(
        "n {n}{}, steps {steps}, {:?}, fused {}, t {:.9e}: checksum {h:016x}; {:.3} M cell-updates/s",
        if three_d { " (3-D)" } else { "" },
        f.simd,
        f.fused,
        f.time,
        (f.grid.cells() * steps) as f64 / el / 1e6
    );
    Ok(())
}
