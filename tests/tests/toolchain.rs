//! The users' toolchain on a real run: `cosim export` to numpy, CSV and Parquet, checked
//! against the recording read with the official MCAP reader; `cosim info --json` through
//! `python3 -m json.tool`; the field picture `cosim run` draws (`fields.png`) shows the
//! chamber's pressure and the bar where the case puts it; the Python package's `open_run`
//! returns the same histories and interface fields as the official reader and an independent
//! decoder of the wire format find in the recording.

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
com = d["bar/com_displacement"][:, 0]
time = d["gas/time"]
rec = {"gas": [], "bar": []}
with open(mcap, "rb") as f:
    for _, ch, m in make_reader(f).iter_messages(topics=["/cosim/node/gas", "/cosim/node/bar"]):
        rec[ch.topic.rsplit("/", 1)[1]].append(json.loads(m.data))
assert pressure.dtype == np.float64 and pressure.shape == (len(rec["gas"]),), pressure.shape
assert d["bar/com_displacement"].shape == (len(rec["bar"]), 3), d["bar/com_displacement"].shape
assert "bar/com_displacement_x" not in d   # one name for a vector
assert np.array_equal(pressure, [r["point2"]["pressure"] for r in rec["gas"]])
# a vector is one key of the recording too, [x, y, z], as momentum is
assert all("com_displacement_x" not in r for r in rec["bar"])
assert np.array_equal(d["bar/com_displacement"], [r["com_displacement"] for r in rec["bar"]])
assert np.array_equal(com, [r["com_displacement"][0] for r in rec["bar"]])
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

/// Foxglove's message paths address every series of a node report: `/cosim/node/gas.point1.pressure`
/// resolved as Foxglove does (the topic, then one key per dot, no quoting) against the official
/// reader's messages gives the same values as the export's `gas/point1.pressure`; no key of any
/// report holds a dot; the channel's schema lists the nested keys with their types; a vector
/// (`bar.com_displacement[0]`) is one array key, whose components are the export's.
const FOXGLOVE_CHECK: &str = r#"
import json, sys
import numpy as np
from mcap.reader import make_reader
npz, mcap = sys.argv[1], sys.argv[2]
d = np.load(npz)
msgs, schemas = {}, {}
with open(mcap, "rb") as f:
    for schema, ch, m in make_reader(f).iter_messages():
        if ch.topic.startswith("/cosim/node/"):
            msgs.setdefault(ch.topic, []).append(json.loads(m.data))
            schemas[ch.topic] = json.loads(schema.data)
def dotted(doc):
    return [k for k, v in doc.items() if "." in k or (isinstance(v, dict) and dotted(v))]
def resolve(path):
    topic, _, rest = path.partition(".")
    out = []
    for doc in msgs[topic]:
        for k in rest.split("."):
            doc = doc[k]
        out.append(doc)
    return out
checked = 0
for node in ("gas", "bar"):
    for doc in msgs[f"/cosim/node/{node}"]:
        assert not dotted(doc), (node, dotted(doc))
for series in ("point1.pressure", "point2.pressure", "point1.density"):
    got = resolve(f"/cosim/node/gas.{series}")
    assert len(got) == 80, len(got)
    assert np.array_equal(np.array(got, dtype=float), d[f"gas/{series}"]), series
    checked += len(got)
props = schemas["/cosim/node/gas"]["properties"]
assert props["point1"]["type"] == "object", props["point1"]
assert props["point1"]["properties"]["pressure"]["type"] == ["number", "null"]
# a vector, as Foxglove addresses it: /cosim/node/bar.com_displacement[0]
bar = schemas["/cosim/node/bar"]["properties"]
assert bar["com_displacement"]["type"] == "array", bar["com_displacement"]
assert "com_displacement_x" not in bar
got = [doc["com_displacement"][0] for doc in msgs["/cosim/node/bar"]]
assert np.array_equal(np.array(got), d["bar/com_displacement"][:, 0])
checked += len(got)
print(f"{checked} values through Foxglove paths")
"#;

#[test]
fn foxglove_paths_address_every_named_scalar() {
    let out = chamber();
    let npz = out.join("history-foxglove.npz");
    let o = cosim(&[
        "export",
        out.to_str().unwrap(),
        "--format",
        "npz",
        "-o",
        npz.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (ok, text) = python(
        FOXGLOVE_CHECK,
        &[
            npz.to_str().unwrap(),
            out.join("run.mcap").to_str().unwrap(),
        ],
    );
    println!("{text}");
    assert!(ok, "{text}");
    assert!(text.contains("320 values through Foxglove paths"), "{text}");
}

/// pyarrow (the Apache Arrow project's Python reader, independent of our writer) reads each
/// node's `history/NODE.parquet`: every column equals the recording's JSON values (vectors as
/// `_x/_y/_z`), a key a window lacks is null.
const PARQUET_CHECK: &str = r#"
import json, sys
import numpy as np
import pyarrow.parquet as pq
from mcap.reader import make_reader
hist, mcap = sys.argv[1], sys.argv[2]
def flat(d, path=""):
    """A report's nested objects as the dotted names of the export's columns."""
    out = {}
    for k, v in d.items():
        name = f"{path}.{k}" if path else k
        out.update(flat(v, name) if isinstance(v, dict) and v else {name: v})
    return out
rec = {}
with open(mcap, "rb") as f:
    for _, ch, m in make_reader(f).iter_messages(topics=["/cosim/node/gas", "/cosim/node/bar", "/cosim/balance"]):
        name = "balance" if ch.topic == "/cosim/balance" else ch.topic.rsplit("/", 1)[1]
        rec.setdefault(name, []).append(flat(json.loads(m.data)))
checked = 0
for node, rows in sorted(rec.items()):
    t = pq.read_table(f"{hist}/{node}.parquet")
    assert t.num_rows == len(rows), (node, t.num_rows, len(rows))
    keys = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    for k in keys:
        width = max(len(r[k]) if isinstance(r.get(k), list) else 1 for r in rows)
        names = [k] if width == 1 else [f"{k}_{a}" for a in "xyz"[:width]] if width in (2, 3) else [f"{k}_{i}" for i in range(width)]
        for i, name in enumerate(names):
            col = t.column(name)
            assert str(col.type) == "double", (node, name, col.type)
            got = col.to_pylist()
            want = [(r[k][i] if width > 1 else r[k]) if k in r else None for r in rows]
            want = [float(w) if isinstance(w, (int, float)) and not isinstance(w, bool) else None for w in want]
            assert got == want, (node, name, got[:3], want[:3])
            checked += 1
print(f"nodes {len(rec)}; windows {len(rec['gas'])}; columns {checked}")
"#;

#[test]
fn parquet_tables_read_back_in_pyarrow_equal_to_the_recording() {
    if !python("import pyarrow, mcap", &[]).0 {
        skip_or_fail(
            "pyarrow with mcap",
            "missing (python3 -m pip install pyarrow mcap)",
        );
        return;
    }
    let out = chamber();
    let hist = out.join("parquet-check");
    let o = cosim(&[
        "export",
        out.to_str().unwrap(),
        "--format",
        "parquet",
        "--output",
        hist.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (ok, text) = python(
        PARQUET_CHECK,
        &[
            hist.to_str().unwrap(),
            out.join("run.mcap").to_str().unwrap(),
        ],
    );
    println!("{text}");
    assert!(ok, "{text}");
    assert!(text.contains("nodes 3; windows 80;"), "{text}");
    let columns: usize = text
        .rsplit("columns ")
        .next()
        .and_then(|c| c.trim().parse().ok())
        .unwrap_or(0);
    assert!(columns > 40, "{text}");
}

/// `cosim.open_run`: the gas probe and the bar's displacement equal the official reader's
/// JSON values; every interface field of every recorded coupling message equals what
/// tools/wire_decode.py (written from PROTOCOL.md alone) decodes; `cosim export --fields`
/// writes the same arrays; `--series` keeps only what it names.
const PYTHON_READER_CHECK: &str = r#"
import json, sys
from collections import defaultdict
import numpy as np
import cosim
from mcap.reader import make_reader
out, tools = sys.argv[1], sys.argv[2]
sys.path.insert(0, tools)
import wire_decode
run = cosim.open_run(out)
assert run.complete and run.nodes == ["bar", "gas"], run
rec = {"gas": [], "bar": []}
sent = defaultdict(list)
with open(out + "/run.mcap", "rb") as f:
    for _, ch, m in make_reader(f).iter_messages():
        if ch.topic in ("/cosim/node/gas", "/cosim/node/bar"):
            rec[ch.topic.rsplit("/", 1)[1]].append(json.loads(m.data))
        elif ch.message_encoding != "json":
            msg = wire_decode.decode(m.data)["message"]
            if "Fields" in msg:
                f = msg["Fields"]
                for fld in f["fields"]:
                    key = (f["coupling"], ch.topic.rsplit("/", 1)[1], fld["name"])
                    sent[key].append((f["window"], f["time"], fld["values"]))
gas, bar = run.report("gas"), run.report("bar")
assert np.array_equal(gas["point2.pressure"], [r["point2"]["pressure"] for r in rec["gas"]])
com = bar["com_displacement"]   # one (windows, 3) array, as the momentum
assert com.shape == (len(rec["bar"]), 3), com.shape
for i, a in enumerate("xyz"):
    assert np.array_equal(com[:, i], [r["com_displacement"][i] for r in rec["bar"]])
assert "com_displacement_x" not in bar
df = bar.to_pandas()   # flat, as CSV and Parquet: one column per component
assert list(df["com_displacement_x"]) == list(com[:, 0])
assert list(df["momentum_y"]) == list(bar["momentum"][:, 1])
assert len(repr(gas)) < 2000, len(repr(gas))
assert bar["momentum"].shape == (len(rec["bar"]), 3)
assert len(run.balance()["energy_residual"]) == len(rec["gas"])
assert run.case is not None and "nodes" in json.dumps(run.case)
values = messages = 0
assert sent and len(run.couplings()) > 0
for (coupling, sender, name), msgs in sent.items():
    s = run.fields(coupling, sender)
    a = s[name]
    assert a.shape[0] == len(msgs), (coupling, sender, name, a.shape, len(msgs))
    assert np.array_equal(s.window[name], [w for w, _, _ in msgs])
    assert np.array_equal(s.time[name], [t for _, t, _ in msgs])
    assert np.array_equal(a.reshape(len(msgs), -1), np.array([v for _, _, v in msgs]).reshape(len(msgs), -1))
    messages += len(msgs)
    values += a.size
npz = np.load(out + "/fields.npz")
for (coupling, sender), s in ((k, run.fields(*k)) for k in run.couplings()):
    for name, a in s.items():
        assert np.array_equal(npz[f"{coupling}/{sender}/{name}"], a)
        assert np.array_equal(npz[f"{coupling}/{sender}/{name}.window"], s.window[name])
h = np.load(out + "/series.npz")
assert sorted(h.keys()) == ["gas/point1.pressure", "gas/point2.pressure", "gas/time", "gas/window"], sorted(h.keys())
assert np.array_equal(h["gas/point2.pressure"], gas["point2.pressure"])
print(f"windows {len(gas['point2.pressure'])}; field series {len(sent)}; messages {messages}; values {values}")
"#;

#[test]
fn the_python_package_reads_the_histories_and_the_interface_fields() {
    if !python_with_cosim() || !python_module_or_skip("pandas", "pandas") {
        return;
    }
    let out = chamber();
    let o = cosim(&[
        "export",
        out.to_str().unwrap(),
        "--fields",
        "--series",
        "gas/point*.pressure",
        "-o",
        out.join("series.npz").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let tools = workspace_root().join("tools");
    let (ok, text) = python(
        PYTHON_READER_CHECK,
        &[out.to_str().unwrap(), tools.to_str().unwrap()],
    );
    println!("{text}");
    assert!(ok, "{text}");
    let n = |key: &str| -> u64 {
        text.split(key)
            .nth(1)
            .and_then(|s| s.split(';').next())
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or(0)
    };
    assert_eq!(n("windows "), 80, "{text}");
    // set-up and 80 windows, both directions of the immersed coupling
    assert!(n("messages ") >= 160, "{text}");
    assert!(n("values ") > 10_000, "{text}");
}

/// Whether `import cosim, numpy, mcap` works; if not, the shared policy (fail under CI).
fn python_with_cosim() -> bool {
    let ok = Command::new("python3")
        .args(["-c", "import cosim, numpy, mcap; cosim.open_run"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        skip_or_fail(
            "the Python package `cosim` with numpy and mcap",
            "missing (python3 -m pip install ./python mcap)",
        );
    }
    ok
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

/// `cosim run` draws each node alone too (`fields_<node>.png`): the bar's particles face on,
/// coloured by damage on the colour map, spread across the plot's width; the gas alone as its
/// pressure map. `cosim render --per-node --gif` animates each node's series: one GIF per
/// node, one frame per written time, each frame the picture's size.
#[test]
fn each_node_is_drawn_alone_and_its_series_animated() {
    use image::AnimationDecoder;
    let out = chamber();
    let listed: Vec<String> = summary(out)["node_fields"]
        .as_array()
        .expect("summary.json lists node_fields")
        .iter()
        .filter_map(|p| p.as_str().map(String::from))
        .collect();
    assert_eq!(listed.len(), 2, "{listed:?}");
    let (w, h, px) = png_pixels(&out.join("fields_bar.png"));
    assert_eq!((w, h), (1200, 800));
    let (mut dots, mut x_lo, mut x_hi) = (0, u32::MAX, 0);
    let mut grey = 0;
    for (k, p) in px.iter().enumerate() {
        let (x, y) = (k as u32 % w, k as u32 / w);
        if !(40..1040).contains(&x) || !(60..760).contains(&y) || *p == [255, 255, 255] {
            continue;
        }
        dots += 1;
        grey += usize::from(p[0] == p[1] && p[1] == p[2]);
        x_lo = x_lo.min(x);
        x_hi = x_hi.max(x);
    }
    println!("bar alone: {dots} particle pixels across x {x_lo}..{x_hi}, {grey} grey");
    assert!(dots >= 31 * 16 * 5, "{dots}");
    assert_eq!(grey, 0, "particles take the colour map, not grey");
    assert!(x_lo < 100 && x_hi > 980, "{x_lo}..{x_hi}");
    let (_, _, gas) = png_pixels(&out.join("fields_gas.png"));
    let colours: std::collections::HashSet<_> = gas.iter().collect();
    assert!(colours.len() >= 20, "{}", colours.len());

    let o = cosim(&["render", out.to_str().unwrap(), "--per-node", "--gif"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (node, series) in [("gas", "fluid.pvd"), ("bar", "pd.pvd")] {
        let pvd = std::fs::read_to_string(out.join(node).join(series)).unwrap();
        let written = pvd.matches("<DataSet").count();
        let file = std::fs::File::open(out.join(format!("{node}.gif"))).unwrap();
        let frames = image::codecs::gif::GifDecoder::new(std::io::BufReader::new(file))
            .unwrap()
            .into_frames()
            .collect_frames()
            .unwrap();
        println!(
            "{node}.gif: {} frames for {written} written times",
            frames.len()
        );
        assert!(written >= 3, "{written}");
        assert_eq!(frames.len(), written);
        assert!(
            frames
                .iter()
                .all(|f| f.buffer().dimensions() == (1200, 800))
        );
    }
}

/// `run.pictures = "frames"` draws every written frame of each node alone after the run
/// (`frames/<node>_<k>.png`, one per `.pvd` entry), "none" draws no picture, and any other
/// value is refused before anything starts, naming the key.
#[test]
fn run_pictures_draws_every_frame_or_none() {
    let (dir, id) = scratch("pictures");
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let out = dir.join("frames");
    let o = run_case(
        &case,
        &out,
        &id,
        &["--variant", "small", "--set", "run.pictures=\"frames\""],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut all_written = 0;
    for (node, series) in [("gas", "fluid.pvd"), ("bar", "pd.pvd")] {
        let pvd = std::fs::read_to_string(out.join(node).join(series)).unwrap();
        let written = pvd.matches("<DataSet").count();
        all_written += written;
        let drawn = std::fs::read_dir(out.join("frames"))
            .unwrap()
            .flatten()
            .filter(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with(&format!("{node}_"))
            })
            .count();
        println!("{node}: {drawn} pictures for {written} written frames");
        assert!(written >= 3, "{written}");
        assert_eq!(drawn, written);
    }
    assert_eq!(summary(&out)["frame_pictures"], all_written);

    let none = dir.join("none");
    let o = run_case(
        &case,
        &none,
        &format!("{id}n"),
        &["--variant", "small", "--set", "run.pictures=\"none\""],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!none.join("fields.png").exists() && !none.join("fields_bar.png").exists());

    let o = cosim(&[
        "validate",
        case.to_str().unwrap(),
        "--set",
        "run.pictures=\"all\"",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("run.pictures"), "{err}");
}

/// `cosim validate --json`: one JSON document either way, the same exit codes (0, or 2 with
/// the full key path of the bad value).
/// `--field NODE.FIELD` colours that node by the field: the bar's particles, light grey by
/// default, take the colour map of their speed (no grey pixel left in the bar's box, many
/// colours); a field the node does not write is refused naming those it does; `--all` draws
/// one picture per written time; `cosim plot --field --at` draws the same picture, and of
/// several runs also one of them side by side.
#[test]
fn a_chosen_field_colours_its_node_and_every_frame_can_be_drawn() {
    let out = chamber();
    let dir = out.join("chosen");
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("velocity.png");
    let o = cosim(&[
        "render",
        out.to_str().unwrap(),
        "--field",
        "bar.velocity",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (w, _, px) = png_pixels(&png);
    let to_px = |x: f64, y: f64| (190.0 + 1750.0 * x, 760.0 - 1750.0 * y);
    let (bx0, by1) = to_px(0.1, 0.15);
    let (bx1, by0) = to_px(0.3, 0.25);
    let (mut grey, mut seen) = (0, 0);
    let mut colours = std::collections::HashSet::new();
    for (k, p) in px.iter().enumerate() {
        let (x, y) = ((k as u32 % w) as f64, (k as u32 / w) as f64);
        if x >= bx0 + 3.0 && x <= bx1 - 3.0 && y >= by0 + 3.0 && y <= by1 - 3.0 {
            seen += 1;
            grey += usize::from(*p == [235, 235, 235]);
            colours.insert(*p);
        }
    }
    println!(
        "bar box: {seen} pixels, {grey} grey, {} colours",
        colours.len()
    );
    assert!(seen > 50_000, "{seen}");
    assert_eq!(grey, 0);
    assert!(colours.len() >= 10, "{}", colours.len());

    let o = cosim(&["render", out.to_str().unwrap(), "--field", "bar.nosuch"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("nosuch") && err.contains("velocity"), "{err}");

    let o = cosim(&["render", out.to_str().unwrap(), "--all"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let frames = std::fs::read_dir(out.join("frames")).unwrap().count();
    let pvd = std::fs::read_to_string(out.join("gas").join("fluid.pvd")).unwrap();
    let written = pvd.matches("<DataSet").count();
    println!("{frames} pictures for {written} written times");
    assert!(written >= 3, "{written}");
    assert_eq!(frames, written);

    let o = cosim(&[
        "plot",
        out.to_str().unwrap(),
        "--field",
        "gas.density",
        "--at",
        "2e-4",
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let listed = String::from_utf8_lossy(&o.stdout);
    assert!(listed.contains("gas_density_2e-4.png"), "{listed}");

    // Several runs also side by side, on one colour range (here the same run twice): a
    // picture twice as wide whose two panels show the bar as the single picture does, pixel
    // for pixel.
    let o = cosim(&[
        "plot",
        out.to_str().unwrap(),
        out.to_str().unwrap(),
        "--field",
        "bar.velocity",
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let listed = String::from_utf8_lossy(&o.stdout);
    assert!(listed.contains("runs_bar_velocity.png"), "{listed}");
    let (w2, h2, px2) = png_pixels(&dir.join("runs_bar_velocity.png"));
    let h = px.len() as u32 / w;
    assert_eq!((w2, h2), (2 * w, h));
    let mut same = 0;
    for y in (by0 + 3.0) as u32..=(by1 - 3.0) as u32 {
        for x in (bx0 + 3.0) as u32..=(bx1 - 3.0) as u32 {
            let single = px[(y * w + x) as usize];
            assert_eq!(
                px2[(y * w2 + x) as usize],
                single,
                "left panel at ({x}, {y})"
            );
            assert_eq!(
                px2[(y * w2 + w + x) as usize],
                single,
                "right panel at ({x}, {y})"
            );
            same += 1;
        }
    }
    assert!(same > 50_000, "{same}");

    // Two different runs (the small chamber at 0.4 and at 0.2 ms): their single pictures
    // colour the bar's velocity over different ranges, so the bar's colour bars differ; side
    // by side, both panels draw it on the union of the two, so their colour bars (ticks and
    // labels) are the same pixel for pixel.
    let (half_dir, half_id) = scratch("toolchain-half");
    let half = half_dir.join("out");
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let o = run_case(
        &case,
        &half,
        &half_id,
        &["--variant", "small", "--set", "run.end_time=2e-4"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let single = |run: &std::path::Path, name: &str| {
        let png = dir.join(name);
        let o = cosim(&[
            "render",
            run.to_str().unwrap(),
            "--field",
            "bar.velocity",
            "-o",
            png.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        png_pixels(&png)
    };
    // the bar's colour bar: the second of two (the gas's grey one is first), its ticks and
    // labels right of it (fields.rs `colour_bar`: x from 1075, y from 100 + 310 + 20, 260 high)
    let bar_scale = |px: &[[u8; 3]], width: u32, x_off: u32| -> Vec<[u8; 3]> {
        (430..690u32)
            .flat_map(|y| (1075..1195u32).map(move |x| (x, y)))
            .map(|(x, y)| px[(y * width + x_off + x) as usize])
            .collect()
    };
    let (wa, _, pa) = single(out, "end.png");
    let (wb, _, pb) = single(&half, "half.png");
    assert_ne!(
        bar_scale(&pa, wa, 0),
        bar_scale(&pb, wb, 0),
        "the two runs' own ranges must differ for this check to mean anything"
    );
    let o = cosim(&[
        "plot",
        out.to_str().unwrap(),
        half.to_str().unwrap(),
        "--field",
        "bar.velocity",
        "-o",
        half_dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (w2, _, px2) = png_pixels(&half_dir.join("runs_bar_velocity.png"));
    assert_eq!(w2, 2 * wa);
    let (left, right) = (bar_scale(&px2, w2, 0), bar_scale(&px2, w2, wa));
    assert_eq!(left.len(), 260 * 120);
    assert!(
        left == right,
        "the panels' colour bars differ: no shared range"
    );
    nothing_left(&half_id);
}

#[test]
fn validate_json_names_the_key_or_lists_the_case() {
    // validating the case checks every variant's executable: the `c` variant's C node
    assert!(build_c_bar(&workspace_root().join("examples/external/bar-c")).is_some());
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
