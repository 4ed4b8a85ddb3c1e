//! The one decoder of a node's parameter table (`[nodes.NAME.params]`): serde with the path
//! of the offending key, so every unknown, missing or mistyped key is named in full at any
//! depth (`materials.air.gamma: invalid type: string "x", expected f64`).

use crate::solver::{SolverError, SolverResult};
use serde::de::DeserializeOwned;
use std::sync::OnceLock;

/// The parameter schemas of a node binary's models: JSON Schemas derived (schemars) from the
/// same types [`decode`] fills, so what `cosim params MODEL` lists is what validation
/// accepts. A node registers its model table ([`crate::registry`]) in `main` before
/// [`crate::participant::node_main`]; `NODE --schema` prints the models, `NODE --schema
/// --model M` the model's schema.
#[derive(Clone, Copy)]
pub struct Schemas {
    pub models: &'static [crate::registry::Model],
}

static SCHEMAS: OnceLock<Schemas> = OnceLock::new();

/// Register this binary's parameter schemas (the first registration holds).
pub fn register_schemas(s: Schemas) {
    let _ = SCHEMAS.set(s);
}

/// The registered schemas, if the binary registered any.
pub fn schemas() -> Option<&'static Schemas> {
    SCHEMAS.get()
}

/// `NODE --schema [--model M]`: prints `{"models": [...]}` or the model's JSON Schema on
/// stdout; exit 0, or 2 for an unknown model or a binary without schemas.
pub fn schema_main(binary: &str, model: Option<&str>) -> i32 {
    let Some(s) = schemas() else {
        crate::log_line!("{binary}: this node publishes no parameter schema");
        return 2;
    };
    let names = crate::registry::names(s.models);
    let doc = match model {
        None => serde_json::json!({ "node": binary, "models": names }),
        Some(m) => match crate::registry::schema(s.models, m) {
            Some(v) => v,
            None => {
                crate::log_line!(
                    "{binary}: unknown model '{m}' (this node has: {})",
                    names.join(", ")
                );
                return 2;
            }
        },
    };
    println!("{doc}");
    0
}

/// Decode `params` into `T`; an error names the key path inside `params` and the reason.
pub fn decode<T: DeserializeOwned>(params: &toml::Table) -> SolverResult<T> {
    decode_keyed(params).map_err(|(key, reason)| SolverError::config(key, reason))
}

/// Decode any TOML table into `T` (a node's parameters, the coordinator's case file): on
/// failure, the full key path of the offending key (`a.b[2].c`) and a readable reason.
pub fn decode_keyed<T: DeserializeOwned>(table: &toml::Table) -> Result<T, (String, String)> {
    serde_path_to_error::deserialize(table.clone()).map_err(|e| {
        let mut path = e.path().to_string();
        let message = e.inner().message().to_string();
        if let Some(inner) = inside_tagged(table, &path, &message) {
            path = inner;
        }
        explain(&path, &message)
    })
}

/// Inside an internally tagged enum (`#[serde(tag = "kind")]`: `damage = { kind = ...,
/// critical_stretch = ... }`) serde reads the table as buffered content, and the error's
/// path stops at the table. The key is found again from the message: an unknown key names
/// itself; a mistyped one is the only key of that table whose value is what serde calls the
/// unexpected value (`invalid type: string "a", expected f64`). `None` when the path already
/// ends at the key, or the key cannot be told.
fn inside_tagged(params: &toml::Table, path: &str, message: &str) -> Option<String> {
    let table = match lookup(params, path)? {
        toml::Value::Table(t) => t,
        _ => return None,
    };
    let join = |k: &str| {
        if path == "." || path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    if let Some(field) = message
        .strip_prefix("unknown field `")
        .and_then(|r| r.split_once('`'))
        .map(|(f, _)| f)
    {
        return table.contains_key(field).then(|| join(field));
    }
    let unexpected = message
        .strip_prefix("invalid type: ")
        .or_else(|| message.strip_prefix("invalid value: "))?
        .split_once(", expected ")?
        .0;
    let mut hits = table
        .iter()
        .filter(|(_, v)| described(v).is_some_and(|d| d == unexpected));
    let (k, _) = hits.next()?;
    hits.next().is_none().then(|| join(k))
}

/// The value at a serde path (`a.b[2].c`) inside `params`.
fn lookup<'a>(params: &'a toml::Table, path: &str) -> Option<&'a toml::Value> {
    if path == "." || path.is_empty() {
        return None;
    }
    let mut cur: Option<&toml::Value> = None;
    for part in path.split('.') {
        let (name, idx) = match part.split_once('[') {
            Some((n, rest)) => (n, Some(rest)),
            None => (part, None),
        };
        cur = Some(match cur {
            None => params.get(name)?,
            Some(toml::Value::Table(t)) => t.get(name)?,
            Some(_) => return None,
        });
        if let Some(rest) = idx {
            for i in rest.split('[') {
                let i: usize = i.trim_end_matches(']').parse().ok()?;
                cur = match cur {
                    Some(toml::Value::Array(a)) => a.get(i),
                    _ => None,
                };
            }
        }
    }
    cur
}

/// How serde's `Unexpected` describes a TOML scalar (`string "a"`, `integer `3``, ...).
fn described(v: &toml::Value) -> Option<String> {
    Some(match v {
        toml::Value::String(s) => format!("string {s:?}"),
        toml::Value::Integer(i) => format!("integer `{i}`"),
        toml::Value::Float(f) => {
            // serde writes a float with a decimal point (`1000000000.0`)
            let t = f.to_string();
            let point = t.contains(['.', 'e', 'E']) || !f.is_finite();
            format!("floating point `{t}{}`", if point { "" } else { ".0" })
        }
        toml::Value::Boolean(b) => format!("boolean `{b}`"),
        toml::Value::Array(_) => "sequence".to_string(),
        toml::Value::Table(_) => "map".to_string(),
        toml::Value::Datetime(_) => return None,
    })
}

/// The closest of `known` to `name` by edit distance (a swap of two letters counts one),
/// where it is close enough to be a typo (at most a third of the name's length, and 3).
pub fn did_you_mean<'a>(name: &str, known: impl Iterator<Item = &'a str>) -> Option<&'a str> {
    let limit = (name.chars().count() / 3).clamp(1, 3);
    known
        .map(|k| (strsim::osa_distance(name, k), k))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d)
        .map(|(_, k)| k)
}

/// The full key and a readable reason from serde's path and message. serde reports a missing
/// field at its parent; the key named is the field itself. An unknown key is answered with
/// the nearest known one.
fn explain(path: &str, message: &str) -> (String, String) {
    let join = |k: &str| {
        if path == "." || path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    if let Some(field) = message
        .strip_prefix("missing field `")
        .and_then(|r| r.strip_suffix('`'))
    {
        return (join(field), "missing".to_string());
    }
    let key = if path == "." || path.is_empty() {
        "params".to_string()
    } else {
        path.to_string()
    };
    if let Some(rest) = message.strip_prefix("unknown field `")
        && let Some((field, expected)) = rest.split_once("`, expected ")
    {
        let expected = expected.replace('`', "").replace("one of ", "");
        let names = expected
            .split([',', ' '])
            .filter(|w| !w.is_empty() && *w != "or");
        let hint = did_you_mean(field, names)
            .map(|k| format!("did you mean '{k}'? "))
            .unwrap_or_default();
        return (
            key,
            format!("unknown key ({hint}expected one of: {expected})"),
        );
    }
    if let Some(rest) = message.strip_prefix("unknown field `")
        && rest.contains("there are no fields")
    {
        return (key, "unknown key (this table takes no keys)".to_string());
    }
    (key, message.trim().replace('\n', " "))
}

/// Refuse keys of a table that do not apply to the choice made in it (e.g. `p_inf` on an
/// ideal gas): `given` are (key, present) pairs, `applies` the keys the choice takes.
pub fn refuse_inapplicable(
    prefix: &str,
    choice: &str,
    given: &[(&str, bool)],
    applies: &[&str],
) -> SolverResult<()> {
    for (k, present) in given {
        if *present && !applies.contains(k) {
            return Err(SolverError::config(
                format!("{prefix}{k}"),
                if applies.is_empty() {
                    format!("does not apply to {choice}")
                } else {
                    format!(
                        "does not apply to {choice} (it takes: {})",
                        applies.join(", ")
                    )
                },
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::decode;
    use crate::solver::SolverError;
    use serde::Deserialize;
    use std::collections::BTreeMap;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Material {
        eos: String,
        gamma: Option<f64>,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Iface {
        name: String,
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Params {
        young: f64,
        #[serde(default)]
        materials: BTreeMap<String, Material>,
        #[serde(default)]
        interfaces: Vec<Iface>,
    }

    /// The key and reason of the config error `text` must give when decoded as `T`.
    fn refusal<T: serde::de::DeserializeOwned + std::fmt::Debug>(text: &str) -> (String, String) {
        let t: toml::Table = toml::from_str(text).unwrap_or_default();
        match decode::<T>(&t) {
            Err(SolverError::Config { key, reason }) => (key, reason),
            other => panic!("expected a config error for {text:?}, got {other:?}"),
        }
    }

    fn err_of(text: &str) -> (String, String) {
        refusal::<Params>(text)
    }

    #[test]
    fn every_kind_of_bad_key_is_named_in_full() {
        let (k, r) = err_of("young = \"abc\"");
        assert_eq!(k, "young");
        assert!(r.contains("invalid type"), "{r}");
        let (k, r) = err_of("young = 1.0\n[materials.air]\neos = \"ideal\"\ngama = 1.4");
        assert_eq!(k, "materials.air.gama");
        assert_eq!(
            r,
            "unknown key (did you mean 'gamma'? expected one of: eos or gamma)"
        );
        let (k, r) = err_of("young = 1.0\n[materials.air]\ngamma = 1.4");
        assert_eq!((k.as_str(), r.as_str()), ("materials.air.eos", "missing"));
        let (k, _) = err_of("young = 1.0\n[[interfaces]]\nname = 3");
        assert_eq!(k, "interfaces[0].name");
        let (k, r) = err_of("yung = 1.0");
        assert_eq!(k, "yung");
        assert!(
            r.starts_with("unknown key (did you mean 'young'? expected one of: young, "),
            "{r}"
        );
        let (k, r) = err_of("");
        assert_eq!((k.as_str(), r.as_str()), ("young", "missing"));
    }

    #[derive(Debug, Deserialize)]
    #[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
    #[allow(dead_code)]
    enum Damage {
        None,
        CriticalStretch {
            critical_stretch: f64,
            scale: Option<u32>,
        },
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Tagged {
        damage: Damage,
        #[serde(default)]
        bodies: Vec<Damage>,
    }

    fn tagged_err(text: &str) -> (String, String) {
        refusal::<Tagged>(text)
    }

    #[test]
    fn keys_inside_tagged_enums_are_named_in_full() {
        let d = "damage = { kind = \"critical_stretch\", ";
        let (k, r) = tagged_err(&format!("{d}critical_strech = 0.01 }}"));
        assert_eq!(k, "damage.critical_strech");
        assert!(r.starts_with("unknown key"), "{r}");
        let (k, r) = tagged_err(&format!("{d}critical_stretch = \"a\" }}"));
        assert_eq!(k, "damage.critical_stretch");
        assert!(r.contains("invalid type"), "{r}");
        let (k, _) = tagged_err(&format!("{d}critical_stretch = 1e9, scale = 2.0 }}"));
        assert_eq!(k, "damage.scale");
        let (k, _) = tagged_err(&format!("{d}critical_stretch = 1, scale = true }}"));
        assert_eq!(k, "damage.scale");
        let (k, r) = tagged_err(&format!("{d}scale = 1 }}"));
        assert_eq!(
            (k.as_str(), r.as_str()),
            ("damage.critical_stretch", "missing")
        );
        let (k, _) = tagged_err(
            "damage = { kind = \"none\" }\nbodies = [{ kind = \"none\" }, { kind = \"critical_stretch\", critical_stretch = 1.0, x = 1 }]",
        );
        assert_eq!(k, "bodies[1].x");
    }
}
