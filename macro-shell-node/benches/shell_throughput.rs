//! Throughput of the shell engine (issue #5 must-show 7): element-cycles per second (one
//! element processed in one step, node pass included) on a 200 × 200 elastic plate.
//! Run with `RAYON_NUM_THREADS=1` and `=2`: `cargo bench -p macro-shell-node`.
//! Plain timing (harness = false): the figure of merit is a rate, not a per-call latency.

use macro_shell_node::{ShellSolver, step};
use std::time::Instant;

fn plate(nip: usize) -> ShellSolver {
    let toml = format!(
        r#"
[mesh]
kind = "plate"
length = 1.0
width = 1.0
nx = 200
ny = 200
[material]
model = "elastic"
density = 7800.0
youngs_modulus = 210.0e9
poisson_ratio = 0.3
[section]
thickness = 0.01
integration_points = {nip}
[[fixed]]
node_set = "x0"
"#
    );
    match ShellSolver::from_toml_str(&toml) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

fn main() {
    let threads = rayon::current_num_threads();
    for nip in [2, 3, 5] {
        let mut s = plate(nip);
        let m = &mut s.model;
        for i in 0..m.num_nodes() {
            let x = m.x0[i][0];
            m.v[i][2] = 0.1 * x * x;
        }
        let dt = step::stable_dt(m);
        for _ in 0..20 {
            step::step(m, dt).unwrap_or_else(|e| panic!("{e}"));
        }
        let steps = 200;
        let t = Instant::now();
        for _ in 0..steps {
            step::step(m, dt).unwrap_or_else(|e| panic!("{e}"));
        }
        let secs = t.elapsed().as_secs_f64();
        let rate = (m.num_elements() * steps) as f64 / secs;
        println!(
            "shell_throughput: 200x200 elastic plate, {nip} integration points, {threads} thread(s): {:.2} M element-cycles/s ({:.1} ns per element-cycle)",
            rate / 1e6,
            1e9 / rate
        );
    }
}
