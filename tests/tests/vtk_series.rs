//! The node kit's VTK output: every built-in
//! node — fluid, peridynamic and bar solids, shell, joint — writes its frames through one
//! writer, and each node's `.pvd` series opens in meshio with a t = 0 frame (the state after
//! set-up, displacement zero), every frame once, in time order.

use cosim_tests::*;

fn run_and_check(case: &std::path::Path, extra: &[&str], tag: &str, series: usize) {
    let (dir, id) = scratch(tag);
    let out = dir.join("out");
    let o = run_case(case, &out, &id, extra);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (ok, text) = check_pvd(&out, series);
    println!("{text}");
    assert!(ok, "{text}");
    nothing_left(&id);
}

#[test]
fn gas_and_peridynamic_bar_series_open_at_t0() {
    run_and_check(
        &workspace_root().join("examples/chamber_detonation.toml"),
        &["--variant", "small"],
        "vtk-chamber",
        2,
    );
}

#[test]
fn shell_and_joint_series_open_at_t0() {
    run_and_check(
        &workspace_root().join("examples/single_joint.toml"),
        &["--variant", "small", "--set", "run.end_time=0.01"],
        "vtk-joint",
        2,
    );
}

#[test]
fn bar_series_open_at_t0() {
    let (dir, _) = scratch("vtk-bar-case");
    let case = split_bar_case(&dir, 20, 60, 0.5, "shm", 0.25);
    run_and_check(&case, &["--set", "run.output_every=20"], "vtk-bar", 2);
}
