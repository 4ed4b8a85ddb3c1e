//! `cosim replay` (docs/architecture.md): the node's executable is launched as a real process and fed
//! its recorded inputs. Same executable → bit-identical over every recorded window (counted
//! from the recording independently of the replay), exit 0; a changed parameter → a
//! difference report and exit 3;
//! a cut recording or a node killed mid-replay → an error, with nothing left behind.

use cosim_tests::*;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// One recorded split-bar run shared by the tests of this file.
fn recorded() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        let (dir, id) = scratch("replay-rec");
        let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 0.5);
        let out = dir.join("out");
        let o = run_case(&case, &out, &id, &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out.join("run.mcap")
    })
}

#[test]
fn each_node_of_the_split_bar_replays_bit_identically_over_every_window() {
    for node in ["left", "right"] {
        assert_replays_bit_identically(recorded(), node, "rp-same");
    }
}

#[test]
fn any_executable_replays_the_node() {
    // The node's executable under another name and place, named with --solver.
    let (dir, id) = scratch("rp-solver");
    let exe = dir.join("my-bar-solver");
    std::fs::copy(bin("solid-node"), &exe).unwrap();
    let (ok, out, err) = replay_node(
        recorded(),
        "right",
        &id,
        &["--solver", exe.to_str().unwrap()],
    );
    println!("{out}{err}");
    assert!(ok, "{err}");
    assert!(out.contains("my-bar-solver"), "{out}");
    assert!(out.contains("bit-identical"), "{out}");
    let (compared, recorded_n, ..) = replay_counts(&out);
    assert_eq!(compared, recorded_windows(recorded(), "right"));
    assert_eq!(compared, recorded_n);
    nothing_left(&id);
}

#[test]
fn a_changed_parameter_reports_differences_and_drift() {
    let (dir, id) = scratch("rp-young");
    let csv = dir.join("report.csv");
    let (code, out, err) = replay_status(
        recorded(),
        "right",
        &id,
        &[
            "--set",
            "young=210e9",
            "--report",
            csv.to_str().unwrap(),
            "--plot",
            dir.join("plots").to_str().unwrap(),
        ],
    );
    println!("{out}{err}");
    // Its own exit code: a regression suite tells a changed result from a broken replay.
    assert_eq!(
        code,
        Some(3),
        "a complete comparison with differences: {err}"
    );
    assert!(!out.contains("bit-identical"), "{out}");
    assert!(out.contains("outputs differ"), "{out}");
    let (compared, recorded_n, fields, ..) = replay_counts(&out);
    assert_eq!(compared, recorded_n);
    assert_eq!(compared, recorded_windows(recorded(), "right"));
    // Every compared field and report value has a CSV row; some differ by a real amount.
    let rows = std::fs::read_to_string(&csv).unwrap();
    let field_rows: Vec<&str> = rows
        .lines()
        .skip(1)
        .filter(|l| !l.contains(",scalar,"))
        .collect();
    assert_eq!(field_rows.len() as u64, fields);
    let worst = rows
        .lines()
        .skip(1)
        .filter(|l| l.contains(",scalar,tip_displacement,"))
        .map(|l| l.split(',').nth(4).unwrap().parse::<f64>().unwrap())
        .fold(0.0f64, nan_max);
    // E 200 → 210 GPa: the wave speed changes by 2.4 %, the tip history by far more than
    // round-off by the end of half a period.
    assert!(worst > 1e-3, "largest relative tip difference {worst:e}");
    let png = dir.join("plots/replay_right_tip_displacement.png");
    let len = std::fs::metadata(&png).map(|m| m.len()).unwrap_or(0);
    assert!(len > 1000, "{}: {len} bytes", png.display());
    nothing_left(&id);
    // The driver's motion is what the recorded responder saw: changing the driver drifts it.
    let (_, id) = scratch("rp-drift");
    let (code, out, err) = replay_status(recorded(), "left", &id, &["--set", "young=210e9"]);
    println!("{out}{err}");
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("drifted"), "no drift warning: {err}");
}

#[test]
fn a_truncated_recording_is_reported_incomplete() {
    let (dir, id) = scratch("rp-cut");
    let bytes = std::fs::read(recorded()).unwrap();
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    for node in ["left", "right"] {
        let (ok, out, err) = replay_node(&cut, node, &id, &[]);
        println!("{node}: {out}{err}");
        assert!(!ok, "{node}: a cut recording replayed as complete: {out}");
        assert!(!out.contains("bit-identical"), "{out}");
        assert!(err.contains("incomplete"), "{node}: {err}");
        nothing_left(&id);
    }
}

#[test]
fn a_decimated_recording_is_replayed_only_where_it_holds_every_input() {
    // `record_every = 2` keeps the coupling fields of even windows only: window 1's input is
    // not in the recording, so the replay stops there and says so.
    let (dir, id) = scratch("rp-decim");
    let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 0.5);
    let out = dir.join("out");
    let o = run_case(&case, &out, &id, &["--set", "run.record_every=2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mcap = out.join("run.mcap");
    let (_, rid) = scratch("rp-decim-r");
    let (ok, stdout, err) = replay_node(&mcap, "right", &rid, &[]);
    println!("{stdout}{err}");
    assert!(!ok);
    assert!(!stdout.contains("bit-identical"), "{stdout}");
    let (compared, recorded_n, ..) = replay_counts(&stdout);
    assert_eq!(recorded_n, recorded_windows(&mcap, "right"));
    assert!(compared < recorded_n);
    assert!(
        err.contains("lacks the peer fields 'mid' of window 1"),
        "{err}"
    );
    nothing_left(&rid);
}

#[test]
fn a_bad_node_solver_or_model_is_refused() {
    let (_, id) = scratch("rp-bad");
    let (ok, _, err) = replay_node(recorded(), "middle", &id, &[]);
    assert!(!ok);
    assert!(
        err.contains("'middle' is not in the recorded case"),
        "{err}"
    );
    let (ok, _, err) = replay_node(
        recorded(),
        "right",
        &id,
        &["--solver", "/nonexistent/solver"],
    );
    assert!(!ok);
    assert!(err.contains("/nonexistent/solver"), "{err}");
    // A model the executable does not have: its own refusal, with the key.
    let (ok, _, err) = replay_node(recorded(), "right", &id, &["--set", "model=no-such-model"]);
    println!("{err}");
    assert!(!ok);
    assert!(err.contains("no-such-model"), "{err}");
    nothing_left(&id);
}

/// A recording long enough for a replay to be interrupted: 4 periods of the bar, 6400 windows.
fn long_recording() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        let (dir, id) = scratch("rp-long");
        let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 4.0);
        let out = dir.join("out");
        let o = run_case(&case, &out, &id, &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out.join("run.mcap")
    })
}

/// Start replaying `right` of the long recording into a folder of its own (replays run side
/// by side); returns the `cosim replay` process, its run id and the pid of its node once the
/// node is under way: it has written its first frame, which it does as it starts window 1
/// (an event on the node's progress, not a sleep: a loaded machine once let a fixed 150 ms
/// pass after the node was found while it ran all 6,400 windows).
fn replay_long(tag: &str) -> (std::process::Child, String, i32) {
    let (dir, id) = scratch(tag);
    let out = dir.join("replay");
    let first_frame = out.join("right").join("bar_000000.vtu");
    let child = Command::new(bin("cosim"))
        .args([
            "replay",
            long_recording().to_str().unwrap(),
            "--node",
            "right",
            "--run-id",
            &id,
            "-o",
            out.to_str().unwrap(),
        ])
        .env("COSIM_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let pid = loop {
        if let Some(&p) = processes_with(&format!("--run {id} --node right")).first()
            && first_frame.exists()
        {
            break p as i32;
        }
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "the node never started its first window"
        );
        std::thread::sleep(Duration::from_millis(1));
    };
    (child, id, pid)
}

/// Replay `right` of the long recording, stop its node (SIGSTOP) once it is under way, do
/// `act` to it, and return the replay's exit status, stdout and stderr, and the seconds from
/// the stop to its exit; checks that nothing of the replay is left.
fn interrupted(tag: &str, act: impl FnOnce(i32)) -> (bool, String, String, f64) {
    let (mut child, id, pid) = replay_long(tag);
    // Freeze it at once, so the replay cannot finish first.
    // SAFETY: kill(2) on the pid of the replay's own node process, found above.
    unsafe { libc::kill(pid, libc::SIGSTOP) };
    let stopped = Instant::now();
    act(pid);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if stopped.elapsed() > Duration::from_secs(15) {
            let _ = child.kill();
            // SAFETY: as above.
            unsafe { libc::kill(pid, libc::SIGKILL) };
            panic!("cosim replay still running 15 s after its node was stopped");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let secs = stopped.elapsed().as_secs_f64();
    let o = child.wait_with_output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    println!("{tag}: {status} after {secs:.2} s: {out}{err}");
    nothing_left(&id);
    (status.success(), out, err, secs)
}

#[test]
fn a_replayed_node_killed_mid_replay_ends_it_with_an_error() {
    let (ok, out, err, secs) = interrupted("rp-kill", |pid| {
        // SAFETY: kill(2) on the replay's own node process.
        unsafe { libc::kill(pid, libc::SIGKILL) };
    });
    assert!(!ok);
    assert!(!out.contains("bit-identical"), "{out}");
    assert!(
        err.contains("node 'right'") && err.contains("SIGKILL"),
        "{err}"
    );
    assert!(secs < 5.0, "{secs} s");
}

#[test]
fn a_hung_replayed_node_ends_it_with_an_error() {
    // Stopped and left so: no heartbeat for the recorded timeout (3 s).
    let (ok, out, err, _) = interrupted("rp-hang", |_| {});
    assert!(!ok);
    assert!(!out.contains("bit-identical"), "{out}");
    assert!(
        err.contains("node 'right'") && err.contains("no heartbeat"),
        "{err}"
    );
}

/// `cosim info` and `cosim replay` take the run's output folder, as `cosim plot` does.
#[test]
fn a_run_folder_stands_for_its_recording() {
    let folder = recorded().parent().expect("the run folder");
    let o = cosim(&["info", folder.to_str().expect("utf-8")]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("run.mcap"), "{text}");
    let (dir, id) = scratch("rp-folder");
    let out = dir.join("replay");
    let (ok, text, err) = replay_node(folder, "left", &id, &["-o", out.to_str().expect("utf-8")]);
    assert!(ok, "{err}");
    assert!(text.contains("bit-identical"), "{text}");
    nothing_left(&id);
}

/// `cosim replay` stopped (SIGSTOP) for longer than the recorded heartbeat timeout (3 s)
/// while its node runs is its own stall, not the node's hang: the replay says so and
/// finishes bit-identical.
#[test]
fn a_replay_stopped_longer_than_the_heartbeat_timeout_blames_no_node() {
    let (mut child, id, _) = replay_long("rp-own-stall");
    // The node under way, the replay itself stops while its node goes on beating.
    signal_child(&child, libc::SIGSTOP);
    std::thread::sleep(Duration::from_millis(4000));
    signal_child(&child, libc::SIGCONT);
    let status = wait_exit(&mut child, Duration::from_secs(120)).expect("the replay ends");
    let o = child.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    println!("{status}: {text}{err}");
    assert!(status.success(), "{err}");
    assert!(text.contains("bit-identical"), "{text}");
    assert!(err.contains("cosim itself did not run for"), "{err}");
    nothing_left(&id);
}
