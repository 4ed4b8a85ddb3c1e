//! Variants of a case and settings from the command line: `[variants.NAME]` (remove, add,
//! set) and `--set KEY=VALUE`, applied to the case's TOML document before it is read again
//! as a whole, so a variant is checked exactly as a case file is.

use super::parse::CaseFile;
use super::resolved::{ConfigError, err};

/// Apply `key=value` overrides to a parameter table (`a.b=3` sets nested keys; the value is
/// parsed as TOML, falling back to a string; `key=` with nothing after it removes the key).
pub fn apply_sets(params: &mut toml::Table, sets: &[String]) -> Result<(), ConfigError> {
    for s in sets {
        let (k, v) = s
            .split_once('=')
            .ok_or_else(|| err(format!("--set {s}"), "must be key=value"))?;
        let parts: Vec<&str> = k.trim().split('.').collect();
        if v.trim().is_empty() {
            // `KEY=` removes the key (e.g. a parameter the swapped-in model does not take).
            let mut t = Some(&mut *params);
            for part in &parts[..parts.len() - 1] {
                t = t
                    .and_then(|t| t.get_mut(*part))
                    .and_then(|e| e.as_table_mut());
            }
            if let Some(t) = t {
                t.remove(parts[parts.len() - 1]);
            }
            continue;
        }
        let value: toml::Value = toml::from_str::<toml::Table>(&format!("v = {v}"))
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(v.to_string()));
        let mut t = &mut *params;
        for part in &parts[..parts.len() - 1] {
            let e = t
                .entry(part.to_string())
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            t = e
                .as_table_mut()
                .ok_or_else(|| err(format!("--set {k}"), format!("'{part}' is not a table")))?;
        }
        t.insert(parts[parts.len() - 1].to_string(), value);
    }
    Ok(())
}

/// The `set` list of variant `name` of the typed case `file`.
fn variant_sets(file: &CaseFile, name: &str) -> Result<Vec<String>, ConfigError> {
    let Some(v) = file.variants.get(name) else {
        let known: Vec<&str> = file.variants.keys().map(String::as_str).collect();
        return Err(err(
            format!("--variant {name}"),
            if known.is_empty() {
                "the case has no [variants]".to_string()
            } else {
                super::resolved::unknown("variant", name, known.iter().copied())
            },
        ));
    };
    let set = v.set.clone().unwrap_or_default();
    Ok(set)
}

/// Apply the structural part of variant `name` to the case document, before its `set`
/// list: `remove = ["nodes.NAME", "couplings.NAME", ...]` drops nodes and couplings (a
/// coupling's name is its `name` or `DRIVER-RESPONDER`), then `[variants.NAME.nodes.X]`
/// tables add nodes and `[[variants.NAME.couplings]]` entries add couplings, exactly as in
/// the case's own `[nodes]` and `[[couplings]]`. A node removed while a coupling still
/// names it is caught by the validation of the result.
pub fn apply_variant_structure(doc: &mut toml::Table, name: &str) -> Result<(), ConfigError> {
    let key = format!("variants.{name}");
    let Some(v) = doc
        .get("variants")
        .and_then(|v| v.get(name))
        .and_then(|v| v.as_table())
        .cloned()
    else {
        return Ok(());
    };
    if let Some(r) = v.get("remove") {
        let arr = r.as_array().ok_or_else(|| {
            err(
                format!("{key}.remove"),
                "must be an array of \"nodes.NAME\" or \"couplings.NAME\" strings",
            )
        })?;
        for (i, item) in arr.iter().enumerate() {
            remove_one(doc, &format!("{key}.remove[{i}]"), item)?;
        }
    }
    if let Some(n) = v.get("nodes") {
        add_nodes(doc, &key, n)?;
    }
    if let Some(c) = v.get("couplings") {
        add_couplings(doc, &key, c)?;
    }
    Ok(())
}

/// A coupling's name in the case document: its `name`, else `DRIVER-RESPONDER`.
fn coupling_name(t: &toml::Value) -> String {
    let node = |k: &str| {
        t.get(k)
            .and_then(|v| v.as_str())
            .and_then(|v| v.split_once('.'))
            .map(|(n, _)| n.to_string())
            .unwrap_or_default()
    };
    t.get("name")
        .and_then(|v| v.as_str())
        .map(str::to_string)
        .unwrap_or_else(|| format!("{}-{}", node("driver"), node("responder")))
}

/// One entry `item` (at key path `k`) of a variant's `remove` list: the node or coupling it
/// names leaves the document.
fn remove_one(doc: &mut toml::Table, k: &str, item: &toml::Value) -> Result<(), ConfigError> {
    let not_a_name = || err(k, "must be a \"nodes.NAME\" or \"couplings.NAME\" string");
    let Some((table, what)) = item.as_str().and_then(|s| s.split_once('.')) else {
        return Err(not_a_name());
    };
    match table {
        "nodes" => {
            let nodes = doc.get_mut("nodes").and_then(|n| n.as_table_mut());
            if nodes.and_then(|n| n.remove(what)).is_none() {
                return Err(err(k, format!("the case has no node '{what}'")));
            }
        }
        "couplings" => {
            let list = doc.get_mut("couplings").and_then(|c| c.as_array_mut());
            let Some(list) = list else {
                return Err(err(k, "the case has no [[couplings]]"));
            };
            let before = list.len();
            list.retain(|c| coupling_name(c) != what);
            if list.len() == before {
                return Err(err(k, format!("the case has no coupling '{what}'")));
            }
        }
        _ => return Err(not_a_name()),
    }
    Ok(())
}

/// The variant's `[variants.NAME.nodes.X]` tables (`n`) added to the case's nodes; a name
/// the case already has is refused.
fn add_nodes(doc: &mut toml::Table, key: &str, n: &toml::Value) -> Result<(), ConfigError> {
    let add = n.as_table().ok_or_else(|| {
        err(
            format!("{key}.nodes"),
            "must be a table of [variants.NAME.nodes.X] tables",
        )
    })?;
    let nodes = doc
        .entry("nodes")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()))
        .as_table_mut()
        .ok_or_else(|| err("nodes", "must be a table"))?;
    for (node, body) in add {
        if nodes.contains_key(node) {
            return Err(err(
                format!("{key}.nodes.{node}"),
                "the case already has this node (remove it first: remove = [\"nodes.NAME\"])",
            ));
        }
        nodes.insert(node.clone(), body.clone());
    }
    Ok(())
}

/// The variant's `[[variants.NAME.couplings]]` entries (`c`) added to the case's
/// couplings; a name the case already has is refused.
fn add_couplings(doc: &mut toml::Table, key: &str, c: &toml::Value) -> Result<(), ConfigError> {
    let add = c.as_array().ok_or_else(|| {
        err(
            format!("{key}.couplings"),
            "must be an array of [[variants.NAME.couplings]] tables",
        )
    })?;
    let list = doc
        .entry("couplings")
        .or_insert_with(|| toml::Value::Array(Vec::new()))
        .as_array_mut()
        .ok_or_else(|| err("couplings", "must be an array of tables"))?;
    for (i, cp) in add.iter().enumerate() {
        let this = coupling_name(cp);
        if list.iter().any(|c| coupling_name(c) == this) {
            return Err(err(
                format!("{key}.couplings[{i}]"),
                format!("the case already has a coupling '{this}' (remove it first)"),
            ));
        }
        list.push(cp.clone());
    }
    Ok(())
}

/// `couplings.NAME.KEY=VALUE`: set a key of the `[[couplings]]` entry named NAME (its
/// `name`, or the default `driver-responder` node pair).
fn set_coupling(doc: &mut toml::Table, s: &str, rest: &str) -> Result<(), ConfigError> {
    let bad = |reason: String| ConfigError {
        key: format!("--set {s}"),
        reason,
    };
    let (name, kv) = rest
        .split_once('.')
        .ok_or_else(|| bad("must be couplings.NAME.KEY=VALUE".into()))?;
    let list = doc
        .get_mut("couplings")
        .and_then(|c| c.as_array_mut())
        .ok_or_else(|| bad("the case has no [[couplings]]".into()))?;
    let node_of = |t: &toml::Table, k: &str| -> String {
        t.get(k)
            .and_then(|v| v.as_str())
            .and_then(|v| v.split_once('.'))
            .map(|(n, _)| n.to_string())
            .unwrap_or_default()
    };
    let mut names = Vec::new();
    for c in list.iter_mut() {
        let Some(t) = c.as_table_mut() else { continue };
        let this = t
            .get("name")
            .and_then(|v| v.as_str())
            .map(str::to_string)
            .unwrap_or_else(|| format!("{}-{}", node_of(t, "driver"), node_of(t, "responder")));
        if this == name {
            return apply_sets(t, &[kv.to_string()]);
        }
        names.push(this);
    }
    Err(bad(format!(
        "no coupling named '{name}' (the case has {})",
        names.join(", ")
    )))
}

/// `model=NAME`, `solver=EXE` or `remote=BOOL` on a node's own table. A solver path that
/// exists from the working directory is made absolute (the case file's own paths are
/// relative to the case file).
fn set_node_key(node: &mut toml::Table, kv: &str) -> Result<(), ConfigError> {
    let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
    let (k, v) = (k.trim(), v.trim());
    let v = v.trim_matches('"');
    let value = match k {
        "remote" => toml::Value::Boolean(match v {
            "true" => true,
            "false" => false,
            _ => {
                return Err(ConfigError {
                    key: format!("--set {kv}"),
                    reason: "remote must be true or false".into(),
                });
            }
        }),
        "solver" if v.contains('/') && std::path::Path::new(v).exists() => {
            let abs = std::path::absolute(v).map_err(|e| ConfigError {
                key: format!("--set {kv}"),
                reason: e.to_string(),
            })?;
            toml::Value::String(abs.display().to_string())
        }
        _ if v.is_empty() => {
            return Err(ConfigError {
                key: format!("--set {kv}"),
                reason: format!("{k} needs a value"),
            });
        }
        _ => toml::Value::String(v.to_string()),
    };
    node.insert(k.to_string(), value);
    Ok(())
}

/// A node's `params = "FILE"` read into the table it names (relative to the case file), so
/// that `--set` can change it.
fn inline_params_file(
    params: &mut toml::Value,
    node: &str,
    case_dir: &std::path::Path,
) -> Result<(), ConfigError> {
    let Some(file) = params.as_str() else {
        return Ok(());
    };
    let t =
        super::validate::read_params_file(&case_dir.join(file), &format!("nodes.{node}.params"))?;
    *params = toml::Value::Table(t);
    Ok(())
}

/// Variant `name`'s structure applied to `doc`, and its `set` list, led by its output folder
/// beside the others' (`run.output` + `/NAME`) unless it says where.
fn variant_sets_placed(
    doc: &mut toml::Table,
    file: &CaseFile,
    name: &str,
) -> Result<Vec<String>, ConfigError> {
    let v = variant_sets(file, name)?;
    apply_variant_structure(doc, name)?;
    let mut all = Vec::new();
    if !v.iter().any(|s| {
        s.split_once('=')
            .is_some_and(|(k, _)| k.trim() == "run.output")
    }) {
        let base = doc
            .get("run")
            .and_then(|r| r.get("output"))
            .and_then(|o| o.as_str())
            .unwrap_or("out")
            .to_string();
        all.push(format!("run.output={:?}", format!("{base}/{name}")));
    }
    all.extend(v);
    Ok(all)
}

/// `--set s` on node `node` (`rest`: what follows `NODE.`): the node's own keys (`model`,
/// `solver`, `remote`) or one of its parameters, its params file read in first.
fn set_node(
    doc: &mut toml::Table,
    path: &std::path::Path,
    s: &str,
    node: &str,
    rest: &str,
) -> Result<(), ConfigError> {
    let names: Vec<String> = doc
        .get("nodes")
        .and_then(|n| n.as_table())
        .map(|t| t.keys().cloned().collect())
        .unwrap_or_default();
    let table = doc
        .get_mut("nodes")
        .and_then(|n| n.get_mut(node))
        .and_then(|n| n.as_table_mut())
        .ok_or_else(|| ConfigError {
            key: format!("--set {s}"),
            reason: super::resolved::unknown("node", node, names.iter().map(String::as_str)),
        })?;
    let key = rest.split_once('=').map_or(rest, |(k, _)| k).trim();
    if matches!(key, "model" | "solver" | "remote") {
        // The node itself: swap its model or its executable (a path as typed on the
        // command line, from the working directory, when it exists there).
        return set_node_key(table, rest);
    }
    // `NODE.params.KEY` reaches a parameter named like a node key; `NODE.KEY` any other.
    let rest = rest.strip_prefix("params.").unwrap_or(rest);
    let case_dir = path.parent().unwrap_or(std::path::Path::new("."));
    let params = table
        .entry("params")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    inline_params_file(params, node, case_dir)?;
    let t = params.as_table_mut().ok_or_else(|| ConfigError {
        key: format!("nodes.{node}.params"),
        reason: "must be a table or a file name".into(),
    })?;
    apply_sets(t, &[rest.to_string()])
}

/// `--set run.output=DIR` with a relative DIR as the absolute path from the working
/// directory (the case file's own `run.output` is relative to the case file); any other
/// setting as it is.
fn from_here(s: &str) -> String {
    let Some(v) = s
        .split_once('=')
        .filter(|(k, _)| k.trim() == "run.output")
        .map(|(_, v)| v.trim().trim_matches('"'))
    else {
        return s.to_string();
    };
    if v.is_empty() {
        return s.to_string(); // `run.output=` removes the key: the case file's default
    }
    let p = std::path::Path::new(v);
    match std::env::current_dir() {
        Ok(here) if p.is_relative() => {
            format!("run.output={:?}", here.join(p).display().to_string())
        }
        _ => s.to_string(),
    }
}

/// Apply variant `variant` (if any) of the typed case `file`, then `sets`, to its document
/// `doc` (`path`: the case file, which params files are relative to).
pub fn apply(
    doc: &mut toml::Table,
    file: &CaseFile,
    path: &std::path::Path,
    variant: Option<&str>,
    sets: &[String],
) -> Result<(), ConfigError> {
    let mut all: Vec<String> = Vec::new();
    if let Some(name) = variant {
        all = variant_sets_placed(doc, file, name)?;
    }
    // a path given on the command line is the working directory's, not the case file's
    all.extend(sets.iter().map(|s| from_here(s)));
    for s in &all {
        let (node, rest) = s.split_once('.').ok_or_else(|| ConfigError {
            key: format!("--set {s}"),
            reason: "must be NODE.KEY=VALUE, NODE.model=NAME, NODE.solver=EXE, run.KEY=VALUE or couplings.NAME.KEY=VALUE".into(),
        })?;
        if node == "run" && doc.get("nodes").is_none_or(|n| n.get("run").is_none()) {
            let t = doc
                .get_mut("run")
                .and_then(|r| r.as_table_mut())
                .ok_or_else(|| ConfigError {
                    key: "run".into(),
                    reason: "missing [run] table".into(),
                })?;
            apply_sets(t, &[rest.to_string()])?;
            continue;
        }
        if node == "couplings"
            && doc
                .get("nodes")
                .is_none_or(|n| n.get("couplings").is_none())
        {
            set_coupling(doc, s, rest)?;
            continue;
        }
        set_node(doc, path, s, node, rest)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::apply_sets;

    #[test]
    fn sets_add_nested_keys_and_an_empty_value_removes_one() {
        let mut t: toml::Table = toml::from_str("a = 1\n[b]\nc = 2\nd = \"x\"").unwrap_or_default();
        let sets = [
            "b.c=3".to_string(),
            "b.d=".to_string(),
            "a=".to_string(),
            "e.f=[1, 2]".to_string(),
            "missing.key=".to_string(),
        ];
        apply_sets(&mut t, &sets).expect("valid sets");
        let want: toml::Table = toml::from_str("[b]\nc = 3\n[e]\nf = [1, 2]").unwrap_or_default();
        assert_eq!(t, want);
    }
}
