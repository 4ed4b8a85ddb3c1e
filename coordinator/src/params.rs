//! `cosim params [MODEL]`: the parameters a model takes, with types, defaults, units and
//! meaning, read from the node executable's JSON Schema (`NODE --schema --model M`), which
//! schemars derives from the same types the node decodes its parameters into — so the list
//! is what validation accepts. Without a model: the built-in nodes and their models.

use anyhow::{Context, bail};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The built-in node executables (beside `cosim`).
pub const BUILT_IN: [&str; 4] = [
    "solid-node",
    "fluid-node",
    "macro-shell-node",
    "meso-joint-node",
];

/// `EXE --schema [--model M]` as JSON.
fn ask(exe: &Path, model: Option<&str>) -> anyhow::Result<Value> {
    let mut cmd = Command::new(exe);
    cmd.arg("--schema");
    if let Some(m) = model {
        cmd.args(["--model", m]);
    }
    let o = cmd
        .output()
        .with_context(|| format!("cannot run {}", exe.display()))?;
    if !o.status.success() {
        bail!(
            "{} --schema: {}",
            exe.display(),
            String::from_utf8_lossy(&o.stderr).trim()
        );
    }
    serde_json::from_slice(&o.stdout)
        .with_context(|| format!("{} --schema printed no JSON", exe.display()))
}

/// The executables to ask: `solver` if given, else the built-in nodes found beside cosim.
fn executables(solver: Option<&Path>) -> anyhow::Result<Vec<PathBuf>> {
    if let Some(s) = solver {
        return crate::launch::resolve_exe(&s.to_string_lossy(), Path::new("."))
            .map(|p| vec![p])
            .with_context(|| format!("{}: no such executable", s.display()));
    }
    let found: Vec<PathBuf> = BUILT_IN
        .iter()
        .filter_map(|n| crate::launch::resolve_exe(n, Path::new(".")))
        .collect();
    if found.is_empty() {
        bail!("no node executables beside cosim (build them: cargo build --release --workspace)");
    }
    Ok(found)
}

/// Every model of the executables: (model, executable name).
pub fn models(solver: Option<&Path>) -> anyhow::Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    for exe in executables(solver)? {
        let v = ask(&exe, None)?;
        let name = exe
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        for m in v["models"].as_array().into_iter().flatten() {
            if let Some(m) = m.as_str() {
                out.push((m.to_string(), name.clone()));
            }
        }
    }
    Ok(out)
}

/// The JSON Schema of `model`'s parameters and the executable that offers it.
pub fn schema(model: &str, solver: Option<&Path>) -> anyhow::Result<(Value, String)> {
    let all = models(solver)?;
    let Some((_, exe)) = all.iter().find(|(m, _)| m == model) else {
        let known: Vec<&str> = all.iter().map(|(m, _)| m.as_str()).collect();
        bail!("unknown model '{model}' (models: {})", known.join(", "));
    };
    let path = executables(solver)?
        .into_iter()
        .find(|p| p.file_name().is_some_and(|n| n.to_string_lossy() == *exe))
        .with_context(|| format!("{exe} vanished"))?;
    Ok((ask(&path, Some(model))?, exe.clone()))
}

/// One line of the listing.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub key: String,
    pub kind: String,
    /// "required", the default's value, or "" (optional, absent by default).
    pub default: String,
    pub meaning: String,
}

/// Follows a `$ref` into the schema's `$defs`.
fn resolve<'a>(root: &'a Value, v: &'a Value) -> &'a Value {
    match v.get("$ref").and_then(Value::as_str) {
        Some(r) => r
            .strip_prefix("#/$defs/")
            .and_then(|n| root.get("$defs").and_then(|d| d.get(n)))
            .map(|d| resolve(root, d))
            .unwrap_or(v),
        None => v,
    }
}

/// The short type of a choice between schemas `alts`: a tagged table (`table, kind = "a" |
/// "b"`) or the alternatives' types, `or none` where one of them is null.
fn alternatives(root: &Value, alts: &[Value]) -> String {
    let (nulls, rest): (Vec<&Value>, Vec<&Value>) = alts
        .iter()
        .partition(|a| a.get("type").and_then(Value::as_str) == Some("null"));
    let tags: Vec<(String, String)> = rest.iter().filter_map(|a| tag_of(root, a)).collect();
    let mut s = if !tags.is_empty() && tags.len() == rest.len() {
        let values: Vec<&str> = tags.iter().map(|(_, c)| c.as_str()).collect();
        format!("table, {} = {}", tags[0].0, values.join(" | "))
    } else {
        let inner: Vec<String> = rest.iter().map(|a| kind(root, a)).collect();
        inner.join(" | ")
    };
    if !nulls.is_empty() {
        s += " or none";
    }
    s
}

/// A short type of a schema: `number`, `integer ≥ 0`, `"a" | "b"`, `[number; 3]`, `table`,
/// `T or none`.
fn kind(root: &Value, v: &Value) -> String {
    let v = resolve(root, v);
    if let Some(e) = v.get("enum").and_then(Value::as_array) {
        return e
            .iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(" | ");
    }
    if let Some(c) = v.get("const") {
        return c.to_string();
    }
    for key in ["anyOf", "oneOf"] {
        if let Some(alts) = v.get(key).and_then(Value::as_array) {
            return alternatives(root, alts);
        }
    }
    let ty = match v.get("type") {
        Some(Value::String(t)) => t.clone(),
        Some(Value::Array(ts)) => {
            let non_null: Vec<&str> = ts
                .iter()
                .filter_map(Value::as_str)
                .filter(|t| *t != "null")
                .collect();
            let s = non_null.join(" | ");
            if non_null.len() < ts.len() {
                format!("{s} or none")
            } else {
                s
            }
        }
        _ => String::new(),
    };
    let base = ty.trim_end_matches(" or none");
    let tail = &ty[base.len()..];
    match base {
        "array" => {
            let item = v.get("items").map(|i| kind(root, i)).unwrap_or_default();
            match (v.get("minItems"), v.get("maxItems")) {
                (Some(a), Some(b)) if a == b => format!("[{item}; {a}]{tail}"),
                _ => format!("[{item}]{tail}"),
            }
        }
        "object" if v.get("properties").is_none() => match v.get("additionalProperties") {
            Some(a) if a.is_object() => format!("{{name → {}}}{tail}", kind(root, a)),
            _ => format!("table{tail}"),
        },
        "object" => format!("table{tail}"),
        "integer" if v.get("minimum").and_then(Value::as_f64) == Some(0.0) => {
            format!("integer ≥ 0{tail}")
        }
        _ => ty,
    }
}

/// The first paragraph of a description, on one line.
fn meaning(v: &Value) -> String {
    v.get("description")
        .and_then(Value::as_str)
        .map(|d| {
            d.split("\n\n")
                .next()
                .unwrap_or("")
                .split_whitespace()
                .collect::<Vec<_>>()
                .join(" ")
        })
        .unwrap_or_default()
}

/// The tag of one variant of a tagged table: (tag key, its value as JSON).
fn tag_of(root: &Value, a: &Value) -> Option<(String, String)> {
    let a = resolve(root, a);
    a.get("properties")?.as_object()?.iter().find_map(|(k, s)| {
        let c = s.get("const").or_else(|| {
            s.get("enum")
                .and_then(Value::as_array)
                .filter(|e| e.len() == 1)
                .and_then(|e| e.first())
        })?;
        Some((k.clone(), c.to_string()))
    })
}

/// The table schema inside `v`: itself when it has keys or tagged variants, else the first
/// alternative of an `anyOf` that is one (an `Option<Table>`, a value or a table).
fn table_of<'a>(root: &'a Value, v: &'a Value) -> Option<&'a Value> {
    let v = resolve(root, v);
    if v.get("properties").is_some() || v.get("oneOf").is_some() {
        return Some(v);
    }
    v.get("anyOf")
        .and_then(Value::as_array)?
        .iter()
        .find_map(|a| table_of(root, a))
}

/// The rows of an object schema at `prefix`, nested tables and the variants of tagged
/// tables walked into (listed as `damage[kind="bond"].critical_stretch`).
fn walk(root: &Value, v: &Value, prefix: &str, out: &mut Vec<Row>) {
    let v = resolve(root, v);
    if let Some(alts) = v
        .get("oneOf")
        .or_else(|| v.get("anyOf"))
        .and_then(Value::as_array)
    {
        for a in alts {
            let a = resolve(root, a);
            if let Some((k, c)) = tag_of(root, a) {
                // the tag itself is in the key path: no row of its own
                let at = format!("{prefix}[{k}={c}]");
                let tag_row = format!("{at}.{k}");
                walk(root, a, &at, out);
                out.retain(|r| r.key != tag_row);
            }
        }
        return;
    }
    let Some(props) = v.get("properties").and_then(Value::as_object) else {
        return;
    };
    let required: Vec<&str> = v
        .get("required")
        .and_then(Value::as_array)
        .map(|r| r.iter().filter_map(Value::as_str).collect())
        .unwrap_or_default();
    for (k, s) in props {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        let r = resolve(root, s);
        let default = match s.get("default").or_else(|| r.get("default")) {
            Some(d) => d.to_string(),
            None if required.contains(&k.as_str()) => "required".into(),
            None => String::new(),
        };
        let mut m = meaning(s);
        if m.is_empty() {
            m = meaning(r);
        }
        out.push(Row {
            key: key.clone(),
            kind: kind(root, s),
            default,
            meaning: m,
        });
        walk_inside(root, r, &key, out);
    }
}

/// The rows inside the value at `key` whose schema is `r`: a nested table (also inside an
/// `Option` or beside a plain value) key by key, an array of tables (`[[...bodies]]`) by the
/// keys of each entry, a table of the user's own names (materials, interfaces) by one entry
/// per name.
fn walk_inside(root: &Value, r: &Value, key: &str, out: &mut Vec<Row>) {
    let inner = table_of(root, r).unwrap_or(r);
    let items = r.get("items").and_then(|i| table_of(root, i));
    if inner.get("properties").is_some() || inner.get("oneOf").is_some() {
        walk(root, inner, key, out);
    } else if let Some(i) = items {
        walk(root, i, key, out);
    } else if let Some(ap) = inner.get("additionalProperties").filter(|a| a.is_object()) {
        let entry = format!("{key}.<name>");
        let a = resolve(root, ap);
        out.push(Row {
            key: entry.clone(),
            kind: kind(root, ap),
            default: String::new(),
            meaning: meaning(a),
        });
        if a.get("properties").is_some() || a.get("oneOf").is_some() {
            walk(root, a, &entry, out);
        }
    }
}

/// The parameter listing of a model's schema.
pub fn rows(schema: &Value) -> Vec<Row> {
    let mut out = Vec::new();
    walk(schema, schema, "", &mut out);
    out
}

/// The listing as text: one line per key (key, type, default, meaning).
pub fn table(model: &str, exe: &str, rows: &[Row]) -> String {
    let w0 = rows
        .iter()
        .map(|r| r.key.chars().count())
        .max()
        .unwrap_or(3)
        .max(3);
    let w1 = rows
        .iter()
        .map(|r| r.kind.chars().count())
        .max()
        .unwrap_or(4)
        .clamp(4, 28);
    let w2 = rows
        .iter()
        .map(|r| r.default.chars().count())
        .max()
        .unwrap_or(7)
        .clamp(7, 16);
    let mut s = format!(
        "{model} ({exe}): [nodes.NAME.params], SI units\n{:<w0$}  {:<w1$}  {:<w2$}  meaning\n",
        "key", "type", "default"
    );
    for r in rows {
        s += &format!(
            "{:<w0$}  {:<w1$}  {:<w2$}  {}\n",
            r.key, r.kind, r.default, r.meaning
        );
    }
    s
}

/// One listing as a Markdown table under a heading: key, type, default, meaning (pipes in the
/// text escaped).
pub fn markdown_table(heading: &str, intro: &str, rows: &[Row]) -> String {
    let cell = |t: &str| t.replace('|', "\\|").replace('\n', " ");
    let mut s = format!(
        "{heading}\n\n{intro}\n\n| key | type | default | meaning |\n| --- | --- | --- | --- |\n"
    );
    for r in rows {
        let default = if r.default.is_empty() {
            String::new()
        } else {
            format!("`{}`", r.default)
        };
        s += &format!(
            "| `{}` | {} | {} | {} |\n",
            r.key,
            cell(&r.kind),
            cell(&default),
            cell(&r.meaning)
        );
    }
    s
}

/// docs/reference.md: every key of the case file, then every parameter of each built-in
/// model, from the JSON Schemas the case types and the node executables derive (what `cosim
/// schema` and `cosim params MODEL --json` print).
pub fn reference() -> anyhow::Result<String> {
    let mut s = String::from(
        "# Reference: the case file and the models' parameters\n\n\
         Generated by `cosim schema --markdown` from the types the case file and every \
         built-in model are read into (the JSON Schemas in [schema/](schema/) are the same); \
         `cosim params MODEL` prints one model's table. Units are SI. A key of a table of the \
         user's own names reads `<name>`; a tagged table's variant reads `[kind=\"...\"]`.\n\n",
    );
    let case = crate::case::parse::schema();
    s += &markdown_table(
        "## The case file",
        "Every key of a case file (`[run]`, `[nodes.NAME]`, `[[couplings]]`, `[variants.NAME]`); \
         a node's `params` are its model's, below.",
        &rows(&case),
    );
    for (model, exe) in models(None)? {
        let (schema, _) = schema(&model, None)?;
        s += "\n";
        s += &markdown_table(
            &format!("## `{model}` ({exe})"),
            &format!("`[nodes.NAME.params]` of a node with `model = \"{model}\"`."),
            &rows(&schema),
        );
    }
    Ok(s)
}
