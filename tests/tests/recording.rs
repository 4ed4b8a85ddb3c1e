//! Recording and `cosim info` on a real split-bar run (ARCHITECTURE §7); replay is in
//! `replay.rs`.

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
