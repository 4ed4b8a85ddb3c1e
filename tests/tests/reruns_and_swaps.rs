//! The command line as our users drive it: a rerun into the same output folder is
//! refused unless `--overwrite`, which clears what the earlier run left (so the `.pvd` series
//! list exactly the new run's frames) and keeps the folders of other variants; `--set
//! NODE.model=` and `--set NODE.solver=` swap a node's model or executable; `--set` reaches a
//! node whose `params` is a file of its own.

use cosim_tests::*;
use std::path::Path;

/// The `DataSet` entries of a ParaView series file.
fn frames(pvd: &Path) -> usize {
    std::fs::read_to_string(pvd)
        .unwrap_or_else(|e| panic!("{}: {e}", pvd.display()))
        .matches("<DataSet")
        .count()
}

fn vtu_files(dir: &Path) -> usize {
    std::fs::read_dir(dir)
        .expect("node output folder")
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "vtu"))
        .count()
}

#[test]
fn a_rerun_needs_overwrite_and_then_lists_only_its_own_frames() {
    let (dir, id) = scratch("rerun");
    // 80 windows (a quarter period of the 20 + 60 element split bar), a frame every 20.
    let case = split_bar_case(&dir, 20, 60, 0.5, "shm", 0.25);
    let out = dir.join("out");
    let every = ["--set", "run.output_every=20"];
    let o = run_case(&case, &out, &id, &every);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(summary(&out)["windows"], 80);
    let pvd = out.join("right/bar.pvd");
    assert_eq!(frames(&pvd), 5, "windows 0, 20, 40, 60, 80");
    // Another run's results beside it, as a variant writes them: kept by --overwrite.
    std::fs::create_dir_all(out.join("fine")).expect("variant folder");
    std::fs::write(out.join("fine/summary.json"), "{}").expect("variant summary");
    let before = std::fs::read(out.join("summary.json")).expect("summary");

    let o = run_case(&case, &out, &id, &every);
    let err = String::from_utf8_lossy(&o.stderr);
    println!("rerun without --overwrite: {err}");
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--overwrite") && err.contains("already holds results"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(out.join("summary.json")).expect("summary"),
        before,
        "the refused rerun changed the earlier results"
    );

    // Half as long: 40 windows, frames at 0, 20 and 40 only.
    let half = format!(
        "run.end_time={:e}",
        0.125 * 4.0 / (200e9f64 / 7860.0).sqrt()
    );
    let o = run_case(
        &case,
        &out,
        &id,
        &[
            "--overwrite",
            "--set",
            "run.output_every=20",
            "--set",
            &half,
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(summary(&out)["windows"], 40);
    for node in ["left", "right"] {
        let node_dir = out.join(node);
        assert_eq!(frames(&node_dir.join("bar.pvd")), 3, "{node}: frames");
        assert_eq!(vtu_files(&node_dir), 3, "{node}: VTK files");
    }
    assert!(
        out.join("fine/summary.json").exists(),
        "--overwrite removed another variant's results"
    );
    nothing_left(&id);
}

/// the chamber's bar swapped from `pd-rk-ba` to `pd-correspondence` from the command line.
#[test]
fn set_swaps_a_node_model_and_executable() {
    let (dir, id) = scratch("swap-model");
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let out = dir.join("out");
    let o = run_case(
        &case,
        &out,
        &id,
        &["--variant", "small", "--set", "bar.model=pd-correspondence"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = summary(&out);
    assert_eq!(
        s["nodes"]["bar"]["model"], "pd-correspondence",
        "{}",
        s["nodes"]
    );
    assert_eq!(s["status"], "finished");
    // The node really ran the other model, not just the summary's echo of the case: the bar's
    // recorded energies are those of a case file that names pd-correspondence itself, bit
    // for bit, and differ from the unswapped run's.
    let text = std::fs::read_to_string(&case).unwrap();
    assert_eq!(text.matches("model = \"pd-rk-ba\"").count(), 1);
    let edited = dir.join("correspondence.toml");
    std::fs::write(
        &edited,
        text.replace("model = \"pd-rk-ba\"", "model = \"pd-correspondence\""),
    )
    .unwrap();
    let series = |case: &std::path::Path, tag: &str, extra: &[&str]| {
        let out = dir.join(tag);
        let mut args = vec!["--variant", "small"];
        args.extend_from_slice(extra);
        let o = run_case(case, &out, &format!("{id}-{tag}"), &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        node_series(&out.join("run.mcap"), "bar", "internal_energy")
    };
    let swapped = node_series(&out.join("run.mcap"), "bar", "internal_energy");
    let written = series(&edited, "written", &[]);
    let default = series(&case, "default", &[]);
    assert!(swapped.len() > 10, "{} windows", swapped.len());
    assert_eq!(swapped, written, "--set and the case file give other runs");
    assert_ne!(swapped, default, "the swapped run is the unswapped one");

    // The right half's executable, named by an absolute path.
    let (dir, id) = scratch("swap-exe");
    let case = split_bar_case(&dir, 20, 60, 0.5, "shm", 0.25);
    let exe = bin("solid-node").display().to_string();
    let out = dir.join("out");
    let o = run_case(&case, &out, &id, &["--set", &format!("right.solver={exe}")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(summary(&out)["nodes"]["right"]["solver"], exe.as_str());
    // A model the executable does not have is refused before anything starts.
    let o = cosim(&[
        "validate",
        case.to_str().expect("utf-8"),
        "--set",
        "right.model=bar-2d",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("nodes.right.model"), "{err}");
}

/// `params = "right.toml"`: `--set` edits the file's table; a bad value is still named with
/// its full key.
#[test]
fn set_reaches_a_params_file() {
    let (dir, _) = scratch("set-file");
    let case = split_bar_case(&dir, 20, 60, 0.5, "shm", 0.25);
    let text = std::fs::read_to_string(&case).expect("case");
    let start = text.find("[nodes.right.params]").expect("right params");
    let end = text[start..].find("[[couplings]]").expect("couplings") + start;
    let params = text[start + "[nodes.right.params]".len()..end].to_string();
    std::fs::write(dir.join("right.toml"), params).expect("params file");
    let text = format!(
        "{}params = \"right.toml\"\n\n{}",
        &text[..start],
        &text[end..]
    );
    std::fs::write(&case, text).expect("case");
    let validate = |set: &str| cosim(&["validate", case.to_str().expect("utf-8"), "--set", set]);
    let o = validate("right.elements=90");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = validate("right.young=\"abc\"");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("nodes.right.params.young"), "{err}");
}

/// `cosim run … 2>log` (stderr not a terminal, as in a batch job) writes progress lines in
/// plain numbers; `-q` writes none.
#[test]
fn progress_lines_when_stderr_is_not_a_terminal() {
    let (dir, id) = scratch("progress");
    // 3200 windows: a second or two.
    let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 2.0);
    let run = |out: &str, quiet: bool| {
        let mut cmd = std::process::Command::new(bin("cosim"));
        cmd.arg("run")
            .arg(&case)
            .arg("--output")
            .arg(dir.join(out))
            .args(["--run-id", &id])
            .env("COSIM_LOG", "warn")
            .env("COSIM_PROGRESS_EVERY", "0.05");
        if quiet {
            cmd.arg("-q");
        }
        let o = cmd.output().expect("cosim runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let err = run("out", false);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("cosim: t = "))
        .collect();
    println!("{} progress lines, e.g. {:?}", lines.len(), lines.first());
    assert!(lines.len() >= 2, "fewer than two progress lines: {err}");
    let mut last = 0;
    for l in &lines {
        let k: u64 = l
            .split("window ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|k| k.parse().ok())
            .unwrap_or_else(|| panic!("no window in '{l}'"));
        assert!(k > last && k <= 3200, "window {k} after {last}: '{l}'");
        last = k;
        assert!(l.contains(" of 3200, "), "{l}");
        let rate = l
            .split(" windows/s")
            .next()
            .and_then(|h| h.rsplit(' ').next())
            .unwrap_or("");
        assert!(
            rate.parse::<f64>().is_ok(),
            "rate '{rate}' is not a plain number: '{l}'"
        );
        assert!(l.contains("elapsed") && l.contains("ETA"), "{l}");
    }
    let quiet = run("out-quiet", true);
    assert!(
        !quiet.contains("cosim: t = "),
        "-q printed progress: {quiet}"
    );
}

/// One path rule: what a case file names (its `run.output`, a node's `solver`) is relative to
/// the case file, wherever `cosim` is started; what the command line names (`--set
/// run.output=`) is relative to the working directory.
#[test]
fn a_case_run_from_elsewhere_writes_and_finds_its_solver_beside_itself() {
    let (dir, id) = scratch("paths");
    let cases = dir.join("cases");
    std::fs::create_dir_all(cases.join("bin")).unwrap();
    let case = split_bar_case(&cases, 20, 60, 0.5, "shm", 0.05);
    // the right half's executable beside the case, named by a relative path
    std::os::unix::fs::symlink(bin("solid-node"), cases.join("bin/my-bar")).unwrap();
    let text = std::fs::read_to_string(&case).unwrap();
    let swapped = text.replacen(
        "[nodes.right]\nsolver = \"solid-node\"",
        "[nodes.right]\nsolver = \"bin/my-bar\"",
        1,
    );
    assert_ne!(swapped, text, "the case names the right half's solver");
    std::fs::write(&case, swapped).unwrap();
    let elsewhere = dir.join("elsewhere");
    std::fs::create_dir_all(&elsewhere).unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec!["run", case.to_str().unwrap(), "--run-id", &id, "--quiet"];
        args.extend_from_slice(extra);
        let o = std::process::Command::new(bin("cosim"))
            .args(&args)
            .current_dir(&elsewhere)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run(&[]);
    // `output = "out"` of the case: beside the case, not in the working directory
    assert!(cases.join("out/run.mcap").is_file());
    assert!(!elsewhere.join("out").exists());
    assert_eq!(
        summary(&cases.join("out"))["nodes"]["right"]["solver"],
        "bin/my-bar"
    );
    // the command line's own path: from the working directory
    run(&["--set", "run.output=mine"]);
    assert!(elsewhere.join("mine/run.mcap").is_file());
    nothing_left(&id);
}
