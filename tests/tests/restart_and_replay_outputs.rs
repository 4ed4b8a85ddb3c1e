//! Restart and replay never overwrite or misread a run's files: a restart of a run that
//! finished is refused (touching nothing) unless a later end time is given, and then it
//! continues the run; a restart appends to the node logs of the run it continues, after a
//! line marking where; a replay into the run's own folder is refused, leaving the run's
//! files as they were.

use cosim_tests::*;
use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

/// `cosim ARGS` with the nodes logging at info level (no `--quiet`, which they would inherit),
/// so that their logs hold lines to keep.
fn cosim_logging(args: &[&str]) -> Output {
    Command::new(bin("cosim"))
        .args(args)
        .env("COSIM_LOG", "info")
        .output()
        .expect("cosim runs")
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn log(out: &Path, node: &str) -> String {
    std::fs::read_to_string(out.join(format!("{node}.log"))).expect("the node's log")
}

/// Each node's log after the restart begins with its whole log from before, then the line
/// that marks the restart, then the restarted node's own lines.
fn assert_appended(before: &[(String, String)], out: &Path) {
    for (node, old) in before {
        let new = log(out, node);
        assert!(!old.is_empty(), "{node}: an empty log proves nothing");
        assert!(new.starts_with(old.as_str()), "{node}: the log was cut");
        let rest = &new[old.len()..];
        assert!(
            rest.starts_with("---- cosim restart from the checkpoint of window "),
            "{node}: no restart line after the old log: {rest}"
        );
        assert!(
            rest.lines().count() > 1,
            "{node}: nothing logged after the restart"
        );
    }
}

#[test]
fn restarting_a_finished_run_is_refused_unless_the_end_time_grows() {
    let (dir, id) = scratch("fin-restart");
    // 80 windows, a checkpoint every 20.
    let case = split_bar_case(&dir, 20, 60, 0.5, "shm", 0.25);
    let out = dir.join("out");
    let (c, o) = (case.to_str().unwrap(), out.to_str().unwrap());
    let r = cosim_logging(&[
        "run",
        c,
        "-o",
        o,
        "--run-id",
        &id,
        "--set",
        "run.checkpoint_every=20",
    ]);
    assert!(r.status.success(), "{}", text(&r));
    let s = summary(&out);
    assert_eq!(
        (s["status"].as_str(), s["windows"].as_u64()),
        (Some("finished"), Some(80))
    );
    let end = s["end_time"].as_f64().expect("end_time");
    // The lock file is rewritten by whoever takes the folder: left out of the comparison.
    let files = files_under(&out, &[".cosim.lock"]);
    let same_end = format!("run.end_time={end:e}");
    for (what, args) in [
        ("restart", vec!["restart", o]),
        (
            "restart, same end",
            vec!["restart", o, "--set", same_end.as_str()],
        ),
        ("run --restart", vec!["run", c, "--restart", o, "--quiet"]),
    ] {
        let r = cosim(&args);
        let t = text(&r);
        println!("{what}: {t}");
        assert_eq!(r.status.code(), Some(2), "{what}: {t}");
        assert!(
            t.contains("the run finished at t = ")
                && t.contains("give a later end time with --set run.end_time="),
            "{what}: {t}"
        );
        assert!(
            files_under(&out, &[".cosim.lock"]) == files,
            "{what}: a refused restart changed the run's files"
        );
    }
    let before: Vec<(String, String)> = ["left", "right"]
        .iter()
        .map(|n| (n.to_string(), log(&out, n)))
        .collect();
    // 120 windows: the restart continues from window 60 to the new end.
    let later = format!("run.end_time={:e}", end * 1.5);
    let r = cosim_logging(&["restart", o, "--set", later.as_str()]);
    assert!(r.status.success(), "{}", text(&r));
    let s = summary(&out);
    assert_eq!(
        (s["status"].as_str(), s["windows"].as_u64()),
        (Some("finished"), Some(120))
    );
    assert_eq!(s["restarted_from_window"].as_u64(), Some(60));
    assert!(out.join("run.1.mcap").is_file());
    assert_eq!(
        balance_windows(&out.join("run.mcap")),
        (1..=120).collect::<Vec<_>>()
    );
    assert_appended(&before, &out);
    nothing_left(&id);
}

#[test]
fn a_restart_appends_to_the_killed_runs_node_logs() {
    let (dir, id) = scratch("fin-killed");
    let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 400.0);
    let out = dir.join("out");
    let mcap = out.join("run.mcap");
    let mut run = Command::new(bin("cosim"))
        .args(["run", case.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(["--run-id", &id, "--set", "run.checkpoint_every=100"])
        .env("COSIM_LOG", "info")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("cosim starts");
    // Windows past the second checkpoint are recorded: the first one is complete on disk.
    wait_for_windows(&mcap, 250, Duration::from_secs(120), &mut run);
    kill_cosim(&mut run, &id);
    let before: Vec<(String, String)> = ["left", "right"]
        .iter()
        .map(|n| (n.to_string(), log(&out, n)))
        .collect();
    // A short continuation: 100 windows past what the killed run recorded.
    let recorded = *balance_windows(&mcap).last().expect("recorded windows");
    let window = summary_window(&case);
    let end = format!("run.end_time={:e}", (recorded + 100) as f64 * window);
    let r = cosim_logging(&["restart", out.to_str().unwrap(), "--set", end.as_str()]);
    assert!(r.status.success(), "{}", text(&r));
    assert_eq!(summary(&out)["status"], "finished");
    assert_appended(&before, &out);
    nothing_left(&id);
}

/// The case's window, read from the case file the test wrote.
fn summary_window(case: &Path) -> f64 {
    let doc: toml::Table = toml::from_str(&std::fs::read_to_string(case).unwrap()).unwrap();
    doc["run"]["window"].as_float().expect("run.window")
}

#[test]
fn a_replay_into_the_runs_own_folder_is_refused_and_leaves_it_untouched() {
    let (dir, id) = scratch("rp-own");
    let case = split_bar_case(&dir, 20, 60, 0.5, "shm", 0.25);
    let out = dir.join("out");
    let r = run_case(&case, &out, &id, &[]);
    assert!(r.status.success(), "{}", text(&r));
    let files = files_under(&out, &[]);
    let mcap = out.join("run.mcap");
    for node in ["left", "right"] {
        let (_, rid) = scratch("rp-own-r");
        let (ok, stdout, err) = replay_node(&mcap, node, &rid, &["-o", out.to_str().unwrap()]);
        println!("{node}: {stdout}{err}");
        assert!(!ok, "{node}: replayed into the run's folder");
        assert!(
            err.contains(out.to_str().unwrap()) && err.contains("holds a run's results"),
            "{node}: {err}"
        );
        assert!(
            files_under(&out, &[]) == files,
            "{node}: the run's files changed"
        );
        nothing_left(&rid);
    }
    // Without -o the replay goes beside the recording, in a folder of its own.
    let (_, rid) = scratch("rp-own-d");
    let (ok, stdout, err) = replay_node(&mcap, "right", &rid, &[]);
    assert!(ok && stdout.contains("bit-identical"), "{stdout}{err}");
    assert!(out.join("replay-right/right.log").is_file());
    let now = files_under(&out, &[]);
    for (f, bytes) in &files {
        assert!(now.get(f) == Some(bytes), "{} changed", f.display());
    }
    nothing_left(&rid);
}
