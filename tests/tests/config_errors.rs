//! Bad case files are refused before any process starts: exit code 2 and one line naming the
//! key path and the reason (docs/architecture.md).

use cosim_tests::*;

const GOOD: &str = r#"
[run]
name = "c"
end_time = 1e-4
window = 1e-6
output = "OUT"

[nodes.left]
solver = "solid-node"
model = "bar-1d"
[nodes.left.params]
length = 0.5
elements = 10
young = 200e9
density = 7860.0
area = 1e-4
interfaces = { tip = "right" }

[nodes.right]
solver = "solid-node"
model = "bar-1d"
[nodes.right.params]
length = 0.5
x0 = 0.5
elements = 10
young = 200e9
density = 7860.0
area = 1e-4
fixed = "none"
interfaces = { root = "left" }

[[couplings]]
kind = "kinematic"
driver = "left.tip"
responder = "right.root"
"#;

/// Run `cosim run` on a variant of the good case; check exit 2, one line, the key named,
/// and that nothing was started or written.
fn refused(tag: &str, edit: impl Fn(&str) -> String, key: &str) {
    refused_naming(tag, edit, &[key]);
}

/// As [`refused`], the line naming every one of `parts` (the key first).
fn refused_naming(tag: &str, edit: impl Fn(&str) -> String, parts: &[&str]) {
    let key = parts[0];
    let (dir, id) = scratch(tag);
    let out = dir.join("out");
    let text = edit(GOOD).replace("OUT", out.to_str().unwrap());
    let case = dir.join("case.toml");
    std::fs::write(&case, text).unwrap();
    let o = cosim(&["run", case.to_str().unwrap(), "--run-id", &id, "--quiet"]);
    let err = String::from_utf8_lossy(&o.stderr);
    println!("{tag}: {err}");
    assert_eq!(o.status.code(), Some(2), "{tag}: {err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "{tag}: one line expected: {err}");
    assert!(
        lines[0].contains(key),
        "{tag}: '{}' does not name {key}",
        lines[0]
    );
    for p in &parts[1..] {
        assert!(
            lines[0].contains(p),
            "{tag}: '{}' does not name {p}",
            lines[0]
        );
    }
    assert!(!out.exists(), "{tag}: output was written before refusing");
    assert!(processes_with(&format!("--run {id}")).is_empty());
    // `validate` says the same.
    let v = cosim(&["validate", case.to_str().unwrap()]);
    assert_eq!(v.status.code(), Some(2));
}

#[test]
fn the_good_case_validates() {
    let (dir, _) = scratch("good");
    let case = dir.join("case.toml");
    std::fs::write(
        &case,
        GOOD.replace("OUT", dir.join("out").to_str().unwrap()),
    )
    .unwrap();
    let v = cosim(&["validate", case.to_str().unwrap()]);
    assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stderr));
}

#[test]
fn unknown_key() {
    refused(
        "unknown",
        |s| s.replace("window = 1e-6", "window = 1e-6\nwindw = 2"),
        "run.windw",
    );
    refused(
        "unknown-param",
        |s| s.replace("elements = 10\n", "elements = 10\nelemnts = 3\n"),
        "nodes.left.params",
    );
}

#[test]
fn missing_node_binary() {
    refused(
        "nobin",
        |s| s.replacen("solver = \"solid-node\"", "solver = \"no-such-node\"", 1),
        "nodes.left.solver",
    );
}

#[test]
fn window_not_positive_or_beyond_the_end() {
    refused(
        "w0",
        |s| s.replace("window = 1e-6", "window = 0.0"),
        "run.window",
    );
    refused(
        "wneg",
        |s| s.replace("window = 1e-6", "window = -1e-6"),
        "run.window",
    );
    refused(
        "wbig",
        |s| s.replace("window = 1e-6", "window = 1.0"),
        "run.window",
    );
}

#[test]
fn print_naming_no_node_or_no_scalar() {
    refused(
        "print-node",
        |s| s.replace("window = 1e-6", "window = 1e-6\nprint = [\"middle.tip\"]"),
        "run.print[0]",
    );
    refused(
        "print-form",
        |s| s.replace("window = 1e-6", "window = 1e-6\nprint = [\"left.\"]"),
        "run.print[0]",
    );
}

#[test]
fn coupling_naming_an_unknown_node_or_interface() {
    refused(
        "nonode",
        |s| s.replace("driver = \"left.tip\"", "driver = \"lft.tip\""),
        "couplings[0].driver",
    );
    refused(
        "noiface",
        |s| s.replace("responder = \"right.root\"", "responder = \"right.stem\""),
        "couplings[0].responder",
    );
}

#[test]
fn duplicate_node_names() {
    refused(
        "dup",
        |s| format!("{s}\n[nodes.left]\nsolver = \"solid-node\"\nmodel = \"bar-1d\"\n"),
        "nodes.left",
    );
}

#[test]
fn bad_solver_parameter_is_named() {
    refused(
        "param",
        |s| s.replacen("elements = 10", "elements = 0", 1),
        "nodes.left.params.elements",
    );
}

#[test]
fn parallel_schedule_is_refused_for_a_kinematic_coupling() {
    // docs/architecture.md: lagging the constraint force by a window is unstable.
    refused(
        "parallel",
        |s| s.replace("window = 1e-6", "window = 1e-6\nschedule = \"parallel\""),
        "run.schedule",
    );
}

/// `[variants]`: a malformed entry is named by its key when the case is read; an unknown
/// variant on the command line is refused with the ones the case has; a good variant runs
/// with its settings and writes to `<output>/<variant>`.
#[test]
fn variants_are_checked_and_applied() {
    refused(
        "variant-set",
        |g| format!("{g}\n[variants.fine]\nset = [\"left.elements\"]\n"),
        "variants.fine.set[0]",
    );
    refused(
        "variant-key",
        |g| format!("{g}\n[variants.fine]\nsets = []\n"),
        "variants.fine.sets",
    );
    let (dir, id) = scratch("variant-ok");
    let out = dir.join("out");
    let text = format!(
        "{GOOD}\n[variants.fine]\ndescription = \"more elements\"\nset = [\"left.elements=20\", \"run.end_time=2e-5\"]\n"
    )
    .replace("OUT", out.to_str().unwrap());
    let case = dir.join("case.toml");
    std::fs::write(&case, text).unwrap();
    let c = case.to_str().unwrap();
    let o = cosim(&["run", c, "--variant", "coarse", "--run-id", &id, "--quiet"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--variant coarse") && err.contains("fine"),
        "{err}"
    );
    let o = cosim(&["run", c, "--variant", "fine", "--run-id", &id, "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = summary(&out.join("fine"));
    assert_eq!(
        s["windows"].as_u64(),
        Some(20),
        "end_time 2e-5 / window 1e-6"
    );
}

/// A variant can restructure the case: `remove` drops nodes and couplings, its own `nodes`
/// and `couplings` tables add new ones (as the grouped crash tube swaps ten joint nodes for
/// one). Bad entries are refused with their key.
#[test]
fn variants_can_remove_and_add_nodes_and_couplings() {
    let regroup = r#"
[variants.split]
description = "the right bar replaced by a longer one with another name"
remove = ["nodes.right", "couplings.left-right"]
set = ["run.end_time=1e-5"]
[variants.split.nodes.far]
solver = "solid-node"
model = "bar-1d"
[variants.split.nodes.far.params]
length = 1.0
x0 = 0.5
elements = 20
young = 200e9
density = 7860.0
area = 1e-4
fixed = "none"
interfaces = { root = "left" }
[[variants.split.couplings]]
kind = "kinematic"
driver = "left.tip"
responder = "far.root"

[variants.unknown-node]
remove = ["nodes.middle"]

[variants.clash]
[variants.clash.nodes.left]
solver = "solid-node"
model = "bar-1d"

[variants.dangling]
remove = ["nodes.right"]
"#;
    let (dir, id) = scratch("variant-structure");
    let out = dir.join("out");
    let case = dir.join("case.toml");
    std::fs::write(
        &case,
        format!("{GOOD}{regroup}").replace("OUT", out.to_str().unwrap()),
    )
    .unwrap();
    let c = case.to_str().unwrap();
    for (variant, key) in [
        ("unknown-node", "variants.unknown-node.remove[0]"),
        ("clash", "variants.clash.nodes.left"),
        // the coupling still names the removed node
        ("dangling", "right"),
    ] {
        let o = cosim(&["run", c, "--variant", variant, "--run-id", &id, "--quiet"]);
        let err = String::from_utf8_lossy(&o.stderr);
        println!("{variant}: {err}");
        assert_eq!(o.status.code(), Some(2), "{variant}: {err}");
        assert!(err.contains(key), "{variant}: '{err}' does not name {key}");
        assert!(!out.join(variant).exists(), "{variant}: output written");
    }
    let o = cosim(&["run", c, "--variant", "split", "--run-id", &id, "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = summary(&out.join("split"));
    let nodes: Vec<&String> = s["nodes"].as_object().expect("nodes").keys().collect();
    assert_eq!(nodes, ["far", "left"], "{nodes:?}");
    assert_eq!(s["couplings"][0]["responder"].as_str(), Some("far.root"));
    assert_eq!(s["windows"].as_u64(), Some(10));
    // `cosim validate` checks every variant of the case, so the broken ones show there too.
    let o = cosim(&["validate", c]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("(variant "), "{err}");
}

#[test]
fn join_timeout_not_positive() {
    refused(
        "join0",
        |s| s.replace("window = 1e-6", "window = 1e-6\njoin_timeout = 0"),
        "run.join_timeout",
    );
    refused(
        "joinstr",
        |s| s.replace("window = 1e-6", "window = 1e-6\njoin_timeout = \"long\""),
        "run.join_timeout",
    );
}

#[test]
fn start_timeout_not_positive() {
    refused(
        "start0",
        |s| s.replace("window = 1e-6", "window = 1e-6\nstart_timeout = -1.0"),
        "run.start_timeout",
    );
    refused(
        "startstr",
        |s| s.replace("window = 1e-6", "window = 1e-6\nstart_timeout = \"soon\""),
        "run.start_timeout",
    );
}

/// A single `fem-2d` node (seed 003 §5.1 bar): its bad keys are named with their full path.
const FEM: &str = r#"
[run]
name = "f"
end_time = 1e-4
window = 1e-5
output = "OUT"

[nodes.beam]
solver = "solid-node"
model = "fem-2d"
[nodes.beam.params]
length = 10.0
height = 1.0
nx = 10
ny = 2
young = 72e9
poisson = 0.3
density = 2700.0
plane = "stress"
fixed = ["left"]
loads = [{ edge = "right", traction = [-1e4, 0.0], ramp = "step" }]
points = { A = [5.0, 0.5] }
"#;

#[test]
fn bad_fem_2d_parameters_are_named() {
    let (dir, _) = scratch("fem-good");
    let case = dir.join("case.toml");
    std::fs::write(&case, FEM.replace("OUT", dir.join("out").to_str().unwrap())).unwrap();
    let v = cosim(&["validate", case.to_str().unwrap()]);
    assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stderr));
    for (tag, from, to, key) in [
        (
            "fem-plane",
            "plane = \"stress\"",
            "plane = \"shell\"",
            "nodes.beam.params.plane",
        ),
        ("fem-nx", "nx = 10", "nx = 0", "nodes.beam.params.nx"),
        (
            "fem-nu",
            "poisson = 0.3",
            "poisson = 1.2",
            "nodes.beam.params.poisson",
        ),
        (
            "fem-fixed",
            "[\"left\"]",
            "[\"left.z\"]",
            "nodes.beam.params.fixed[0]",
        ),
        (
            "fem-edge",
            "edge = \"right\"",
            "edge = \"east\"",
            "nodes.beam.params.loads[0].edge",
        ),
        (
            "fem-ramp",
            "ramp = \"step\"",
            "ramp = \"septic\"",
            "nodes.beam.params.loads[0].ramp_time",
        ),
        (
            "fem-point",
            "A = [5.0, 0.5]",
            "A = [50.0, 0.5]",
            "nodes.beam.params.points.A",
        ),
        (
            "fem-unknown",
            "ny = 2",
            "ny = 2\nnz = 2",
            "nodes.beam.params.nz",
        ),
        (
            "fem-integrator",
            "ny = 2",
            "ny = 2\nintegrator = { scheme = \"gs4\", design = \"wbz\", implicit = true }",
            "nodes.beam.params.integrator.rho_inf",
        ),
        (
            "fem-dt",
            "ny = 2",
            "ny = 2\ndt = 1.0",
            "nodes.beam.params.dt",
        ),
    ] {
        refused(tag, |_| FEM.replacen(from, to, 1), key);
    }
    refused(
        "fem-ramp-name",
        |_| FEM.replacen("ramp = \"step\"", "ramp = \"cosine\", ramp_time = 0.5", 1),
        "nodes.beam.params.loads[0].ramp",
    );
}

/// A load's start is `ramp` with `ramp_time`, as `bar-1d`'s end force; the older spelling,
/// `history = "ramp"`, still reads as the septic ramp, and a step takes no ramp time.
#[test]
fn a_load_ramp_reads_in_both_spellings() {
    for (tag, load) in [
        ("ramp-septic", "ramp = \"septic\", ramp_time = 0.5"),
        ("ramp-sin2", "ramp = \"sin2\", ramp_time = 0.5"),
        ("ramp-older", "history = \"ramp\", ramp_time = 0.5"),
        ("ramp-older-step", "history = \"step\""),
    ] {
        let (dir, _) = scratch(tag);
        let case = dir.join("case.toml");
        let text = FEM
            .replace("OUT", dir.join("out").to_str().unwrap())
            .replacen("ramp = \"step\"", load, 1);
        std::fs::write(&case, text).unwrap();
        let v = cosim(&["validate", case.to_str().unwrap()]);
        assert!(
            v.status.success(),
            "{tag}: {}",
            String::from_utf8_lossy(&v.stderr)
        );
    }
    refused(
        "ramp-step-timed",
        |_| FEM.replacen("ramp = \"step\"", "ramp = \"step\", ramp_time = 0.5", 1),
        "nodes.beam.params.loads[0].ramp_time",
    );
}

/// The good case's coupling as a lagrange coupling, the lines of `[[couplings]]`
/// replaced by `coupling`.
fn lagrange(text: &str, coupling: &str) -> String {
    let head = text
        .split("[[couplings]]")
        .next()
        .unwrap_or_default()
        .to_string();
    format!("{head}[[couplings]]\n{coupling}\n")
}

#[test]
fn lagrange_coupling_keys_are_checked() {
    refused(
        "lag-driver",
        |t| {
            lagrange(
                t,
                "kind = \"lagrange\"\ndriver = \"left.tip\"\nsides = [\"left.tip\", \"right.root\"]",
            )
        },
        "couplings[0].driver",
    );
    refused(
        "lag-one-side",
        |t| lagrange(t, "kind = \"lagrange\"\nsides = [\"left.tip\"]"),
        "couplings[0].sides",
    );
    refused(
        "lag-no-sides",
        |t| lagrange(t, "kind = \"lagrange\""),
        "couplings[0].sides",
    );
    refused_naming(
        "lag-unknown-node",
        |t| {
            lagrange(
                t,
                "kind = \"lagrange\"\nsides = [\"left.tip\", \"middle.root\"]",
            )
        },
        &["couplings[0].sides[1]", "middle"],
    );
    refused_naming(
        "lag-same-node",
        |t| {
            lagrange(
                t,
                "kind = \"lagrange\"\nsides = [\"left.tip\", \"left.tip\"]",
            )
        },
        &["couplings[0].sides[1]", "left"],
    );
    refused_naming(
        "lag-method",
        |t| {
            lagrange(
                t,
                "kind = \"lagrange\"\nmethod = \"newmark\"\nsides = [\"left.tip\", \"right.root\"]",
            )
        },
        &["couplings[0].method", "newmark"],
    );
    refused_naming(
        "lag-interface",
        |t| {
            lagrange(
                t,
                "kind = \"lagrange\"\nsides = [\"left.tip\", \"right.side\"]",
            )
        },
        &["couplings[0].sides[1]", "side"],
    );
    refused(
        "lag-sides-kinematic",
        |t| {
            t.replace(
                "kind = \"kinematic\"",
                "kind = \"kinematic\"\nsides = [\"left.tip\", \"right.root\"]",
            )
        },
        "couplings[0].sides",
    );
    // Every subdomain steps whole system steps: 100.5 windows are refused.
    refused(
        "lag-end-time",
        |t| {
            lagrange(
                t,
                "kind = \"lagrange\"\nsides = [\"left.tip\", \"right.root\"]",
            )
            .replace("end_time = 1e-4", "end_time = 1.005e-4")
        },
        "run.end_time",
    );
}

/// a coupling whose node does not provide or accept a field its scheme
/// needs is refused before anything starts, naming the coupling, the node and the field.
#[test]
fn a_field_the_scheme_needs_and_the_node_lacks_is_refused() {
    refused_naming(
        "fields-kinematic",
        |t| {
            t.replace(
                "kind = \"kinematic\"",
                "kind = \"kinematic\"\ndriver_fields = [\"position\", \"temperature\"]",
            )
        },
        &[
            "couplings[0].driver_fields",
            "kinematic coupling 'left-right'",
            "node 'left'",
            "interface 'tip'",
            "provide field 'temperature'",
        ],
    );
    refused_naming(
        "fields-kinematic-accept",
        |t| {
            t.replace(
                "kind = \"kinematic\"",
                "kind = \"kinematic\"\nresponder_fields = [\"force\", \"heat\"]",
            )
        },
        &[
            "couplings[0].responder_fields",
            "kinematic coupling 'left-right'",
            "node 'left'",
            "interface 'tip'",
            "accept field 'heat'",
        ],
    );
    // Immersed: the driver (a solid) must provide its particles' volumes; a bar has none.
    refused_naming(
        "fields-immersed",
        |t| t.replace("kind = \"kinematic\"", "kind = \"immersed\""),
        &[
            "couplings[0].driver_fields",
            "immersed coupling 'left-right'",
            "node 'left'",
            "interface 'tip'",
            "provide field 'volume'",
        ],
    );
    // Lagrange: a side must provide its interface velocities and condensed operator; the echo
    // node has neither, and the first missing is named.
    refused_naming(
        "fields-lagrange",
        |t| {
            let t = t.replace(
                "[nodes.right]",
                "[nodes.e]\nsolver = \"cosim-echo-node\"\nmodel = \"echo\"\n[nodes.e.params]\npoints = 1\n\n[nodes.right]",
            );
            lagrange(
                &t,
                "name = \"cut\"\nkind = \"lagrange\"\nsides = [\"left.tip\", \"e.port\"]",
            )
        },
        &[
            "couplings[0].sides[1]",
            "'cut'",
            "node 'e'",
            "provide field 'velocity'",
        ],
    );
}

/// A lagrange side on the device path (it could neither set up nor checkpoint) is
/// refused by `cosim validate` before anything starts, naming the node's `device` key — the
/// notched specimen with its ligament on the GPU (plane strain, which the device kernels take).
#[test]
fn a_lagrange_side_on_the_gpu_is_refused_at_validation() {
    let case = workspace_root().join("examples/seed003_notch.toml");
    let o = cosim(&[
        "validate",
        case.to_str().unwrap(),
        "--variant",
        "small",
        "--set",
        "notch.dimension=\"plane_strain\"",
        "--set",
        "notch.device=\"gpu\"",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    println!("{err}");
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("nodes.notch.params.device"), "{err}");
    assert!(err.contains("couplings[0]") && err.contains("cpu"), "{err}");
}

/// MemAvailable of /proc/meminfo in bytes, read here independently of the node.
fn mem_available() -> f64 {
    let text = std::fs::read_to_string("/proc/meminfo").expect("/proc/meminfo");
    let kb: f64 = text
        .lines()
        .find_map(|l| l.strip_prefix("MemAvailable:"))
        .and_then(|v| v.trim().strip_suffix("kB"))
        .and_then(|v| v.trim().parse().ok())
        .expect("MemAvailable in kB");
    kb * 1024.0
}

/// `cosim ARGS`, refused with exit 2 and one line: the line, and how long it took.
fn refused_in_one_line(args: &[&str]) -> (String, std::time::Duration) {
    let start = std::time::Instant::now();
    let o = cosim(args);
    let took = start.elapsed();
    let err = String::from_utf8_lossy(&o.stderr);
    println!("{} ({took:?}): {err}", args[0]);
    assert_eq!(o.status.code(), Some(2), "{}: {err}", args[0]);
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{}: one line expected: {err}", args[0]);
    (lines[0].to_string(), took)
}

/// The numbers `N` of each `N bytes` in `line`, in order.
fn byte_counts(line: &str) -> Vec<f64> {
    let words: Vec<&str> = line.split_whitespace().collect();
    words
        .windows(2)
        .filter(|w| w[1] == "bytes")
        .filter_map(|w| w[0].parse().ok())
        .collect()
}

/// A fluid of 30,000 × 30,000 cells (the chamber's gas; more on a host with over 72 GB
/// available) is refused by `cosim validate` and `cosim run` before the node allocates its
/// state: exit 2 at once, one line naming the key `nodes.gas.params.grid.cells`, the bytes the
/// state needs (at least its conserved values alone, 30,000² cells × 5 values × 8 bytes =
/// 36 GB) and the memory available.
#[test]
fn a_grid_larger_than_the_memory_is_refused_by_its_key() {
    let case = workspace_root().join("examples/chamber_detonation.toml");
    let (dir, id) = scratch("huge-grid");
    let out = dir.join("out");
    // 30,000² as found; larger on a host with more than twice its 36 GB available.
    let side = (2.0 * mem_available() / 40.0).sqrt().ceil().max(30_000.0);
    let set = format!("gas.grid.cells=[{side}, {side}, 1]");
    let conserved = side * side * 5.0 * 8.0;
    for cmd in ["validate", "run"] {
        let mut args = vec![cmd, case.to_str().unwrap(), "--set", &set];
        if cmd == "run" {
            args.extend([
                "--output",
                out.to_str().unwrap(),
                "--run-id",
                &id,
                "--quiet",
            ]);
        }
        let (line, took) = refused_in_one_line(&args);
        let line = line.as_str();
        assert!(line.contains("nodes.gas.params.grid.cells"), "{line}");
        assert!(line.contains("MemAvailable"), "{line}");
        let counts = byte_counts(line);
        assert_eq!(counts.len(), 2, "needed and available bytes: {line}");
        assert!(
            counts[0] >= conserved,
            "needs {} < {conserved}: {line}",
            counts[0]
        );
        // Available memory moves while the test runs (the other tests): within 25 %.
        let avail = mem_available();
        assert!(
            (counts[1] - avail).abs() < 0.25 * avail,
            "available {} vs {avail} read here: {line}",
            counts[1]
        );
        // Refused before allocating: no 36 GB to fault in, no abort, seconds not minutes.
        assert!(
            took < std::time::Duration::from_secs(20),
            "{cmd} took {took:?}"
        );
        assert!(!out.exists(), "{cmd}: output written before refusing");
    }
    assert!(processes_with(&format!("--run {id}")).is_empty());
}

/// Coupled points that do not coincide are refused by `cosim validate` and `cosim run`: the
/// right bar shifted 0.2 m away from the left bar's tip (x0 = 0.7 where the tip is at 0.5)
/// names the coupling, both nodes and interfaces, the point and the distance; a shift within
/// the tolerance (1e-4 m, under 1e-3 of the 1 m scale of a single point) validates, and a
/// `point_tolerance` raised above the shift lets the shifted case through.
#[test]
fn coupled_points_apart_are_refused() {
    refused_naming(
        "shifted",
        |s| s.replace("x0 = 0.5", "x0 = 0.7"),
        &[
            "couplings[0]",
            "right.root",
            "left.tip",
            "point 0",
            "2.0000e-1 m",
            "point_tolerance",
        ],
    );
    let validates = |tag: &str, edit: &dyn Fn(&str) -> String| {
        let (dir, _) = scratch(tag);
        let case = dir.join("case.toml");
        let text = edit(GOOD).replace("OUT", dir.join("out").to_str().unwrap());
        std::fs::write(&case, text).unwrap();
        let v = cosim(&["validate", case.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&v.stderr).to_string();
        (v.status.code(), err)
    };
    let (code, err) = validates("near", &|s| s.replace("x0 = 0.5", "x0 = 0.5001"));
    assert_eq!(code, Some(0), "a 1e-4 m gap is within the default: {err}");
    let (code, err) = validates("loose", &|s| {
        s.replace("x0 = 0.5", "x0 = 0.7").replace(
            "responder = \"right.root\"",
            "responder = \"right.root\"\npoint_tolerance = 0.25",
        )
    });
    assert_eq!(code, Some(0), "point_tolerance 0.25 admits 0.2 m: {err}");
    let (code, err) = validates("bad-tolerance", &|s| {
        s.replace(
            "responder = \"right.root\"",
            "responder = \"right.root\"\npoint_tolerance = -1.0",
        )
    });
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("couplings[0].point_tolerance"), "{err}");
}

/// A peridynamic body whose bonds would not fit in memory is refused before they are built,
/// even with `max_bonds` raised past them: the chamber's bar at a spacing that gives more than
/// twice the available memory in bonds at the fewest bytes a bond takes (57), refused naming
/// `nodes.bar.params.spacing` and both byte counts.
#[test]
fn a_body_whose_bonds_exceed_the_memory_is_refused_by_its_key() {
    let case = workspace_root().join("examples/chamber_detonation.toml");
    // The bar is 0.2 × 0.1 m in plane strain: 0.02 / s² particles with about π·3.015² ≈ 28.6
    // neighbours each at a horizon of 3.015 spacings.
    let avail = mem_available();
    let spacing = (0.02 * 28.6 * 57.0 / (2.0 * avail)).sqrt().max(1.1e-5);
    let bonds = 0.02 / (spacing * spacing) * 28.6;
    assert!(
        bonds * 57.0 > avail,
        "this host has {avail} bytes available, more than the finest lattice's bonds need"
    );
    let sets = [
        format!("bar.spacing={spacing:e}"),
        format!("bar.horizon={:e}", 3.015 * spacing),
        "bar.max_bonds=1000000000000".to_string(),
    ];
    let mut args = vec!["validate", case.to_str().unwrap()];
    for s in &sets {
        args.extend(["--set", s.as_str()]);
    }
    let (err, took) = refused_in_one_line(&args);
    assert!(err.contains("nodes.bar.params.spacing"), "{err}");
    // First what it needs, last what is available (between them: the bytes a bond takes).
    let counts = byte_counts(&err);
    assert!(counts.len() >= 2, "needed and available bytes: {err}");
    let counts = [counts[0], counts[counts.len() - 1]];
    // The node counts the lattice's own family (28 neighbours inside 3.015 spacings, against
    // the disc's 28.6 here): at least 0.8 of this estimate, and over what is available.
    assert!(
        counts[0] > counts[1] && counts[0] > 0.8 * bonds * 57.0,
        "needs {} for about {bonds:e} bonds: {err}",
        counts[0]
    );
    assert!(took < std::time::Duration::from_secs(60), "took {took:?}");
}

#[test]
fn a_misspelt_key_node_or_variant_is_answered_with_the_nearest_name() {
    // A key of the case, and one of a model's parameters.
    refused_naming(
        "typo-key",
        |s| s.replace("window = 1e-6", "windw = 1e-6"),
        &["run.windw", "did you mean 'window'?"],
    );
    refused_naming(
        "typo-param",
        |s| s.replacen("young = 200e9", "yuong = 200e9", 1),
        &["nodes.left.params.yuong", "did you mean 'young'?"],
    );
    // A coupling naming a node that is not there lists the nodes.
    refused_naming(
        "typo-node",
        |s| s.replace("driver = \"left.tip\"", "driver = \"lefft.tip\""),
        &[
            "unknown node 'lefft'",
            "did you mean 'left'?",
            "left, right",
        ],
    );
    // On the command line: a node of --set, a variant; and the missing case file is named
    // once.
    let case = workspace_root().join("examples/crash_tube.toml");
    for (args, want) in [
        (
            vec!["--variant", "smal"],
            "unknown variant 'smal' (did you mean 'small'? the case has: case2, crush, crush2, grouped, small, small2)",
        ),
        (
            vec!["--set", "tub.params.section.thickness=2e-3"],
            "unknown node 'tub' (did you mean 'tube'?",
        ),
    ] {
        let mut a = vec!["validate", case.to_str().unwrap()];
        a.extend(args);
        let o = cosim(&a);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains(want), "{e}");
    }
    let o = cosim(&["validate", "no/such/case.toml"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert_eq!(e.matches("no/such/case.toml").count(), 1, "{e}");
}
