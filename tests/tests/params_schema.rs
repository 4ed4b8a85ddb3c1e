//! `cosim params`: every model's parameters listed from the JSON Schema its node
//! derives from the types it decodes them into. The schema covers every parameter the
//! example cases use, refuses what validation refuses (unknown keys), and the copies
//! published for editors in docs/schema/ are the ones the nodes print.

use cosim_tests::*;
use serde_json::Value;
use std::collections::BTreeMap;
use std::process::Command;

const MODELS: [&str; 8] = [
    "bar-1d",
    "fem-2d",
    "pd-bond",
    "pd-correspondence",
    "pd-rk-ba",
    "euler",
    "blt-shell",
    "mc-spg",
];

fn cosim(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(bin("cosim")).args(args).output().unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// The key paths the listing of `model` shows (variants of tagged tables as `a[kind = "x"].b`,
/// written here without the variant part).
fn keys(model: &str) -> Vec<String> {
    let (code, out, err) = cosim(&["params", model]);
    assert_eq!(code, 0, "{model}: {err}");
    let mut keys = Vec::new();
    for k in out
        .lines()
        .skip(2)
        .filter_map(|l| l.split_whitespace().next())
    {
        let mut s = String::new();
        let mut tag = String::new();
        let mut depth = 0;
        for c in k.chars() {
            match c {
                '[' => depth += 1,
                ']' => {
                    depth -= 1;
                    // the tag key of a variant (`bodies[shape="box"]` → `bodies.shape`)
                    if let Some((key, _)) = tag.split_once('=') {
                        keys.push(format!("{s}.{key}"));
                    }
                    tag.clear();
                }
                _ if depth == 0 => s.push(c),
                _ => tag.push(c),
            }
        }
        keys.push(s);
    }
    keys
}

/// Every key path of a TOML table (tables walked into, arrays of tables by their keys).
fn paths(t: &toml::Table, prefix: &str, out: &mut Vec<String>) {
    for (k, v) in t {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        out.push(key.clone());
        match v {
            toml::Value::Table(inner) => paths(inner, &key, out),
            toml::Value::Array(a) => {
                for x in a {
                    if let toml::Value::Table(inner) = x {
                        paths(inner, &key, out);
                    }
                }
            }
            _ => {}
        }
    }
}

#[test]
fn every_model_is_listed_with_its_node() {
    let (code, out, err) = cosim(&["params"]);
    assert_eq!(code, 0, "{err}");
    for m in MODELS {
        assert!(out.lines().any(|l| l.starts_with(m)), "{m} missing:\n{out}");
    }
    let (code, _, err) = cosim(&["params", "no-such-model"]);
    assert_eq!(code, 2);
    assert!(
        err.contains("no-such-model") && err.contains("pd-bond"),
        "{err}"
    );
}

#[test]
fn the_listing_gives_types_defaults_and_meanings() {
    let (code, out, err) = cosim(&["params", "bar-1d"]);
    assert_eq!(code, 0, "{err}");
    println!("{out}");
    let line = |k: &str| {
        out.lines()
            .find(|l| l.split_whitespace().next() == Some(k))
            .unwrap_or_else(|| panic!("no {k}:\n{out}"))
            .to_string()
    };
    let young = line("young");
    assert!(
        young.contains("number") && young.contains("required") && young.contains("(Pa)"),
        "{young}"
    );
    let fixed = line("fixed");
    assert!(fixed.contains("\"left\""), "{fixed}");
    let elements = line("elements");
    assert!(elements.contains("integer"), "{elements}");
    // a nested table's keys are listed under it
    assert!(
        out.contains("integrator.rho_inf") || out.contains("integrator.design"),
        "{out}"
    );
}

/// Every key the listing shows has a meaning (a doc comment on the field or its type),
/// except the entries of the user's own names (`materials.<name>`), which their table's row
/// explains.
#[test]
fn every_parameter_is_explained() {
    let mut missing = Vec::new();
    let mut rows = 0;
    for m in MODELS {
        let (code, out, err) = cosim(&["params", m, "--json"]);
        assert_eq!(code, 0, "{m}: {err}");
        let schema: Value = serde_json::from_str(&out).unwrap();
        for r in coordinator::params::rows(&schema) {
            rows += 1;
            if r.meaning.is_empty() && !r.key.ends_with("<name>") {
                missing.push(format!("{m}: {}", r.key));
            }
        }
    }
    println!("{rows} rows");
    assert!(rows > 250, "{rows}");
    assert!(
        missing.is_empty(),
        "keys without a meaning:\n{}",
        missing.join("\n")
    );
}

/// Every parameter key of every node of every example case is in its model's schema.
#[test]
fn the_schemas_cover_every_parameter_the_examples_use() {
    let mut known: BTreeMap<String, Vec<String>> = BTreeMap::new();
    let mut checked = 0;
    let dir = workspace_root().join("examples");
    let mut cases: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    cases.sort();
    for case in &cases {
        let text = std::fs::read_to_string(case).unwrap();
        let doc: toml::Table = toml::from_str(&text).unwrap();
        let Some(nodes) = doc.get("nodes").and_then(|n| n.as_table()) else {
            continue;
        };
        for (name, node) in nodes {
            let (Some(model), Some(params)) = (
                node.get("model").and_then(|m| m.as_str()),
                node.get("params").and_then(|p| p.as_table()),
            ) else {
                continue;
            };
            if !MODELS.contains(&model) {
                continue;
            }
            let list = known
                .entry(model.to_string())
                .or_insert_with(|| keys(model));
            let mut used = Vec::new();
            paths(params, "", &mut used);
            for k in used {
                // `<name>` in a listed key stands for any name of the user's (materials,
                // interfaces)
                let matches = |l: &String| {
                    let (a, b): (Vec<&str>, Vec<&str>) =
                        (l.split('.').collect(), k.split('.').collect());
                    a.len() == b.len() && a.iter().zip(&b).all(|(x, y)| x == y || *x == "<name>")
                };
                assert!(
                    list.iter().any(matches),
                    "{}: nodes.{name}.params.{k} ({model}) is not in `cosim params {model}`",
                    case.display()
                );
                checked += 1;
            }
        }
    }
    println!(
        "{checked} parameter keys of {} cases checked against {} models",
        cases.len(),
        known.len()
    );
    assert!(checked > 200, "{checked}");
    assert!(known.len() >= 6, "{known:?}");
}

/// docs/schema/MODEL.json is what `cosim params MODEL --json` prints, and each refuses
/// unknown keys at its top level as validation does.
#[test]
fn the_published_schemas_are_current() {
    for m in MODELS {
        let (code, out, err) = cosim(&["params", m, "--json"]);
        assert_eq!(code, 0, "{m}: {err}");
        let live: Value = serde_json::from_str(&out).unwrap();
        assert_eq!(live["additionalProperties"], Value::Bool(false), "{m}");
        same_as_published(&live, &format!("{m}.json"), &format!("params {m} --json"));
    }
}

/// `live` is docs/schema/`file`, which `cosim args` writes.
fn same_as_published(live: &Value, file: &str, args: &str) {
    let path = workspace_root().join("docs/schema").join(file);
    let published: Value = std::fs::read_to_string(&path)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or(Value::Null);
    assert!(
        &published == live,
        "{} is out of date: ./target/release/cosim {args} > {}",
        path.display(),
        path.display()
    );
}

/// docs/schema/case.json is what `cosim schema` prints, derived from the types the case is
/// read into.
#[test]
fn the_published_case_schema_is_current() {
    let (code, out, err) = cosim(&["schema"]);
    assert_eq!(code, 0, "{err}");
    let live: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(live["additionalProperties"], Value::Bool(false));
    same_as_published(&live, "case.json", "schema");
}

/// docs/reference.md is what `cosim schema --markdown` prints: every key of the case file
/// and every parameter of each built-in model, from the schemas above.
#[test]
fn the_published_reference_is_current() {
    let (code, out, err) = cosim(&["schema", "--markdown"]);
    assert_eq!(code, 0, "{err}");
    let path = workspace_root().join("docs/reference.md");
    let published = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        published.trim_end() == out.trim_end(),
        "{} is out of date: ./target/release/cosim schema --markdown > {}",
        path.display(),
        path.display()
    );
    // the case's keys, nested ones included, and a section per built-in model
    for key in [
        "| `run.end_time` |",
        "| `run.balance.energy` |",
        "| `couplings.decouple_when` |",
        "| `variants.<name>.set` |",
    ] {
        assert!(out.contains(key), "no row {key}");
    }
    let models = out.matches("\n## `").count();
    let listing = cosim(&["params"]).1;
    // `cosim params`: a header line, a line per model, and a line of how to go on
    let listed = listing.lines().filter(|l| l.contains("-node")).count();
    assert_eq!(models, listed, "a section per model of `cosim params`");
}

/// Validates TOML files against a JSON Schema with the `jsonschema` package (an independent
/// validator): prints `PATH: ok` or `PATH: KEY.PATH: message` per file.
const VALIDATE: &str = r#"
import json, sys, tomllib
from jsonschema import Draft202012Validator
schema = json.load(open(sys.argv[1]))
Draft202012Validator.check_schema(schema)
v = Draft202012Validator(schema)
for p in sys.argv[2:]:
    doc = tomllib.load(open(p, "rb"))
    errors = sorted(v.iter_errors(doc), key=lambda e: list(e.absolute_path))
    if errors:
        e = errors[0]
        where = ".".join(str(k) for k in e.absolute_path) or "(top)"
        print(f"{p}: {where}: {e.message}")
    else:
        print(f"{p}: ok")
"#;

/// Each line of the validator's verdicts on `files`.
fn schema_verdicts(files: &[std::path::PathBuf]) -> Vec<String> {
    let schema = workspace_root().join("docs/schema/case.json");
    let o = Command::new("python3")
        .arg("-c")
        .arg(VALIDATE)
        .arg(&schema)
        .args(files)
        .output()
        .expect("python3");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(str::to_string)
        .collect()
}

/// Every example case validates against docs/schema/case.json with an independent validator,
/// and the schema refuses a misspelt key at any depth, as `cosim validate` does.
#[test]
fn the_case_schema_validates_every_example_and_refuses_a_misspelt_key() {
    if !python_module_or_skip("jsonschema", "jsonschema") {
        return;
    }
    let mut files: Vec<_> = std::fs::read_dir(workspace_root().join("examples"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 18, "{} example cases", files.len());
    let verdicts = schema_verdicts(&files);
    assert_eq!(verdicts.len(), files.len(), "{verdicts:?}");
    for v in &verdicts {
        assert!(v.ends_with(": ok"), "{v}");
    }
    let (dir, _) = scratch("case-schema");
    let good = std::fs::read_to_string(workspace_root().join("examples/split_bar.toml")).unwrap();
    let bad = [
        ("run", good.replace("end_time =", "end_tme =")),
        (
            "nodes.left",
            good.replace("model = \"bar-1d\"", "modl = \"bar-1d\""),
        ),
        (
            "couplings.0",
            good.replace("kind = \"kinematic\"", "kind = \"kinematic\"\nsid = 1"),
        ),
        (
            "couplings.0.kind",
            good.replace("kind = \"kinematic\"", "kind = \"glued\""),
        ),
    ];
    let mut paths = Vec::new();
    for (k, (_, text)) in bad.iter().enumerate() {
        assert_ne!(text, &good, "edit {k} changed nothing");
        let p = dir.join(format!("bad{k}.toml"));
        std::fs::write(&p, text).unwrap();
        paths.push(p);
    }
    let verdicts = schema_verdicts(&paths);
    assert_eq!(verdicts.len(), bad.len(), "{verdicts:?}");
    for ((key, _), v) in bad.iter().zip(&verdicts) {
        assert!(
            v.contains(&format!(": {key}: ")),
            "expected a refusal at {key}: {v}"
        );
    }
}
