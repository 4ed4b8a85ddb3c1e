//! Validation through the node executables (`NODE --describe`): every bad parameter of a
//! case is refused by `cosim validate` with exit 2 and its full key path, at any depth and for
//! every way a key can be wrong (unknown, misspelt, mistyped, missing, inapplicable, bad
//! value); a node answers `--describe` with its interfaces as JSON, or exit 2 naming the key;
//! and a GPU case validates with no GPU driver at all (no GPU context is opened to validate).

use cosim_tests::*;
use std::io::Write;
use std::process::{Command, Stdio};

/// Two bars, one kinematic coupling.
const BARS: &str = r#"
[run]
end_time = 1e-4
window = 1e-6
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

/// One fluid node: a 1-D tube of air.
const GAS: &str = r#"
[run]
end_time = 1e-4
window = 1e-5
[nodes.gas]
solver = "fluid-node"
model = "euler"
[nodes.gas.params]
cfl = 0.5
[nodes.gas.params.grid]
cells = [20, 1, 1]
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
[nodes.gas.params.materials.air]
eos = "ideal"
gamma = 1.4
[[nodes.gas.params.regions]]
shape = "all"
material = "air"
density = 1.0
pressure = 1.0
"#;

/// One peridynamic block.
const BLOCK: &str = r#"
[run]
end_time = 1e-6
window = 1e-7
[nodes.plate]
solver = "solid-node"
model = "pd-bond"
[nodes.plate.params]
dimension = "3d"
spacing = 1e-3
horizon = 3.015e-3
density = 7850.0
young = 200e9
poisson = 0.25
bodies = [{ shape = "box", min = [0.0, 0.0, 0.0], max = [0.006, 0.004, 0.004] }]
interfaces = [{ name = "surface", select = "surface" }]
"#;

/// One MC-SPG joint block.
const JOINT: &str = r#"
[run]
end_time = 1e-6
window = 1e-7
[nodes.joint]
solver = "meso-joint-node"
model = "mc-spg"
[nodes.joint.params]
spacing = 0.5e-3
kernel_support = 1.0e-3
density = 7850.0
young = 210e9
poisson = 0.3
yield_stress = 0.2e9
tangent_modulus = 20e9
eps_crit = 0.1
[nodes.joint.params.geometry]
kind = "block"
origin = [0.0, 0.0, 0.0]
size = [3e-3, 2e-3, 2e-3]
"#;

/// One shell plate.
const SHELL: &str = r#"
[run]
end_time = 1e-6
window = 1e-7
[nodes.sheet]
solver = "macro-shell-node"
model = "blt-shell"
[nodes.sheet.params]
mesh = { kind = "plate", length = 4e-3, width = 3e-3, nx = 4, ny = 3 }
material = { model = "j2", density = 7850.0, youngs_modulus = 210e9, poisson_ratio = 0.3, yield_stress = 1e9, tangent_modulus = 1e9 }
section = { thickness = 1e-3, integration_points = 3 }
node_sets = [{ name = "left", box = [-1.0, -1.0, -1.0, 1.0e-4, 1.0, 1.0] }]
fixed = [{ node_set = "left", dofs = ["all"] }]
"#;

/// Write `text` as a case file in a fresh scratch directory and validate it.
fn validate(tag: &str, text: &str, env: &[(&str, &str)]) -> std::process::Output {
    let (dir, _) = scratch(tag);
    let case = dir.join("case.toml");
    std::fs::write(&case, text).expect("case written");
    let mut c = Command::new(bin("cosim"));
    c.args(["validate", case.to_str().expect("utf-8 path")]);
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("cosim runs")
}

#[test]
fn the_base_cases_validate() {
    for (tag, base) in [
        ("ok-bars", BARS),
        ("ok-gas", GAS),
        ("ok-block", BLOCK),
        ("ok-joint", JOINT),
        ("ok-shell", SHELL),
    ] {
        let o = validate(tag, base, &[]);
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{tag}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(out.contains("described by its executable"), "{tag}: {out}");
    }
}

#[test]
fn every_bad_parameter_is_refused_naming_its_full_key() {
    // (tag, base case, text to replace, replacement, key the refusal must name)
    let table: &[(&str, &str, &str, &str, &str)] = &[
        // the 1-D bar
        (
            "bar-mistyped",
            BARS,
            "young = 200e9",
            "young = \"abc\"",
            "nodes.left.params.young",
        ),
        (
            "bar-misspelt",
            BARS,
            "young = 200e9",
            "yung = 200e9",
            "nodes.left.params.yung",
        ),
        (
            "bar-unknown",
            BARS,
            "area = 1e-4\ninterfaces = { tip",
            "area = 1e-4\ndamping = 0.1\ninterfaces = { tip",
            "nodes.left.params.damping",
        ),
        (
            "bar-missing",
            BARS,
            "density = 7860.0\n",
            "",
            "nodes.left.params.density",
        ),
        (
            "bar-float-count",
            BARS,
            "elements = 10",
            "elements = 2.5",
            "nodes.left.params.elements",
        ),
        (
            "bar-negative-count",
            BARS,
            "elements = 10",
            "elements = -3",
            "nodes.left.params.elements",
        ),
        (
            "bar-zero-count",
            BARS,
            "elements = 10",
            "elements = 0",
            "nodes.left.params.elements",
        ),
        (
            "bar-iface-type",
            BARS,
            "interfaces = { tip = \"right\" }",
            "interfaces = { tip = 3 }",
            "nodes.left.params.interfaces.tip",
        ),
        (
            "bar-courant",
            BARS,
            "area = 1e-4\ninterfaces = { tip",
            "area = 1e-4\ncourant = 1.5\ninterfaces = { tip",
            "nodes.left.params.courant",
        ),
        (
            "bar-length",
            BARS,
            "length = 0.5",
            "length = -0.5",
            "nodes.left.params.length",
        ),
        (
            "bar-model",
            BARS,
            "model = \"bar-1d\"",
            "model = \"bar-2d\"",
            "nodes.left.model",
        ),
        // the fluid, nested keys
        (
            "gas-gamma-type",
            GAS,
            "gamma = 1.4",
            "gamma = \"x\"",
            "nodes.gas.params.materials.air.gamma",
        ),
        (
            "gas-gamma-misspelt",
            GAS,
            "gamma = 1.4",
            "gama = 1.4",
            "nodes.gas.params.materials.air.gama",
        ),
        (
            "gas-p-inf-ideal",
            GAS,
            "gamma = 1.4",
            "gamma = 1.4\np_inf = 1e8",
            "nodes.gas.params.materials.air.p_inf",
        ),
        (
            "gas-jwl-on-ideal",
            GAS,
            "gamma = 1.4",
            "gamma = 1.4\nomega = 0.3",
            "nodes.gas.params.materials.air.omega",
        ),
        (
            "gas-eos-missing",
            GAS,
            "eos = \"ideal\"\n",
            "",
            "nodes.gas.params.materials.air.eos",
        ),
        (
            "gas-eos-unknown",
            GAS,
            "eos = \"ideal\"",
            "eos = \"vdw\"",
            "nodes.gas.params.materials.air.eos",
        ),
        (
            "gas-gamma-value",
            GAS,
            "gamma = 1.4",
            "gamma = 0.9",
            "nodes.gas.params.materials.air.gamma",
        ),
        (
            "gas-cells-length",
            GAS,
            "cells = [20, 1, 1]",
            "cells = [20, 1]",
            "nodes.gas.params.grid.cells",
        ),
        (
            "gas-lower-missing",
            GAS,
            "lower = [0.0, 0.0, 0.0]\n",
            "",
            "nodes.gas.params.grid.lower",
        ),
        (
            "gas-grid-unknown",
            GAS,
            "cells = [20, 1, 1]",
            "cells = [20, 1, 1]\nspacing = 0.1",
            "nodes.gas.params.grid.spacing",
        ),
        (
            "gas-pressure-type",
            GAS,
            "pressure = 1.0",
            "pressure = \"high\"",
            "nodes.gas.params.regions[0].pressure",
        ),
        (
            "gas-radius-on-all",
            GAS,
            "shape = \"all\"",
            "shape = \"all\"\nradius = 0.1",
            "nodes.gas.params.regions[0].radius",
        ),
        (
            "gas-region-misspelt",
            GAS,
            "density = 1.0",
            "densty = 1.0",
            "nodes.gas.params.regions[0].densty",
        ),
        (
            "gas-limiter-type",
            GAS,
            "cfl = 0.5",
            "cfl = 0.5\nlimiter = 3",
            "nodes.gas.params.limiter",
        ),
        (
            "gas-device",
            GAS,
            "cfl = 0.5",
            "cfl = 0.5\ndevice = \"tpu\"",
            "nodes.gas.params.device",
        ),
        (
            "gas-f32-on-cpu",
            GAS,
            "cfl = 0.5",
            "cfl = 0.5\nprecision = \"f32\"",
            "nodes.gas.params.precision",
        ),
        (
            "gas-cfl",
            GAS,
            "cfl = 0.5",
            "cfl = 0.0",
            "nodes.gas.params.cfl",
        ),
        (
            "gas-wall-with-state",
            GAS,
            "cfl = 0.5",
            "cfl = 0.5\nboundaries = { x_lower = { kind = \"wall\", pressure = 2.0 } }",
            "nodes.gas.params.boundaries.x_lower.pressure",
        ),
        (
            "gas-missing-grid",
            GAS,
            "[nodes.gas.params.grid]\ncells = [20, 1, 1]\nlower = [0.0, 0.0, 0.0]\nupper = [1.0, 1.0, 1.0]\n",
            "",
            "nodes.gas.params.grid",
        ),
        // a GPU-related key checked without opening a GPU: a radial grid has no device kernels
        (
            "gas-gpu-radial",
            GAS,
            "cfl = 0.5",
            "cfl = 0.5\ndevice = \"gpu\"\ngeometry = \"spherical\"",
            "nodes.gas.params.device",
        ),
        // peridynamics
        (
            "pd-misspelt",
            BLOCK,
            "horizon = 3.015e-3",
            "horizn = 3.015e-3",
            "nodes.plate.params.horizn",
        ),
        (
            "pd-mistyped",
            BLOCK,
            "young = 200e9",
            "young = \"abc\"",
            "nodes.plate.params.young",
        ),
        (
            "pd-select",
            BLOCK,
            "select = \"surface\"",
            "select = \"edge\"",
            "nodes.plate.params.interfaces[0].select",
        ),
        (
            "pd-iface-unknown",
            BLOCK,
            "select = \"surface\"",
            "select = \"surface\", side = 1",
            "nodes.plate.params.interfaces[0].side",
        ),
        (
            "pd-horizon",
            BLOCK,
            "horizon = 3.015e-3",
            "horizon = 0.5e-3",
            "nodes.plate.params.horizon",
        ),
        // the bond budget (max_bonds, default 5e7): 200³ particles at δ = 3.015 Δx (~10⁹
        // bonds), 50³ at δ = 20 Δx (~4·10⁹), and 96 particles over a lowered budget
        (
            "pd-bonds-spacing",
            BLOCK,
            "max = [0.006, 0.004, 0.004]",
            "max = [0.2, 0.2, 0.2]",
            "nodes.plate.params.spacing",
        ),
        (
            "pd-bonds-horizon",
            BLOCK,
            "horizon = 3.015e-3\ndensity = 7850.0\nyoung = 200e9\npoisson = 0.25\nbodies = [{ shape = \"box\", min = [0.0, 0.0, 0.0], max = [0.006, 0.004, 0.004] }]",
            "horizon = 2e-2\ndensity = 7850.0\nyoung = 200e9\npoisson = 0.25\nbodies = [{ shape = \"box\", min = [0.0, 0.0, 0.0], max = [0.05, 0.05, 0.05] }]",
            "nodes.plate.params.horizon",
        ),
        (
            "pd-bonds-max",
            BLOCK,
            "poisson = 0.25",
            "poisson = 0.25\nmax_bonds = 1000",
            "nodes.plate.params.spacing",
        ),
        (
            "pd-f32-on-cpu",
            BLOCK,
            "poisson = 0.25",
            "poisson = 0.25\nprecision = \"f32\"",
            "nodes.plate.params.precision",
        ),
        (
            "pd-gpu-rk-ba",
            BLOCK,
            "model = \"pd-bond\"\n[nodes.plate.params]",
            "model = \"pd-rk-ba\"\n[nodes.plate.params]\ndevice = \"gpu\"",
            "nodes.plate.params.device",
        ),
        // keys inside tagged tables (`kind = ...`, `shape = ...`) and keys that do not
        // apply to the chosen model
        (
            "pd-damage-misspelt",
            BLOCK,
            "poisson = 0.25",
            "poisson = 0.25\ndamage = { kind = \"critical_stretch\", critical_strech = 0.01 }",
            "nodes.plate.params.damage.critical_strech",
        ),
        (
            "pd-damage-mistyped",
            BLOCK,
            "poisson = 0.25",
            "poisson = 0.25\ndamage = { kind = \"critical_stretch\", critical_stretch = \"a\" }",
            "nodes.plate.params.damage.critical_stretch",
        ),
        (
            "pd-key-on-no-damage",
            BLOCK,
            "poisson = 0.25",
            "poisson = 0.25\ndamage = { kind = \"none\", critical_stretch = 0.01 }",
            "nodes.plate.params.damage.critical_stretch",
        ),
        (
            "pd-body-misspelt",
            BLOCK,
            "max = [0.006",
            "maxx = [0.006",
            "nodes.plate.params.bodies[0].maxx",
        ),
        (
            "pd-body-mistyped",
            BLOCK,
            "max = [0.006, 0.004, 0.004]",
            "max = \"big\"",
            "nodes.plate.params.bodies[0].max",
        ),
        (
            "pd-stabilization-on-bond",
            BLOCK,
            "poisson = 0.25",
            "poisson = 0.25\nstabilization = 0.3",
            "nodes.plate.params.stabilization",
        ),
        (
            "pd-rk-order-on-correspondence",
            BLOCK,
            "model = \"pd-bond\"\n[nodes.plate.params]",
            "model = \"pd-correspondence\"\n[nodes.plate.params]\nrk_order = 1",
            "nodes.plate.params.rk_order",
        ),
        (
            "pd-hardening-elastic",
            BLOCK,
            "model = \"pd-bond\"\n[nodes.plate.params]",
            "model = \"pd-rk-ba\"\n[nodes.plate.params]\niso_hardening = 1e9",
            "nodes.plate.params.iso_hardening",
        ),
        (
            "pd-thickness-3d",
            BLOCK,
            "poisson = 0.25",
            "poisson = 0.25\nthickness = 1e-3",
            "nodes.plate.params.thickness",
        ),
        (
            "bar-force-no-end",
            BARS,
            "fixed = \"none\"",
            "fixed = \"none\"\ntip_force = 1e3\nload_end = \"none\"",
            "nodes.right.params.tip_force",
        ),
        (
            "shell-mesh-key-of-tube",
            SHELL,
            "nx = 4, ny = 3",
            "nx = 4, ny = 3, side = 1e-3",
            "nodes.sheet.params.mesh.side",
        ),
        (
            "shell-yield-on-elastic",
            SHELL,
            "model = \"j2\"",
            "model = \"elastic\"",
            "nodes.sheet.params.material.yield_stress",
        ),
        (
            "shell-section-mistyped",
            SHELL,
            "integration_points = 3",
            "integration_points = \"three\"",
            "nodes.sheet.params.section.integration_points",
        ),
        (
            "joint-geometry-misspelt",
            JOINT,
            "size = [3e-3",
            "sise = [3e-3",
            "nodes.joint.params.geometry.sise",
        ),
        (
            "joint-geometry-mistyped",
            JOINT,
            "size = [3e-3, 2e-3, 2e-3]",
            "size = \"big\"",
            "nodes.joint.params.geometry.size",
        ),
        // joints
        (
            "joint-mistyped",
            JOINT,
            "young = 210e9",
            "young = \"steel\"",
            "nodes.joint.params.young",
        ),
        (
            "joint-eps",
            JOINT,
            "eps_crit = 0.1",
            "eps_crit = -0.1",
            "nodes.joint.params.eps_crit",
        ),
        (
            "joint-unknown",
            JOINT,
            "eps_crit = 0.1",
            "eps_crit = 0.1\nhorizon = 1.0",
            "nodes.joint.params.horizon",
        ),
    ];
    assert!(table.len() >= 30, "{} cases", table.len());
    let mut refused = 0;
    for (tag, base, from, to, key) in table {
        assert!(base.contains(from), "{tag}: the base case has no '{from}'");
        let text = base.replacen(from, to, 1);
        let o = validate(tag, &text, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        println!("{tag}: {}", err.trim());
        assert_eq!(o.status.code(), Some(2), "{tag}: {err}");
        assert!(
            err.contains(&format!("{key}: ")),
            "{tag}: '{}' does not name {key}",
            err.trim()
        );
        refused += 1;
    }
    assert_eq!(refused, table.len());
}

/// A body past the bond budget is refused before it is built (its ~10⁹ bonds would take
/// some 60 GB): exit 2 naming the spacing, with the estimate and the way out in the reason;
/// the same body within a raised `max_bonds` but at a coarser spacing validates.
#[test]
fn a_body_past_the_bond_budget_is_refused_naming_the_key() {
    let big = BLOCK.replacen("max = [0.006, 0.004, 0.004]", "max = [0.2, 0.2, 0.2]", 1);
    let o = validate("bonds-over", &big, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    // 200³ particles, the interior family of δ = 3.015 Δx has 122 members
    for part in [
        "nodes.plate.params.spacing: ",
        "8000000 particles",
        "122 neighbours",
        "9.760e8 bonds",
        "max_bonds = 50000000",
    ] {
        assert!(err.contains(part), "'{part}' not in: {err}");
    }
    // 20³ particles at 10 mm (~8·10⁵ bonds) under a budget lowered to 10⁶: accepted
    let coarse = big
        .replacen("spacing = 1e-3", "spacing = 1e-2", 1)
        .replacen("horizon = 3.015e-3", "horizon = 3.015e-2", 1)
        .replacen("poisson = 0.25", "poisson = 0.25\nmax_bonds = 1000000", 1);
    let o = validate("bonds-under", &coarse, &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `solid-node --describe`: the interfaces of a bar as JSON (params on stdin or from a
/// file), and exit 2 with the key for a bad parameter.
#[test]
fn solid_node_describes_a_bar_or_names_the_bad_key() {
    let params = "length = 0.5\nelements = 10\nyoung = 200e9\ndensity = 7860.0\narea = 1e-4\ninterfaces = { tip = \"right\", base = \"left\" }\n";
    let describe = |params: &str, file: Option<&std::path::Path>| {
        let mut c = Command::new(bin("solid-node"));
        c.args(["--describe", "--model", "bar-1d"]);
        if let Some(f) = file {
            c.arg("--params").arg(f);
        }
        let mut child = c
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("solid-node runs");
        if let Some(mut i) = child.stdin.take() {
            i.write_all(params.as_bytes()).expect("params written");
        }
        child.wait_with_output().expect("solid-node answers")
    };
    let o = describe(params, None);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value =
        serde_json::from_slice(&o.stdout).expect("one JSON document on stdout");
    let d = &json["description"];
    assert_eq!(d["binary"], "solid-node");
    assert_eq!(d["model"], "bar-1d");
    let ifaces = d["interfaces"].as_array().expect("interfaces");
    let mut names: Vec<&str> = ifaces.iter().filter_map(|i| i["name"].as_str()).collect();
    names.sort_unstable();
    assert_eq!(names, ["base", "tip"]);
    for i in ifaces {
        assert_eq!(i["points"], 1, "{i}");
        assert!(
            !i["provides"].as_array().expect("provides").is_empty(),
            "{i}"
        );
        assert!(!i["accepts"].as_array().expect("accepts").is_empty(), "{i}");
    }
    // c = sqrt(E/ρ), h = L/n: the stable step is at most h/c
    let dt = d["stable_dt"].as_f64().expect("stable_dt");
    let h_over_c = 0.05 / (200e9f64 / 7860.0).sqrt();
    assert!(
        dt > 0.0 && dt <= h_over_c * (1.0 + 1e-12),
        "{dt} vs {h_over_c}"
    );

    // The same from a file.
    let (dir, _) = scratch("describe-file");
    let f = dir.join("params.toml");
    std::fs::write(&f, params).expect("params file");
    let o2 = describe("", Some(&f));
    assert!(o2.status.success());
    assert_eq!(o2.stdout, o.stdout);

    // A mistyped key: exit 2, the key in the JSON and on stderr.
    let o = describe(&params.replace("young = 200e9", "young = \"abc\""), None);
    assert_eq!(o.status.code(), Some(2));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON error");
    assert_eq!(json["error"]["key"], "params.young");
    assert!(
        json["error"]["reason"]
            .as_str()
            .is_some_and(|r| r.contains("invalid type")),
        "{json}"
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("params.young: "));
    // An unknown model names the model.
    let mut c = Command::new(bin("solid-node"));
    let o = c
        .args(["--describe", "--model", "beam", "--params"])
        .arg(&f)
        .output()
        .expect("solid-node runs");
    assert_eq!(o.status.code(), Some(2));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON error");
    assert_eq!(json["error"]["key"], "model");
}

/// `cosim validate` on a case with `device = "gpu"` succeeds with the Vulkan driver hidden:
/// validation opens no GPU context (neither in cosim nor in the node). The control: the same
/// case run with the driver hidden fails at the node, which does need the GPU.
#[test]
fn a_gpu_case_validates_without_any_gpu() {
    let hidden = [
        ("VK_ICD_FILENAMES", "/nonexistent.json"),
        ("VK_DRIVER_FILES", "/nonexistent.json"),
        ("WGPU_BACKEND", "vulkan"),
    ];
    let gpu = GAS.replacen("cfl = 0.5", "cfl = 0.5\ndevice = \"gpu\"", 1);
    let o = validate("gpu-validate", &gpu, &hidden);
    assert!(
        o.status.success(),
        "validate needed a GPU: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let block = BLOCK.replacen("poisson = 0.25", "poisson = 0.25\ndevice = \"gpu\"", 1);
    let o = validate("gpu-validate-pd", &block, &hidden);
    assert!(
        o.status.success(),
        "validate needed a GPU: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    // Control: a run needs the adapter, and without the driver there is none.
    let (dir, id) = scratch("gpu-run-hidden");
    let case = dir.join("case.toml");
    std::fs::write(
        &case,
        gpu.replace(
            "window = 1e-5",
            &format!(
                "window = 1e-5\noutput = {:?}",
                dir.join("out").display().to_string()
            ),
        ),
    )
    .expect("case written");
    let o = Command::new(bin("cosim"))
        .args([
            "run",
            case.to_str().expect("utf-8"),
            "--run-id",
            &id,
            "--quiet",
        ])
        .envs(hidden)
        .output()
        .expect("cosim runs");
    assert!(
        !o.status.success(),
        "the run got a GPU with the driver hidden, so the check above proves nothing"
    );
}
