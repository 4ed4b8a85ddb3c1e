//! Stopping on request and surviving the coordinator's death (docs/architecture.md): SIGINT and
//! SIGTERM to `cosim` end the run at a window boundary within 2 s with status "interrupted",
//! a finalised recording and nothing left behind; SIGKILL of `cosim` at random times leaves
//! no node alive 2 s later, a recoverable recording, and no shared memory after `cosim clean`
//! or the next `cosim run`.

use cosim_tests::*;
use std::process::Child;
use std::time::{Duration, Instant};

/// Start the long split bar and return once its nodes run and `after` has passed.
fn start(tag: &str, transport: &str, after: Duration) -> (Child, std::path::PathBuf, String) {
    let (case, out, id) = long_split_bar(tag, transport);
    let child = spawn_cosim(&case, &out, &id);
    let start = Instant::now();
    while node_pid(&id, "right").is_none() {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "nodes never started"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(after);
    (child, out, id)
}

fn signal(child: &Child, sig: i32) {
    // SAFETY: kill with a pid of our own child and a valid signal number.
    let rc = unsafe { libc::kill(child.id() as i32, sig) };
    assert_eq!(rc, 0, "kill failed");
}

/// SIGKILL the nodes of run `id`, then `cosim`, so that nobody can clean up (the OOM killer,
/// `kill -9` of the whole group): what they leave in shared memory is for `cosim clean` or
/// the next `cosim run` to remove.
fn kill_everything(child: &mut Child, id: &str) {
    for pid in live_processes(id) {
        // SAFETY: kill with a pid read from /proc and a valid signal number.
        unsafe { libc::kill(pid as i32, libc::SIGKILL) };
    }
    signal(child, libc::SIGKILL);
    let _ = child.wait();
    let t = Instant::now();
    while !live_processes(id).is_empty() && t.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(live_processes(id).is_empty());
    assert!(
        !shm_files(id).is_empty(),
        "nothing left to clean: the scenario is void"
    );
}

/// Signal `cosim` mid-run and check that it stops as the README says.
fn stopped_by(tag: &str, sig: i32, name: &str, code: i32) {
    let (mut child, out, id) = start(tag, "shm", Duration::from_millis(1500));
    let t = Instant::now();
    signal(&child, sig);
    // The bound is the point of the test: no margin beyond the 2 s.
    let status = wait_exit(&mut child, Duration::from_secs(2));
    let elapsed = t.elapsed();
    if status.is_none() {
        let _ = child.kill();
    }
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    println!("{tag}: {status:?} after {elapsed:?}: {stderr}");
    let status = status.unwrap_or_else(|| panic!("cosim still running 2 s after {name}"));
    assert_eq!(status.code(), Some(code), "{stderr}");
    assert!(
        stderr.contains(&format!("interrupted by {name}")),
        "{stderr}"
    );
    let s = summary(&out);
    assert_eq!(s["status"], "interrupted");
    assert_eq!(s["signal"], name);
    let reached = s["window_reached"].as_u64().unwrap();
    assert!(reached >= 1, "no window completed before the signal");
    // Finalised: the official reader opens it through its summary, without recovery.
    let mcap = out.join("run.mcap");
    let (ok, text) = check_mcap(&mcap, "--require-json");
    assert!(ok, "check_mcap: {text}");
    let windows = balance_windows(&mcap);
    assert_eq!(
        windows,
        (1..=reached).collect::<Vec<_>>(),
        "recorded windows are not 1..={reached}"
    );
    // Nothing left: no process, no shared memory.
    let alive = live_processes(&id);
    assert!(alive.is_empty(), "surviving node processes: {alive:?}");
    assert!(shm_files(&id).is_empty(), "left: {:?}", shm_files(&id));
}

#[test]
fn ctrl_c_stops_the_run_at_a_window_boundary() {
    stopped_by("sigint", libc::SIGINT, "SIGINT", 130);
}

#[test]
fn sigterm_stops_the_run_at_a_window_boundary() {
    stopped_by("sigterm", libc::SIGTERM, "SIGTERM", 143);
}

#[test]
fn a_killed_cosim_leaves_no_node_and_no_shared_memory() {
    const KILLS: usize = 5;
    let mut draw = Draw::seeded();
    println!("seed {} (COSIM_TEST_SEED repeats it)", draw.0);
    let mut killed = Vec::new();
    let mut self_cleaned = 0;
    let mut recovered = 0;
    for k in 0..KILLS {
        let after = Duration::from_millis(300 + (draw.uniform() * 2000.0) as u64);
        let (mut child, out, id) = start(&format!("kill9-{k}"), "shm", after);
        signal(&child, libc::SIGKILL);
        let t = Instant::now();
        let _ = child.wait();
        // Every node follows its coordinator within the bound.
        while !live_processes(&id).is_empty() && t.elapsed() < Duration::from_secs(2) {
            std::thread::sleep(Duration::from_millis(10));
        }
        let gone_after = t.elapsed();
        let alive = live_processes(&id);
        println!(
            "kill {k} at {after:?}: nodes gone after {gone_after:?}, {} shm files left by the run itself",
            shm_files(&id).len()
        );
        assert!(
            alive.is_empty(),
            "kill {k}: node processes alive 2 s after cosim's SIGKILL: {alive:?}"
        );
        if shm_files(&id).is_empty() {
            self_cleaned += 1;
        }
        // The recording is recoverable and holds windows 1, 2, ... without a gap.
        let mcap = out.join("run.mcap");
        let (ok, text) = check_mcap(&mcap, "--recover");
        assert!(ok, "kill {k}: check_mcap --recover: {text}");
        let windows = balance_windows(&mcap);
        assert!(
            windows.iter().enumerate().all(|(i, &w)| w == i as u64 + 1),
            "kill {k}: recovered windows not contiguous: {windows:?}"
        );
        if !windows.is_empty() {
            recovered += 1;
        }
        killed.push(id);
    }
    // Contiguity of an empty list proves nothing: most kills must have left windows.
    println!("{recovered} of {KILLS} killed runs had recorded windows");
    assert!(
        recovered >= 3,
        "only {recovered} of {KILLS} kills left recorded windows"
    );
    println!("{self_cleaned} of {KILLS} killed runs left no shared memory even before a cleanup");
    assert_eq!(killed.len(), KILLS);
    // A run killed with all its nodes cannot clean up after itself.
    let (mut child, _, id) = start("kill9-all", "shm", Duration::from_millis(1200));
    kill_everything(&mut child, &id);
    println!("killed with its nodes: {} files left", shm_files(&id).len());
    killed.push(id);
    // `cosim clean` removes what the dead runs left ...
    let o = cosim(&["clean"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    println!("{}", String::from_utf8_lossy(&o.stdout));
    for id in &killed {
        assert!(
            shm_files(id).is_empty(),
            "{id}: left after cosim clean: {:?}",
            shm_files(id)
        );
    }
    // ... while a live run keeps all its files.
    let (mut live, _, live_id) = start("live", "shm", Duration::from_millis(1000));
    let before = shm_files(&live_id);
    let o = cosim(&["clean"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let after: Vec<String> = shm_files(&live_id);
    assert!(!before.is_empty());
    assert!(
        before.iter().all(|f| after.contains(f)),
        "cosim clean removed files of a live run"
    );
    signal(&live, libc::SIGTERM);
    let status = wait_exit(&mut live, Duration::from_secs(10)).expect("live run stops");
    assert_eq!(status.code(), Some(143));
    assert!(shm_files(&live_id).is_empty());
}

#[test]
fn the_next_run_removes_what_a_killed_cosim_left() {
    let (mut child, _, id) = start("kill9-next", "shm", Duration::from_millis(1500));
    kill_everything(&mut child, &id);
    // A short run of another case.
    let (dir, id2) = scratch("next");
    let case = split_bar_case(&dir, 10, 30, 0.5, "shm", 0.5);
    let o = run_case(&case, &dir.join("out"), &id2, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(shm_files(&id).is_empty(), "left: {:?}", shm_files(&id));
    assert!(shm_files(&id2).is_empty());
}

#[test]
fn ctrl_c_while_waiting_for_a_remote_node_stops_at_once() {
    let (dir, id) = scratch("join-int");
    let case = split_bar_case(&dir, 10, 30, 0.5, "zenoh", 0.5);
    let text = std::fs::read_to_string(&case)
        .unwrap()
        .replace("[nodes.right]\n", "[nodes.right]\nremote = true\n");
    std::fs::write(&case, text).unwrap();
    let out = dir.join("out");
    let mut child = spawn_cosim(&case, &out, &id);
    let start = Instant::now();
    while node_pid(&id, "left").is_none() {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "left never started"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    std::thread::sleep(Duration::from_millis(500));
    signal(&child, libc::SIGINT);
    let status = wait_exit(&mut child, Duration::from_secs(2));
    if status.is_none() {
        let _ = child.kill();
    }
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    let status = status.unwrap_or_else(|| panic!("cosim still running 2 s after SIGINT: {stderr}"));
    assert_eq!(status.code(), Some(130), "{stderr}");
    let s = summary(&out);
    assert_eq!(s["status"], "interrupted");
    assert_eq!(s["window_reached"], 0);
    let (ok, text) = check_mcap(&out.join("run.mcap"), "--require-json");
    assert!(ok, "check_mcap: {text}");
    assert!(live_processes(&id).is_empty(), "the local node survived");
}
