//! Time per phase of the MC-SPG step (issue 22): `joint_profile N THREADS STEPS [EPS_CRIT]`
//! advances the benchmark block of N³ particles STEPS steps in a pool of THREADS threads and
//! prints the throughput, each phase's time per step and share (`meso_joint_node::profile`)
//! and a hash of the final state's bits (to compare builds and thread counts). EPS_CRIT
//! (default the block's 0.1) set to 0 makes every stretched bond break (the failure path).

use meso_joint_node::geometry::benchmark_block;
use meso_joint_node::profile::Phase;

fn main() -> anyhow::Result<()> {
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
        Ok(())
    })
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
        s.stress.iter().chain(&s.back_stress).for_each(|&v| eat(v));
        eat(s.eq_plastic_strain);
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
