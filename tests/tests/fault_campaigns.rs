//! Fault campaigns on the example cases (docs/architecture.md):
//! `cosim` SIGKILLed at 20 random times during a small chamber run, and a random node of the
//! small crash tube (11 processes) SIGKILLed at 20 random times on shared memory and on
//! zenoh. Each kill must land mid-run; the draws come from a seeded generator whose seed is
//! printed (`COSIM_TEST_SEED` repeats a campaign).

use cosim_tests::*;
use std::path::{Path, PathBuf};
use std::process::Child;
use std::time::{Duration, Instant};

const KILLS: usize = 20;
/// Draws that may miss the run (it ended, or had not started, before the kill) before the
/// campaign gives up.
const TRIES: usize = 40;

fn example(name: &str) -> PathBuf {
    workspace_root().join("examples").join(name)
}

/// Wait until every node in `nodes` of run `id` runs; `false` if `child` ended first.
fn wait_for_nodes(child: &mut Child, id: &str, nodes: &[&str]) -> bool {
    let t = Instant::now();
    loop {
        if nodes.iter().all(|n| node_pid(id, n).is_some()) {
            return true;
        }
        if child.try_wait().ok().flatten().is_some() {
            return false;
        }
        assert!(
            t.elapsed() < Duration::from_secs(60),
            "the nodes of {id} never started"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn sigkill(pid: u32) {
    // SAFETY: kill with a pid of a process of this test's run and a valid signal number.
    unsafe { libc::kill(pid as i32, libc::SIGKILL) };
}

/// Seconds from "every node runs" to the end of an uninterrupted run of `case`, for drawing
/// kill times inside the run.
fn run_length(case: &Path, extra: &[&str], nodes: &[&str], tag: &str) -> f64 {
    let (dir, id) = scratch(tag);
    let mut child = spawn_cosim_with(case, &dir.join("out"), &id, extra);
    assert!(
        wait_for_nodes(&mut child, &id, nodes),
        "reference run ended early"
    );
    let t = Instant::now();
    let o = child.wait_with_output().expect("cosim ends");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    t.elapsed().as_secs_f64()
}

/// The newest window with a complete checkpoint (its `coordinator.ckpt`) under `out`.
fn newest_checkpoint(out: &Path) -> Option<u64> {
    std::fs::read_dir(out.join("checkpoints"))
        .ok()?
        .flatten()
        .filter_map(|e| {
            let w: u64 = e.file_name().to_str()?.strip_prefix('w')?.parse().ok()?;
            protocol::checkpoint::file(out, w, "coordinator")
                .exists()
                .then_some(w)
        })
        .max()
}

/// Must-show 2: SIGKILL of `cosim` at 20 random times during the small chamber run (with
/// checkpoints every 10 windows): every node gone within 2 s, the recording recoverable
/// with windows 1..=n and n at least the newest complete checkpoint (the recording is flushed
/// before a checkpoint completes), `cosim info` reading it as incomplete with at least those
/// windows, and no file of any killed run in /dev/shm after the next `cosim run`. A kill that
/// lands after the recording was finalised (the run had ended) is drawn again, from a span
/// shortened to that run's length.
#[test]
fn cosim_killed_at_20_random_times_during_a_chamber_run() {
    let case = example("chamber_detonation.toml");
    // 240 windows: a run long enough for kills anywhere in it.
    let extra = [
        "--variant",
        "small",
        "--set",
        "run.end_time=1.2e-3",
        "--set",
        "run.checkpoint_every=10",
    ];
    let nodes = ["gas", "bar"];
    let mut span = run_length(&case, &extra, &nodes, "ch-len");
    let mut draw = Draw::seeded();
    let seed = draw.0;
    println!("seed {seed} (COSIM_TEST_SEED repeats it); run length {span:.2} s");
    let mut killed = Vec::new();
    let mut bounded = 0;
    for k in 0..TRIES {
        if killed.len() == KILLS {
            break;
        }
        let after = Duration::from_secs_f64(draw.uniform() * 0.8 * span);
        let (dir, id) = scratch(&format!("ch-k{k}"));
        let out = dir.join("out");
        let mut child = spawn_cosim_with(&case, &out, &id, &extra);
        if !wait_for_nodes(&mut child, &id, &nodes) {
            continue;
        }
        // The machine's load changes the run's length: a run that ends before its kill
        // shortens the span drawn from.
        let started = Instant::now();
        while started.elapsed() < after && child.try_wait().ok().flatten().is_none() {
            std::thread::sleep(Duration::from_millis(2));
        }
        if child.try_wait().ok().flatten().is_some() {
            span = span.min(started.elapsed().as_secs_f64());
            println!(
                "draw {k}: the run ended before the kill at {after:?}; drawn again from {span:.2} s"
            );
            continue;
        }
        sigkill(child.id());
        let t = Instant::now();
        let _ = child.wait();
        while !live_processes(&id).is_empty() && t.elapsed() < Duration::from_secs(2) {
            std::thread::sleep(Duration::from_millis(10));
        }
        let gone = t.elapsed();
        let alive = live_processes(&id);
        assert!(
            alive.is_empty(),
            "seed {seed}, kill at {after:?}: nodes alive 2 s after cosim's SIGKILL: {alive:?}"
        );
        let o = cosim(&["info", out.to_str().expect("utf-8 path")]);
        let info = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "seed {seed}: cosim info: {info}");
        if !info.contains("INCOMPLETE") {
            // Killed while writing its summary: the recording was already finalised.
            span = span.min(after.as_secs_f64());
            println!(
                "draw {k}: the run had ended before the kill at {after:?}; drawn again from {span:.2} s"
            );
            continue;
        }
        let mcap = out.join("run.mcap");
        let (ok, text) = check_mcap(&mcap, "--recover");
        assert!(
            ok,
            "seed {seed}, kill at {after:?}: check_mcap --recover: {text}"
        );
        let windows = balance_windows(&mcap);
        assert!(
            windows.iter().enumerate().all(|(i, &w)| w == i as u64 + 1),
            "seed {seed}, kill at {after:?}: recovered windows not 1..=n: {windows:?}"
        );
        let n = windows.len() as u64;
        let ckpt = newest_checkpoint(&out);
        if let Some(c) = ckpt {
            assert!(
                n >= c,
                "seed {seed}, kill at {after:?}: recovered up to window {n}, but window {c} was checkpointed"
            );
            bounded += 1;
        }
        let completed: u64 = info
            .split("windows    ")
            .nth(1)
            .and_then(|l| l.split_whitespace().next())
            .and_then(|w| w.parse().ok())
            .unwrap_or_else(|| panic!("seed {seed}: no window count in: {info}"));
        assert!(
            completed >= n,
            "seed {seed}: cosim info reads {completed} windows, check_mcap {n}"
        );
        println!(
            "kill {} at {after:?}: nodes gone after {gone:?}, {n} windows recovered, newest checkpoint {ckpt:?}, {} shm files left",
            killed.len() + 1,
            shm_files(&id).len()
        );
        killed.push(id);
    }
    assert_eq!(
        killed.len(),
        KILLS,
        "seed {seed}: only {} of {TRIES} draws killed cosim mid-run",
        killed.len()
    );
    println!("{bounded} of {KILLS} kills came after a complete checkpoint");
    // Kills fall uniformly over the first 80 % of a 240-window run checkpointed every 10
    // windows: most land after a checkpoint, so the recovery bound above was really tested
    // (fewer than a quarter would mean the draws missed the run).
    assert!(
        bounded >= KILLS / 4,
        "seed {seed}: only {bounded} of {KILLS} kills came after a complete checkpoint"
    );
    // The next run removes whatever the killed runs left in shared memory.
    let (dir, id2) = scratch("ch-next");
    let next = split_bar_case(&dir, 10, 30, 0.5, "shm", 0.5);
    let o = run_case(&next, &dir.join("out"), &id2, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for id in &killed {
        assert!(
            shm_files(id).is_empty(),
            "{id}: left in /dev/shm after the next run: {:?}",
            shm_files(id)
        );
    }
    nothing_left(&id2);
}

const TUBE_NODES: [&str; 11] = [
    "tube", "j1", "j1p", "j2", "j2p", "j3", "j3p", "j4", "j4p", "j5", "j5p",
];

/// Must-show 3: a random node of the small crash tube SIGKILLed at a random time, 20 times:
/// `cosim` exits non-zero within 2 s naming the node, no process of the run survives it, no
/// shared memory of the run is left, and the recording is finalised (the official reader
/// opens it through its summary) with windows 1..=n.
fn crash_tube_node_kills(transport: &str, tag: &str) {
    let case = example("crash_tube.toml");
    let set = format!("run.transport=\"{transport}\"");
    let extra = ["--variant", "small", "--set", &set];
    let mut draw = Draw::seeded();
    let seed = draw.0;
    // Kills fall in the first 3 s after every node runs: the windows are alike, and the
    // campaign stays short.
    const SPAN_S: f64 = 3.0;
    println!("{transport}: seed {seed} (COSIM_TEST_SEED repeats it)");
    let mut clean = 0;
    let mut in_windows = 0;
    for k in 0..TRIES {
        if clean == KILLS {
            break;
        }
        let after = Duration::from_secs_f64(draw.uniform() * SPAN_S);
        let victim = TUBE_NODES
            [((draw.uniform() * TUBE_NODES.len() as f64) as usize).min(TUBE_NODES.len() - 1)];
        let (dir, id) = scratch(&format!("{tag}{k}"));
        let out = dir.join("out");
        let mut child = spawn_cosim_with(&case, &out, &id, &extra);
        if !wait_for_nodes(&mut child, &id, &TUBE_NODES) {
            let o = child.wait_with_output().expect("cosim ends");
            panic!(
                "seed {seed}: the crash tube ended before its nodes ran: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        std::thread::sleep(after);
        let Some(pid) = node_pid(&id, victim) else {
            println!("draw {k}: node {victim} already gone; drawn again");
            continue;
        };
        sigkill(pid);
        let t = Instant::now();
        let status = wait_exit(&mut child, Duration::from_secs(2));
        let took = t.elapsed();
        if status.is_none() {
            let _ = child.kill();
        }
        let o = child.wait_with_output().expect("cosim ends");
        let stderr = String::from_utf8_lossy(&o.stderr);
        let what = format!("seed {seed}, {victim} killed at {after:?}");
        let status = status.unwrap_or_else(|| panic!("{what}: cosim still running 2 s later"));
        assert!(!status.success(), "{what}: cosim exited 0");
        assert!(
            stderr.contains(&format!("'{victim}'")),
            "{what}: the message does not name the node: {stderr}"
        );
        while !live_processes(&id).is_empty() && t.elapsed() < Duration::from_secs(2) {
            std::thread::sleep(Duration::from_millis(10));
        }
        let alive = live_processes(&id);
        assert!(
            alive.is_empty(),
            "{what}: processes alive 2 s later: {alive:?}"
        );
        assert!(
            shm_files(&id).is_empty(),
            "{what}: left in /dev/shm: {:?}; cosim said: {stderr}",
            shm_files(&id)
        );
        let mcap = out.join("run.mcap");
        let (ok, text) = check_mcap(&mcap, "--require-json");
        assert!(ok, "{what}: check_mcap: {text}");
        let windows = balance_windows(&mcap);
        assert!(
            windows.iter().enumerate().all(|(i, &w)| w == i as u64 + 1),
            "{what}: recorded windows not 1..=n: {windows:?}"
        );
        assert_eq!(summary(&out)["status"], "failed", "{what}");
        if !windows.is_empty() {
            in_windows += 1;
        }
        clean += 1;
        println!(
            "{transport} kill {clean}: {victim} at {after:?}, cosim exit {status} after {took:?}, {} windows recorded",
            windows.len()
        );
    }
    assert_eq!(
        clean, KILLS,
        "seed {seed}: only {clean} of {TRIES} draws killed a node mid-run"
    );
    // "windows 1..=n" holds trivially for a kill during set-up: most kills must have come
    // after recorded windows for it to have been tested.
    println!("{transport}: {in_windows} of {KILLS} kills came after recorded windows");
    assert!(
        in_windows >= KILLS / 2,
        "seed {seed}: only {in_windows} of {KILLS} kills came after a recorded window"
    );
}

#[test]
fn a_random_crash_tube_node_killed_20_times_on_shm() {
    crash_tube_node_kills("shm", "ct-s");
}

#[test]
fn a_random_crash_tube_node_killed_20_times_on_zenoh() {
    crash_tube_node_kills("zenoh", "ct-z");
}
