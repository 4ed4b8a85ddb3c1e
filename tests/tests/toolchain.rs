//! The users' toolchain on a real run (issue 21): `cosim export` to numpy and CSV, checked
//! against the recording read with the official MCAP reader; `cosim info --json` through
//! `python3 -m json.tool`; the field picture `cosim run` draws (`fields.png`) shows the
//! chamber's pressure and the bar where the case puts it.

use cosim_tests::*;
use std::path::PathBuf;
use std::process::Command;
use std::sync::OnceLock;

/// The chamber's small variant, run once for this file: 80 windows.
fn chamber() -> &'static PathBuf {
    static OUT: OnceLock<PathBuf> = OnceLock::new();
    OUT.get_or_init(|| {
        let (dir, id) = scratch("toolchain");
        let out = dir.join("out");
        let case = workspace_root().join("examples/chamber_detonation.toml");
        let o = run_case(&case, &out, &id, &["--variant", "small"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    })
}

fn python(script: &str, args: &[&str]) -> (bool, String) {
    let o = Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .expect("python3 runs");
    (
        o.status.success(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        ),
    )
}

/// numpy reads each history in one call; every value equals the one the official MCAP
/// reader finds in the recording's JSON node reports.
const NUMPY_CHECK: &str = r#"
import json, sys
import numpy as np
from mcap.reader import make_reader
npz, mcap = sys.argv[1], sys.argv[2]
d = np.load(npz)
pressure = d["gas/point2.pressure"]
com = d["bar/com_displacement_x"]
time = d["gas/time"]
rec = {"gas": [], "bar": []}
with open(mcap, "rb") as f:
    for _, ch, m in make_reader(f).iter_messages(topics=["/cosim/node/gas", "/cosim/node/bar"]):
        rec[ch.topic.rsplit("/", 1)[1]].append(json.loads(m.data))
assert pressure.dtype == np.float64 and pressure.shape == (len(rec["gas"]),), pressure.shape
assert com.shape == (len(rec["bar"]),), com.shape
assert np.array_equal(pressure, [r["point2.pressure"] for r in rec["gas"]])
assert np.array_equal(com, [r["com_displacement_x"] for r in rec["bar"]])
assert np.array_equal(time, [r["time"] for r in rec["gas"]])
assert d["bar/momentum"].shape == (len(rec["bar"]), 3)
p1 = d["gas/point1.pressure"]
assert p1.max() > 2e5, p1.max()   # the charge's wall (point 1) sees the blast
assert com[-1] > 0, com[-1]       # the blast pushes the bar away from the charge
print(f"windows {len(pressure)}; point1 peak {p1.max():.6e} Pa; bar com_x final {com[-1]:.6e} m")
"#;

#[test]
fn export_gives_numpy_arrays_equal_to_the_recording() {
    let out = chamber();
    let o = cosim(&["export", out.to_str().unwrap(), "--format", "npz"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let npz = out.join("history.npz");
    let (ok, text) = python(
        NUMPY_CHECK,
        &[
            npz.to_str().unwrap(),
            out.join("run.mcap").to_str().unwrap(),
        ],
    );
    println!("{text}");
    assert!(ok, "{text}");
    assert!(text.contains("windows 80;"), "{text}");

    let o = cosim(&["export", out.to_str().unwrap(), "--format", "csv"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for node in ["gas", "bar", "balance"] {
        let csv = std::fs::read_to_string(out.join("history").join(format!("{node}.csv")))
            .unwrap_or_else(|e| panic!("{node}.csv: {e}"));
        let mut lines = csv.lines();
        let head: Vec<&str> = lines.next().unwrap().split(',').collect();
        assert_eq!(&head[..2], ["window", "time"], "{node}");
        let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
        assert_eq!(rows.len(), 80, "{node}");
        assert!(rows.iter().all(|r| r.len() == head.len()), "{node}");
        assert_eq!(rows[79][0], "80", "{node}");
    }
}

#[test]
fn info_json_is_valid_json() {
    let out = chamber();
    let o = Command::new(bin("cosim"))
        .args(["info", "--json", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut tool = Command::new("python3")
        .args(["-m", "json.tool"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    tool.stdin.take().unwrap().write_all(&o.stdout).unwrap();
    let r = tool.wait_with_output().unwrap();
    assert!(
        r.status.success(),
        "json.tool refused: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["windows_completed"], 80);
    assert_eq!(v["complete"], true);
    let nodes: Vec<&str> = v["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n["name"].as_str().unwrap())
        .collect();
    assert_eq!(nodes.len(), 2);
    assert!(
        nodes.contains(&"gas") && nodes.contains(&"bar"),
        "{nodes:?}"
    );
    assert_eq!(v["couplings"][0]["kind"], "immersed");
    assert!(v["balance"]["energy_residual"].is_number());
}

/// `fields.png`: the 0.4 m × 0.4 m chamber drawn 700 px square in the picture's plot area
/// (1750 px/m, lower left corner at pixel (190, 760)); the bar's particles (light grey dots)
/// lie inside its box x ∈ [0.1, 0.3] m, y ∈ [0.15, 0.25] m and fill it, and the gas around it
/// shows a pressure field (many colours of the map), at the last frame and at 0.2 ms.
#[test]
fn the_field_picture_shows_the_pressure_and_the_bar_where_it_is() {
    let out = chamber();
    let summary = summary(out);
    assert!(
        summary["fields"]
            .as_str()
            .is_some_and(|p| p.ends_with("fields.png"))
    );
    let o = cosim(&["render", out.to_str().unwrap(), "--time", "2e-4"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for png in [out.join("fields.png"), out.join("fields_2e-4.png")] {
        let (w, h, px) = png_pixels(&png);
        assert_eq!((w, h), (1200, 800));
        let to_px = |x: f64, y: f64| (190.0 + 1750.0 * x, 760.0 - 1750.0 * y);
        let (bx0, by1) = to_px(0.1, 0.15);
        let (bx1, by0) = to_px(0.3, 0.25);
        let mut inside = 0;
        let mut outside = 0;
        let mut colours = std::collections::HashSet::new();
        for (k, p) in px.iter().enumerate() {
            let (x, y) = ((k as u32 % w) as f64, (k as u32 / w) as f64);
            if !(190.0..890.0).contains(&x) || !(60.0..760.0).contains(&y) {
                continue;
            }
            if *p == [235, 235, 235] {
                let near = x >= bx0 - 3.0 && x <= bx1 + 3.0 && y >= by0 - 3.0 && y <= by1 + 3.0;
                if near {
                    inside += 1;
                } else {
                    outside += 1;
                }
            } else {
                colours.insert(*p);
            }
        }
        println!(
            "{}: {inside} particle pixels in the bar's box, {outside} outside, {} colours",
            png.display(),
            colours.len()
        );
        // 31 × 16 particles of 5 px each at least (the small variant's bar), none elsewhere
        assert!(inside >= 31 * 16 * 5, "{inside}");
        assert_eq!(outside, 0);
        assert!(colours.len() >= 20, "{} colours", colours.len());
    }
}

/// `cosim validate --json`: one JSON document either way, the same exit codes (0, or 2 with
/// the full key path of the bad value).
#[test]
fn validate_json_names_the_key_or_lists_the_case() {
    let case = workspace_root().join("examples/split_bar.toml");
    let o = cosim(&["validate", case.to_str().unwrap(), "--json"]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON document");
    assert_eq!(v["ok"], true);
    assert_eq!(v["nodes"].as_array().unwrap().len(), 2);
    assert_eq!(v["nodes"][1]["interfaces"][0], "root");
    let variants: Vec<&str> = v["variants"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x["name"].as_str().unwrap())
        .collect();
    assert!(
        variants.contains(&"python") && variants.contains(&"c"),
        "{variants:?}"
    );

    let o = cosim(&[
        "validate",
        case.to_str().unwrap(),
        "--json",
        "--set",
        "left.young=abc",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON document");
    assert_eq!(v["ok"], false);
    assert_eq!(v["key"], "nodes.left.params.young");
    assert!(v["reason"].as_str().unwrap().contains("abc"), "{v}");
}
