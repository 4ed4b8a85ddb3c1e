//! Solvers of our users' own, through the participant libraries (docs/architecture.md: the node is
//! the unit of extension): the 1-D bar written in Python (`examples/external/bar.py`, package
//! `cosim` from `python/`) and in C (`examples/external/bar.c` on `participant-c`) runs as the
//! right half of the split bar exactly as the built-in `bar-1d` does — the tip follows the
//! exact triangle wave, the momentum residual is round-off, and summary and recording have the
//! built-in run's shape — and a Python node killed mid-run ends the run cleanly.
//!
//! These need the Python package installed (`pip install ./python`) and a C compiler: under
//! `CI=true` a missing one is a failure, elsewhere the test is skipped with a message.

use cosim_tests::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// `examples/external/bar-c`, built from `bar.c` (see [`build_c_bar`]).
fn c_bar() -> Option<PathBuf> {
    build_c_bar(&workspace_root().join("examples/external/bar-c"))
}

fn split_bar() -> PathBuf {
    workspace_root().join("examples/split_bar.toml")
}

/// `cosim run examples/split_bar.toml [--variant V]` into a scratch directory.
fn run_variant(tag: &str, variant: Option<&str>) -> (PathBuf, Value, String) {
    let (dir, id) = scratch(tag);
    let out = dir.join("out");
    let extra: Vec<&str> = variant.map(|v| vec!["--variant", v]).unwrap_or_default();
    let o = run_case(&split_bar(), &out, &id, &extra);
    assert!(
        o.status.success(),
        "cosim run {variant:?} failed: {}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        shm_files(&id).is_empty(),
        "left in /dev/shm: {:?}",
        shm_files(&id)
    );
    let s = summary(&out);
    (out, s, id)
}

/// The shape of a JSON value: its keys and types, with every leaf replaced by its type.
fn shape(v: &Value) -> Value {
    match v {
        // the lists of drawn files are as long as what the nodes write: the C bar writes no
        // VTK, so its run has no picture of that node alone; every other list keeps its length
        Value::Object(m) => Value::Object(
            m.iter()
                .map(|(k, v)| match (k.as_str(), v) {
                    ("plots" | "node_fields", Value::Array(_)) => {
                        (k.clone(), Value::String("files".into()))
                    }
                    _ => (k.clone(), shape(v)),
                })
                .collect(),
        ),
        Value::Array(a) => Value::Array(a.iter().map(shape).collect()),
        Value::Number(_) => Value::String("number".into()),
        Value::String(_) => Value::String("string".into()),
        Value::Bool(_) => Value::String("bool".into()),
        Value::Null => Value::Null,
    }
}

/// Topic (with the run id taken out), message type and count of everything recorded, but
/// heartbeats (their number follows the wall clock).
fn channels(mcap: &Path, id: &str) -> Vec<(String, String, usize)> {
    let (msgs, _) = coordinator::record::read_all(mcap).expect("readable recording");
    let mut v: std::collections::BTreeMap<(String, String), usize> = Default::default();
    for m in &msgs {
        let kind = if m.json {
            "json"
        } else {
            protocol::decode(&m.data)
                .expect("a recorded envelope decodes")
                .message
                .type_name()
        };
        if kind == "cosim.Heartbeat" {
            continue;
        }
        *v.entry((m.topic.replace(id, "RUN"), kind.to_string()))
            .or_default() += 1;
    }
    v.into_iter().map(|((t, k), n)| (t, k, n)).collect()
}

/// The external right half against the built-in one: exact wave, round-off momentum
/// residual, the same summary shape and recorded channels, the same tip history.
fn compare_with_builtin(variant: &str) {
    let (out, s, id) = run_variant(&format!("ext-{variant}"), Some(variant));
    let (out0, s0, id0) = run_variant(&format!("ext-{variant}-rs"), None);
    let mcap = out.join("run.mcap");
    let tip = node_series(&mcap, "right", "tip_displacement");
    let windows = s["windows"].as_u64().expect("windows");
    assert_eq!(tip.len() as u64, windows, "one tip value per window");
    assert_eq!(s0["windows"].as_u64(), Some(windows));
    let err = tip_error(&tip);
    let resid = s["balance"]["max_momentum_residual_relative"]
        .as_f64()
        .expect("momentum residual");
    let resid0 = s0["balance"]["max_momentum_residual_relative"]
        .as_f64()
        .expect("momentum residual");
    println!(
        "{variant}: {windows} windows, largest tip error {err:.4e} of the amplitude, momentum \
         residual {resid:.3e} (built-in {resid0:.3e})"
    );
    assert!(err <= 0.02, "tip error {err} > 2 % of the amplitude");
    assert!(resid <= 1e-12, "momentum residual {resid} is not round-off");
    // The same discretisation as the built-in bar: the same tip, window by window.
    let tip0 = node_series(&out0.join("run.mcap"), "right", "tip_displacement");
    assert_eq!(tip0.len(), tip.len());
    let worst = tip
        .iter()
        .zip(&tip0)
        .map(|((t, u), (t0, u0))| {
            assert_eq!(t, t0);
            (u - u0).abs() / amplitude()
        })
        .fold(0.0, nan_max);
    println!(
        "{variant}: largest tip difference from the built-in run {worst:.3e} of the amplitude"
    );
    assert!(
        worst <= 1e-12,
        "tip differs from the built-in bar by {worst}"
    );
    // summary.json and the recording look like a built-in run's.
    assert_eq!(shape(&s), shape(&s0), "summary.json shapes differ");
    assert_eq!(channels(&mcap, &id), channels(&out0.join("run.mcap"), &id0));
    let (ok, text) = check_mcap(&mcap, "--require-json");
    assert!(ok, "check_mcap: {text}");
    // The external node replays from the recording like a built-in one: its recorded
    // executable is launched, fed every recorded input, and matches bit for bit over every
    // window; a recording cut in half is reported incomplete, never identical.
    let replayed = assert_replays_bit_identically(&mcap, "right", &format!("ext-{variant}-rp"));
    assert_eq!(replayed, windows, "replayed windows");
    let (dir, rid) = scratch(&format!("ext-{variant}-cut"));
    let bytes = std::fs::read(&mcap).expect("the recording");
    let cut = dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).expect("write the cut recording");
    let (ok, out, err) = replay_node(&cut, "right", &rid, &[]);
    println!("{variant}, cut recording: {out}{err}");
    assert!(!ok, "a cut recording replayed as complete: {out}");
    assert!(!out.contains("bit-identical"), "{out}");
    assert!(err.contains("incomplete"), "{err}");
    nothing_left(&rid);
    if variant == "python" {
        // A replayed Python node that stops early (a clean exit half-way) is an error.
        let (dir, rid) = scratch("ext-py-short");
        let quitting = "    def advance(self, window, inbox, outbox):\n        \
                        if window.index == 1000:\n            os._exit(0)\n        \
                        return super().advance(window, inbox, outbox)\n";
        let script = patched_python_bar(&dir, quitting);
        let solver = script.display().to_string();
        let (ok, out, err) = replay_node(&mcap, "right", &rid, &["--solver", &solver]);
        println!("python, node stopping at window 1000: {out}{err}");
        assert!(!ok, "a node that stopped early replayed as complete: {out}");
        assert!(!out.contains("bit-identical"), "{out}");
        assert!(
            err.contains("node 'right'") && err.contains("during window 1000"),
            "the error does not say which node stopped when: {err}"
        );
        nothing_left(&rid);
    }
}

#[test]
fn python_right_half_follows_the_exact_wave_like_the_builtin_bar() {
    if !python_package_or_skip() {
        return;
    }
    compare_with_builtin("python");
}

#[test]
fn c_right_half_follows_the_exact_wave_like_the_builtin_bar() {
    if c_bar().is_none() {
        return;
    }
    compare_with_builtin("c");
}

#[test]
fn a_killed_python_node_ends_the_run_cleanly() {
    if !python_package_or_skip() {
        return;
    }
    let (dir, id) = scratch("ext-kill");
    let out = dir.join("out");
    // Two hundred periods: long enough to be killed mid-run.
    let mut child = Command::new(bin("cosim"))
        .args(["run"])
        .arg(split_bar())
        .args([
            "--variant",
            "python",
            "--set",
            "run.end_time=0.3",
            "--output",
        ])
        .arg(&out)
        .args(["--run-id", &id, "--quiet"])
        .env("COSIM_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("cosim starts");
    let node = format!("--run {id} --node right");
    // Killed once the run has recorded windows (Python may take seconds to start on a loaded
    // machine): an event of the run, not a guess at its speed.
    let seen = wait_for_windows(
        &out.join("run.mcap"),
        20,
        Duration::from_secs(60),
        &mut child,
    );
    let pid = *processes_with(&node)
        .first()
        .unwrap_or_else(|| panic!("no Python node running after {seen} windows"));
    let killed = Instant::now();
    // SAFETY: plain kill(2) of the node process this test found.
    assert_eq!(unsafe { libc::kill(pid as i32, libc::SIGKILL) }, 0);
    let status = loop {
        if let Some(s) = child.try_wait().expect("cosim status") {
            break s;
        }
        if killed.elapsed() > Duration::from_secs(2) {
            let _ = child.kill();
            panic!("cosim still running 2 s after the Python node was killed");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let took = killed.elapsed();
    let o = child.wait_with_output().expect("cosim output");
    let stderr = String::from_utf8_lossy(&o.stderr);
    println!("killed the Python node: cosim exited {status} after {took:?}: {stderr}");
    assert!(!status.success());
    assert!(
        stderr.contains("right"),
        "the message does not name the node: {stderr}"
    );
    // No process of the run survives, no shared memory of it is left.
    std::thread::sleep(Duration::from_millis(100));
    let alive: Vec<u32> = processes_with(&format!("--run {id}"))
        .into_iter()
        .filter(|pid| {
            std::fs::read_to_string(format!("/proc/{pid}/stat"))
                .map(|s| !s.contains(") Z"))
                .unwrap_or(false)
        })
        .collect();
    assert!(alive.is_empty(), "surviving node processes: {alive:?}");
    assert!(
        shm_files(&id).is_empty(),
        "left in /dev/shm: {:?}",
        shm_files(&id)
    );
    // The recording is readable and holds the windows completed before the kill, in order.
    let mcap = out.join("run.mcap");
    let (ok, text) = check_mcap(&mcap, "--recover");
    assert!(ok, "check_mcap --recover: {text}");
    let (msgs, _) = coordinator::record::read_all(&mcap).expect("readable recording");
    let windows: Vec<u64> = msgs
        .iter()
        .filter(|m| m.topic == "/cosim/balance")
        .filter_map(|m| serde_json::from_slice::<Value>(&m.data).ok()?["window"].as_u64())
        .collect();
    println!("{} windows recorded before the kill", windows.len());
    assert!(
        windows.len() >= seen,
        "{} windows recorded, {seen} seen before the kill",
        windows.len()
    );
    assert!(
        windows.iter().enumerate().all(|(i, &w)| w == i as u64 + 1),
        "windows not contiguous"
    );
    assert_eq!(summary(&out)["status"], "failed");
}

/// `dir/patched_bar.py`: the Python bar with `body` (Python source, indented for a method)
/// overriding its methods, executable.
fn patched_python_bar(dir: &Path, body: &str) -> PathBuf {
    let script = dir.join("patched_bar.py");
    let text = format!(
        "#!/usr/bin/env python3\nimport os\nimport sys\nsys.path.insert(0, {:?})\nimport bar\nimport cosim\n\n\
         class Patched(bar.Bar):\n{body}\n\nraise SystemExit(cosim.run_node(Patched))\n",
        workspace_root()
            .join("examples/external")
            .display()
            .to_string()
    );
    std::fs::write(&script, text).expect("write the script");
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    script
}

/// A split bar whose right half is the Python bar with `body` replacing its `advance`
/// (Python source, indented for a method); returns cosim's exit and stderr.
fn run_patched_python_bar(
    tag: &str,
    body: &str,
) -> (std::process::ExitStatus, String, PathBuf, String) {
    let (dir, id) = scratch(tag);
    let script = patched_python_bar(&dir, body);
    let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 0.2);
    let text = std::fs::read_to_string(&case).expect("case").replace(
        "[nodes.right]\nsolver = \"solid-node\"",
        &format!("[nodes.right]\nsolver = {:?}", script.display().to_string()),
    );
    std::fs::write(&case, text).expect("case");
    let out = dir.join("out");
    let o = run_case(&case, &out, &id, &[]);
    (
        o.status,
        String::from_utf8_lossy(&o.stderr).into_owned(),
        out,
        id,
    )
}

#[test]
fn a_python_exception_or_a_kept_view_ends_the_run_with_the_reason() {
    if !python_package_or_skip() {
        return;
    }
    let raising = "    def advance(self, window, inbox, outbox):\n        \
                   if window.index == 5:\n            return self.explode(window)\n        \
                   return super().advance(window, inbox, outbox)\n\n    \
                   def explode(self, window):\n        \
                   raise ZeroDivisionError(f'broken in window {window.index}')\n";
    let keeping = "    def advance(self, window, inbox, outbox):\n        \
                   self.kept = inbox['root', 'velocity'][0]\n        \
                   return super().advance(window, inbox, outbox)\n";
    for (tag, body, expect) in [
        (
            "ext-raise",
            raising,
            &[
                "right",
                "ZeroDivisionError: broken in window 5",
                "in explode",
            ][..],
        ),
        (
            "ext-keep",
            keeping,
            &["right", "kept a numpy view of inbox['root', 'velocity']"][..],
        ),
    ] {
        let (status, stderr, out, id) = run_patched_python_bar(tag, body);
        println!("{tag}: exit {status}: {stderr}");
        assert!(!status.success(), "{tag}: the run succeeded");
        for e in expect {
            assert!(
                stderr.contains(e),
                "{tag}: '{stderr}' does not mention '{e}'"
            );
        }
        assert!(
            !stderr.contains("panicked"),
            "{tag}: a panic is not a failure message: {stderr}"
        );
        assert_eq!(summary(&out)["status"], "failed");
        assert!(
            shm_files(&id).is_empty(),
            "left in /dev/shm: {:?}",
            shm_files(&id)
        );
    }
}

/// `cosim validate` asks the external node itself (`bar.py --describe`, `bar-c --describe`):
/// a misspelt and a mistyped parameter are refused with exit 2 and the full key, as for a
/// built-in node, before anything of a run starts.
#[test]
fn validate_names_the_bad_key_of_an_external_node() {
    let mut variants = Vec::new();
    if python_package_or_skip() {
        variants.push("python");
    }
    if c_bar().is_some() {
        variants.push("c");
    }
    let case = split_bar();
    let mut checked = 0;
    for variant in &variants {
        for (set, key) in [
            ("right.youngg=1e9", "nodes.right.params.youngg"),
            ("right.young=\"abc\"", "nodes.right.params.young"),
        ] {
            let o = cosim(&[
                "validate",
                case.to_str().expect("utf-8 path"),
                "--variant",
                variant,
                "--set",
                set,
            ]);
            let err = String::from_utf8_lossy(&o.stderr);
            println!("{variant} --set {set}: exit {:?}: {err}", o.status.code());
            assert_eq!(o.status.code(), Some(2), "{variant} --set {set}: {err}");
            assert!(err.contains(&format!("{key}: ")), "{variant}: {err}");
            checked += 1;
        }
        // and the same case without the bad key validates
        let o = cosim(&[
            "validate",
            case.to_str().expect("utf-8 path"),
            "--variant",
            variant,
        ]);
        assert!(
            o.status.success(),
            "{variant}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    if !variants.is_empty() {
        assert_eq!(checked, 2 * variants.len());
    }
}
