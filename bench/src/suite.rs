//! `cosim bench`: every benchmark of the project in one command.
//!
//! Kernels and their units (one update = the unit of work the issues define):
//! * `transport` — one window round trip (Advance → Fields → Done) per transport; one update
//!   is one payload byte (`protocol::transport::bench`).
//! * `fluid` — one full SSP-RK3 step of one cell on the 2-D cylindrical blast
//!   (`fluid_node::setup::benchmark_blast_case`), CPU and GPU (`fluid_node::gpu::GpuEuler`);
//!   `fluid-3d` the same on the 3-D spherical blast of n³ cells, CPU only.
//!   `fluid-tnt` the five-equation model with two materials on a 2-D TNT charge in air (JWL
//!   products and an ideal gas, n² cells).
//! * `pd-bond`, `pd-correspondence` — one particle–family-member pair processed in one
//!   velocity-Verlet step (forces, damage check, integration) on an n³ cubic block,
//!   δ = 3.015 Δx; `pd-bond` also on the GPU (`solid_node::pd::gpu::GpuBondBody`).
//! * `shell` — one element processed in one explicit step of an n × n elastic plate.
//! * `joint` — one MC-SPG particle advanced one step in an n³ block pulled apart.
//! * `joint-solid` — the same block as hexahedra around a central SPG core (a 27th of the
//!   cells): one lattice cell advanced one step, comparable row for row with `joint`.
//!
//! Each CPU kernel runs in a rayon pool of 1 and of 2 threads built here (not through
//! `RAYON_NUM_THREADS`). A measurement is: one warm-up step, one step to estimate the cost,
//! then at least five timed samples of `k` steps each (`k` chosen so that a sample lasts a
//! few milliseconds); the time per step is the median over the samples. The 1- and 2-thread
//! samples of a problem are taken back to back in pairs (which pool goes first alternates),
//! and the 2-thread row also gives the median of the pairs' ratios: on a machine whose speed
//! drifts, a better speed-up than the ratio of two medians taken at different times. The cost growth of a
//! size is its time per update divided by that of the smallest size of the same kernel and
//! device: 1 for a linear-cost kernel. The note column is computed from the data: a
//! least-squares fit `t_step = a + b · updates` separates a fixed per-step cost `a` (thread
//! fork/join, GPU submission, message latency) from the per-update cost `b`, and growth
//! beyond 25 % is flagged with the evidence at hand (working-set size against the caches,
//! timing spread under load).

use anyhow::{Context, anyhow};
use clap::Args;
use mechanics::gpu::{GpuContext, wgpu};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// Options of the whole suite (`cosim bench [--only ...] [--quick] [-o DIR]`).
#[derive(Debug, Clone, Args)]
pub struct SuiteArgs {
    /// Kernels to run, comma-separated: transport, window (whole coupled windows through
    /// `cosim run`: participant round trip in Rust, Python and C; the split bar per transport),
    /// fluid, fluid-3d, fluid-tnt, solid (= pd-bond and pd-correspondence), pd-bond, pd-correspondence, shell,
    /// joint, joint-solid, gpu-profile (the GPU's copy bandwidth and each fluid kernel's device time).
    /// Default: all.
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Tiny problems (2 sizes per kernel) and few repetitions: a smoke run for tests.
    #[arg(long)]
    pub quick: bool,
    /// Directory for bench.json and bench.md.
    #[arg(long, short, default_value = "out/bench")]
    pub output: PathBuf,
    /// No GPU rows even when an adapter exists.
    #[arg(long)]
    pub no_gpu: bool,
    /// Also the sizes that fill a data-centre GPU (fluid and fluid-tnt 1600² and 4096²,
    /// fluid-3d 128³ and 256³, pd-bond 64³), on the GPU only: the host would take minutes per
    /// sample there.
    #[arg(long)]
    pub large: bool,
}

/// All kernels, in run order.
pub const KERNELS: [&str; 11] = [
    "transport",
    "window",
    "fluid",
    "fluid-3d",
    "fluid-tnt",
    "pd-bond",
    "pd-correspondence",
    "shell",
    "joint",
    "joint-solid",
    "gpu-profile",
];

/// The kernels `--only` selects (aliases expanded), in run order; errors name the bad entry.
pub fn select(only: &[String]) -> Result<Vec<&'static str>, String> {
    if only.is_empty() {
        return Ok(KERNELS.to_vec());
    }
    let mut want: Vec<&'static str> = Vec::new();
    for o in only {
        let o = o.trim();
        let names: Vec<&'static str> = match o {
            "solid" | "pd" => vec!["pd-bond", "pd-correspondence"],
            "all" => KERNELS.to_vec(),
            _ => match KERNELS.iter().find(|k| **k == o) {
                Some(k) => vec![*k],
                None => {
                    return Err(format!(
                        "--only: unknown kernel '{o}' (known: {}, solid, all)",
                        KERNELS.join(", ")
                    ));
                }
            },
        };
        want.extend(names);
    }
    Ok(KERNELS
        .iter()
        .copied()
        .filter(|k| want.contains(k))
        .collect())
}

/// The kernels with GPU rows.
const GPU_KERNELS: [&str; 5] = ["fluid", "fluid-3d", "fluid-tnt", "pd-bond", "gpu-profile"];

/// The sizes `--large` adds (GPU rows only).
fn large_sizes(kernel: &str) -> Vec<usize> {
    match kernel {
        "fluid" | "fluid-tnt" => vec![1600, 4096],
        "fluid-3d" => vec![128, 256],
        "pd-bond" => vec![64],
        _ => vec![],
    }
}

/// Problem sizes (per-side counts, or payload bytes for the transport) of each kernel.
fn sizes(kernel: &str, quick: bool) -> Vec<usize> {
    match (kernel, quick) {
        ("transport", false) => protocol::transport::bench::DEFAULT_SIZES.to_vec(),
        ("transport", true) => vec![1 << 10, 1 << 16],
        ("fluid" | "fluid-tnt", false) => vec![100, 200, 400, 800],
        ("fluid" | "fluid-tnt", true) => vec![16, 32],
        // 54³ has the cells of 400² (3-D per-cell throughput against 2-D)
        ("fluid-3d", false) => vec![24, 34, 44, 54],
        ("fluid-3d", true) => vec![8, 12],
        ("pd-bond" | "pd-correspondence", false) => vec![16, 23, 31, 40],
        ("pd-bond" | "pd-correspondence", true) => vec![6, 8],
        ("shell", false) => vec![100, 200, 400, 800],
        ("shell", true) => vec![8, 16],
        ("joint" | "joint-solid", false) => vec![16, 24, 32, 40],
        ("joint" | "joint-solid", true) => vec![6, 8],
        _ => vec![],
    }
}

/// How hard to measure.
#[derive(Debug, Clone, Copy)]
struct Plan {
    /// A sample (k steps) lasts at least this long (s), so the clock resolution and one-off
    /// jitter do not dominate tiny problems.
    min_sample_s: f64,
    /// Timed seconds per (kernel, device, size) beyond the minimum sample count.
    budget_s: f64,
    min_samples: usize,
    max_samples: usize,
    /// The sizes of a kernel are measured in turn, this many times over (each round takes
    /// its share of the samples), so that a burst of load from other jobs hits all sizes
    /// rather than one.
    rounds: usize,
    transport_rounds: usize,
}

impl Plan {
    fn new(quick: bool) -> Plan {
        if quick {
            Plan {
                min_sample_s: 5e-4,
                budget_s: 0.02,
                min_samples: 5,
                max_samples: 5,
                rounds: 1,
                transport_rounds: 10,
            }
        } else {
            Plan {
                min_sample_s: 5e-3,
                budget_s: 3.0,
                min_samples: 7,
                max_samples: 50,
                rounds: 3,
                transport_rounds: 100,
            }
        }
    }
}

/// Median, 10th and 90th percentile of the time per step, and how it was sampled.
#[derive(Debug, Clone, Copy)]
struct Timing {
    median: f64,
    p10: f64,
    p90: f64,
    batch: u64,
    samples: usize,
    /// Mean wall time per step over all samples.
    wall_mean: f64,
    /// Mean process CPU time per step over all samples (all threads of the process).
    cpu_mean: Option<f64>,
}

/// CPU time of the whole process (all threads) in seconds, if the clock is available.
fn process_cpu_s() -> Option<f64> {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer to a local.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    (rc == 0).then_some(ts.tv_sec as f64 + 1e-9 * ts.tv_nsec as f64)
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

fn median(sorted: &[f64]) -> f64 {
    let n = sorted.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    }
}

/// A step function: `run(k)` advances its problem by k steps (and waits for the device).
type StepFn = Box<dyn FnMut(u64) -> anyhow::Result<()> + Send>;

/// The samples of one (problem, device) pair, gathered over several rounds.
#[derive(Debug, Clone, Default)]
struct Acc {
    batch: u64,
    target: usize,
    samples: Vec<f64>,
    wall: f64,
    cpu: Option<f64>,
    steps: u64,
}

impl Acc {
    /// Warm-up step, then one step to estimate the cost: fixes the batch (steps per sample,
    /// so that a sample lasts at least `min_sample_s`) and the number of samples.
    fn calibrate(plan: &Plan, run: &mut StepFn) -> anyhow::Result<Acc> {
        run(1).context("warm-up step")?;
        let t0 = Instant::now();
        run(1)?;
        let est = t0.elapsed().as_secs_f64().max(1e-9);
        let batch = ((plan.min_sample_s / est).ceil() as u64).clamp(1, 10_000);
        let target = ((plan.budget_s / (est * batch as f64)).floor() as usize)
            .clamp(plan.min_samples, plan.max_samples);
        Ok(Acc {
            batch,
            target,
            cpu: Some(0.0),
            ..Acc::default()
        })
    }

    /// `count` more samples.
    fn take(&mut self, run: &mut StepFn, count: usize) -> anyhow::Result<()> {
        let c0 = process_cpu_s();
        let w0 = Instant::now();
        for _ in 0..count {
            let t0 = Instant::now();
            run(self.batch)?;
            self.samples
                .push(t0.elapsed().as_secs_f64() / self.batch as f64);
        }
        self.wall += w0.elapsed().as_secs_f64();
        self.cpu = match (self.cpu, c0, process_cpu_s()) {
            (Some(c), Some(a), Some(b)) => Some(c + b - a),
            _ => None,
        };
        self.steps += count as u64 * self.batch;
        Ok(())
    }

    fn timing(&self) -> Timing {
        let mut t = self.samples.clone();
        t.sort_by(f64::total_cmp);
        let steps = self.steps.max(1) as f64;
        Timing {
            median: median(&t),
            p10: percentile(&t, 0.1),
            p90: percentile(&t, 0.9),
            batch: self.batch,
            samples: t.len(),
            wall_mean: self.wall / steps,
            cpu_mean: self.cpu.map(|c| c / steps),
        }
    }
}

/// One line of the result table.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub kernel: String,
    /// "cpu", "gpu", or the transport ("local", "shm", "zenoh").
    pub device: String,
    /// rayon threads (CPU rows only).
    pub threads: Option<usize>,
    /// Human description of the problem.
    pub problem: String,
    /// Cells/particles/elements per side, or payload bytes.
    pub size: usize,
    /// What one update is.
    pub unit: String,
    pub updates_per_step: u64,
    /// Steps per timed sample and number of samples.
    pub steps_per_sample: u64,
    pub samples: usize,
    pub median_step_s: f64,
    pub p10_step_s: f64,
    pub p90_step_s: f64,
    /// updates_per_step / median_step_s.
    pub throughput_per_s: f64,
    /// 1e9 · median_step_s / updates_per_step.
    pub ns_per_update: f64,
    /// ns_per_update / ns_per_update of the smallest size of this kernel and device.
    pub cost_growth: f64,
    /// Mean process CPU time per step (all threads) / updates per step, in ns: insensitive
    /// to the time the process waits for a core on a loaded machine.
    pub cpu_ns_per_update: Option<f64>,
    /// cpu_ns_per_update / that of the smallest size.
    pub cpu_cost_growth: Option<f64>,
    /// Mean CPU time per step / (mean wall time per step × cores it may use): the share of
    /// its cores the step got (below 1: descheduled by other load, or threads idle).
    pub core_share: Option<f64>,
    /// Neighbour entries per particle (kernels whose update is a particle with a family).
    pub neighbours_per_update: Option<f64>,
    /// 1-minute load average of the machine when the row was recorded.
    pub loadavg_1min: f64,
    /// Estimated bytes the kernel streams through per step (its main arrays), when known.
    pub working_set_bytes: Option<u64>,
    pub setup_s: f64,
    pub note: String,
    /// 2-thread CPU rows: the speed-up over 1 thread as the median of paired samples (a
    /// 1-thread and a 2-thread sample of the same problem taken back to back, so drift in the
    /// machine's speed shifts both alike), and the number of pairs.
    pub paired_speedup: Option<f64>,
    pub pairs: Option<usize>,
}

impl Row {
    fn series(&self) -> (String, String, Option<usize>) {
        (self.kernel.clone(), self.device.clone(), self.threads)
    }
}

/// Relative least-squares fit t_step = a + b·updates over one series (weights 1/t², so
/// every size counts alike), and the series' verdict on linear cost.
#[derive(Debug, Clone, Serialize)]
pub struct Fit {
    pub kernel: String,
    pub device: String,
    pub threads: Option<usize>,
    /// "cpu": fitted to the process CPU time per step (all threads); "wall": to the median
    /// wall time.
    pub basis: &'static str,
    /// Fixed cost per step (s).
    pub fixed_s: f64,
    /// Marginal cost per update (ns).
    pub marginal_ns: f64,
    /// The cost growth (wall clock) farthest from 1 over the sizes.
    pub max_growth: f64,
    /// The CPU-time cost growth farthest from 1, when measured.
    pub max_cpu_growth: Option<f64>,
    /// Wall-clock time per update within 25 % of the smallest size's at every size.
    pub linear_within_25_percent: bool,
    /// The same on CPU time per update.
    pub cpu_linear_within_25_percent: Option<bool>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Skipped {
    pub kernel: String,
    pub device: String,
    pub reason: String,
}

#[derive(Debug, Clone, Serialize)]
pub struct Gpu {
    pub name: String,
    pub driver: String,
    pub driver_info: String,
    pub backend: String,
    pub device_type: String,
    pub precision: String,
    pub warning: Option<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Cache {
    pub level: String,
    pub kind: String,
    pub size: String,
    pub bytes: u64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Machine {
    pub cpu_model: String,
    pub logical_cpus: usize,
    pub available_parallelism: usize,
    pub caches: Vec<Cache>,
    pub memory: String,
    pub os: String,
    pub kernel: String,
    pub build: &'static str,
    pub loadavg_start: [f64; 3],
    pub loadavg_end: [f64; 3],
    pub gpu: Option<Gpu>,
    pub gpu_skipped: Option<String>,
    pub env: Vec<(String, String)>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub started_utc: String,
    pub quick: bool,
    pub kernels: Vec<String>,
    pub total_wall_s: f64,
    pub machine: Machine,
    pub results: Vec<Row>,
    pub fits: Vec<Fit>,
    pub skipped: Vec<Skipped>,
    pub errors: Vec<String>,
    /// The transport table in its own format (`cosim bench transport`).
    pub transport_table: Option<String>,
    /// Whole windows through `cosim run` (kernel `window`).
    pub windows: Vec<crate::window::WindowRow>,
    /// Their tables.
    pub window_table: Option<String>,
    /// The GPU's own streaming bandwidth (kernel `gpu-profile`).
    pub bandwidth: Option<BandwidthRow>,
    /// Each fluid kernel's device time and achieved bandwidth (kernel `gpu-profile`).
    pub gpu_kernels: Vec<KernelRow>,
}

/// The device's streaming bandwidth: bytes read plus written per second.
#[derive(Debug, Clone, Serialize)]
pub struct BandwidthRow {
    /// `copy_buffer_to_buffer`.
    pub copy_bytes_per_s: f64,
    /// A WGSL kernel copying 16 bytes per invocation (the reference of `fraction`).
    pub kernel_bytes_per_s: f64,
    pub buffer_bytes: u64,
    pub repeats: u32,
}

/// One kernel of one fluid problem's GPU step, timed on the device's clock.
#[derive(Debug, Clone, Serialize)]
pub struct KernelRow {
    pub problem: String,
    pub kernel: String,
    pub dispatches_per_step: u32,
    /// Device seconds per step (its dispatches, one compute pass each).
    pub seconds_per_step: f64,
    /// Bytes it must move at the least per step (each value read or written once).
    pub bytes_per_step: u64,
    pub bytes_per_s: f64,
    /// bytes_per_s / the copy kernel's bandwidth.
    pub fraction_of_copy: f64,
    /// Steps timed.
    pub steps: u32,
}

// ---------------------------------------------------------------- machine description

fn read(path: &str) -> String {
    std::fs::read_to_string(path).unwrap_or_default()
}

fn loadavg() -> [f64; 3] {
    let s = read("/proc/loadavg");
    let mut it = s.split_whitespace().map(|x| x.parse().unwrap_or(f64::NAN));
    [
        it.next().unwrap_or(f64::NAN),
        it.next().unwrap_or(f64::NAN),
        it.next().unwrap_or(f64::NAN),
    ]
}

fn size_bytes(s: &str) -> u64 {
    let s = s.trim();
    let (num, mul) = if let Some(n) = s.strip_suffix('K') {
        (n, 1 << 10)
    } else if let Some(n) = s.strip_suffix('M') {
        (n, 1 << 20)
    } else if let Some(n) = s.strip_suffix('G') {
        (n, 1 << 30)
    } else {
        (s, 1)
    };
    num.parse::<u64>().map_or(0, |n| n * mul)
}

fn machine() -> Machine {
    let cpuinfo = read("/proc/cpuinfo");
    let cpu_model = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map_or_else(|| "unknown".to_string(), |(_, v)| v.trim().to_string());
    let logical_cpus = cpuinfo
        .lines()
        .filter(|l| l.starts_with("processor"))
        .count();
    let mut caches = Vec::new();
    for i in 0..8 {
        let dir = format!("/sys/devices/system/cpu/cpu0/cache/index{i}");
        let size = read(&format!("{dir}/size")).trim().to_string();
        if size.is_empty() {
            break;
        }
        caches.push(Cache {
            level: format!("L{}", read(&format!("{dir}/level")).trim()),
            kind: read(&format!("{dir}/type")).trim().to_string(),
            bytes: size_bytes(&size),
            size,
        });
    }
    let memory = read("/proc/meminfo")
        .lines()
        .find(|l| l.starts_with("MemTotal"))
        .and_then(|l| l.split_once(':'))
        .map_or_else(String::new, |(_, v)| v.trim().to_string());
    let os = read("/etc/os-release")
        .lines()
        .find_map(|l| l.strip_prefix("PRETTY_NAME="))
        .map_or_else(
            || std::env::consts::OS.to_string(),
            |v| v.trim_matches('"').to_string(),
        );
    let env = ["WGPU_BACKEND", "RAYON_NUM_THREADS", "LP_NUM_THREADS"]
        .iter()
        .filter_map(|k| std::env::var(k).ok().map(|v| (k.to_string(), v)))
        .collect();
    Machine {
        cpu_model,
        logical_cpus,
        available_parallelism: std::thread::available_parallelism().map_or(0, |n| n.get()),
        caches,
        memory,
        os,
        kernel: format!(
            "{} {}",
            read("/proc/sys/kernel/ostype").trim(),
            read("/proc/sys/kernel/osrelease").trim()
        ),
        build: if cfg!(debug_assertions) {
            "debug"
        } else {
            "release"
        },
        loadavg_start: loadavg(),
        loadavg_end: [f64::NAN; 3],
        gpu: None,
        gpu_skipped: None,
        env,
    }
}

/// "2026-11-22 07:40:28" from the system clock (UTC).
fn utc_now() -> String {
    utc(std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64)
}

/// Seconds since the epoch → "YYYY-MM-DD hh:mm:ss" (civil-from-days, H. Hinnant).
fn utc(secs: i64) -> String {
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02}:{:02}",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

// ---------------------------------------------------------------- kernels

/// Everything a kernel run needs.
struct Ctx {
    plan: Plan,
    /// Cores a device without a thread count (the GPU driver, e.g. lavapipe) may use.
    cores: usize,
    quick: bool,
    pools: Vec<rayon::ThreadPool>,
    gpu: Option<Arc<GpuContext>>,
    /// The same adapter with f32 kernels, beside f64 ones (fluid rows "gpu-f32").
    gpu32: Option<Arc<GpuContext>>,
    rows: Vec<Row>,
    skipped: Vec<Skipped>,
}

/// The fields of a row known before the measurement.
struct Problem {
    kernel: &'static str,
    problem: String,
    size: usize,
    unit: &'static str,
    updates: u64,
    working_set: Option<u64>,
    neighbours: Option<f64>,
    setup_s: f64,
}

impl Ctx {
    fn push(&mut self, p: &Problem, device: &str, threads: Option<usize>, t: Timing) {
        let row = Row {
            kernel: p.kernel.to_string(),
            device: device.to_string(),
            threads,
            problem: p.problem.clone(),
            size: p.size,
            unit: p.unit.to_string(),
            updates_per_step: p.updates,
            steps_per_sample: t.batch,
            samples: t.samples,
            median_step_s: t.median,
            p10_step_s: t.p10,
            p90_step_s: t.p90,
            throughput_per_s: p.updates as f64 / t.median,
            ns_per_update: 1e9 * t.median / p.updates as f64,
            cost_growth: f64::NAN,
            cpu_ns_per_update: t.cpu_mean.map(|c| 1e9 * c / p.updates as f64),
            cpu_cost_growth: None,
            core_share: t
                .cpu_mean
                .map(|c| c / (t.wall_mean * threads.unwrap_or(self.cores).max(1) as f64)),
            neighbours_per_update: p.neighbours,
            loadavg_1min: loadavg()[0],
            working_set_bytes: p.working_set,
            setup_s: p.setup_s,
            note: String::new(),
            paired_speedup: None,
            pairs: None,
        };
        println!(
            "{:>18} {:>5} {:<28} {:>12.4} ms/step {:>10.3} M {}/s {:>8.2} ns/update",
            row.kernel,
            match threads {
                Some(n) => format!("{n}t"),
                None => device.to_string(),
            },
            row.problem,
            1e3 * row.median_step_s,
            row.throughput_per_s / 1e6,
            row.unit,
            row.ns_per_update
        );
        self.rows.push(row);
    }

    /// Measure every problem of one kernel on every device, the sizes in turn for
    /// `plan.rounds` rounds, and push the rows (sizes in order, CPU threads then GPU).
    fn sweep(&mut self, cases: &mut [Case]) -> anyhow::Result<()> {
        let plan = self.plan;
        // (case, pool index or None for a GPU variant, that variant, samples)
        let mut items: Vec<(usize, Option<usize>, usize, Acc)> = Vec::new();
        for (c, case) in cases.iter_mut().enumerate() {
            for (j, pool) in self.pools.iter().enumerate() {
                let Some(cpu) = case.cpu.as_mut() else {
                    break;
                };
                let acc = pool
                    .install(|| Acc::calibrate(&plan, cpu))
                    .with_context(|| format!("{} on {} thread(s)", case.p.problem, j + 1))?;
                items.push((c, Some(j), 0, acc));
            }
            for (v, (label, g)) in case.gpu.iter_mut().enumerate() {
                let acc = Acc::calibrate(&plan, g)
                    .with_context(|| format!("{} on the {label} path", case.p.problem))?;
                items.push((c, None, v, acc));
            }
        }
        // The CPU pools of a problem take their samples in pairs, one after the other (which
        // goes first alternates): the speed-up of 2 threads is the median of the pairs' ratios.
        for (c, case) in cases.iter_mut().enumerate() {
            let mine: Vec<usize> = (0..items.len())
                .filter(|&i| items[i].0 == c && items[i].1.is_some())
                .collect();
            let n = mine.iter().map(|&i| items[i].3.target).max().unwrap_or(0);
            for s in 0..n {
                for k in 0..mine.len() {
                    let i = mine[if s % 2 == 0 { k } else { mine.len() - 1 - k }];
                    let (_, dev, _, acc) = &mut items[i];
                    if let (Some(j), Some(cpu)) = (dev, case.cpu.as_mut()) {
                        self.pools[*j].install(|| acc.take(cpu, 1))?;
                    }
                }
            }
        }
        let rounds = plan.rounds.max(1);
        for r in 0..rounds {
            for (c, dev, v, acc) in items.iter_mut().filter(|it| it.1.is_none()) {
                let case = &mut cases[*c];
                // this round's share of the samples
                let upto = (acc.target * (r + 1)).div_ceil(rounds);
                let count = upto.saturating_sub(acc.samples.len());
                if count == 0 {
                    continue;
                }
                match dev {
                    Some(j) => {
                        if let Some(cpu) = case.cpu.as_mut() {
                            self.pools[*j].install(|| acc.take(cpu, count))?;
                        }
                    }
                    None => {
                        if let Some((_, g)) = case.gpu.get_mut(*v) {
                            acc.take(g, count)?;
                        }
                    }
                }
            }
        }
        for (c, dev, v, acc) in &items {
            let p = &cases[*c].p;
            match dev {
                Some(j) => {
                    let n = self.pools[*j].current_num_threads();
                    self.push(p, "cpu", Some(n), acc.timing());
                    // Pair this pool's samples with the 1-thread pool's of the same problem.
                    let one = items
                        .iter()
                        .find(|it| it.0 == *c && it.1.is_some_and(|k| k != *j))
                        .filter(|it| {
                            it.1.is_some_and(|k| self.pools[k].current_num_threads() == 1)
                        });
                    if let (Some((_, _, _, a1)), Some(row)) = (one, self.rows.last_mut()) {
                        let mut r: Vec<f64> = a1
                            .samples
                            .iter()
                            .zip(&acc.samples)
                            .map(|(a, b)| a / b)
                            .collect();
                        r.sort_by(f64::total_cmp);
                        if !r.is_empty() {
                            row.paired_speedup = Some(median(&r));
                            row.pairs = Some(r.len());
                        }
                    }
                }
                None => {
                    let label = cases[*c].gpu.get(*v).map_or("gpu", |g| g.0);
                    self.push(p, label, None, acc.timing());
                }
            }
        }
        Ok(())
    }
}

/// One problem size of a kernel: its CPU step (owning the state) and, where there is one,
/// its GPU step (owning the device state).
struct Case {
    p: Problem,
    /// `None` at the `--large` sizes (GPU only).
    cpu: Option<StepFn>,
    /// Its GPU steps: the device label of the row ("gpu", or "gpu-f32" for the f32 kernels
    /// beside f64 ones) and the step.
    gpu: Vec<(&'static str, StepFn)>,
}

/// The fluid step of `kernel`: on the 2-D cylindrical blast (`n`² cells, `fluid`), the 3-D
/// spherical blast (`n`³ cells, `fluid-3d`) or the 2-D TNT charge in air (`fluid-tnt`); with
/// `gpu_only` no host rows (and the host copy freed).
fn fluid(cx: &mut Ctx, n: usize, kernel: &'static str, gpu_only: bool) -> anyhow::Result<Case> {
    use fluid_node::{gpu::GpuEuler, setup, step};
    let t0 = Instant::now();
    let text = match kernel {
        "fluid-3d" => setup::benchmark_blast_case_3d(n),
        "fluid-tnt" => setup::benchmark_tnt_case(n),
        _ => setup::benchmark_blast_case(n),
    };
    let f0 = setup::from_toml_str(&text).map_err(|e| anyhow!("benchmark case: {e}"))?;
    let working_set = 8
        * (f0.cons.len()
            + f0.cons0.len()
            + f0.prim.len()
            + f0.flux.iter().map(Vec::len).sum::<usize>()) as u64;
    let p = Problem {
        kernel,
        problem: match kernel {
            "fluid-3d" => format!("blast 3-D {n}×{n}×{n} cells"),
            "fluid-tnt" => format!("TNT in air 2-D {n}×{n} cells"),
            _ => format!("blast 2-D {n}×{n} cells"),
        },
        size: n,
        unit: "cell-updates",
        updates: f0.grid.cells() as u64,
        working_set: Some(working_set),
        neighbours: None,
        setup_s: t0.elapsed().as_secs_f64(),
    };
    let mut gpu: Vec<(&'static str, StepFn)> = Vec::new();
    let devices = [("gpu", cx.gpu.clone()), ("gpu-f32", cx.gpu32.clone())];
    for (label, ctx) in devices {
        let Some(ctx) = ctx else { continue };
        let what = format!("{} at {} ({label})", p.kernel, p.problem);
        match fluid_node::gpu::supports(&f0) {
            Err(why) => skip(cx, &what, &why),
            // an adapter limit (the largest binding, 32-bit indices) skips this size's row
            Ok(()) => match GpuEuler::with_context(ctx, &f0) {
                Ok(mut g) => {
                    gpu.push((
                        label,
                        Box::new(move |k| {
                            g.steps_n(k, f64::INFINITY)?;
                            Ok(())
                        }),
                    ));
                }
                Err(e) => skip(cx, &what, &e.to_string()),
            },
        }
    }
    if gpu_only {
        return Ok(Case { p, cpu: None, gpu });
    }
    let mut f = f0;
    Ok(Case {
        p,
        cpu: Some(Box::new(move |k| {
            for _ in 0..k {
                step::step(&mut f, f64::INFINITY)?;
            }
            Ok(())
        })),
        gpu,
    })
}

fn skip(cx: &mut Ctx, kernel: &str, reason: &str) {
    println!("{kernel:>18}   gpu skipped: {reason}");
    cx.skipped.push(Skipped {
        kernel: kernel.into(),
        device: "gpu".into(),
        reason: reason.into(),
    });
}

fn pd(cx: &mut Ctx, kernel: &'static str, n: usize, gpu_only: bool) -> anyhow::Result<Case> {
    let t0 = Instant::now();
    let blk = solid_node::pd::cases::benchmark_block(n, kernel).map_err(|e| anyhow!("{e}"))?;
    let (mut b, bond, model_bytes) = (blk.body, blk.bond, blk.model_bytes.unwrap_or(0));
    // pd-bond with damage that happens: on top of the block's velocity field, every
    // particle gets a velocity of up to ±V in each component (a fixed pseudo-random
    // sequence). Neighbours moving apart stretch their bond by about V/c before the elastic
    // response turns them round; with V = 60 m/s the bonds whose stretch passes s0 = 1 %
    // break within the first steps, and the block then rings with the rest intact, so the
    // timed steps run on a block with a settled share of broken bonds (printed when the
    // problem is dropped), as on the CPU and the GPU rows alike.
    let shaken = kernel == "pd-bond";
    if shaken {
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        for v in b.vel.iter_mut() {
            for c in v.iter_mut() {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                *c += 60.0 * (2.0 * (seed >> 11) as f64 / (1u64 << 53) as f64 - 1.0);
            }
        }
    }
    let nb = b.bonds.len();
    let np = b.len();
    // pos, vel, force, fext, vpres, x0 (3 reals each), vol, offsets; per bond: nbr, xi,
    // inv_len, intact; and the model's own arrays (bond coefficients, or the
    // correspondence model's per-particle kinematics and state and per-bond data).
    let working_set = (np * (6 * 24 + 8 + 8) + nb * (4 + 24 + 8 + 8) + model_bytes) as u64;
    let p = Problem {
        kernel,
        problem: if shaken {
            format!("block {n}³ = {np} particles, breaking")
        } else {
            format!("block {n}³ = {np} particles")
        },
        size: n,
        unit: "bond-updates",
        updates: nb as u64,
        working_set: Some(working_set),
        neighbours: Some(nb as f64 / np as f64),
        setup_s: t0.elapsed().as_secs_f64(),
    };
    let dt = 0.5 * b.stable_dt();
    let mut gpu: Vec<(&'static str, StepFn)> = Vec::new();
    if let (Some(ctx), Some(model)) = (cx.gpu.clone(), bond) {
        // An adapter limit (e.g. the largest storage binding) skips the GPU row of this size
        // with the reason; the CPU rows are still measured.
        match solid_node::pd::gpu::GpuBondBody::new(ctx.clone(), &b, &model, Some(0.01)) {
            Ok(g) => {
                let mut g = BrokenShare::Gpu(Box::new(g), format!("{kernel} {n}³ gpu"));
                gpu.push((
                    "gpu",
                    Box::new(move |k| {
                        let BrokenShare::Gpu(g, _) = &mut g else {
                            unreachable!("a GPU body")
                        };
                        g.steps(k, dt).map_err(|e| anyhow!("{e}"))?;
                        ctx.device
                            .poll(wgpu::PollType::wait_indefinitely())
                            .map_err(|e| anyhow!("waiting for the device: {e}"))?;
                        ctx.take_uncaptured("pd-bond steps")
                            .map_err(|e| anyhow!("{e}"))
                    }),
                ));
            }
            Err(e) => skip(cx, &format!("{kernel} at {n}³"), &e.to_string()),
        }
    }
    if gpu_only {
        return Ok(Case { p, cpu: None, gpu });
    }
    let mut b = BrokenShare::Cpu(Box::new(b), format!("{kernel} {n}³ cpu"));
    Ok(Case {
        p,
        cpu: Some(Box::new(move |k| {
            let BrokenShare::Cpu(b, _) = &mut b else {
                unreachable!("a host body")
            };
            for _ in 0..k {
                b.step(dt);
            }
            Ok(())
        })),
        gpu,
    })
}

/// A PD benchmark body that prints, when the measurement is over and it is dropped, the
/// share of its bonds broken by then (the damage the timed steps included).
enum BrokenShare {
    Cpu(Box<solid_node::pd::integrate::Body>, String),
    Gpu(Box<solid_node::pd::gpu::GpuBondBody>, String),
}

impl Drop for BrokenShare {
    fn drop(&mut self) {
        let (broken, total, what) = match self {
            BrokenShare::Cpu(b, what) => {
                let mut bonds = b.bonds.clone();
                b.model.sync_bonds(&mut bonds);
                let broken = bonds.intact.iter().filter(|&&w| w == 0.0).count();
                (broken, bonds.len(), what)
            }
            BrokenShare::Gpu(g, what) => match g.intact_bits() {
                Ok(bits) => {
                    let intact: u32 = bits.iter().map(|w| w.count_ones()).sum();
                    let total = g.bonds();
                    (total - intact as usize, total, what)
                }
                Err(_) => return,
            },
        };
        if total > 0 {
            println!(
                "{what:>18}   {:.1} % of the bonds broken at the end ({broken} of {total})",
                100.0 * broken as f64 / total as f64
            );
        }
    }
}

fn shell(n: usize) -> anyhow::Result<Case> {
    use macro_shell_node::step;
    let t0 = Instant::now();
    // Five through-thickness points (the default).
    let mut s =
        macro_shell_node::setup::benchmark_plate(n, 5).map_err(|e| anyhow!("shell plate: {e}"))?;
    let m = &mut s.model;
    let p = Problem {
        kernel: "shell",
        problem: format!("plate {n}×{n} elements"),
        size: n,
        unit: "element-cycles",
        updates: m.num_elements() as u64,
        working_set: Some(shell_bytes(m)),
        neighbours: None,
        setup_s: t0.elapsed().as_secs_f64(),
    };
    let dt = step::stable_dt(m);
    Ok(Case {
        p,
        cpu: Some(Box::new(move |k| {
            for _ in 0..k {
                step::step(&mut s.model, dt)?;
            }
            Ok(())
        })),
        gpu: Vec::new(),
    })
}

fn joint(n: usize) -> anyhow::Result<Case> {
    let t0 = Instant::now();
    let m =
        meso_joint_node::geometry::benchmark_block(n).map_err(|e| anyhow!("joint block: {e}"))?;
    let problem = format!("block {n}³ = {} particles", m.len());
    let (updates, bytes) = (m.len() as u64, joint_bytes(&m));
    joint_case(
        m,
        "joint",
        problem,
        n,
        "particle-updates",
        updates,
        Some(bytes),
        t0,
    )
}

/// The joint block of [`joint`] as hexahedra around a central SPG core a third of its side
/// (a 27th of its cells): one update is one lattice cell's material advanced one step, so its
/// rows compare with the all-particle block's of the same size.
fn joint_solid(n: usize) -> anyhow::Result<Case> {
    let t0 = Instant::now();
    let m = meso_joint_node::geometry::benchmark_block_solid(n)
        .map_err(|e| anyhow!("joint block with solid elements: {e}"))?;
    let elements = m.solid.as_ref().map_or(0, |s| s.part.elements.len());
    let problem = format!(
        "block {n}³ cells: {elements} hexahedra around {} particles",
        m.len()
    );
    let cells = (n * n * n) as u64;
    joint_case(
        m,
        "joint-solid",
        problem,
        n,
        "cell-updates",
        cells,
        None,
        t0,
    )
}

/// A joint model stepped at its stable step as a benchmark case.
#[allow(clippy::too_many_arguments)]
fn joint_case(
    mut m: meso_joint_node::model::Model,
    kernel: &'static str,
    problem: String,
    size: usize,
    unit: &'static str,
    updates: u64,
    working_set: Option<u64>,
    t0: Instant,
) -> anyhow::Result<Case> {
    let p = Problem {
        kernel,
        problem,
        size,
        unit,
        updates,
        working_set,
        neighbours: Some(m.rows.cols.len() as f64 / m.len() as f64),
        setup_s: t0.elapsed().as_secs_f64(),
    };
    let dt = m.stable_dt();
    Ok(Case {
        p,
        cpu: Some(Box::new(move |k| {
            for _ in 0..k {
                m.step(dt).map_err(|e| anyhow!("{kernel} step: {e}"))?;
            }
            Ok(())
        })),
        gpu: Vec::new(),
    })
}

/// Bytes of the shell model's node and element arrays that a step reads or writes.
fn shell_bytes(m: &macro_shell_node::model::Model) -> u64 {
    use std::mem::size_of_val as sz;
    let vec3 = [
        &m.x0, &m.x, &m.v, &m.w, &m.n0, &m.f_ext, &m.f_c, &m.m_c, &m.v_pres,
    ]
    .iter()
    .map(|a| sz(&a[..]))
    .sum::<usize>();
    let nodes = vec3 + sz(&m.q[..]) + sz(&m.mass[..]) + sz(&m.inertia[..]) + sz(&m.fix[..]);
    let nodes = nodes + sz(&m.reaction[..]) + sz(&m.adj_offsets[..]) + sz(&m.adj[..]);
    let elements = sz(&m.conn[..])
        + sz(&m.stress[..])
        + sz(&m.plastic[..])
        + sz(&m.res[..])
        + sz(&m.fe[..])
        + sz(&m.pressure[..])
        + sz(&m.h0[..]);
    (nodes + elements) as u64
}

/// Bytes of the MC-SPG model's per-particle and per-entry arrays that a step reads or writes.
fn joint_bytes(m: &meso_joint_node::model::Model) -> u64 {
    use std::mem::size_of_val as sz;
    let r = &m.rows;
    let entries = sz(&r.cols[..])
        + sz(&r.row_of[..])
        + sz(&r.mirror[..])
        + sz(&r.alive[..])
        + sz(&r.len0[..])
        + sz(&r.phi[..])
        + sz(&r.grad[..])
        + sz(&r.psi[..])
        + sz(&r.psi_t[..])
        + sz(&r.grad_t[..]);
    let vec3 = [&m.x0, &m.xa, &m.x, &m.xh, &m.u, &m.vh, &m.v, &m.f, &m.acc]
        .iter()
        .map(|a| sz(&a[..]))
        .sum::<usize>();
    let reals = [
        &m.mass, &m.mh, &m.ms, &m.rho, &m.vol, &m.vol0, &m.vol_a, &m.eint,
    ]
    .iter()
    .map(|a| sz(&a[..]))
    .sum::<usize>();
    let mats = [&m.fhat, &m.ftot_a, &m.finv_a, &m.bmat]
        .iter()
        .map(|a| sz(&a[..]))
        .sum::<usize>();
    (entries + vec3 + reals + mats + sz(&m.mat[..])) as u64
}

/// The transports' round trips as rows (one update = one payload byte), plus their table.
fn transport(cx: &mut Ctx, errors: &mut Vec<String>) -> Option<String> {
    use protocol::transport::TransportKind;
    use protocol::transport::bench::{BenchTable, bench_transport};
    let exe = match std::env::current_exe() {
        Ok(e) => e,
        Err(e) => {
            errors.push(format!("transport: {e}"));
            return None;
        }
    };
    let sizes = sizes("transport", cx.quick);
    let mut all = Vec::new();
    for kind in [
        TransportKind::Local,
        TransportKind::Shm,
        TransportKind::Zenoh,
    ] {
        let mut cmd = std::process::Command::new(&exe);
        cmd.arg("echo");
        match bench_transport(kind, &sizes, cx.plan.transport_rounds, &mut cmd) {
            Ok(rows) => {
                for r in &rows {
                    let p = Problem {
                        kernel: "transport",
                        problem: format!("window round trip, {} B payload", r.bytes),
                        size: r.bytes,
                        unit: "bytes",
                        updates: r.bytes as u64,
                        working_set: Some(2 * r.bytes as u64),
                        neighbours: None,
                        setup_s: 0.0,
                    };
                    let t = Timing {
                        median: r.median_us * 1e-6,
                        p10: r.p10_us * 1e-6,
                        p90: r.p90_us * 1e-6,
                        batch: 1,
                        samples: r.rounds,
                        wall_mean: r.median_us * 1e-6,
                        cpu_mean: None,
                    };
                    cx.push(&p, kind.as_str(), None, t);
                }
                all.extend(rows);
            }
            Err(e) => {
                println!("         transport {:>5} skipped: {e}", kind.as_str());
                cx.skipped.push(Skipped {
                    kernel: "transport".into(),
                    device: kind.as_str().into(),
                    reason: e.to_string(),
                });
            }
        }
    }
    (!all.is_empty()).then(|| BenchTable(&all).to_string())
}

// ---------------------------------------------------------------- analysis

fn human(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= (1u64 << 30) as f64 {
        format!("{:.1} GiB", b / (1u64 << 30) as f64)
    } else if b >= (1u64 << 20) as f64 {
        format!("{:.1} MiB", b / (1u64 << 20) as f64)
    } else {
        format!("{:.0} KiB", b / 1024.0)
    }
}

fn seconds(s: f64) -> String {
    if s >= 1.0 {
        format!("{s:.3} s")
    } else if s >= 1e-3 {
        format!("{:.3} ms", s * 1e3)
    } else {
        format!("{:.1} µs", s * 1e6)
    }
}

/// What the fixed per-step cost of a device is made of.
fn fixed_cost_cause(device: &str, threads: Option<usize>) -> &'static str {
    match (device, threads) {
        ("cpu", Some(1)) => "serial per-step work (boundary fill, reductions, loop set-up)",
        ("cpu", _) => "thread fork/join and serial per-step work",
        ("gpu" | "gpu-f32", _) => "command submission, dispatch and synchronisation",
        _ => "message latency (wake-up, envelope, control messages)",
    }
}

/// Relative weighted least squares t = a + b·n (weights 1/t²): returns (a, b).
fn fit_line(pts: &[(f64, f64)]) -> (f64, f64) {
    let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(x, y) in pts {
        let w = 1.0 / (y * y).max(f64::MIN_POSITIVE);
        sw += w;
        sx += w * x;
        sy += w * y;
        sxx += w * x * x;
        sxy += w * x * y;
    }
    let det = sw * sxx - sx * sx;
    if pts.len() < 2 || det.abs() <= 1e-12 * sw * sxx {
        let (x, y) = pts.first().copied().unwrap_or((1.0, 0.0));
        return (0.0, y / x.max(f64::MIN_POSITIVE));
    }
    ((sy * sxx - sx * sxy) / det, (sw * sxy - sx * sy) / det)
}

/// The value of `v` farthest from 1.
fn farthest_from_one(v: impl Iterator<Item = f64>) -> f64 {
    v.fold(1.0, |w, g| {
        if (g - 1.0).abs() > (w - 1.0).abs() {
            g
        } else {
            w
        }
    })
}

fn within_25(g: f64) -> bool {
    (0.75..=1.25).contains(&g)
}

/// Cost growth, series fits and the note of each row, from the measured data.
fn analyse(rows: &mut [Row], caches: &[Cache], cpus: usize) -> Vec<Fit> {
    let l2 = caches
        .iter()
        .filter(|c| c.level == "L2")
        .map(|c| c.bytes)
        .max()
        .unwrap_or(0);
    let llc = caches.iter().map(|c| c.bytes).max().unwrap_or(0);
    let mut series: Vec<(String, String, Option<usize>)> = Vec::new();
    for r in rows.iter() {
        if !series.contains(&r.series()) {
            series.push(r.series());
        }
    }
    let mut fits = Vec::new();
    for s in series {
        let idx: Vec<usize> = (0..rows.len()).filter(|&i| rows[i].series() == s).collect();
        let i0 = idx[0];
        let base = rows[i0].ns_per_update;
        let cpu_base = rows[i0].cpu_ns_per_update;
        // Fit on CPU time when every size has it (robust to load), else on the wall clock.
        let cpu_pts: Option<Vec<(f64, f64)>> = idx
            .iter()
            .map(|&i| {
                let n = rows[i].updates_per_step as f64;
                rows[i].cpu_ns_per_update.map(|c| (n, 1e-9 * c * n))
            })
            .collect();
        let basis = if cpu_pts.is_some() { "cpu" } else { "wall" };
        let pts: Vec<(f64, f64)> = cpu_pts.unwrap_or_else(|| {
            idx.iter()
                .map(|&i| (rows[i].updates_per_step as f64, rows[i].median_step_s))
                .collect()
        });
        let (a, b) = fit_line(&pts);
        for &i in &idx {
            rows[i].cost_growth = rows[i].ns_per_update / base;
            rows[i].cpu_cost_growth = rows[i]
                .cpu_ns_per_update
                .zip(cpu_base)
                .map(|(c, c0)| c / c0);
        }
        let worst = farthest_from_one(idx.iter().map(|&i| rows[i].cost_growth));
        let cpu_worst = idx
            .iter()
            .map(|&i| rows[i].cpu_cost_growth)
            .collect::<Option<Vec<f64>>>()
            .map(|v| farthest_from_one(v.into_iter()));
        let is_transport = s.0 == "transport";
        let t0 = pts[0].1;
        let r0 = rows[i0].clone();
        let spread0 = r0.p90_step_s / r0.p10_step_s;
        for (k, &i) in idx.iter().enumerate() {
            let r = &rows[i];
            let g = r.cost_growth;
            let mut note = String::new();
            if is_transport {
                note = format!(
                    "latency {} + {:.3} ns/B: the fixed latency dominates below ~{}",
                    seconds(a.max(0.0)),
                    b * 1e9,
                    human((a / b.max(1e-30)).clamp(0.0, 1e15) as u64)
                );
            } else if k == 0 {
                if a > 0.2 * t0 && a < t0 {
                    note = format!(
                        "fixed cost ≈ {} per step ({:.0} % of this step): {}",
                        seconds(a),
                        100.0 * a / t0,
                        fixed_cost_cause(&s.1, s.2)
                    );
                }
            } else if !within_25(g) {
                let mut why = Vec::new();
                let share = |q: &Row| q.core_share.map_or(f64::NAN, |x| 100.0 * x);
                // 1. Load: the CPU time per update stayed linear, only the wall clock moved.
                if let Some(gc) = r.cpu_cost_growth
                    && within_25(gc)
                    && (gc - 1.0).abs() < 0.5 * (g - 1.0).abs()
                {
                    why.push(format!(
                            "load, not the kernel: CPU time per update is {gc:.2}× the smallest's; the step got {:.0} % of its core(s) here, {:.0} % at the smallest (load average {:.1} on {cpus} CPUs)",
                            share(r),
                            share(&r0),
                            r.loadavg_1min
                        ));
                }
                // 1b. Descheduled (also inflates the CPU time of 2 threads: the waiting one spins).
                if let (Some(sh), Some(sh0)) = (r.core_share, r0.core_share) {
                    let loaded = sh < 0.75 * sh0 || sh0 < 0.75 * sh;
                    if loaded && !why.iter().any(|w: &String| w.starts_with("load")) {
                        why.push(format!(
                            "load: the step got {:.0} % of its core(s) here, {:.0} % at the smallest (load average {:.1} on {cpus} CPUs{})",
                            share(r),
                            share(&r0),
                            r.loadavg_1min,
                            if s.2.is_some_and(|t| t > 1) {
                                "; a descheduled worker also makes the other spin, inflating CPU time"
                            } else {
                                ""
                            }
                        ));
                    }
                }
                // 2. More work per update: larger (less surface-truncated) families.
                if let (Some(n), Some(n0)) = (r.neighbours_per_update, r0.neighbours_per_update) {
                    let ratio = n / n0;
                    let gw = r.cpu_cost_growth.unwrap_or(g);
                    if ratio > 1.05 && (gw > 1.0) == (ratio > 1.0) {
                        why.push(format!(
                            "{n0:.1} → {n:.1} neighbour entries per particle (×{ratio:.2}: fewer surface-truncated families), so more work per update"
                        ));
                    }
                }
                let gw = r.cpu_cost_growth.unwrap_or(g);
                if why.is_empty() || !within_25(gw) {
                    if gw > 1.25 {
                        // 3. Caches.
                        if let (Some(w), Some(w0)) = (r.working_set_bytes, r0.working_set_bytes) {
                            if w > llc && w0 <= llc {
                                why.push(format!(
                                    "working set ≈ {} exceeds the {} last-level cache ({} at the smallest)",
                                    human(w),
                                    human(llc),
                                    human(w0)
                                ));
                            } else if w > 4 * l2 {
                                why.push(format!(
                                    "working set ≈ {} vs {} at the smallest, beyond the {} L2: streams from the shared L3/memory",
                                    human(w),
                                    human(w0),
                                    human(l2)
                                ));
                            }
                        }
                    } else if gw < 0.75 && a > 0.0 {
                        why.push(format!(
                            "the smallest size carries the fixed cost ≈ {} per step ({})",
                            seconds(a),
                            fixed_cost_cause(&s.1, s.2)
                        ));
                    }
                }
                // 4. Noise.
                let spread = r.p90_step_s / r.p10_step_s;
                if spread > 1.25 || spread0 > 1.25 {
                    why.push(format!(
                        "timings spread p90/p10 = {spread:.2} here, {spread0:.2} at the smallest"
                    ));
                }
                if why.is_empty() {
                    why.push("not explained by the data: investigate".into());
                }
                note = format!(
                    "FLAG {}{:.0} %: {}",
                    if g > 1.0 { "+" } else { "−" },
                    100.0 * (g - 1.0).abs(),
                    why.join("; ")
                );
            }
            rows[i].note = note;
        }
        fits.push(Fit {
            kernel: s.0.clone(),
            device: s.1.clone(),
            threads: s.2,
            basis,
            fixed_s: a,
            marginal_ns: b * 1e9,
            max_growth: worst,
            max_cpu_growth: cpu_worst,
            linear_within_25_percent: within_25(worst),
            cpu_linear_within_25_percent: cpu_worst.map(within_25),
        });
    }
    fits
}

// ---------------------------------------------------------------- output

fn fmt_rate(x: f64) -> String {
    if x >= 1e9 {
        format!("{:.2} G", x / 1e9)
    } else if x >= 1e6 {
        format!("{:.2} M", x / 1e6)
    } else if x >= 1e3 {
        format!("{:.1} k", x / 1e3)
    } else {
        format!("{x:.1}")
    }
}

fn device_label(r_device: &str, threads: Option<usize>) -> String {
    match threads {
        Some(n) => format!("{r_device} {n}t"),
        None => r_device.to_string(),
    }
}

/// The Markdown report.
pub fn markdown(rep: &Report) -> String {
    let m = &rep.machine;
    let mut s = String::new();
    let _ = writeln!(s, "# cosim bench\n");
    let _ = writeln!(
        s,
        "Measured {} UTC{} in {:.0} s.\n",
        rep.started_utc,
        if rep.quick {
            " (--quick: tiny sizes, not representative)"
        } else {
            ""
        },
        rep.total_wall_s
    );
    let caches: Vec<String> = m
        .caches
        .iter()
        .filter(|c| c.kind != "Instruction")
        .map(|c| format!("{} {}", c.level, c.size))
        .collect();
    let _ = writeln!(
        s,
        "* CPU: {} — {} logical CPUs ({} available), caches {}; memory {}",
        m.cpu_model,
        m.logical_cpus,
        m.available_parallelism,
        caches.join(", "),
        m.memory
    );
    let _ = writeln!(s, "* OS: {}, {}; {} build", m.os, m.kernel, m.build);
    let _ = writeln!(
        s,
        "* Load average (1/5/15 min): {:.2} {:.2} {:.2} at the start, {:.2} {:.2} {:.2} at the end — a shared machine: other jobs compete for the cores, so rates are lower bounds",
        m.loadavg_start[0],
        m.loadavg_start[1],
        m.loadavg_start[2],
        m.loadavg_end[0],
        m.loadavg_end[1],
        m.loadavg_end[2]
    );
    match (&m.gpu, &m.gpu_skipped) {
        (Some(g), _) => {
            let _ = writeln!(
                s,
                "* GPU: {} ({}, {}), driver {} {}, {} kernels{}",
                g.name,
                g.backend,
                g.device_type,
                g.driver,
                g.driver_info,
                g.precision,
                g.warning
                    .as_deref()
                    .map_or_else(String::new, |w| format!(" — {w}"))
            );
        }
        (None, Some(why)) => {
            let _ = writeln!(s, "* GPU: none used — {why}");
        }
        (None, None) => {
            let _ = writeln!(s, "* GPU: not needed by the selected kernels");
        }
    }
    if !m.env.is_empty() {
        let e: Vec<String> = m.env.iter().map(|(k, v)| format!("{k}={v}")).collect();
        let _ = writeln!(s, "* Environment: {}", e.join(" "));
    }
    let _ = writeln!(
        s,
        "\nTime per step: median of the timed samples (≥ {} samples of k steps each after a warm-up step). Throughput = updates per step / median time per step. Cost growth = time per update / time per update at the smallest size of the same kernel and device (1.00 = linear cost). CPU time/update: the process's CPU time (all its threads) per step over the samples, per update — unlike the wall clock it does not count time spent waiting for a core, so its growth shows the kernel's own scaling on a loaded machine. Core share = CPU time / (wall time × cores the row may use). Notes flag a cost growth beyond ±25 % with the evidence from the data.\n",
        if rep.quick { 5 } else { 7 }
    );
    let _ = writeln!(
        s,
        "| kernel | device | problem | updates/step | unit | median time/step | throughput (updates/s) | time/update (ns) | cost growth | CPU time/update (ns) | CPU cost growth | core share | note |"
    );
    let _ = writeln!(
        s,
        "|---|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|"
    );
    let opt = |x: Option<f64>, f: &dyn Fn(f64) -> String| x.map_or_else(|| "–".to_string(), f);
    for r in &rep.results {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {:.3} | {:.2} | {} | {} | {} | {} |",
            r.kernel,
            device_label(&r.device, r.threads),
            r.problem,
            r.updates_per_step,
            r.unit,
            seconds(r.median_step_s),
            fmt_rate(r.throughput_per_s),
            r.ns_per_update,
            r.cost_growth,
            opt(r.cpu_ns_per_update, &|x| format!("{x:.3}")),
            opt(r.cpu_cost_growth, &|x| format!("{x:.2}")),
            opt(r.core_share, &|x| format!("{:.0} %", 100.0 * x)),
            r.note
        );
    }
    let _ = writeln!(
        s,
        "\nLinear fit t_step = a + b · updates per kernel and device (relative least squares; a: fixed cost per step, b: marginal cost per update; on the process CPU time where measured, else on the median wall time; a < 0 means the cost per update grows with the size):\n"
    );
    let _ = writeln!(
        s,
        "| kernel | device | fitted on | a (fixed/step) | b (ns/update) | cost growth farthest from 1 | same on CPU time | linear within 25 % |"
    );
    let _ = writeln!(s, "|---|---|---|---:|---:|---:|---:|---|");
    for f in &rep.fits {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.3} | {:.2} | {} | {} |",
            f.kernel,
            device_label(&f.device, f.threads),
            f.basis,
            if f.fixed_s >= 0.0 {
                seconds(f.fixed_s)
            } else {
                format!("−{}", seconds(-f.fixed_s))
            },
            f.marginal_ns,
            f.max_growth,
            opt(f.max_cpu_growth, &|x| format!("{x:.2}")),
            match (
                f.kernel.as_str(),
                f.linear_within_25_percent,
                f.cpu_linear_within_25_percent
            ) {
                ("transport", ..) => "no: latency-bound (see notes)",
                (_, true, _) => "yes",
                (_, false, Some(true)) => "on CPU time yes; wall clock no (load, see notes)",
                _ => "no (see notes)",
            }
        );
    }
    // Speed-ups, 2 threads over 1, per kernel and size.
    let mut sp = String::new();
    for r in rep.results.iter().filter(|r| r.threads == Some(2)) {
        if let Some(r1) = rep
            .results
            .iter()
            .find(|q| q.kernel == r.kernel && q.size == r.size && q.threads == Some(1))
        {
            let _ = writeln!(
                sp,
                "| {} | {} | {:.2} | {} |",
                r.kernel,
                r.problem,
                r1.median_step_s / r.median_step_s,
                match (r.paired_speedup, r.pairs) {
                    (Some(x), Some(n)) => format!("{x:.2} ({n} pairs)"),
                    _ => "—".into(),
                }
            );
        }
    }
    if !sp.is_empty() {
        let _ = writeln!(
            s,
            "\nSpeed-up of 2 threads over 1: the ratio of the two rows' medians, and the median of \
             the ratios of paired samples (a 1-thread and a 2-thread sample of the problem taken \
             back to back, so a drift in the machine's speed shifts both alike):\n\n\
             | kernel | problem | speed-up (medians) | speed-up (paired) |\n|---|---|---:|---:|\n{sp}"
        );
    }
    if !rep.skipped.is_empty() {
        let _ = writeln!(s, "\nSkipped:\n");
        for k in &rep.skipped {
            let _ = writeln!(s, "* {} on {}: {}", k.kernel, k.device, k.reason);
        }
    }
    if !rep.errors.is_empty() {
        let _ = writeln!(s, "\nErrors:\n");
        for e in &rep.errors {
            let _ = writeln!(s, "* {e}");
        }
    }
    if let Some(t) = &rep.transport_table {
        let _ = writeln!(
            s,
            "\nTransport round trips (`cosim bench transport` format):\n\n{t}"
        );
    }
    if let Some(t) = &rep.window_table {
        let _ = writeln!(s, "\n{t}");
    }
    if let Some(b) = &rep.bandwidth {
        let _ = writeln!(
            s,
            "\nGPU streaming bandwidth (bytes read + written per second, {} buffer, {} copies): copy engine {:.0} GB/s, copy kernel {:.0} GB/s.",
            human(b.buffer_bytes),
            b.repeats,
            b.copy_bytes_per_s / 1e9,
            b.kernel_bytes_per_s / 1e9
        );
    }
    if !rep.gpu_kernels.is_empty() {
        let _ = writeln!(
            s,
            "\nGPU fluid kernels, each dispatch in its own timed pass (device clock), per step; bytes are the least each must move:\n\n| problem | kernel | dispatches | µs/step | share | MB/step | GB/s | of copy kernel |\n|---|---|---:|---:|---:|---:|---:|---:|"
        );
        let mut by_problem: Vec<&str> = Vec::new();
        for r in &rep.gpu_kernels {
            if !by_problem.contains(&r.problem.as_str()) {
                by_problem.push(&r.problem);
            }
        }
        for prob in by_problem {
            let rows: Vec<&KernelRow> = rep
                .gpu_kernels
                .iter()
                .filter(|r| r.problem == prob)
                .collect();
            let total: f64 = rows.iter().map(|r| r.seconds_per_step).sum();
            for r in &rows {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {:.1} | {:.0} % | {:.2} | {:.0} | {:.0} % |",
                    r.problem,
                    r.kernel,
                    r.dispatches_per_step,
                    1e6 * r.seconds_per_step,
                    100.0 * r.seconds_per_step / total,
                    r.bytes_per_step as f64 / 1e6,
                    r.bytes_per_s / 1e9,
                    100.0 * r.fraction_of_copy
                );
            }
            let bytes: u64 = rows.iter().map(|r| r.bytes_per_step).sum();
            let _ = writeln!(
                s,
                "| {prob} | **step** | {} | {:.1} | 100 % | {:.2} | {:.0} | {:.0} % |",
                rows.iter().map(|r| r.dispatches_per_step).sum::<u32>(),
                1e6 * total,
                bytes as f64 / 1e6,
                bytes as f64 / total / 1e9,
                rep.bandwidth.as_ref().map_or(f64::NAN, |b| {
                    100.0 * bytes as f64 / total / b.kernel_bytes_per_s
                })
            );
        }
    }
    s
}

/// Kernel `gpu-profile`: the device's copy bandwidth, then each kernel of the fluid step
/// timed on the device clock at the largest 2-D and 3-D size of the plan.
fn gpu_profile(cx: &mut Ctx, large: bool) -> anyhow::Result<(BandwidthRow, Vec<KernelRow>)> {
    let ctx = cx.gpu.clone().ok_or_else(|| anyhow!("no GPU"))?;
    let (bytes, repeats) = if cx.quick {
        (16 << 20, 2)
    } else {
        (1 << 30, 20)
    };
    let bw = ctx.bandwidth(bytes, repeats).map_err(|e| anyhow!("{e}"))?;
    println!(
        "       gpu-profile  bandwidth: copy {:.1} GB/s, copy kernel {:.1} GB/s ({} buffer)",
        bw.copy / 1e9,
        bw.kernel / 1e9,
        human(bw.bytes)
    );
    let band = BandwidthRow {
        copy_bytes_per_s: bw.copy,
        kernel_bytes_per_s: bw.kernel,
        buffer_bytes: bw.bytes,
        repeats: bw.repeats,
    };
    if !ctx.timestamps {
        cx.skipped.push(Skipped {
            kernel: "gpu-profile".into(),
            device: "gpu".into(),
            reason: "the adapter has no timestamp queries: no per-kernel times".into(),
        });
        return Ok((band, Vec::new()));
    }
    let pick = |k: &str| {
        let mut v = sizes(k, cx.quick);
        if large {
            v.extend(large_sizes(k));
        }
        v.last().copied().unwrap_or(8)
    };
    let mut rows = Vec::new();
    for (n, three_d) in [(pick("fluid"), false), (pick("fluid-3d"), true)] {
        let text = if three_d {
            fluid_node::setup::benchmark_blast_case_3d(n)
        } else {
            fluid_node::setup::benchmark_blast_case(n)
        };
        let problem = if three_d {
            format!("blast 3-D {n}³")
        } else {
            format!("blast 2-D {n}²")
        };
        let f0 = fluid_node::setup::from_toml_str(&text).map_err(|e| anyhow!("{e}"))?;
        let mut g = match fluid_node::gpu::GpuEuler::with_context(ctx.clone(), &f0) {
            Ok(g) => g,
            Err(e) => {
                skip(cx, &format!("gpu-profile {problem}"), &e.to_string());
                continue;
            }
        };
        drop(f0);
        let steps = if cx.quick { 2 } else { 10 };
        let Some(prof) = g.profile(steps).map_err(|e| anyhow!("{problem}: {e}"))? else {
            continue;
        };
        for k in prof {
            let rate = k.bytes as f64 / k.seconds.max(1e-12);
            println!(
                "       gpu-profile  {problem:<16} {:<10} {:>3} dispatches {:>10.1} µs/step {:>8.1} GB/s {:>5.1} % of copy",
                k.kernel,
                k.dispatches,
                1e6 * k.seconds,
                rate / 1e9,
                100.0 * rate / bw.kernel
            );
            rows.push(KernelRow {
                problem: problem.clone(),
                kernel: k.kernel.to_string(),
                dispatches_per_step: k.dispatches,
                seconds_per_step: k.seconds,
                bytes_per_step: k.bytes,
                bytes_per_s: rate,
                fraction_of_copy: rate / bw.kernel,
                steps,
            });
        }
    }
    Ok((band, rows))
}

/// Run the suite; returns the exit code (0: all selected kernels ran; skipped GPU/transport
/// rows are not errors).
pub fn suite(args: &SuiteArgs) -> i32 {
    let kernels = match select(&args.only) {
        Ok(k) => k,
        Err(e) => {
            eprintln!("cosim bench: {e}");
            return 2;
        }
    };
    if let Err(e) = std::fs::create_dir_all(&args.output) {
        eprintln!("cosim bench: -o {}: {e}", args.output.display());
        return 1;
    }
    let started = Instant::now();
    let started_utc = utc_now();
    let mut mach = machine();
    let mut pools = Vec::new();
    for n in [1, 2] {
        match rayon::ThreadPoolBuilder::new().num_threads(n).build() {
            Ok(p) => pools.push(p),
            Err(e) => {
                eprintln!("cosim bench: rayon pool of {n} threads: {e}");
                return 1;
            }
        }
    }
    let wants_gpu = kernels.iter().any(|k| GPU_KERNELS.contains(k));
    let gpu = if !wants_gpu {
        None
    } else if args.no_gpu {
        mach.gpu_skipped = Some("--no-gpu".into());
        None
    } else {
        match GpuContext::new() {
            Ok(c) => {
                println!("GPU: {}", c.describe());
                mach.gpu = Some(Gpu {
                    name: c.info.name.clone(),
                    driver: c.info.driver.clone(),
                    driver_info: c.info.driver_info.clone(),
                    backend: format!("{:?}", c.info.backend),
                    device_type: format!("{:?}", c.info.device_type),
                    precision: c.precision.wgsl().to_string(),
                    warning: c.warning.clone(),
                });
                Some(Arc::new(c))
            }
            Err(e) => {
                let why = format!(
                    "no GPU adapter: {e} (on Linux without a GPU, Mesa's lavapipe: WGPU_BACKEND=vulkan)"
                );
                println!("GPU rows skipped: {why}");
                mach.gpu_skipped = Some(why);
                None
            }
        }
    };
    // f32 fluid rows where the f64 ones run in f64 (otherwise the "gpu" rows are f32)
    let gpu32 = match &gpu {
        Some(c)
            if c.precision == mechanics::gpu::Precision::F64
                && kernels.iter().any(|k| k.starts_with("fluid")) =>
        {
            GpuContext::with_precision(mechanics::gpu::PrecisionRequest::ForceF32)
                .ok()
                .map(Arc::new)
        }
        _ => None,
    };
    let mut cx = Ctx {
        plan: Plan::new(args.quick),
        cores: mach.available_parallelism.max(1),
        quick: args.quick,
        pools,
        gpu,
        gpu32,
        rows: Vec::new(),
        skipped: Vec::new(),
    };
    if cx.gpu.is_none() && wants_gpu {
        let why = mach.gpu_skipped.clone().unwrap_or_default();
        for k in kernels.iter().filter(|k| GPU_KERNELS.contains(k)) {
            cx.skipped.push(Skipped {
                kernel: (*k).into(),
                device: "gpu".into(),
                reason: why.clone(),
            });
        }
    }
    let mut errors = Vec::new();
    let mut transport_table = None;
    let mut windows = Vec::new();
    let mut window_table = None;
    let mut bandwidth = None;
    let mut gpu_kernels = Vec::new();
    for &k in &kernels {
        if k == "transport" {
            transport_table = transport(&mut cx, &mut errors);
            continue;
        }
        if k == "gpu-profile" {
            if cx.gpu.is_some() {
                match gpu_profile(&mut cx, args.large && !args.quick) {
                    Ok((bw, rows)) => {
                        bandwidth = Some(bw);
                        gpu_kernels = rows;
                    }
                    Err(e) => {
                        let msg = format!("gpu-profile: {e:#}");
                        eprintln!("cosim bench: {msg}");
                        errors.push(msg);
                    }
                }
            }
            continue;
        }
        if k == "window" {
            println!("            window  whole coupled windows through `cosim run` ...");
            match crate::window::run(args.quick) {
                Ok((rows, missing)) => {
                    let rt: Vec<(String, f64)> = cx
                        .rows
                        .iter()
                        .filter(|r| r.kernel == "transport" && r.size == 1024)
                        .map(|r| (r.device.clone(), r.median_step_s * 1e6))
                        .collect();
                    for m in &missing {
                        cx.skipped.push(Skipped {
                            kernel: "window".into(),
                            device: m.what.clone(),
                            reason: m.reason.clone(),
                        });
                    }
                    window_table = Some(crate::window::table(&rows, &missing, &rt));
                    windows = rows;
                }
                Err(e) => {
                    let msg = format!("window: {e:#}");
                    eprintln!("cosim bench: {msg}");
                    errors.push(msg);
                }
            }
            continue;
        }
        // Set every size up first, then measure them in turn.
        let mut cases = Vec::new();
        let mut failed = false;
        let large = if args.large && !args.quick && cx.gpu.is_some() {
            large_sizes(k)
        } else {
            Vec::new()
        };
        let all = sizes(k, args.quick).into_iter().map(|n| (n, false));
        for (n, gpu_only) in all.chain(large.into_iter().map(|n| (n, true))) {
            let r = match k {
                "fluid" | "fluid-3d" | "fluid-tnt" => fluid(&mut cx, n, k, gpu_only),
                "pd-bond" | "pd-correspondence" => pd(&mut cx, k, n, gpu_only),
                "shell" => shell(n),
                "joint" => joint(n),
                "joint-solid" => joint_solid(n),
                _ => continue,
            };
            match r {
                Ok(c) => cases.push(c),
                Err(e) => {
                    let msg = format!("{k} at size {n}: set-up: {e:#}");
                    eprintln!("cosim bench: {msg}");
                    errors.push(msg);
                    failed = true;
                    break;
                }
            }
        }
        if !failed && let Err(e) = cx.sweep(&mut cases) {
            let msg = format!("{k}: {e:#}");
            eprintln!("cosim bench: {msg}");
            errors.push(msg);
        }
    }
    mach.loadavg_end = loadavg();
    let mut rows = cx.rows;
    let fits = analyse(&mut rows, &mach.caches, mach.logical_cpus);
    let report = Report {
        started_utc,
        quick: args.quick,
        kernels: kernels.iter().map(|k| k.to_string()).collect(),
        total_wall_s: started.elapsed().as_secs_f64(),
        machine: mach,
        results: rows,
        fits,
        skipped: cx.skipped,
        errors,
        transport_table,
        windows,
        window_table,
        bandwidth,
        gpu_kernels,
    };
    match write(&report, &args.output) {
        Ok(md) => {
            println!("\n{md}");
            println!(
                "cosim bench: {} rows in {:.0} s; {} and {}",
                report.results.len(),
                report.total_wall_s,
                args.output.join("bench.json").display(),
                args.output.join("bench.md").display()
            );
        }
        Err(e) => {
            eprintln!("cosim bench: {e:#}");
            return 1;
        }
    }
    if report.errors.is_empty() { 0 } else { 1 }
}

fn write(rep: &Report, dir: &Path) -> anyhow::Result<String> {
    let json = serde_json::to_string_pretty(rep)?;
    std::fs::write(dir.join("bench.json"), json)
        .with_context(|| format!("writing {}", dir.join("bench.json").display()))?;
    let md = markdown(rep);
    std::fs::write(dir.join("bench.md"), &md)
        .with_context(|| format!("writing {}", dir.join("bench.md").display()))?;
    Ok(md)
}

// ---------------------------------------------------------------- transport subcommand

/// `cosim bench transport`: the round-trip table of one or all transports.
pub fn bench_transport(rounds: usize, which: &str, sizes: &[usize]) -> i32 {
    use protocol::transport::TransportKind;
    use protocol::transport::bench::{BenchTable, bench_transport as bench};
    let kinds = match which {
        "all" => vec![
            TransportKind::Local,
            TransportKind::Shm,
            TransportKind::Zenoh,
        ],
        k => match k.parse::<TransportKind>() {
            Ok(k) => vec![k],
            Err(e) => {
                eprintln!("cosim bench transport: --transport: {e}");
                return 2;
            }
        },
    };
    let exe = match std::env::current_exe() {
        Ok(e) => e,
        Err(e) => {
            eprintln!("cosim bench transport: {e}");
            return 1;
        }
    };
    let mut rows = Vec::new();
    for kind in kinds {
        let mut cmd = std::process::Command::new(&exe);
        cmd.arg("echo");
        match bench(kind, sizes, rounds.max(1), &mut cmd) {
            Ok(r) => rows.extend(r),
            Err(e) => {
                eprintln!("cosim bench transport: {}: {e}", kind.as_str());
                return 1;
            }
        }
    }
    println!("{}", BenchTable(&rows));
    0
}

/// The hidden `cosim-bench echo`: the echo side of a transport benchmark.
pub fn bench_echo() -> i32 {
    use protocol::transport::bench::{echo_main, echo_spec_from_env};
    match echo_spec_from_env().and_then(|s| echo_main(&s)) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("cosim-bench echo: {e}");
            1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_expands_aliases_and_refuses_unknown_names() {
        let s = |v: &[&str]| select(&v.iter().map(|x| x.to_string()).collect::<Vec<_>>());
        assert_eq!(
            s(&["solid", "fluid"]),
            Ok(vec!["fluid", "pd-bond", "pd-correspondence"])
        );
        assert_eq!(s(&[]).map(|k| k.len()), Ok(KERNELS.len()));
        let e = s(&["fluid", "lbm"]).unwrap_err();
        assert!(e.contains("--only") && e.contains("lbm"), "{e}");
    }

    #[test]
    fn utc_date_of_known_instants() {
        assert_eq!(utc(0), "1970-01-01 00:00:00");
        // `date -u -d @1700000000`; 951868800 is the leap day of 2000 (a 400-year century).
        assert_eq!(utc(1_700_000_000), "2023-11-14 22:13:20");
        assert_eq!(utc(951_868_800), "2000-03-01 00:00:00");
        assert_eq!(utc(951_782_400), "2000-02-29 00:00:00");
        assert_eq!(size_bytes("2048K"), 2 << 20);
        assert_eq!(size_bytes("32K"), 32 << 10);
    }

    fn row(n: u64, t: f64, ws: Option<u64>) -> Row {
        Row {
            kernel: "k".into(),
            device: "cpu".into(),
            threads: Some(1),
            problem: String::new(),
            size: n as usize,
            unit: "u".into(),
            updates_per_step: n,
            steps_per_sample: 1,
            samples: 5,
            median_step_s: t,
            p10_step_s: t,
            p90_step_s: t,
            throughput_per_s: n as f64 / t,
            ns_per_update: 1e9 * t / n as f64,
            cost_growth: f64::NAN,
            cpu_ns_per_update: None,
            cpu_cost_growth: None,
            core_share: None,
            neighbours_per_update: None,
            loadavg_1min: 0.0,
            working_set_bytes: ws,
            setup_s: 0.0,
            note: String::new(),
            paired_speedup: None,
            pairs: None,
        }
    }

    #[test]
    fn fit_recovers_fixed_and_marginal_cost_and_flags_growth() {
        // t = 1 ms + 10 ns · N exactly: the fit must return a = 1e-3 s, b = 10 ns.
        let mut rows: Vec<Row> = [1e4, 1e5, 1e6, 1e7]
            .iter()
            .map(|&n| row(n as u64, 1e-3 + 1e-8 * n, None))
            .collect();
        let fits = analyse(&mut rows, &[], 2);
        assert!((fits[0].fixed_s - 1e-3).abs() < 1e-12, "{:?}", fits[0]);
        assert!((fits[0].marginal_ns - 10.0).abs() < 1e-9, "{:?}", fits[0]);
        // smallest: (1 ms + 0.1 ms)/1e4 = 110 ns; largest (1 ms + 100 ms)/1e7 = 10.1 ns
        assert!((rows[3].cost_growth - 10.1 / 110.0).abs() < 1e-12);
        assert!(rows[3].note.starts_with("FLAG −"), "{}", rows[3].note);
        assert!(rows[0].note.contains("fixed cost"), "{}", rows[0].note);
        assert!(!fits[0].linear_within_25_percent);
        // Pure linear cost: growth 1, no flag.
        let mut lin: Vec<Row> = [1e4, 1e6]
            .iter()
            .map(|&n| row(n as u64, 1e-8 * n, None))
            .collect();
        let f = analyse(&mut lin, &[], 2);
        assert!((lin[1].cost_growth - 1.0).abs() < 1e-9 && lin[1].note.is_empty());
        assert!(f[0].linear_within_25_percent);
    }

    #[test]
    fn wall_clock_growth_with_linear_cpu_time_is_attributed_to_load() {
        // Same CPU time per update at both sizes, but the large one got half the core.
        let mut rows = vec![row(1000, 1e-3, None), row(10_000, 2e-2, None)];
        rows[0].cpu_ns_per_update = Some(1000.0);
        rows[0].core_share = Some(1.0);
        rows[1].cpu_ns_per_update = Some(1000.0);
        rows[1].core_share = Some(0.5);
        let f = analyse(&mut rows, &[], 2);
        assert!((rows[1].cost_growth - 2.0).abs() < 1e-12);
        assert_eq!(rows[1].cpu_cost_growth, Some(1.0));
        assert!(
            rows[1]
                .note
                .starts_with("FLAG +100 %: load, not the kernel"),
            "{}",
            rows[1].note
        );
        assert!(!f[0].linear_within_25_percent);
        assert_eq!(f[0].cpu_linear_within_25_percent, Some(true));
    }

    #[test]
    fn larger_families_and_caches_are_named_when_cpu_time_grows() {
        let mib = 1u64 << 20;
        let mut rows = vec![
            row(1000, 1e-3, Some(mib)),
            row(10_000, 1.6e-2, Some(400 * mib)),
        ];
        for (r, nb) in rows.iter_mut().zip([100.0, 120.0]) {
            r.cpu_ns_per_update = Some(r.ns_per_update);
            r.core_share = Some(1.0);
            r.neighbours_per_update = Some(nb);
        }
        let caches = [Cache {
            level: "L3".into(),
            kind: "Unified".into(),
            size: "256M".into(),
            bytes: 256 * mib,
        }];
        analyse(&mut rows, &caches, 2);
        let n = &rows[1].note;
        assert!(n.starts_with("FLAG +60 %"), "{n}");
        assert!(n.contains("100.0 → 120.0 neighbour entries"), "{n}");
        assert!(n.contains("exceeds the 256.0 MiB last-level cache"), "{n}");
        assert!(!n.contains("load"), "{n}");
    }
}
