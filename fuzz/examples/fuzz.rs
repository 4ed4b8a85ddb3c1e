//! The long fuzz run, outside the test suite: `cargo run --release -p cosim-fuzz --example
//! fuzz -- TARGET [INPUTS] [SEED]` (TARGET: wire, case or params; INPUTS default 1 000 000).
//! Every input runs under `catch_unwind`; a watchdog ends the run (exit 3) if one input
//! takes longer than 60 s. Prints inputs run, accepted, refused, panics, the slowest input
//! and the wall time; exit 1 if any input panicked.

use cosim_fuzz::*;
use proptest::strategy::{Strategy, ValueTree};
use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Slow-input threshold of the summary (s): inputs slower than this are counted as slow (a
/// hang is an input that does not finish: the watchdog's 60 s).
const SLOW_S: f64 = 1.0;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let target = args.first().map(String::as_str).unwrap_or("");
    let n: u64 = args
        .get(1)
        .and_then(|v| v.parse().ok())
        .unwrap_or(1_000_000);
    let seed: u64 = args.get(2).and_then(|v| v.parse().ok()).unwrap_or(20);
    let code = match target {
        "wire" => run(target, n, seed, wire_input(), |b| wire_target(b)),
        "case" => run(target, n, seed, case_input(), |(t, s)| case_target(t, s)),
        "params" => run(target, n, seed, params_input(), |(m, t)| {
            params_target(&MODELS[*m], t)
        }),
        _ => {
            eprintln!("usage: fuzz TARGET [INPUTS] [SEED], TARGET one of {TARGETS:?}");
            2
        }
    };
    std::process::exit(code);
}

fn run<S: Strategy>(
    name: &str,
    n: u64,
    seed: u64,
    strategy: S,
    target: impl Fn(&S::Value) -> bool,
) -> i32
where
    S::Value: std::fmt::Debug,
{
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    let rng = TestRng::from_seed(RngAlgorithm::ChaCha, &key);
    let mut runner = TestRunner::new_with_rng(Config::default(), rng);
    // the watchdog: progress every 30 s; no progress in 60 s is a hang
    let done = Arc::new(AtomicU64::new(0));
    let current: Arc<Mutex<String>> = Arc::new(Mutex::new(String::new()));
    {
        let (done, current, name) = (done.clone(), current.clone(), name.to_string());
        std::thread::spawn(move || {
            let (mut last, mut since) = (0, Instant::now());
            loop {
                std::thread::sleep(Duration::from_secs(30));
                let d = done.load(Ordering::Relaxed);
                eprintln!("{name}: {d} inputs");
                if d != last {
                    (last, since) = (d, Instant::now());
                } else if since.elapsed() > Duration::from_secs(60) {
                    let input = current.lock().map(|s| s.clone()).unwrap_or_default();
                    eprintln!("{name}: HANG: no input finished in 60 s; the input: {input}");
                    std::process::exit(3);
                }
            }
        });
    }
    // panics are counted, not printed one by one
    let first_panic: Arc<Mutex<Option<String>>> = Arc::new(Mutex::new(None));
    {
        let first = first_panic.clone();
        std::panic::set_hook(Box::new(move |info| {
            if let Ok(mut f) = first.lock()
                && f.is_none()
            {
                *f = Some(info.to_string());
            }
        }));
    }
    // FUZZ_TRACE=1 prints every input before it runs (the last one names a crash)
    let trace = std::env::var_os("FUZZ_TRACE").is_some();
    let wall = Instant::now();
    let (mut ok, mut err, mut panics, mut slow) = (0u64, 0u64, 0u64, 0u64);
    let mut slowest = 0.0f64;
    let mut first_input = None;
    for _ in 0..n {
        let input = match strategy.new_tree(&mut runner) {
            Ok(t) => t.current(),
            Err(e) => {
                eprintln!("{name}: no input: {e}");
                return 2;
            }
        };
        if let Ok(mut c) = current.lock() {
            *c = format!("{input:?}");
            if trace {
                eprintln!("input: {c}");
            }
        }
        let t = Instant::now();
        match catch_unwind(AssertUnwindSafe(|| target(&input))) {
            Ok(true) => ok += 1,
            Ok(false) => err += 1,
            Err(_) => {
                panics += 1;
                first_input.get_or_insert_with(|| format!("{input:?}"));
            }
        }
        let s = t.elapsed().as_secs_f64();
        slowest = slowest.max(s);
        if s > SLOW_S {
            slow += 1;
        }
        done.fetch_add(1, Ordering::Relaxed);
    }
    let _ = std::panic::take_hook();
    println!(
        "{name}: {} inputs, {ok} accepted, {err} refused, {panics} panics, 0 hangs, {slow} slower than {SLOW_S} s (slowest {:.3} s), wall {:.1} s",
        ok + err + panics,
        slowest,
        wall.elapsed().as_secs_f64()
    );
    if panics > 0 {
        if let Ok(f) = first_panic.lock() {
            println!("first panic: {}", f.clone().unwrap_or_default());
        }
        println!("its input: {}", first_input.unwrap_or_default());
        return 1;
    }
    0
}
