//! A chain of three `bar-1d` subdomains through `cosim run` (seed 003 §4, §5.3):
//! `examples/split_bar_chain.toml`'s small variant, whose middle bar has both ends in one
//! interface. At the case's system step and at half of it the run is the in-process chain
//! (`solid_node::fixtures::bar_chain`) to round-off, series by series and in its interface
//! energy; u and v at both cuts and at the tip and the multipliers of both cuts approach the
//! single-domain bar of the same mesh (average acceleration at 1/128 of the case's step) at
//! second order; each series has one sample per window; momentum closes.

use cosim_tests::*;
use protocol::scheme::lagrange::Method;
use solid_node::fixtures::bar_chain::{self, Histories, NAMES};
use std::path::{Path, PathBuf};

/// The small variant's window (h_left/c, s) and its window count to 2T.
const WINDOW: f64 = 1.982422760159901e-06;
const WINDOWS: usize = 600;

fn run(tag: &str, window: f64) -> PathBuf {
    let (dir, id) = scratch(tag);
    let out = dir.join("out");
    let case = workspace_root().join("examples/split_bar_chain.toml");
    let sets = [format!("run.window={window:e}")];
    let mut extra = vec!["--variant", "small"];
    for s in &sets {
        extra.extend(["--set", s.as_str()]);
    }
    let o = run_case(&case, &out, &id, &extra);
    assert!(
        o.status.success(),
        "{tag}: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    nothing_left(&id);
    out
}

/// The eight series of a run ([`NAMES`]), t = 0 (at rest) first, from its recording.
fn recorded(out: &Path, dt: f64) -> Histories {
    let mcap = out.join("run.mcap");
    let series = |node: &str, key: &str| -> Vec<f64> {
        std::iter::once(0.0)
            .chain(node_series(&mcap, node, key).into_iter().map(|(_, v)| v))
            .collect()
    };
    let (msgs, _) = coordinator::record::read_json(&mcap).expect("readable recording");
    let lambda = |k: usize| -> Vec<f64> {
        std::iter::once(0.0)
            .chain(
                msgs.iter()
                    .filter(|m| m.topic == "/cosim/lagrange/cuts")
                    .filter_map(|m| {
                        let v: serde_json::Value = serde_json::from_slice(&m.data).ok()?;
                        v["lambda"][k].as_f64()
                    }),
            )
            .collect()
    };
    // The coordinator ties the cuts in the order of the sides: λ₀ on the left bar, λ₁ on
    // the middle one's right end, each the force on the part left of its cut.
    Histories {
        dt,
        series: vec![
            series("left", "cut_displacement"),
            series("left", "cut_velocity"),
            series("middle", "cuts_right_displacement"),
            series("middle", "cuts_right_velocity"),
            series("right", "tip_displacement"),
            series("right", "tip_velocity"),
            lambda(0),
            lambda(1),
        ],
    }
}

#[test]
fn bar_chain_through_cosim_run_is_the_library_chain_and_second_order() {
    assert!((bar_chain::transit() - WINDOW).abs() < 1e-12 * WINDOW);
    assert_eq!(bar_chain::steps0(), WINDOWS);
    let fine = 128;
    let reference =
        bar_chain::single(WINDOW / fine as f64, fine * WINDOWS, 1).expect("reference bar");
    let mut e = vec![Vec::new(); NAMES.len()];
    let mut energy = Vec::new();
    for (level, window) in [WINDOW, WINDOW / 2.0].into_iter().enumerate() {
        let out = run(&format!("chain-{level}"), window);
        let windows = WINDOWS << level;
        let got = recorded(&out, window);
        // The run through cosim is the in-process chain, to round-off.
        let (library, library_energy) =
            bar_chain::chain(Method::Gs4, window, windows).expect("library chain");
        for (k, (d, n)) in bar_chain::errors(&got, &library).into_iter().enumerate() {
            assert_eq!(n, windows + 1, "level {level} {}: samples", NAMES[k]);
            assert!(
                d < 1e-9,
                "level {level} {}: cosim and library differ by {d:e}",
                NAMES[k]
            );
        }
        for (k, (x, n)) in bar_chain::errors(&got, &reference).into_iter().enumerate() {
            assert_eq!(n, windows + 1, "level {level} {}: samples", NAMES[k]);
            e[k].push(x);
        }
        let s = summary(&out);
        let p = s["balance"]["max_momentum_residual_relative"]
            .as_f64()
            .unwrap_or(f64::NAN);
        assert!(p < 1e-9, "level {level}: momentum residual {p:e}");
        let de = s["couplings"][0]["interface_energy"]
            .as_f64()
            .unwrap_or(f64::NAN);
        let lib = library_energy.last().copied().unwrap_or(f64::NAN);
        assert!(
            (de - lib).abs() <= 1e-9 * lib.abs(),
            "level {level}: ΔE_Γ {de:e} J, library {lib:e} J"
        );
        energy.push(de);
    }
    for (k, name) in NAMES.iter().enumerate() {
        let o = (e[k][0] / e[k][1]).log2();
        println!("{name}: errors {:?}, order {o:.3}", e[k]);
        assert!(o >= 1.8, "{name}: order {o:.3} ({:?})", e[k]);
    }
    println!("ΔE_Γ {energy:?} J");
}
