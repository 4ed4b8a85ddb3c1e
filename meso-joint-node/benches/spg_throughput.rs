//! Throughput of the MC-SPG step: particle-updates per second (one particle advanced one
//! step: smoothing gather/scatter, kinematics, J2 update, internal force, and the amortised
//! re-anchoring every 100 steps) on a 40³ block.
//! Run with `RAYON_NUM_THREADS=1` and `=2`; target ≥ 2 M particle-updates/s on one thread.

#![allow(clippy::needless_range_loop)]

use meso_joint_node::geometry::benchmark_block;

fn main() {
    let n = 40;
    let t_setup = std::time::Instant::now();
    let mut m = benchmark_block(n).expect("model");
    let setup = t_setup.elapsed().as_secs_f64();
    let dt = m.stable_dt();
    for _ in 0..5 {
        m.step(dt).expect("warm-up step");
    }
    let steps = 100;
    let t0 = std::time::Instant::now();
    for _ in 0..steps {
        m.step(dt).expect("step");
    }
    let wall = t0.elapsed().as_secs_f64();
    let updates = m.len() as f64 * steps as f64 / wall;
    println!(
        "spg_throughput: {} particles, {} entries/row avg, {} steps in {:.3} s -> {:.3} M particle-updates/s (threads {}, set-up {:.2} s)",
        m.len(),
        m.rows.cols.len() / m.len(),
        steps,
        wall,
        updates / 1e6,
        rayon::current_num_threads(),
        setup
    );
}
