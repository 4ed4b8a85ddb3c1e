//! A run holds a lock on its output folder: while it runs, a second `cosim run` (with or
//! without `--overwrite`), a restart and a replay into that folder are refused, naming the
//! folder and the live run's pid, and touch nothing there; the live run goes on and ends with
//! its own summary and a recording of its own windows only. A lock left by a killed run does
//! not block the next one (the kernel drops it with the process).

use cosim_tests::*;
use std::time::Duration;

#[test]
fn a_second_run_restart_or_replay_into_a_live_runs_folder_is_refused() {
    let (dir, id) = scratch("lock-live");
    // 400 periods of the wave: far longer than this test lets it run.
    let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 400.0);
    let out = dir.join("out");
    let mcap = out.join("run.mcap");
    let mut first = spawn_cosim_with(&case, &out, &id, &[]);
    wait_for_windows(&mcap, 20, Duration::from_secs(120), &mut first);
    let pid = first.id();
    // Hidden names are files being written under a temporary name, renamed once whole.
    let listed = || -> Vec<_> {
        files_under(&out, &[])
            .into_keys()
            .filter(|f| !f.to_string_lossy().split('/').any(|c| c.starts_with('.')))
            .collect()
    };
    let before = listed();
    let (c, o, m) = (
        case.to_str().unwrap(),
        out.to_str().unwrap(),
        mcap.to_str().unwrap(),
    );
    let (_, other) = scratch("lock-other");
    let attempts: [(&str, Vec<&str>, i32); 5] = [
        (
            "run",
            vec!["run", c, "-o", o, "--run-id", other.as_str(), "--quiet"],
            2,
        ),
        (
            "run --overwrite",
            vec![
                "run",
                c,
                "-o",
                o,
                "--run-id",
                other.as_str(),
                "--overwrite",
                "--quiet",
            ],
            2,
        ),
        (
            "run --restart",
            vec!["run", c, "--restart", o, "--quiet"],
            2,
        ),
        ("restart", vec!["restart", o], 2),
        (
            "replay -o",
            vec![
                "replay",
                m,
                "--node",
                "right",
                "-o",
                o,
                "--run-id",
                other.as_str(),
            ],
            1,
        ),
    ];
    for (what, args, code) in attempts {
        let r = cosim(&args);
        let err = String::from_utf8_lossy(&r.stderr);
        println!("{what}: {err}");
        assert_eq!(r.status.code(), Some(code), "{what}: {err}");
        assert!(err.contains(o), "{what}: the folder is not named: {err}");
        assert!(
            err.contains(&format!("pid {pid}")) && err.contains("in progress"),
            "{what}: the live run is not named: {err}"
        );
        nothing_left(&other);
    }
    assert!(
        first.try_wait().unwrap().is_none(),
        "the live run stopped while refused processes came and went"
    );
    // Nothing of the live run's went, and the refused ones wrote nothing there.
    let after = listed();
    for f in &before {
        assert!(after.contains(f), "{} went", f.display());
    }
    for f in &after {
        let name = f.to_string_lossy();
        assert!(
            !name.contains("replay") && name != "summary.json" && name != "run.1.mcap",
            "written by a refused process: {name}"
        );
    }
    signal_child(&first, libc::SIGINT);
    let status = wait_exit(&mut first, Duration::from_secs(60)).expect("the run stops");
    assert_eq!(status.code(), Some(130), "{status}");
    // Its own summary, and a recording of its own windows, each once and in order.
    let s = summary(&out);
    assert_eq!(s["status"], "interrupted");
    assert_eq!(s["run"], id.as_str());
    let reached = s["window_reached"].as_u64().expect("window_reached");
    assert!(reached >= 20, "{s}");
    let windows = balance_windows(&mcap);
    assert_eq!(windows, (1..=reached).collect::<Vec<_>>());
    nothing_left(&id);
}

#[test]
fn a_killed_runs_lock_does_not_block_the_next_run() {
    let (dir, id) = scratch("lock-killed");
    let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 400.0);
    let out = dir.join("out");
    let mut first = spawn_cosim_with(&case, &out, &id, &[]);
    wait_for_windows(
        &out.join("run.mcap"),
        5,
        Duration::from_secs(120),
        &mut first,
    );
    kill_cosim(&mut first, &id);
    assert!(
        out.join(".cosim.lock").is_file(),
        "no lock file left: the scenario is void"
    );
    let (_, next) = scratch("lock-next");
    let short = split_bar_case(&dir, 100, 300, 0.5, "shm", 0.25);
    let o = run_case(&short, &out, &next, &["--overwrite"]);
    let err = String::from_utf8_lossy(&o.stderr);
    println!("{err}");
    assert!(o.status.success(), "{err}");
    assert_eq!(summary(&out)["status"], "finished");
    assert_eq!(summary(&out)["run"], next.as_str());
    nothing_left(&next);
}
