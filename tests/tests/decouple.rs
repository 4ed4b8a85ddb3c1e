//! Decoupling (docs/architecture.md, seed 000 §4): once enough impulse has reached the
//! solid, the immersed coupling ends, the fluid node is finished and the solid goes on alone.
//! Run on the small chamber: decoupled at half time (by time, then by a reported quantity),
//! the bar must keep exactly the impulse the gas gave it up to the decoupling — including the
//! last window's, still in flight across the one-window lag — and receive nothing after.

use cosim_tests::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const WINDOW: f64 = 5.0e-6;
const AT: f64 = 2.0e-4; // the start of window 41 of 80

fn run(tag: &str, extra: &[&str]) -> PathBuf {
    let (dir, id) = scratch(tag);
    let out = dir.join("out");
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let mut args = vec!["--variant", "small"];
    args.extend_from_slice(extra);
    let o = run_case(&case, &out, &id, &args);
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

fn by_time() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        run(
            "decouple-time",
            &["--set", &format!("couplings.blast.decouple_at={AT:e}")],
        )
    })
}

fn decoupled_before(out: &Path) -> u64 {
    let s = summary(out);
    s["couplings"][0]["decoupled"]["before_window"]
        .as_u64()
        .unwrap_or_else(|| panic!("no decoupling in summary.json: {}", s["couplings"]))
}

#[test]
fn after_decoupling_the_gas_stops_and_the_bar_keeps_exactly_the_impulse_it_was_given() {
    let out = by_time();
    let k = decoupled_before(out);
    assert_eq!(k, (AT / WINDOW).round() as u64 + 1);
    let s = summary(out);
    assert_eq!(
        s["nodes"]["gas"]["finished_after_window"].as_u64(),
        Some(k - 1)
    );
    assert!(s["nodes"]["bar"]["finished_after_window"].is_null());
    let mcap = out.join("run.mcap");
    let gas = node_vectors(&mcap, "gas", "interface_impulse");
    let bar = node_vectors(&mcap, "bar", "interface_impulse");
    assert_eq!(
        gas.last().map(|g| g.0),
        Some(k - 1),
        "gas ran past the decoupling"
    );
    assert_eq!(bar.len(), 80, "the bar goes on to the end");
    // What the gas gave up to its last window, the bar has received by window k (lag 1) ...
    let given = gas.last().expect("gas reports").1;
    let got = bar[(k - 1) as usize].1;
    let scale = given[0].abs().max(given[1].abs());
    assert!(scale > 1e-9, "no impulse crossed before the decoupling");
    for d in 0..3 {
        assert!(
            (given[d] + got[d]).abs() <= 1e-12 * scale,
            "given {given:?}, received {got:?}"
        );
    }
    // ... and nothing after: the received impulse is frozen bitwise.
    for (w, j) in &bar[k as usize..] {
        assert_eq!(j, &got, "window {w}: the bar still receives a force");
    }
    let r = s["balance"]["max_momentum_residual_relative"]
        .as_f64()
        .expect("residual");
    println!("decoupled before window {k}: impulse {scale:e} N s, residual {r:e}");
    assert!(r <= 1e-12, "momentum residual {r:e}");
    // The gas wrote its final state when it was finished (VTK of window k - 1).
    let last = std::fs::read_dir(out.join("gas"))
        .expect("gas output")
        .filter_map(|e| e.ok())
        .any(|e| {
            e.file_name()
                .to_string_lossy()
                .contains(&format!("{:06}", k - 1))
        });
    assert!(last, "no gas output of window {}", k - 1);
}

#[test]
fn the_decoupled_run_replays_bit_for_bit() {
    let out = by_time();
    let mcap = out.join("run.mcap");
    // The bar is told of the decoupling and goes on alone to the end; the gas is finished
    // after the window before it. Both replay every window they ran.
    assert_eq!(
        assert_replays_bit_identically(&mcap, "bar", "rp-dec-bar"),
        80
    );
    let k = decoupled_before(out);
    assert_eq!(
        assert_replays_bit_identically(&mcap, "gas", "rp-dec-gas"),
        k - 1
    );
}

#[test]
fn decoupling_on_a_reported_quantity_and_bad_rules() {
    // The bar's centre of mass has moved 1 nm: well before the end in the small chamber.
    let out = run(
        "decouple-when",
        &[
            "--set",
            "couplings.blast.decouple_when=\"bar.com_displacement_x >= 1e-9\"",
        ],
    );
    let k = decoupled_before(&out);
    let x = node_series(&out.join("run.mcap"), "bar", "com_displacement_x");
    // The first window whose predecessor reached the level.
    let first = x
        .iter()
        .position(|(_, v)| *v >= 1e-9)
        .expect("the level is reached") as u64
        + 2;
    assert_eq!(k, first, "{x:?}");
    assert!(k > 2 && k < 80, "decoupled before window {k}");
    // A quantity the node does not report ends the run with the key named.
    let (dir, id) = scratch("decouple-bad");
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let o = run_case(
        &case,
        &dir.join("out"),
        &id,
        &[
            "--variant",
            "small",
            "--set",
            "run.end_time=2e-5",
            "--set",
            "couplings.blast.decouple_when=\"bar.no_such_thing >= 1\"",
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("decouple_when") && err.contains("no_such_thing"),
        "{err}"
    );
    // A kinematic coupling cannot be decoupled; a bad time is refused before anything starts.
    for (case, set, key) in [
        (
            "examples/split_bar.toml",
            "couplings.mid.decouple_at=1e-4",
            "couplings[0].decouple_at",
        ),
        (
            "examples/chamber_detonation.toml",
            "couplings.blast.decouple_at=-1",
            "couplings[0].decouple_at",
        ),
        (
            "examples/chamber_detonation.toml",
            "couplings.blast.decouple_when=\"nobody.x >= 1\"",
            "couplings[0].decouple_when",
        ),
        (
            "examples/chamber_detonation.toml",
            "couplings.nope.decouple_at=1e-4",
            "no coupling named 'nope'",
        ),
    ] {
        let path = workspace_root().join(case);
        let o = cosim(&["validate", path.to_str().unwrap(), "--set", set]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{set} accepted");
        assert!(err.contains(key), "{set}: {err}");
    }
}
