//! The MC-SPG step gives the same bits on any number of threads (the joint kernel's
//! 2-thread scaling must not buy speed with reordered sums): a block pulled apart with every
//! stretched bond breaking (eq. 15–17, rows rebuilt and detached) and re-anchored every few
//! steps, for each smoothing, stepped in pools of 1, 2 and 3 threads.

use meso_joint_node::config::Smoothing;
use meso_joint_node::geometry::benchmark_block;
use meso_joint_node::model::{Model, Point};

const STEPS: u64 = 40;
const REANCHOR_EVERY: u64 = 7;

fn run(threads: usize, smoothing: Smoothing) -> Model {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");
    pool.install(|| {
        let mut m = benchmark_block(10).expect("benchmark block");
        m.p.eps_crit = 0.0;
        m.p.reanchor_every = REANCHOR_EVERY;
        m.p.smoothing = smoothing;
        m.separation_weight = 0.6;
        m.rebuild_shapes(None).expect("shapes");
        m.initial_forces();
        let dt = m.stable_dt();
        for _ in 0..STEPS {
            m.step(dt).expect("step");
        }
        m
    })
}

/// Every evolving value of the state, as bits.
fn bits(m: &Model) -> Vec<u64> {
    let mut b = Vec::new();
    for a in [&m.x, &m.xh, &m.xa, &m.u, &m.v, &m.vh, &m.f] {
        b.extend(a.iter().flatten().map(|v| v.to_bits()));
    }
    for a in [&m.rho, &m.vol, &m.vol_a, &m.eint, &m.ms] {
        b.extend(a.iter().map(|v| v.to_bits()));
    }
    for a in [&m.fhat, &m.ftot_a, &m.bmat] {
        b.extend(a.iter().flatten().flatten().map(|v| v.to_bits()));
    }
    for s in &m.mat {
        let Point::J2(s) = s else {
            panic!("the thread test's material is J2")
        };
        b.extend(s.stress.iter().chain(&s.back_stress).map(|v| v.to_bits()));
        b.push(s.eq_plastic_strain.to_bits());
    }
    let r = &m.rows;
    for a in [&r.phi, &r.psi, &r.psi_t] {
        b.extend(a.iter().map(|v| v.to_bits()));
    }
    b.extend(
        r.grad
            .iter()
            .chain(&r.grad_t)
            .flatten()
            .map(|v| v.to_bits()),
    );
    b.extend(r.alive.iter().map(|&a| a as u64));
    b.extend([
        m.broken_bonds as u64,
        m.detached as u64,
        m.max_eps.to_bits(),
    ]);
    b.extend([m.bc_work.to_bits(), m.kinetic_energy().to_bits()]);
    b
}

#[test]
fn a_step_gives_the_same_bits_on_1_2_and_3_threads() {
    for smoothing in [
        Smoothing::Consistent,
        Smoothing::Shepard,
        Smoothing::Average,
        Smoothing::None,
    ] {
        let one = run(1, smoothing);
        // The run must exercise what can depend on the split: breaking, re-anchoring.
        assert!(one.broken_bonds > 0, "{smoothing:?}: no bond broke");
        assert!(
            one.steps >= 2 * REANCHOR_EVERY,
            "{smoothing:?}: no re-anchoring"
        );
        let reference = bits(&one);
        for threads in [2, 3] {
            let other = bits(&run(threads, smoothing));
            assert_eq!(other.len(), reference.len());
            let first = reference.iter().zip(&other).position(|(a, b)| a != b);
            assert_eq!(
                first, None,
                "{smoothing:?}: {threads} threads differ from 1 at state value {first:?}"
            );
        }
        eprintln!(
            "{smoothing:?}: {} values equal on 1, 2, 3 threads; {} bonds broken, {} rows detached",
            reference.len(),
            one.broken_bonds,
            one.detached
        );
    }
}
