//! Checkpoint and restart of a whole run (docs/architecture.md, README "Restart a run"): a run
//! with `run.checkpoint_every` whose `cosim` is SIGKILLed mid-run, then `cosim restart`, ends
//! bit-identical to an uninterrupted run — the final state (every node's last VTK frame), the
//! balance in summary.json, every node report and every coupling message after the restart
//! point — and the recording reads as one run. Split bar (bar-1d), small chamber (fluid and
//! pd-correspondence, on the CPU and on the GPU), single joint (shell and MC-SPG joint), the
//! split bar with a Python or a C right half (the external nodes' own save/load hooks), and
//! lagrange couplings (bar-1d and fem-2d subdomains, peridynamic particle sides, the
//! coordinator's interface problem); a case with other parameters is refused; Ctrl-C
//! checkpoints where it stops.

use cosim_tests::*;
use protocol::{Message, StepReport};
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// Node reports per (node, window), timings zeroed or dropped (wall-clock, not physics).
fn reports(mcap: &Path) -> BTreeMap<(String, u64), StepReport> {
    let (msgs, complete) = coordinator::record::read_all(mcap).expect("readable recording");
    assert!(complete, "{} is not complete", mcap.display());
    let mut out = BTreeMap::new();
    for m in msgs.iter().filter(|m| !m.json) {
        let Ok(env) = protocol::decode(&m.data) else {
            continue;
        };
        if let Message::Done(d) = env.message {
            let mut r = d.report;
            (r.wall_s, r.coupling_wait_s, r.idle_s) = (0.0, 0.0, 0.0);
            r.scalars
                .retain(|(n, _)| !protocol::message::is_timing_scalar(n));
            let old = out.insert((env.sender.clone(), d.window), r);
            assert!(
                old.is_none(),
                "two reports of {} window {}",
                env.sender,
                d.window
            );
        }
    }
    out
}

/// Coupling data per (coupling/sender topic without the run id, window): the exact values
/// of each message, in the order sent (a lagrange side and the coordinator exchange one per
/// coupling step; the set-up, window 0, has the request and the first multipliers).
fn traffic(mcap: &Path) -> BTreeMap<(String, u64), Vec<Vec<u64>>> {
    let (msgs, _) = coordinator::record::read_all(mcap).expect("readable recording");
    let mut out = BTreeMap::new();
    for m in msgs.iter().filter(|m| !m.json) {
        let Ok(env) = protocol::decode(&m.data) else {
            continue;
        };
        if let Message::Fields(f) = env.message {
            let bits: Vec<u64> = f
                .fields
                .iter()
                .flat_map(|x| x.values.iter().map(|v| v.to_bits()))
                .collect();
            let key = format!("{}/{}", f.coupling, env.sender);
            out.entry((key, f.window))
                .or_insert_with(Vec::new)
                .push(bits);
        }
    }
    out
}

/// The VTK frame of the highest window under `dir` (recursively), by file name.
fn last_frames(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    for node in std::fs::read_dir(dir).expect("output dir").flatten() {
        if !node.path().is_dir() || node.file_name() == "checkpoints" {
            continue;
        }
        let mut frames: Vec<PathBuf> = std::fs::read_dir(node.path())
            .expect("node dir")
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "vtu" || e == "vtk"))
            .collect();
        frames.sort();
        if let Some(last) = frames.last() {
            out.insert(
                format!(
                    "{}/{}",
                    node.file_name().to_string_lossy(),
                    last.file_name().unwrap().to_string_lossy()
                ),
                std::fs::read(last).expect("frame"),
            );
        }
    }
    out
}

/// Run `case` uninterrupted, then again with checkpoints every `every` windows, SIGKILL its
/// `cosim` once the checkpoint of window `kill_after` is complete, restart, and compare.
/// Returns the window the restart continued from.
/// `extra`: further `cosim run` arguments (a variant, settings); `changed`: a `--set` that
/// changes a node parameter, which a restart must refuse.
fn kill_and_restart(
    case: &Path,
    dir: &Path,
    id: &str,
    extra: &[&str],
    changed: &str,
    every: u64,
    kill_after: u64,
) -> u64 {
    kill_later_and_restart(case, dir, id, extra, changed, every, kill_after, 0.0)
}

/// [`kill_and_restart`], killing `later` windows after the checkpoint of `kill_after` is
/// complete (timed by the reference run's window rate).
#[allow(clippy::too_many_arguments)]
fn kill_later_and_restart(
    case: &Path,
    dir: &Path,
    id: &str,
    extra: &[&str],
    changed: &str,
    every: u64,
    kill_after: u64,
    later: f64,
) -> u64 {
    let reference = dir.join("reference");
    let o = run_case(case, &reference, &format!("{id}r"), extra);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = summary(&reference);
    let per_window = r["window_loop_s"].as_f64().unwrap() / r["windows"].as_f64().unwrap();

    let out = dir.join("restarted");
    let every_s = format!("run.checkpoint_every={every}");
    let mut args = vec![
        "run",
        case.to_str().unwrap(),
        "--output",
        out.to_str().unwrap(),
        "--run-id",
        id,
        "--quiet",
        "--set",
        &every_s,
    ];
    args.extend_from_slice(extra);
    let mut child = std::process::Command::new(bin("cosim"))
        .args(&args)
        .env("COSIM_LOG", "warn")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("cosim starts");
    let mark = protocol::checkpoint::file(&out, kill_after, "coordinator");
    let t = Instant::now();
    while !mark.exists() {
        assert!(
            t.elapsed() < Duration::from_secs(120),
            "no checkpoint of window {kill_after} within 120 s"
        );
        assert!(
            child.try_wait().unwrap().is_none(),
            "cosim ended before the kill"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    std::thread::sleep(Duration::from_secs_f64(later * per_window));
    // SAFETY: kill with the pid of our own child and a valid signal number.
    assert_eq!(unsafe { libc::kill(child.id() as i32, libc::SIGKILL) }, 0);
    let status = child.wait().unwrap();
    assert!(status.code().is_none(), "cosim was not killed: {status:?}");
    assert!(
        !out.join("summary.json").exists(),
        "the run finished before the kill: the scenario is void"
    );
    let t = Instant::now();
    while !live_processes(id).is_empty() && t.elapsed() < Duration::from_secs(5) {
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(
        live_processes(id).is_empty(),
        "nodes outlived their coordinator"
    );

    // A case with another parameter may not continue the run.
    let mut bad = vec![
        "run",
        case.to_str().unwrap(),
        "--quiet",
        "--restart",
        out.to_str().unwrap(),
        "--set",
        changed,
    ];
    bad.extend_from_slice(extra);
    let o = cosim(&bad);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("params changed"), "{stderr}");

    let o = cosim(&["restart", out.to_str().unwrap(), "--quiet"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "restart failed: {stderr}");
    let k: u64 = stderr
        .split("restarted from the checkpoint of window ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no restart line in: {stderr}"));
    assert!(
        k >= kill_after && k.is_multiple_of(every),
        "restarted from window {k}"
    );

    continues_identically(&reference, &out, k);
    k
}

/// A run in `out` restarted from the checkpoint of window `k` ended as the uninterrupted run
/// in `reference`: summary.json (balance, every node's final values and step counts), every
/// node report and coupling message after window `k`, every node's last VTK frame; and the
/// recording reads as one run.
fn continues_identically(reference: &Path, out: &Path, k: u64) {
    // summary.json: the whole run's balance, every node's final values and step counts.
    let (a, b) = (summary(reference), summary(out));
    assert_eq!(b["status"], "finished");
    assert_eq!(b["restarted_from_window"], k);
    assert_eq!(a["window_reached"], b["window_reached"]);
    let (rows_a, rows_b) = (
        a["balance"]["per_window"].as_array().unwrap(),
        b["balance"]["per_window"].as_array().unwrap(),
    );
    assert_eq!(rows_a.len(), rows_b.len(), "balance rows");
    if let Some((ra, rb)) = rows_a.iter().zip(rows_b).find(|(x, y)| x != y) {
        panic!("first balance row that differs:\n uninterrupted {ra}\n restarted     {rb}");
    }
    assert_eq!(a["balance"], b["balance"], "balance differs");
    let windows = a["windows"].as_u64().unwrap();
    assert_eq!(
        a["balance"]["per_window"].as_array().unwrap().len() as u64,
        windows
    );
    // the final values without the timing scalars (wall-clock, not physics)
    let physics = |v: &serde_json::Value| {
        let mut v = v.clone();
        if let Some(s) = v["scalars"].as_object_mut() {
            s.retain(|n, _| !protocol::message::is_timing_scalar(n));
        }
        v
    };
    for (name, n) in a["nodes"].as_object().unwrap() {
        assert_eq!(
            physics(&n["final"]),
            physics(&b["nodes"][name]["final"]),
            "final values of {name}"
        );
        assert_eq!(
            n["substeps"], b["nodes"][name]["substeps"],
            "substeps of {name}"
        );
    }
    // Every report and every coupling message after the restart point, bit for bit; the
    // recording (two segments) reads as one run with every window once.
    let (ra, rb) = (
        reports(&reference.join("run.mcap")),
        reports(&out.join("run.mcap")),
    );
    assert_eq!(ra.len(), rb.len(), "reports in the recordings");
    let mut compared = 0;
    for (key, r) in ra.iter().filter(|(k2, _)| k2.1 > k) {
        assert_eq!(Some(r), rb.get(key), "report of {key:?}");
        compared += 1;
    }
    let nodes = a["nodes"].as_object().unwrap().len() as u64;
    assert_eq!(compared, nodes * (windows - k), "reports compared");
    let (ta, tb) = (
        traffic(&reference.join("run.mcap")),
        traffic(&out.join("run.mcap")),
    );
    let missing: Vec<_> = ta.keys().filter(|x| !tb.contains_key(*x)).collect();
    let extra: Vec<_> = tb.keys().filter(|x| !ta.contains_key(*x)).collect();
    assert!(
        missing.is_empty() && extra.is_empty(),
        "coupling messages (checkpoint {k}): missing after the restart {missing:?}, not in the uninterrupted run {extra:?}"
    );
    assert_eq!(ta.len(), tb.len(), "coupling messages in the recordings");
    let mut messages = 0;
    for (key, v) in ta.iter().filter(|(k2, _)| k2.1 > k) {
        assert!(Some(v) == tb.get(key), "coupling data of {key:?}");
        messages += 1;
    }
    // Every case here is coupled: coupling traffic after the restart point must exist.
    assert!(
        messages > 0,
        "no coupling message after window {k} was compared"
    );
    // The final state: every node's last frame, byte for byte.
    let (fa, fb) = (last_frames(reference), last_frames(out));
    assert!(!fa.is_empty(), "no frames written");
    assert_eq!(fa.keys().collect::<Vec<_>>(), fb.keys().collect::<Vec<_>>());
    for (f, bytes) in &fa {
        assert!(bytes == &fb[f], "final frame {f} differs");
    }
    // Each node's series lists every frame once, from t = 0, though the frames after the
    // checkpoint were written twice.
    let (ok, text) = check_pvd(out, fa.len());
    assert!(ok, "{text}");
    let o = cosim(&["info", out.join("run.mcap").to_str().unwrap()]);
    let info = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{info}");
    assert!(info.contains("run.mcap + run.1.mcap"), "{info}");
    assert!(
        info.contains(&format!("windows    {windows} completed")),
        "{info}"
    );
    println!(
        "restarted from window {k} of {windows}: {compared} reports, {messages} coupling messages and {} final frames identical",
        fa.len()
    );
}

/// [`kill_and_restart`] of `examples/<name>.toml` in scratch directory `tag`: continued
/// from the checkpoint of `kill_after` or a later one.
fn example_killed_and_restarted(
    tag: &str,
    name: &str,
    extra: &[&str],
    changed: &str,
    every: u64,
    kill_after: u64,
) {
    let (dir, id) = scratch(tag);
    let case = workspace_root().join(format!("examples/{name}.toml"));
    let k = kill_and_restart(&case, &dir, &id, extra, changed, every, kill_after);
    assert!(k >= kill_after);
}

#[test]
fn split_bar_killed_and_restarted_is_bit_identical() {
    let (dir, id) = scratch("restart-bar");
    let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 8.0);
    let k = kill_and_restart(&case, &dir, &id, &[], "right.tip_force=2000.0", 1000, 2000);
    assert!(k >= 2000);
    // Replay reads the two segments as one run: every window of the node, bit for bit.
    let windows =
        assert_replays_bit_identically(&dir.join("restarted/run.mcap"), "right", "restart-replay");
    assert_eq!(
        windows,
        summary(&dir.join("reference"))["windows"].as_u64().unwrap()
    );
}

#[test]
fn chamber_small_killed_and_restarted_is_bit_identical() {
    example_killed_and_restarted(
        "restart-chamber",
        "chamber_detonation",
        &["--variant", "small"],
        "bar.yield_stress=3.0e8",
        10,
        20,
    );
}

/// The overlap coupling: the mesh's force held from the last window and the particle
/// layer's pull at the window's start and the force it sent ride in the checkpoints.
#[test]
fn overlap_band_killed_and_restarted_is_bit_identical() {
    example_killed_and_restarted(
        "restart-overlap",
        "overlap_wave",
        &["--variant", "band"],
        "band.stabilization=0.4",
        100,
        300,
    );
}

/// Ctrl-C with checkpoints on: the run checkpoints the next window and stops there (exit
/// 130, status "interrupted"), and a restart continues from that window to the same end as
/// an uninterrupted run.
#[test]
fn ctrl_c_checkpoints_where_it_stops_and_the_restart_continues() {
    let (dir, id) = scratch("restart-sigint");
    let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 8.0);
    let reference = dir.join("reference");
    let o = run_case(&case, &reference, &id, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    interrupt_and_restart(
        &case,
        &reference,
        &[],
        (libc::SIGINT, "SIGINT", 130),
        "restart-sigint-s",
    );
}

#[test]
fn shell_and_joint_killed_and_restarted_are_bit_identical() {
    example_killed_and_restarted(
        "restart-joint",
        "single_joint",
        &["--variant", "small", "--set", "run.end_time=0.03"],
        "joint.geometry.bolt_radius=1.4e-3",
        20,
        40,
    );
}

/// The device paths: the gas and the bar on the GPU keep their state on the device; the
/// checkpoint reads it back and the restore uploads it.
#[test]
fn chamber_small_on_the_gpu_killed_and_restarted_is_bit_identical() {
    let test = "chamber_small_on_the_gpu_killed_and_restarted_is_bit_identical";
    if mechanics::gpu::f64_context_or_skip(test).is_none() {
        return;
    }
    example_killed_and_restarted(
        "restart-gpu",
        "chamber_detonation",
        &[
            "--variant",
            "small",
            "--set",
            "gas.device=\"gpu\"",
            // the model with device kernels
            "--set",
            "bar.model=pd-correspondence",
            "--set",
            "bar.device=\"gpu\"",
        ],
        "bar.yield_stress=3.0e8",
        10,
        20,
    );
}

/// Must-show 5: `sig` (SIGINT or SIGTERM, `name`, exit `code`) to `cosim` mid-run of `case`
/// with checkpoints on (far apart: the one the restart uses is the one the stop wrote), as
/// soon as its progress lines say it reached half the windows of the uninterrupted run in
/// `reference` (an event of the run, not a wall-clock guess): exit `code` within 2 s, status
/// "interrupted", a recording the official reader opens without recovery holding windows
/// 1..=reached, no process or shared memory left; then `cosim restart` continues to the end
/// of the reference run, bit-identically.
fn interrupt_and_restart(
    case: &Path,
    reference: &Path,
    extra: &[&str],
    (sig, name, code): (i32, &str, i32),
    tag: &str,
) {
    let (dir, id) = scratch(tag);
    let out = dir.join("stopped");
    let windows = summary(reference)["windows"].as_u64().unwrap();
    let half = windows / 2;
    // Not quiet, with a progress line after every window: a reader thread follows them.
    let mut child = Command::new(bin("cosim"))
        .args([
            "run",
            case.to_str().unwrap(),
            "--output",
            out.to_str().unwrap(),
        ])
        .args(["--run-id", &id, "--set", "run.checkpoint_every=1000000"])
        .args(extra)
        .env("COSIM_LOG", "warn")
        .env("COSIM_PROGRESS_EVERY", "1e-9")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("cosim starts");
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if let Some(k) = line
                .split(", window ")
                .nth(1)
                .and_then(|r| r.split(' ').next())
                .and_then(|k| k.parse::<u64>().ok())
            {
                let _ = tx.send(k);
            }
            text.push_str(&line);
            text.push('\n');
        }
        text
    });
    let t = Instant::now();
    loop {
        match rx.recv_timeout(Duration::from_secs(60)) {
            Ok(k) if k >= half => break,
            Ok(_) => {}
            Err(e) => panic!("{tag}: no progress line of window {half} within 60 s: {e}"),
        }
        assert!(t.elapsed() < Duration::from_secs(120), "{tag}: too slow");
    }
    let t = Instant::now();
    // SAFETY: kill with the pid of our own child and a valid signal number.
    assert_eq!(unsafe { libc::kill(child.id() as i32, sig) }, 0);
    let status = wait_exit(&mut child, Duration::from_secs(2));
    let took = t.elapsed();
    if status.is_none() {
        let _ = child.kill();
    }
    let _ = child.wait();
    let stderr = reader.join().expect("stderr reader");
    let status = status.unwrap_or_else(|| panic!("cosim still running 2 s after {name}"));
    println!("{tag}: {status} after {took:?} (sent at window ≥ {half} of {windows})");
    assert_eq!(status.code(), Some(code), "{stderr}");
    assert!(
        stderr.contains(&format!("interrupted by {name}")),
        "{stderr}"
    );
    let s = summary(&out);
    assert_eq!(s["status"], "interrupted");
    assert_eq!(s["signal"], name);
    let reached = s["window_reached"].as_u64().unwrap();
    assert!(
        reached >= half && reached < windows,
        "stopped after window {reached} of {windows}: the scenario is void"
    );
    let mcap = out.join("run.mcap");
    let (ok, text) = check_mcap(&mcap, "--require-json");
    assert!(ok, "check_mcap: {text}");
    assert_eq!(
        balance_windows(&mcap),
        (1..=reached).collect::<Vec<_>>(),
        "recorded windows are not 1..={reached}"
    );
    nothing_left(&id);
    assert!(
        protocol::checkpoint::file(&out, reached, "coordinator").exists(),
        "no checkpoint of window {reached}, where the run stopped"
    );
    let o = cosim(&["restart", out.to_str().unwrap(), "--quiet"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "restart failed: {stderr}");
    assert!(
        stderr.contains(&format!(
            "restarted from the checkpoint of window {reached} "
        )),
        "{stderr}"
    );
    continues_identically(reference, &out, reached);
}

/// Runs `case` uninterrupted, then stops it with SIGINT and with SIGTERM and restarts each.
fn interrupted_both_ways(case: &Path, extra: &[&str], tag: &str) {
    let (dir, id) = scratch(tag);
    let reference = dir.join("reference");
    let o = run_case(case, &reference, &id, extra);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (sig, name, code) in [
        (libc::SIGINT, "SIGINT", 130),
        (libc::SIGTERM, "SIGTERM", 143),
    ] {
        interrupt_and_restart(
            case,
            &reference,
            extra,
            (sig, name, code),
            &format!("{tag}-{code}"),
        );
    }
}

/// The small chamber, run to 1.2 ms (240 windows) so that a signal lands mid-run.
#[test]
fn chamber_interrupted_by_sigint_and_sigterm_restarts_bit_identically() {
    interrupted_both_ways(
        &workspace_root().join("examples/chamber_detonation.toml"),
        &["--variant", "small", "--set", "run.end_time=1.2e-3"],
        "int-ch",
    );
}

/// The small crash tube (11 processes), run to 20 ms (200 windows) with a VTK frame every 50.
#[test]
fn crash_tube_interrupted_by_sigint_and_sigterm_restarts_bit_identically() {
    interrupted_both_ways(
        &workspace_root().join("examples/crash_tube.toml"),
        &[
            "--variant",
            "small",
            "--set",
            "run.end_time=0.02",
            "--set",
            "run.output_every=50",
        ],
        "int-ct",
    );
}

/// A killed run restarted bit-identically at full size (minutes: run by hand with `--ignored`): `case`'s
/// `variant` with checkpoints every 10 windows, cosim SIGKILLed about 5 windows after the
/// checkpoint of window 30 (after window 35), restarted from window 30 (`changed`: a setting
/// the restart must refuse): bit-identical to the uninterrupted run.
fn killed_after_window_35(case: &str, variant: &str, changed: &str) {
    let (dir, id) = scratch(&format!("restart35-{variant}"));
    let case = workspace_root().join(format!("examples/{case}.toml"));
    let extra = ["--variant", variant];
    let k = kill_later_and_restart(&case, &dir, &id, &extra, changed, 10, 30, 5.5);
    assert_eq!(k, 30, "killed before window 40");
}

#[test]
#[ignore = "the medium chamber: minutes; run with --ignored"]
fn medium_chamber_killed_after_window_35_restarts_bit_identically() {
    killed_after_window_35("chamber_detonation", "medium", "bar.yield_stress=3.0e8");
}

/// The same for the small crash tube (11 processes).
#[test]
#[ignore = "the crash tube: minutes; run with --ignored"]
fn crash_tube_killed_after_window_35_restarts_bit_identically() {
    killed_after_window_35("crash_tube", "small", "j1.yield_stress=3.0e8");
}

/// The split bar with its right half an external node (`solver`: the Python or C bar of
/// `examples/external`, which save and load their state through the participant library's
/// hooks), cosim SIGKILLed after a checkpoint and restarted: bit-identical as above.
fn external_half_killed_and_restarted(dir: &Path, id: &str, solver: &Path) {
    let case = split_bar_case(dir, 100, 300, 0.5, "shm", 2.0);
    let text = std::fs::read_to_string(&case).expect("case");
    let builtin = "[nodes.right]\nsolver = \"solid-node\"";
    assert!(text.contains(builtin), "the split bar's right half moved");
    let text = text.replace(
        builtin,
        &format!("[nodes.right]\nsolver = \"{}\"", solver.display()),
    );
    std::fs::write(&case, text).expect("case");
    let k = kill_and_restart(&case, dir, id, &[], "right.tip_force=2000.0", 500, 1000);
    assert!(k >= 1000);
}

#[test]
fn split_bar_with_a_python_half_killed_and_restarted_is_bit_identical() {
    if !python_package_or_skip() {
        return;
    }
    let (dir, id) = scratch("restart-python");
    let bar = workspace_root().join("examples/external/bar.py");
    external_half_killed_and_restarted(&dir, &id, &bar);
}

#[test]
fn split_bar_with_a_c_half_killed_and_restarted_is_bit_identical() {
    let (dir, id) = scratch("restart-c");
    let Some(bar) = build_c_bar(&dir.join("bar-c")) else {
        return;
    };
    external_half_killed_and_restarted(&dir, &id, &bar);
}

/// A lagrange coupling: each side's subdomain (state, clock, last multipliers,
/// audit sums) and the coordinator's interface problem (window, multipliers) continue from
/// the checkpoint — the split bar as two bar-1d subdomains (average acceleration | central
/// differences in 4 substeps), to 600 windows.
#[test]
fn split_bar_lagrange_killed_and_restarted_is_bit_identical() {
    example_killed_and_restarted(
        "restart-lagrange",
        "split_bar_lagrange",
        &["--set", "run.end_time=5.947268280479703e-4"],
        "right.tip_force=2000.0",
        100,
        200,
    );
}

/// The three fem-2d subdomains of seed 003 §5.3 (small), one coupling of three sides, steps
/// 1 : 2 : 2.
#[test]
fn seed003_three_small_killed_and_restarted_is_bit_identical() {
    example_killed_and_restarted(
        "restart-three",
        "seed003_three",
        &["--variant", "small"],
        "two.young=70e9",
        50,
        100,
    );
}

/// Seed 003 §5.4's notched specimen (small): a fem-2d subdomain and two pd-correspondence
/// particle bodies in one coupling of three sides, gs4 at one particle step per system step.
/// Each particle side saves its coupling state (step-end accelerations, multipliers, audit
/// sums, clock) beside its body; 500 windows.
#[test]
fn seed003_notch_small_killed_and_restarted_is_bit_identical() {
    example_killed_and_restarted(
        "restart-notch",
        "seed003_notch",
        &["--variant", "small"],
        "notch.young=71e9",
        100,
        200,
    );
}

/// The same with gc at four particle steps per system step (the `multirate` settings on the
/// small case, to 100 windows): the particle sides' clocks and multipliers cross system
/// steps in substeps.
#[test]
fn seed003_notch_small_gc_substeps_killed_and_restarted_is_bit_identical() {
    example_killed_and_restarted(
        "restart-notch-gc",
        "seed003_notch",
        &[
            "--variant",
            "small",
            "--set",
            "run.window=6.0e-5",
            "--set",
            "notch.substeps=4",
            "--set",
            "right.substeps=4",
            "--set",
            "couplings.cuts.method=gc",
            "--set",
            "run.end_time=6.0e-3",
        ],
        "right.young=71e9",
        20,
        40,
    );
}

/// The first line of `err` containing `what` (the lines before it are returned too, for
/// the message when it never comes).
fn line_with(err: &mut impl std::io::BufRead, what: &str) -> String {
    let mut seen = String::new();
    loop {
        let mut line = String::new();
        let n = err.read_line(&mut line).expect("cosim's stderr");
        assert!(n > 0, "cosim ended without printing '{what}': {seen}");
        if line.contains(what) {
            return line;
        }
        seen.push_str(&line);
    }
}

/// Starts the remote node with the join command `cosim` printed in `line` (the executable
/// first), writing its output and checkpoints under `dir` on "its host".
fn join_remote(line: &str, dir: &Path) -> std::process::Child {
    let cmd: Vec<&str> = line
        .split(": ")
        .last()
        .expect("a command")
        .split_whitespace()
        .collect();
    assert!(cmd.contains(&"--token"), "no join command in: {line}");
    std::process::Command::new(bin("solid-node"))
        .args(&cmd[1..])
        .arg("--output")
        .arg(dir)
        .env("COSIM_LOG", "warn")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("the remote node starts")
}

/// Two hosts on loopback (zenoh): the split bar's right half joins as a remote node with its
/// own run directory (`--output`, standing for the other host's disk), so its checkpoints
/// are written there and not in `cosim`'s. `cosim` is SIGKILLed after a checkpoint (the
/// remote node follows it), `cosim restart` accepts the checkpoint without the remote file
/// (the node's `Done` acknowledged it), prints the join command saying the node resumes,
/// the node rejoins with the same directory and restores from it: bit-identical to the same
/// case run uninterrupted with both nodes local.
#[test]
fn a_remote_node_checkpoints_on_its_own_host_and_resumes_with_the_restart() {
    let (dir, id) = scratch("restart-remote");
    let case = split_bar_case(&dir, 50, 150, 0.5, "zenoh", 4.0);
    let reference = dir.join("reference");
    let o = run_case(&case, &reference, &format!("{id}r"), &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&case)
        .expect("case")
        .replace("[nodes.right]\n", "[nodes.right]\nremote = true\n");
    std::fs::write(&case, text).expect("case");

    let (out, host) = (dir.join("restarted"), dir.join("other-host"));
    let mut cosim = spawn_cosim_with(&case, &out, &id, &["--set", "run.checkpoint_every=200"]);
    let mut err = std::io::BufReader::new(cosim.stderr.take().expect("stderr"));
    let mut node = join_remote(
        &line_with(&mut err, "waiting for remote node 'right'"),
        &host,
    );
    let mark = protocol::checkpoint::file(&out, 400, "coordinator");
    let t = Instant::now();
    while !mark.exists() {
        assert!(
            t.elapsed() < Duration::from_secs(120),
            "no checkpoint of window 400"
        );
        assert!(
            cosim.try_wait().unwrap().is_none(),
            "cosim ended before the kill"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    // SAFETY: kill with the pid of our own child and a valid signal number.
    assert_eq!(unsafe { libc::kill(cosim.id() as i32, libc::SIGKILL) }, 0);
    let _ = cosim.wait();
    assert!(
        !out.join("summary.json").exists(),
        "the run finished before the kill: the scenario is void"
    );
    assert!(
        wait_exit(&mut node, Duration::from_secs(5)).is_some(),
        "the remote node outlived its coordinator"
    );
    assert!(
        protocol::checkpoint::file(&host, 400, "right").is_file(),
        "the remote node wrote no checkpoint in its own run directory"
    );
    assert!(
        !protocol::checkpoint::file(&out, 400, "right").exists(),
        "the remote node's checkpoint is in cosim's directory"
    );

    let mut cosim = std::process::Command::new(bin("cosim"))
        .args(["restart", out.to_str().unwrap(), "--quiet"])
        .env("COSIM_LOG", "warn")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("cosim restart starts");
    let mut err = std::io::BufReader::new(cosim.stderr.take().expect("stderr"));
    let join = line_with(&mut err, "waiting for remote node 'right'");
    let resumes = line_with(&mut err, "remote node 'right' resumes");
    assert!(resumes.contains("checkpoint of window"), "{resumes}");
    let node = join_remote(&join, &host);
    let status = cosim.wait().expect("cosim restart ends");
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).expect("stderr");
    let node = node.wait_with_output().expect("the remote node ends");
    assert!(
        node.status.success(),
        "remote node {:?}: {}",
        node.status,
        String::from_utf8_lossy(&node.stderr)
    );
    assert!(status.success(), "restart failed: {rest}");
    let k: u64 = rest
        .split("restarted from the checkpoint of window ")
        .nth(1)
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no restart line in: {rest}"));
    assert!(
        k >= 400 && k.is_multiple_of(200),
        "restarted from window {k}"
    );
    // The remote host's frames, gathered into the run directory as a user copies them back.
    let (from, to) = (host.join("right"), out.join("right"));
    std::fs::create_dir_all(&to).expect("node dir");
    for e in std::fs::read_dir(&from)
        .expect("the remote node's output")
        .flatten()
    {
        std::fs::copy(e.path(), to.join(e.file_name())).expect("copy a frame");
    }
    continues_identically(&reference, &out, k);
    nothing_left(&id);
}
