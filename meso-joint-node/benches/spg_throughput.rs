//! Throughput of the MC-SPG step: particle-updates per second (one particle advanced one
//! step: smoothing gather/scatter, kinematics, J2 update, internal force, and the amortised
//! re-anchoring every 100 steps) on a 40³ block.
//! Run with `RAYON_NUM_THREADS=1` and `=2`; target ≥ 2 M particle-updates/s on one thread.

#![allow(clippy::needless_range_loop)]

use mechanics::j2::J2Material;
use meso_joint_node::config::Smoothing;
use meso_joint_node::geometry::block;
use meso_joint_node::model::{Model, ModelParams};

fn main() {
    let n = 40;
    let h = 1e-3;
    let s = block([0.0; 3], [n as f64 * h; 3], h);
    let p = ModelParams {
        material: J2Material {
            young: 210e9,
            poisson: 0.3,
            yield_stress: 0.2e9,
            iso_hardening: 0.0,
            kin_hardening: 22e9,
        },
        density: 7850.0,
        spacing: h,
        support: 2.0 * h,
        eps_crit: 0.1,
        e_crit: 1.0,
        // The default rate; one re-anchoring falls inside the timed steps (amortised cost).
        reanchor_every: 100,
        smoothing: Smoothing::Consistent,
        cfl: 0.4,
    };
    let t_setup = std::time::Instant::now();
    let mut m = Model::new(p, s.x, s.vol, s.part, &s.rigid_parts).expect("model");
    let setup = t_setup.elapsed().as_secs_f64();
    let top = n as f64 * h;
    m.add_velocity_bc("bottom", [0.0, 0.0, -1.0], 0.0, |x| x[2] < 2.0 * h);
    m.add_velocity_bc("top", [0.0, 0.0, 1.0], 0.0, |x| x[2] > top - 2.0 * h);
    m.initial_forces();
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
