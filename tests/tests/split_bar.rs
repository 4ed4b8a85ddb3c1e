//! Verification of the kinematic coupling on the split elastic bar (seed 001 §5.2; docs/architecture.md
//! "Couplings"): exact triangle-wave tip response, equality with the single-node run, sub-cycling
//! stability, and the first-order momentum balance, each through real node processes.

use cosim_tests::*;

fn run_split(
    tag: &str,
    n_left: usize,
    n_right: usize,
    transport: &str,
    periods: f64,
) -> (std::path::PathBuf, serde_json::Value) {
    let (dir, id) = scratch(tag);
    let case = split_bar_case(&dir, n_left, n_right, 0.5, transport, periods);
    let out = dir.join("out");
    let o = run_case(&case, &out, &id, &[]);
    assert!(
        o.status.success(),
        "cosim failed: {}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let s = summary(&out);
    // A finished run leaves nothing in shared memory.
    assert!(
        shm_files(&id).is_empty(),
        "left in /dev/shm: {:?}",
        shm_files(&id)
    );
    (out, s)
}

#[test]
fn split_bar_tip_follows_the_exact_triangle_wave_over_shared_memory() {
    let (out, s) = run_split("tri-shm", 100, 300, "shm", 2.0);
    let tip = node_series(&out.join("run.mcap"), "right", "tip_displacement");
    assert_eq!(tip.len() as u64, s["windows"].as_u64().unwrap());
    let err = tip_error(&tip);
    println!("shm: largest tip error {err:.4e} of the amplitude over two periods");
    assert!(err <= 0.02, "tip error {err} > 2 % of the amplitude");
}

#[test]
fn split_bar_tip_follows_the_exact_triangle_wave_over_zenoh() {
    let (out, s) = run_split("tri-zenoh", 100, 300, "zenoh", 2.0);
    let tip = node_series(&out.join("run.mcap"), "right", "tip_displacement");
    assert_eq!(tip.len() as u64, s["windows"].as_u64().unwrap());
    let err = tip_error(&tip);
    println!("zenoh: largest tip error {err:.4e} of the amplitude over two periods");
    assert!(err <= 0.02, "tip error {err} > 2 % of the amplitude");
}

#[test]
fn equal_meshes_reproduce_the_single_node_run_every_window() {
    let (dir, id) = scratch("single");
    let single = workspace_root().join("examples/bar.toml");
    let out1 = dir.join("single");
    let o = run_case(&single, &out1, &id, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (out2, _) = run_split("equal", 100, 100, "shm", 2.0);
    let a = node_series(&out1.join("run.mcap"), "bar", "tip_displacement");
    let b = node_series(&out2.join("run.mcap"), "right", "tip_displacement");
    assert_eq!(a.len(), b.len());
    assert!(!a.is_empty());
    let amp = amplitude();
    let mut worst: f64 = 0.0;
    for ((ta, ua), (tb, ub)) in a.iter().zip(&b) {
        assert_eq!(ta, tb);
        let rel = (ua - ub).abs() / amp;
        worst = worst.max(rel);
        assert!(rel <= 1e-12, "window at t = {ta}: single {ua}, split {ub}");
    }
    println!("equal meshes: largest difference {worst:e} of the amplitude");
}

#[test]
fn non_integer_and_large_sub_cycle_ratios_run_stable() {
    // Ratio 2.5 (250 right elements for 100 left) and 7 (700).
    for (n_right, bound) in [(250usize, 0.04), (700, 0.04)] {
        let (out, s) = run_split(&format!("ratio{n_right}"), 100, n_right, "shm", 2.0);
        let tip = node_series(&out.join("run.mcap"), "right", "tip_displacement");
        let err = tip_error(&tip);
        let sub = s["nodes"]["right"]["substeps"].as_u64().unwrap() as f64
            / s["windows"].as_f64().unwrap();
        println!(
            "ratio {}: {sub} substeps per window, tip error {err:.4e}",
            n_right as f64 / 100.0
        );
        // Every window reported a tip (an empty series would make the error 0).
        assert_eq!(
            tip.len() as u64,
            s["windows"].as_u64().unwrap(),
            "tip samples against windows"
        );
        assert!(tip.iter().all(|(_, u)| u.is_finite()));
        assert!(
            err <= bound,
            "ratio {}: tip error {err}",
            n_right as f64 / 100.0
        );
    }
}

#[test]
fn momentum_balance_is_first_order_in_the_step() {
    // Ratio 3 at two resolutions: the largest momentum imbalance over the run, relative to
    // the applied impulse, is ≤ 5e-4 and halves when mesh and steps are halved.
    let (_, s1) = run_split("mom100", 100, 300, "shm", 2.0);
    let (_, s2) = run_split("mom200", 200, 600, "shm", 2.0);
    let e1 = s1["balance"]["max_momentum_imbalance_relative"]
        .as_f64()
        .unwrap();
    let e2 = s2["balance"]["max_momentum_imbalance_relative"]
        .as_f64()
        .unwrap();
    println!(
        "momentum imbalance / impulse: {e1:.3e} (100/300), {e2:.3e} (200/600), ratio {:.3}",
        e2 / e1
    );
    assert!(e1 > 0.0 && e1 <= 5e-4, "imbalance {e1}");
    let r = e2 / e1;
    assert!(
        (0.4..=0.6).contains(&r),
        "halving the step should halve the imbalance, ratio {r}"
    );
    // The balance is carried per window in summary.json.
    let rows = s1["balance"]["per_window"].as_array().unwrap();
    assert_eq!(rows.len() as u64, s1["windows"].as_u64().unwrap());
    assert!(rows.iter().all(|r| r["momentum_imbalance"].is_number()));
}
