//! Recording, `cosim info` and `cosim replay` on a real split-bar run (ARCHITECTURE §7).

use cosim_tests::*;
use std::sync::OnceLock;

/// One recorded run shared by the tests of this file.
fn recorded() -> &'static std::path::PathBuf {
    static OUT: OnceLock<std::path::PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        let (dir, id) = scratch("rec");
        let case = split_bar_case(&dir, 100, 300, 0.5, "shm", 0.5);
        let out = dir.join("out");
        let o = run_case(&case, &out, &id, &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out.join("run.mcap")
    })
}

#[test]
fn recording_passes_the_official_reader() {
    let (ok, s) = check_mcap(recorded(), "--require-json");
    println!("{s}");
    assert!(ok, "check_mcap failed: {s}");
    assert!(s.contains("/cosim/balance"));
}

#[test]
fn info_summarises_the_run() {
    let o = cosim(&["info", recorded().to_str().unwrap()]);
    let s = String::from_utf8_lossy(&o.stdout);
    println!("{s}");
    assert!(o.status.success());
    for needle in [
        "left",
        "right",
        "kinematic",
        "windows",
        "messages",
        "energy",
        "momentum",
    ] {
        assert!(s.contains(needle), "info lacks '{needle}'");
    }
}

#[test]
fn replay_with_the_same_solver_is_bit_identical() {
    for node in ["right", "left"] {
        let o = cosim(&["replay", recorded().to_str().unwrap(), "--node", node]);
        let s = String::from_utf8_lossy(&o.stdout);
        println!("{node}: {s}");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(s.contains("bit-identical"), "{node}: {s}");
    }
}

#[test]
fn replay_with_a_changed_parameter_reports_differences_and_drift() {
    let (dir, _) = scratch("replay");
    let csv = dir.join("report.csv");
    let o = cosim(&[
        "replay",
        recorded().to_str().unwrap(),
        "--node",
        "right",
        "--set",
        "young=210e9",
        "--report",
        csv.to_str().unwrap(),
        "--plot",
        dir.join("plots").to_str().unwrap(),
    ]);
    let s = String::from_utf8_lossy(&o.stdout);
    println!("{s}");
    assert!(o.status.success());
    assert!(!s.contains("bit-identical"));
    assert!(s.contains("max rel diff"));
    let rows = std::fs::read_to_string(&csv).unwrap();
    assert!(rows.lines().count() > 10);
    // Recorded against replayed tip displacement, one chart.
    let png = dir.join("plots/replay_right_tip_displacement.png");
    let len = std::fs::metadata(&png).map(|m| m.len()).unwrap_or(0);
    assert!(len > 1000, "{}: {len} bytes", png.display());
    // The driver's motion is what the recorded responder saw: changing the driver drifts it.
    let o = cosim(&[
        "replay",
        recorded().to_str().unwrap(),
        "--node",
        "left",
        "--set",
        "young=210e9",
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    println!("{e}");
    assert!(o.status.success());
    assert!(e.contains("drifted"), "no drift warning: {e}");
}

#[test]
fn nodes_write_paraview_output_at_the_end() {
    let out = recorded().parent().unwrap();
    for (node, points) in [("left", 101), ("right", 301)] {
        let pvd = std::fs::read_to_string(out.join(node).join("bar.pvd")).expect("a .pvd series");
        let file = pvd
            .split("file=\"")
            .nth(1)
            .and_then(|s| s.split('"').next())
            .expect("the series names a file");
        let vtu = std::fs::read_to_string(out.join(node).join(file)).expect("the .vtu it names");
        assert!(
            vtu.contains(&format!("NumberOfPoints=\"{points}\"")),
            "{node}: {file}"
        );
        assert!(vtu.contains("Name=\"displacement\""));
    }
}
