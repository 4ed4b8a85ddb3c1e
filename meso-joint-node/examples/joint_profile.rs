//! Time per phase of the MC-SPG step: `joint_profile N THREADS STEPS [EPS_CRIT]`
//! advances the benchmark block of N³ particles STEPS steps in a pool of THREADS threads and
//! prints the throughput, each phase's time per step and share (`meso_joint_node::profile`)
//! and a hash of the final state's bits (to compare builds and thread counts). EPS_CRIT
//! (default the block's 0.1) set to 0 makes every stretched bond break (the failure path).
//!
//! `joint_profile N pairs BLOCKS` measures the 2-thread speed-up in pairs instead: blocks of
//! 10 steps on one model alternate between a pool of 1 and a pool of 2 threads, and each
//! pair's ratio is taken, so a machine whose speed drifts over seconds (a shared VM) shifts
//! both halves of a pair alike. It prints every pair's ratio, their median, and the ratio of
//! the fastest block of each pool.
//!
//! `joint_profile N solid THREADS STEPS` profiles the block of hexahedra around an SPG core
//! (`geometry::benchmark_block_solid`; the hexahedra's forces count in "internal force", their
//! node updates in the velocity phases and "positions").
//!
//! `joint_profile N versus BLOCKS [THREADS]` measures the speed-up of the same block as
//! hexahedra around an SPG core (`geometry::benchmark_block_solid`) over the all-particle
//! block, side by side the same way: blocks of 10 steps, each model at its own stable step,
//! alternate between the two models in one pool, and each pair's ratio (all-particle time
//! over hexahedra time) is taken.

use meso_joint_node::geometry::{benchmark_block, benchmark_block_solid};
use meso_joint_node::profile::Phase;

fn main() -> anyhow::Result<()> {
    let arg = |i: usize, d: usize| -> anyhow::Result<usize> {
        std::env::args().nth(i).map_or(Ok(d), |s| Ok(s.parse()?))
    };
    match std::env::args().nth(2).as_deref() {
        Some("pairs") => return pairs(arg(1, 40)?, arg(3, 30)?.max(1)),
        Some("versus") => return versus(arg(1, 40)?, arg(3, 30)?.max(1), arg(4, 1)?.max(1)),
        Some("solid") => {
            let (n, threads, steps) = (arg(1, 40)?, arg(3, 1)?.max(1), arg(4, 200)?.max(1));
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()?;
            return pool.install(|| {
                let m = benchmark_block_solid(n).map_err(anyhow::Error::msg)?;
                profile(m, n, threads, steps)
            });
        }
        _ => {}
    }
    let a: Vec<usize> = std::env::args()
        .skip(1)
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    let (n, threads, steps) = (
        a.first().copied().unwrap_or(40),
        a.get(1).copied().unwrap_or(1),
        a.get(2).copied().unwrap_or(200),
    );
    let eps_crit: Option<f64> = std::env::args().nth(4).map(|s| s.parse()).transpose()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    pool.install(|| {
        let mut m = benchmark_block(n).map_err(anyhow::Error::msg)?;
        if let Some(e) = eps_crit {
            m.p.eps_crit = e;
        }
        profile(m, n, threads, steps)
    })
}

/// `steps` steps of `m` (the block of `n`³ cells) on `threads` threads, with each phase's
/// time (module doc).
fn profile(
    mut m: meso_joint_node::model::Model,
    n: usize,
    threads: usize,
    steps: usize,
) -> anyhow::Result<()> {
    {
        let dt = m.stable_dt();
        for _ in 0..5 {
            m.step(dt).map_err(anyhow::Error::msg)?;
        }
        m.clock.enable();
        let cpu0 = process_cpu_s();
        let t0 = std::time::Instant::now();
        for _ in 0..steps {
            m.step(dt).map_err(anyhow::Error::msg)?;
        }
        let wall = t0.elapsed().as_secs_f64();
        let cpu = process_cpu_s().zip(cpu0).map(|(b, a)| b - a);
        println!(
            "{n}³ {} particles, {threads} threads, {steps} steps: {:.3} M particle-updates/s, \
             process CPU {} ms/step",
            m.len(),
            m.len() as f64 * steps as f64 / wall / 1e6,
            cpu.map_or("?".into(), |c| format!("{:.2}", 1e3 * c / steps as f64))
        );
        let total = m.clock.total();
        for p in Phase::ALL {
            let s = m.clock.secs[p as usize];
            println!(
                "  {:<18} {:>9.1} µs/step {:>6.1} %",
                p.name(),
                1e6 * s / steps as f64,
                100.0 * s / total
            );
        }
        println!(
            "  (phases sum to {:.1} % of the wall time)",
            100.0 * total / wall
        );
        println!(
            "state hash {:016x}, broken bonds {}",
            state_hash(&m),
            m.broken_bonds
        );
    }
    Ok(())
}

/// The hexahedra-and-core block's speed-up over the all-particle block of the same size, in
/// `blocks` pairs of 10-step blocks on `threads` threads (module doc).
fn versus(n: usize, blocks: usize, threads: usize) -> anyhow::Result<()> {
    const STEPS: usize = 10;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()?;
    pool.install(|| {
        let mut part = benchmark_block(n).map_err(anyhow::Error::msg)?;
        let mut solid = benchmark_block_solid(n).map_err(anyhow::Error::msg)?;
        let elements = solid.solid.as_ref().map_or(0, |s| s.part.elements.len());
        let (dp, ds) = (part.stable_dt(), solid.stable_dt());
        let block = |m: &mut meso_joint_node::model::Model, dt: f64| {
            let t0 = std::time::Instant::now();
            for _ in 0..STEPS {
                m.step(dt).map_err(anyhow::Error::msg)?;
            }
            anyhow::Ok(t0.elapsed().as_secs_f64())
        };
        block(&mut part, dp)?;
        block(&mut solid, ds)?;
        let mut ratios = Vec::with_capacity(blocks);
        for b in 0..blocks {
            // which model goes first alternates, so a steady drift favours neither
            let (tp, ts) = if b % 2 == 0 {
                let tp = block(&mut part, dp)?;
                (tp, block(&mut solid, ds)?)
            } else {
                let ts = block(&mut solid, ds)?;
                (block(&mut part, dp)?, ts)
            };
            println!(
                "pair {b}: all particles {:.3} ms/step, hexahedra {:.3} ms/step, speed-up {:.3}",
                1e3 * tp / STEPS as f64,
                1e3 * ts / STEPS as f64,
                tp / ts
            );
            ratios.push(tp / ts);
        }
        ratios.sort_by(f64::total_cmp);
        println!(
            "{n}³ cells, {threads} thread(s): {} particles against {elements} hexahedra around {} \
             particles; median speed-up {:.3} over {} pairs of {STEPS}-step blocks (10th–90th \
             percentile {:.3}–{:.3})",
            part.len(),
            solid.len(),
            ratios[ratios.len() / 2],
            ratios.len(),
            ratios[ratios.len() / 10],
            ratios[ratios.len() * 9 / 10]
        );
        Ok(())
    })
}

/// The 2-thread speed-up in `blocks` pairs of 10-step blocks (module doc).
fn pairs(n: usize, blocks: usize) -> anyhow::Result<()> {
    const STEPS: usize = 10;
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build()?;
    let mut m = benchmark_block(n).map_err(anyhow::Error::msg)?;
    let dt = m.stable_dt();
    let block = |pool: &rayon::ThreadPool, m: &mut meso_joint_node::model::Model| {
        pool.install(|| {
            let t0 = std::time::Instant::now();
            for _ in 0..STEPS {
                m.step(dt).map_err(anyhow::Error::msg)?;
            }
            anyhow::Ok(t0.elapsed().as_secs_f64())
        })
    };
    // Warm-up: both pools once.
    block(&one, &mut m)?;
    block(&two, &mut m)?;
    let mut ratios = Vec::with_capacity(blocks);
    let (mut best1, mut best2) = (f64::INFINITY, f64::INFINITY);
    for b in 0..blocks {
        // Which pool goes first alternates, so a steady drift favours neither.
        let (t1, t2) = if b % 2 == 0 {
            let t1 = block(&one, &mut m)?;
            (t1, block(&two, &mut m)?)
        } else {
            let t2 = block(&two, &mut m)?;
            (block(&one, &mut m)?, t2)
        };
        let per = |t: f64| m.len() as f64 * STEPS as f64 / t / 1e6;
        println!(
            "pair {b}: 1 thread {:.3}, 2 threads {:.3} M particle-updates/s, speed-up {:.3}",
            per(t1),
            per(t2),
            t1 / t2
        );
        ratios.push(t1 / t2);
        best1 = best1.min(t1);
        best2 = best2.min(t2);
    }
    ratios.sort_by(f64::total_cmp);
    let med = ratios[ratios.len() / 2];
    println!(
        "{n}³ {} particles: median 2-thread speed-up {med:.3} over {} pairs of {STEPS}-step \
         blocks (10th–90th percentile {:.3}–{:.3})",
        m.len(),
        ratios.len(),
        ratios[ratios.len() / 10],
        ratios[ratios.len() * 9 / 10]
    );
    // The fastest block of each pool: what each reaches when nothing else on the machine
    // slows it (the least disturbed estimate on a shared machine).
    println!(
        "fastest blocks: 1 thread {:.3}, 2 threads {:.3} M particle-updates/s, speed-up {:.3}",
        m.len() as f64 * STEPS as f64 / best1 / 1e6,
        m.len() as f64 * STEPS as f64 / best2 / 1e6,
        best1 / best2
    );
    Ok(())
}

/// FNV-1a over the bits of the evolving state.
fn state_hash(m: &meso_joint_node::model::Model) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325_u64;
    let mut eat = |v: f64| {
        for b in v.to_bits().to_le_bytes() {
            h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
    };
    for a in [&m.x, &m.xh, &m.v, &m.vh, &m.f, &m.u] {
        a.iter().flatten().for_each(|&v| eat(v));
    }
    for a in [&m.rho, &m.vol, &m.eint, &m.ms] {
        a.iter().for_each(|&v| eat(v));
    }
    m.fhat
        .iter()
        .chain(&m.bmat)
        .flatten()
        .flatten()
        .for_each(|&v| eat(v));
    for s in &m.mat {
        s.stress().iter().for_each(|&v| eat(v));
        if let meso_joint_node::model::Point::J2(j) = s {
            j.back_stress.iter().for_each(|&v| eat(v));
        }
        eat(s.eq_plastic_strain());
    }
    h
}

/// User + system CPU time of the whole process (all threads) in seconds, from
/// `/proc/self/stat` (clock ticks of 10 ms; time enough steps).
fn process_cpu_s() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which is in parentheses and may hold spaces).
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}
