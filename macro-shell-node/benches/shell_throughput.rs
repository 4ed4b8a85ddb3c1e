//! Throughput of the shell engine: element-cycles per second (one
//! element processed in one step, node pass included) on a 200 × 200 elastic plate.
//! Run with `RAYON_NUM_THREADS=1` and `=2`: `cargo bench -p macro-shell-node`.
//! Plain timing (harness = false): the figure of merit is a rate, not a per-call latency.
//! For profiling (e.g. under callgrind) the environment may shrink the run:
//! `SHELL_BENCH_N` (elements per side, 200), `SHELL_BENCH_STEPS` (timed steps, 200),
//! `SHELL_BENCH_NIP` (one through-thickness rule instead of 2, 3 and 5).

use macro_shell_node::{ShellSolver, step};
use std::time::Instant;

fn env(name: &str) -> Option<usize> {
    std::env::var(name).ok().and_then(|s| s.parse().ok())
}

fn plate(n: usize, nip: usize) -> ShellSolver {
    match macro_shell_node::setup::benchmark_plate(n, nip) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

fn main() {
    let threads = rayon::current_num_threads();
    let n = env("SHELL_BENCH_N").unwrap_or(200);
    let steps = env("SHELL_BENCH_STEPS").unwrap_or(200);
    let nips = match env("SHELL_BENCH_NIP") {
        Some(k) => vec![k],
        None => vec![2, 3, 5],
    };
    for nip in nips {
        let t_setup = Instant::now();
        let mut s = plate(n, nip);
        let setup_s = t_setup.elapsed().as_secs_f64();
        let m = &mut s.model;
        let dt = step::stable_dt(m);
        for _ in 0..20 {
            step::step(m, dt).unwrap_or_else(|e| panic!("{e}"));
        }
        let t = Instant::now();
        for _ in 0..steps {
            step::step(m, dt).unwrap_or_else(|e| panic!("{e}"));
        }
        let secs = t.elapsed().as_secs_f64();
        let rate = (m.num_elements() * steps) as f64 / secs;
        println!(
            "shell_throughput: {n}x{n} elastic plate, {nip} integration points, {threads} thread(s): {:.2} M element-cycles/s ({:.1} ns per element-cycle)",
            rate / 1e6,
            1e9 / rate
        );
        // A fingerprint of the final state, to check that an optimisation changed nothing
        // beyond round-off (and the set-up time, which is not part of the rate).
        println!(
            "  set-up {setup_s:.3} s; final KE {:.12e} J, IE {:.12e} J",
            m.kinetic_energy(),
            m.internal_energy()
        );
    }
}
