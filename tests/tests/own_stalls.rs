//! The coordinator's own stalls are not a node's hang (docs/architecture.md, "Failures"): a
//! `cosim` stopped by SIGSTOP for longer than `run.heartbeat_timeout`, and a split bar run
//! beside busy loops on every core, both finish; a node that really stops beating is still
//! named (`failures.rs`, `a_hung_node_is_detected_by_its_missing_heartbeat`).

use cosim_tests::*;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The split bar over `periods` periods, beating every 100 ms with a 1 s heartbeat timeout.
fn short_timeout_bar(tag: &str, periods: f64) -> (std::path::PathBuf, std::path::PathBuf, String) {
    let (dir, id) = scratch(tag);
    let case = split_bar_case(&dir, 100, 300, 0.5, "shm", periods);
    let text = std::fs::read_to_string(&case).expect("case").replace(
        "output = \"out\"",
        "output = \"out\"\nheartbeat_ms = 100\nheartbeat_timeout = 1.0",
    );
    std::fs::write(&case, text).expect("write case");
    (case, dir.join("out"), id)
}

/// Wait for the run to end and check that it finished every window.
fn finishes(mut child: std::process::Child, out: &std::path::Path, id: &str) -> String {
    let status = wait_exit(&mut child, Duration::from_secs(300)).expect("the run ends");
    let o = child.wait_with_output().expect("output");
    let stderr = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(status.success(), "exit {status}: {stderr}");
    let s = summary(out);
    assert_eq!(s["status"], "finished", "{stderr}");
    assert_eq!(s["window_reached"], s["windows"], "{stderr}");
    nothing_left(id);
    stderr
}

#[test]
fn a_coordinator_stopped_longer_than_the_heartbeat_timeout_blames_no_node() {
    let (case, out, id) = short_timeout_bar("own-stall", 40.0);
    let mut child = spawn_cosim(&case, &out, &id);
    // Stop it mid-run, once windows are recorded (an event, not a sleep).
    wait_for_windows(
        &out.join("run.mcap"),
        20,
        Duration::from_secs(60),
        &mut child,
    );
    signal_child(&child, libc::SIGSTOP);
    let stopped = Instant::now();
    std::thread::sleep(Duration::from_millis(2500));
    let stop_s = stopped.elapsed().as_secs_f64();
    signal_child(&child, libc::SIGCONT);
    let stderr = finishes(child, &out, &id);
    // The stall was seen as the coordinator's own, as long as the test stopped it at least.
    let s = summary(&out);
    let stalls = &s["coordinator_stalls"];
    assert!(stalls["count"].as_u64() >= Some(1), "no stall seen: {s}");
    let longest = stalls["longest_s"].as_f64().expect("longest_s");
    assert!(
        longest >= stop_s - 0.05,
        "longest stall {longest} s, stopped {stop_s} s"
    );
    assert!(
        stderr.contains("the coordinator itself did not run for"),
        "no warning: {stderr}"
    );
}

#[test]
fn a_split_bar_beside_busy_loops_on_every_core_finishes() {
    let (case, out, id) = short_timeout_bar("cpu-hog", 20.0);
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    let stop = Arc::new(AtomicBool::new(false));
    let hogs: Vec<_> = (0..2 * cores)
        .map(|_| {
            let stop = stop.clone();
            std::thread::spawn(move || {
                let mut x = 0u64;
                while !stop.load(Ordering::Relaxed) {
                    x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
                }
                x
            })
        })
        .collect();
    let started = Instant::now();
    let child = spawn_cosim(&case, &out, &id);
    let result = std::panic::catch_unwind(|| finishes(child, &out, &id));
    stop.store(true, Ordering::Relaxed);
    for h in hogs {
        let _ = h.join();
    }
    println!(
        "{} busy threads, run {:.1} s",
        2 * cores,
        started.elapsed().as_secs_f64()
    );
    if let Err(e) = result {
        std::panic::resume_unwind(e);
    }
}
