//! Fuzz targets for everything that reads input from outside: the message decoder
//! (`wire::decode` on arbitrary bytes and on mutated valid messages), the case parser with
//! `--set` overrides (the coordinator's `load_variant_text`), and the parameter decoder and
//! set-up of every node model (describe-only, as `NODE --describe` runs it). Each target
//! takes one input and returns whether it was accepted; the property is that it returns at
//! all: no panic, no hang, an error is an error. Inputs come from proptest strategies, so the
//! same targets serve the short smoke run in the test suite (`tests/smoke.rs`) and the long
//! run of ≥ 10⁶ inputs per target (`examples/fuzz.rs`).

use proptest::prelude::*;
use protocol::BuildOptions;
pub use protocol::registry::Model;

/// The fuzz targets, by name.
pub const TARGETS: [&str; 3] = ["wire", "case", "params"];

/// The message decoder on `bytes`: Ok or a `CodecError`, whatever the bytes.
pub fn wire_target(bytes: &[u8]) -> bool {
    wire::decode(bytes).is_ok()
}

/// The case parser: `text` as a case file, then the `--set` overrides, as `cosim validate`
/// reads them (no file, no process).
pub fn case_target(text: &str, sets: &[String]) -> bool {
    coordinator::case::load_variant_text(text, std::path::Path::new("fuzz.toml"), None, sets)
        .is_ok()
}

/// A node model's parameter decoder and set-up on `params`, describe-only (no device).
pub fn params_target(model: &Model, params: &toml::Table) -> bool {
    params_check(model, params).is_ok()
}

/// As [`params_target`], with the refusal.
pub fn params_check(model: &Model, params: &toml::Table) -> Result<(), String> {
    (model.build)(params, &BuildOptions::DESCRIBE)
        .map(drop)
        .map_err(|e| e.to_string())
}

/// Every model of the four node crates, as each node's registry lists it, with its example
/// parameters (the seed the mutations start from; small, so that an input builds in well
/// under a millisecond).
pub static MODELS: std::sync::LazyLock<Vec<Model>> = std::sync::LazyLock::new(|| {
    [
        solid_node::MODELS,
        fluid_node::MODELS,
        macro_shell_node::MODELS,
        meso_joint_node::MODELS,
    ]
    .concat()
});

/// A case file for the parser: two bars, variants, couplings (the shapes `--set` reaches).
/// The nodes are remote, so the parser does not start their executables to describe them
/// (node parameters are the `params` target's).
pub const CASE: &str = r#"
[run]
name = "fuzz"
end_time = 1e-4
window = 1e-6
schedule = "serial"
output = "out/fuzz"
[nodes.left]
solver = "solid-node"
model = "bar-1d"
remote = true
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
remote = true
[nodes.right.params]
length = 0.5
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
[variants.fine]
description = "finer"
set = ["left.elements=20", "right.elements=20"]
"#;

/// The seed table of a model.
pub fn base_table(m: &Model) -> toml::Table {
    toml::from_str(m.example).unwrap_or_default()
}

/// Bytes: arbitrary, or one of the golden messages mutated (bytes set, inserted, removed,
/// the tail cut), which gets past the header checks into the body decoder.
pub fn wire_input() -> impl Strategy<Value = Vec<u8>> {
    let golden = golden_messages();
    let arbitrary = proptest::collection::vec(any::<u8>(), 0..600);
    let mutated = (
        0..golden.len().max(1),
        proptest::collection::vec((any::<u16>(), any::<u8>(), 0u8..4), 1..6),
        any::<u16>(),
    )
        .prop_map(move |(k, edits, cut)| {
            let mut b = golden.get(k).cloned().unwrap_or_default();
            for (pos, val, op) in edits {
                let n = b.len().max(1);
                let p = pos as usize % n;
                match op {
                    0 if !b.is_empty() => b[p] = val,
                    1 => b.insert(p.min(b.len()), val),
                    2 if !b.is_empty() => {
                        b.remove(p);
                    }
                    _ if !b.is_empty() => b[p] ^= 1 << (val % 8),
                    _ => b.push(val),
                }
            }
            if cut % 5 == 0 {
                let keep = cut as usize % (b.len() + 1);
                b.truncate(keep);
            }
            b
        });
    prop_oneof![1 => arbitrary, 3 => mutated]
}

/// Valid encoded messages of every kind (the golden vectors of `wire/golden/`).
pub fn golden_messages() -> Vec<Vec<u8>> {
    macro_rules! golden {
        ($($f:literal),*) => { vec![$(include_bytes!(concat!("../../wire/golden/", $f)).to_vec()),*] };
    }
    golden!(
        "01_hello.bin",
        "02_welcome.bin",
        "03_reject.bin",
        "04_describe.bin",
        "05_mesh.bin",
        "06_advance.bin",
        "07_fields.bin",
        "08_done.bin",
        "09_heartbeat.bin",
        "10_finish.bin",
        "11_abort.bin",
        "12_failed.bin",
        "13_decouple.bin",
        "14_mesh_quad.bin",
        "15_mesh_points.bin",
        "16_fields_multi.bin",
        "17_describe_warnings.bin",
        "18_done_scalars.bin",
        "19_advance_varints.bin",
        "20_abort_long_reason.bin"
    )
}

/// Values that stress a decoder: every TOML type, signs, zero, NaN, infinities, extremes,
/// names of kinds and choices from the seed tables, nested arrays and tables.
fn value(seed: u64, like: Option<&toml::Value>) -> toml::Value {
    use toml::Value as V;
    let pick = |list: &[&str]| list[(seed >> 8) as usize % list.len()].to_string();
    match seed % 16 {
        0 => V::String(pick(&[
            "",
            "abc",
            "3d",
            "gpu",
            "cpu",
            "f32",
            "none",
            "all",
            "box",
            "plate",
            "j2",
            "ideal",
            "jwl",
            "inflow",
            "left",
            "right",
            "block",
            "critical_stretch",
        ])),
        1 => V::Integer([0, 1, -1, 2, 3, 7, i64::MAX, i64::MIN][(seed >> 8) as usize % 8]),
        2 => V::Float(
            [
                0.0,
                -0.0,
                -1.0,
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
                1e300,
                0.5,
            ][(seed >> 8) as usize % 8],
        ),
        3 => V::Boolean(seed & 256 != 0),
        4 => V::Array(vec![]),
        5 => V::Array((0..(seed >> 8) % 4).map(|k| V::Float(k as f64)).collect()),
        6 => {
            let mut t = toml::Table::new();
            t.insert(
                pick(&["kind", "shape", "x", "name", "min"]),
                value(seed >> 12, None),
            );
            V::Table(t)
        }
        // scaled and sign-flipped versions of the value it replaces (stays in range often
        // enough to get past the first checks)
        _ => match like {
            Some(V::Float(f)) => V::Float(f * [-1.0, 0.5, 2.0, 0.0][(seed >> 8) as usize % 4]),
            Some(V::Integer(i)) => {
                V::Integer(i.saturating_mul([-1, 0, 2, 1][(seed >> 8) as usize % 4]))
            }
            Some(V::Array(a)) => {
                let mut a = a.clone();
                match (seed >> 8) % 3 {
                    0 => {
                        a.pop();
                    }
                    1 => a.push(value(seed >> 12, None)),
                    _ => a.reverse(),
                }
                V::Array(a)
            }
            Some(other) => other.clone(),
            None => V::Float(1.0),
        },
    }
}

/// Paths to every value in a table (keys and array indexes).
fn paths(t: &toml::Table) -> Vec<Vec<Step>> {
    fn walk(v: &toml::Value, here: &mut Vec<Step>, out: &mut Vec<Vec<Step>>) {
        out.push(here.clone());
        match v {
            toml::Value::Table(t) => {
                for (k, v) in t {
                    here.push(Step::Key(k.clone()));
                    walk(v, here, out);
                    here.pop();
                }
            }
            toml::Value::Array(a) => {
                for (i, v) in a.iter().enumerate() {
                    here.push(Step::Index(i));
                    walk(v, here, out);
                    here.pop();
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(&toml::Value::Table(t.clone()), &mut Vec::new(), &mut out);
    out
}

#[derive(Debug, Clone)]
enum Step {
    Key(String),
    Index(usize),
}

fn at_mut<'a>(v: &'a mut toml::Value, path: &[Step]) -> Option<&'a mut toml::Value> {
    let mut cur = v;
    for s in path {
        cur = match (s, cur) {
            (Step::Key(k), toml::Value::Table(t)) => t.get_mut(k)?,
            (Step::Index(i), toml::Value::Array(a)) => a.get_mut(*i)?,
            _ => return None,
        };
    }
    Some(cur)
}

/// One structured edit of a table: (operation, which path, a seed for the value or name).
pub type Edit = (u8, u32, u64);

/// Applies `edits` to `t`: replace a value, remove a key, add an unknown key, misspell a key,
/// or set a key that another model or choice takes.
pub fn mutate(t: &toml::Table, edits: &[Edit]) -> toml::Table {
    let mut root = toml::Value::Table(t.clone());
    for &(op, which, seed) in edits {
        let all = match &root {
            toml::Value::Table(t) => paths(t),
            _ => return toml::Table::new(),
        };
        let path = &all[which as usize % all.len()];
        let Some(v) = at_mut(&mut root, path) else {
            continue;
        };
        match op % 5 {
            0 | 1 => {
                let old = v.clone();
                *v = value(seed, Some(&old));
            }
            2 => {
                if let (Some(Step::Key(k)), Some(parent)) = (
                    path.last(),
                    at_mut(&mut root, &path[..path.len().saturating_sub(1)]),
                ) && let toml::Value::Table(p) = parent
                {
                    p.remove(k);
                }
            }
            3 => {
                if let toml::Value::Table(tab) = v {
                    let keys = [
                        "stabilization",
                        "rk_order",
                        "bond_associative",
                        "p_inf",
                        "thickness",
                        "yield_stress",
                        "iso_hardening",
                        "device",
                        "precision",
                        "extra",
                        "kind",
                        "radius",
                        "seams",
                        "contact_stiffness",
                        "tip_force",
                        "load_end",
                    ];
                    tab.insert(
                        keys[(seed >> 4) as usize % keys.len()].to_string(),
                        value(seed >> 8, None),
                    );
                }
            }
            _ => {
                if let (Some(Step::Key(k)), Some(parent)) = (
                    path.last(),
                    at_mut(&mut root, &path[..path.len().saturating_sub(1)]),
                ) && let toml::Value::Table(p) = parent
                    && let Some(val) = p.remove(k)
                {
                    let mut bad = k.clone();
                    if bad.len() > 1 {
                        bad.remove((seed as usize) % bad.len());
                    } else {
                        bad.push('x');
                    }
                    p.insert(bad, val);
                }
            }
        }
    }
    match root {
        toml::Value::Table(t) => t,
        _ => toml::Table::new(),
    }
}

/// Edits for [`mutate`]: one to four.
pub fn edits() -> impl Strategy<Value = Vec<Edit>> {
    proptest::collection::vec((any::<u8>(), any::<u32>(), any::<u64>()), 1..5)
}

/// A case input: the seed case text with bytes edited (sometimes none) and `--set` strings
/// built from key paths of the case, random names and values (TOML or not).
pub fn case_input() -> impl Strategy<Value = (String, Vec<String>)> {
    let text = prop_oneof![
        3 => Just(CASE.to_string()),
        1 => proptest::collection::vec((any::<u16>(), any::<char>()), 1..4).prop_map(|ed| {
            let mut t: Vec<char> = CASE.chars().collect();
            for (p, c) in ed {
                let n = t.len();
                t[p as usize % n] = c;
            }
            t.into_iter().collect()
        }),
        1 => "\\PC{0,200}".prop_map(|s| s.to_string()),
    ];
    let heads = [
        "left",
        "right",
        "run",
        "couplings",
        "couplings.left-right",
        "nodes",
        "nope",
        "",
    ];
    let keys = [
        "elements",
        "young",
        "length",
        "end_time",
        "window",
        "schedule",
        "kind",
        "a.b",
        "interfaces.tip",
        "fixed",
        "output",
        "responder",
        "x.y.z",
        "",
        "=",
    ];
    let values = [
        "1",
        "-1",
        "0",
        "1e300",
        "nan",
        "inf",
        "\"x\"",
        "[1, 2]",
        "{ a = 1 }",
        "",
        "true",
        "abc",
        "'",
        "[",
        "2.5",
        "\"none\"",
        "\"left\"",
    ];
    let set = (
        0..heads.len(),
        0..keys.len(),
        0..values.len(),
        any::<bool>(),
    )
        .prop_map(move |(h, k, v, eq)| {
            let sep = if eq { "=" } else { ":" };
            format!("{}.{}{sep}{}", heads[h], keys[k], values[v])
        });
    (text, proptest::collection::vec(set, 0..4))
}

/// A params input: the index of a model in [`MODELS`] and its seed table mutated.
pub fn params_input() -> impl Strategy<Value = (usize, toml::Table)> {
    (0..MODELS.len(), edits()).prop_map(|(m, e)| (m, mutate(&base_table(&MODELS[m]), &e)))
}
