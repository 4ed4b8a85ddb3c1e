//! Failure handling (docs/architecture.md): a node killed mid-run, a node that stops answering,
//! and a malformed message on a data topic each end the run within 5 s with one line naming
//! the node and the reason, no surviving child, no shared memory left, and a readable
//! recording holding every window completed before the fault.

use cosim_tests::*;
use std::process::Command;
use std::time::{Duration, Instant};

/// Start cosim, wait until the run is under way, do `act`, and check the aftermath.
fn fault_scenario(tag: &str, transport: &str, act: impl FnOnce(&str), expect: &[&str]) {
    let (case, out, id) = long_split_bar(tag, transport);
    let mut child = spawn_cosim(&case, &out, &id);
    // Wait for both nodes and some windows.
    let start = Instant::now();
    while node_pid(&id, "right").is_none() || start.elapsed() < Duration::from_millis(1500) {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "nodes never started"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let t_fault = Instant::now();
    act(&id);
    // cosim must exit non-zero within 5 s.
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t_fault.elapsed() > Duration::from_secs(5) {
            let _ = child.kill();
            panic!("cosim still running 5 s after the fault");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let elapsed = t_fault.elapsed();
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).to_string();
    println!("{tag}: exit {status} after {elapsed:?}: {stderr}");
    assert!(!status.success());
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "expected one line, got: {stderr}");
    for e in expect {
        assert!(
            lines[0].contains(e),
            "'{}' does not mention '{e}'",
            lines[0]
        );
    }
    // No child survives, no shared memory of the run is left.
    std::thread::sleep(Duration::from_millis(100));
    nothing_left(&id);
    // The recording is readable and holds every window completed before the fault.
    let mcap = out.join("run.mcap");
    let (ok, text) = check_mcap(&mcap, "--recover");
    assert!(ok, "check_mcap --recover: {text}");
    let windows = balance_windows(&mcap);
    assert!(!windows.is_empty(), "no window recorded before the fault");
    assert!(
        windows.iter().enumerate().all(|(i, &w)| w == i as u64 + 1),
        "windows not contiguous"
    );
    let s = summary(&out);
    assert_eq!(s["status"], "failed");
}

#[test]
fn a_killed_node_ends_the_run_cleanly() {
    fault_scenario(
        "kill",
        "shm",
        |id| {
            let pid = node_pid(id, "right").unwrap();
            unsafe { libc::kill(pid as i32, libc::SIGKILL) };
        },
        &["right", "SIGKILL"],
    );
}

#[test]
fn a_hung_node_is_detected_by_its_missing_heartbeat() {
    fault_scenario(
        "hang",
        "shm",
        |id| {
            let pid = node_pid(id, "right").unwrap();
            unsafe { libc::kill(pid as i32, libc::SIGSTOP) };
        },
        &["right", "heartbeat"],
    );
}

#[test]
fn a_malformed_message_on_a_data_topic_ends_the_run() {
    fault_scenario(
        "garbage",
        "shm",
        |id| {
            let o = Command::new(bin("cosim-inject"))
                .args([
                    "--run",
                    id,
                    "--transport",
                    "shm",
                    "--topic",
                    &format!("cosim/{id}/mid/left"),
                    "--readers",
                    "right,coordinator",
                ])
                .output()
                .unwrap();
            assert!(
                o.status.success(),
                "inject: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        },
        &["malformed"],
    );
}

#[test]
fn a_killed_node_ends_a_zenoh_run_cleanly() {
    fault_scenario(
        "kill-z",
        "zenoh",
        |id| {
            let pid = node_pid(id, "left").unwrap();
            unsafe { libc::kill(pid as i32, libc::SIGKILL) };
        },
        &["left"],
    );
}

/// The split bar with its right half launched through `wrapper` (a shell script given the
/// node's arguments), run with `extra` `--set`s; returns (exit, stderr, seconds, run id).
fn run_wrapped_right_half(
    tag: &str,
    wrapper: &str,
    extra: &[&str],
) -> (std::process::ExitStatus, String, f64, String) {
    let (dir, id) = scratch(tag);
    let script = dir.join("wrapped-node");
    std::fs::write(&script, wrapper).expect("write the wrapper");
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    let case = split_bar_case(&dir, 20, 60, 0.5, "shm", 0.5);
    let text = std::fs::read_to_string(&case).expect("case").replace(
        "[nodes.right]\nsolver = \"solid-node\"",
        &format!("[nodes.right]\nsolver = {:?}", script.display().to_string()),
    );
    std::fs::write(&case, text).expect("case");
    let mut args = Vec::new();
    for s in extra {
        args.extend_from_slice(&["--set", s]);
    }
    let t = Instant::now();
    let o = run_case(&case, &dir.join("out"), &id, &args);
    (
        o.status,
        String::from_utf8_lossy(&o.stderr).into_owned(),
        t.elapsed().as_secs_f64(),
        id,
    )
}

/// A node that takes longer than the heartbeat timeout to say Hello (an interpreter
/// importing its libraries on a busy machine) is not declared hung: before its Hello only
/// `run.start_timeout` applies.
#[test]
fn a_slow_starting_node_joins_within_the_start_timeout() {
    let exe = bin("solid-node");
    let wrapper = format!(
        "#!/bin/sh\ncase \"$*\" in *--describe*) ;; *) sleep 4.5 ;; esac\nexec {:?} \"$@\"\n",
        exe.display().to_string()
    );
    let (status, stderr, took, id) =
        run_wrapped_right_half("slow-start", &wrapper, &["run.heartbeat_timeout=2"]);
    println!("slow start: exit {status} after {took:.1} s: {stderr}");
    assert!(status.success(), "{stderr}");
    assert!(took >= 4.5, "the node did not start late ({took} s)");
    nothing_left(&id);
}

/// A launched node that never says Hello ends the run at `run.start_timeout`, naming the node
/// and the key to raise, and is killed (no process outlives the run).
#[test]
fn a_node_that_never_joins_ends_the_run_at_the_start_timeout() {
    let exe = bin("solid-node");
    let wrapper = format!(
        "#!/bin/sh\ncase \"$*\" in *--describe*) exec {:?} \"$@\" ;; esac\nexec sleep 61.25\n",
        exe.display().to_string()
    );
    let (status, stderr, took, id) =
        run_wrapped_right_half("never-joins", &wrapper, &["run.start_timeout=2"]);
    println!("never joins: exit {status} after {took:.1} s: {stderr}");
    assert!(!status.success());
    assert!(
        stderr.contains("right") && stderr.contains("run.start_timeout"),
        "{stderr}"
    );
    assert!(took < 15.0, "the run took {took} s to give up");
    std::thread::sleep(Duration::from_millis(200));
    assert!(
        processes_with("61.25").is_empty(),
        "the node that never joined outlived the run"
    );
    nothing_left(&id);
}

/// A node that prints its error and exits at set-up: cosim's message carries the node's
/// last log lines and the log's path, not only the exit status.
#[test]
fn a_node_failing_at_setup_shows_its_last_log_lines() {
    let exe = bin("solid-node");
    let wrapper = format!(
        "#!/bin/sh\ncase \"$*\" in *--describe*) exec {:?} \"$@\" ;; esac\n\
         echo 'starting the right half' >&2\n\
         echo 'licence server unreachable: connection refused' >&2\nexit 3\n",
        exe.display().to_string()
    );
    let (status, stderr, _, id) = run_wrapped_right_half("setup-dies", &wrapper, &[]);
    println!("{stderr}");
    assert_eq!(status.code(), Some(1), "{stderr}");
    for want in [
        "node 'right'",
        "exited with status 3",
        "right.log",
        "licence server unreachable: connection refused",
        "starting the right half",
    ] {
        assert!(stderr.contains(want), "'{want}' missing from: {stderr}");
    }
    nothing_left(&id);
}

/// A Rust node that panics mid-run is reported as a panic with its message and place (the
/// participant runtime catches it and tells the coordinator) and the log's path.
#[test]
fn a_panicking_node_is_reported_as_a_panic_with_its_place() {
    let (dir, id) = scratch("panics");
    let echo = bin("cosim-echo-node").display().to_string();
    let case = dir.join("case.toml");
    std::fs::write(
        &case,
        format!(
            r#"[run]
name = "panics"
end_time = 0.02
window = 1e-3
output = "out"

[nodes.a]
solver = {echo:?}
model = "echo"

[nodes.b]
solver = {echo:?}
model = "echo"
[nodes.b.params]
panic_at_window = 5

[[couplings]]
name = "echo"
kind = "immersed"
driver = "a.port"
responder = "b.port"
driver_fields = ["signal"]
responder_fields = ["echo"]
"#
        ),
    )
    .expect("case");
    let out = dir.join("out");
    let o = run_case(&case, &out, &id, &[]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    println!("{stderr}");
    assert!(!o.status.success());
    for want in [
        "node 'b'",
        "panicked",
        "index out of bounds",
        "cosim-echo-node.rs:",
        "b.log",
    ] {
        assert!(stderr.contains(want), "'{want}' missing from: {stderr}");
    }
    assert_eq!(summary(&out)["status"], "failed");
    nothing_left(&id);
}
