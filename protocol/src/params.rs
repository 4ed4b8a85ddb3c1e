//! The one decoder of a node's parameter table (`[nodes.NAME.params]`): serde with the path
//! of the offending key, so every unknown, missing or mistyped key is named in full at any
//! depth (`materials.air.gamma: invalid type: string "x", expected f64`).

use crate::solver::{SolverError, SolverResult};
use serde::de::DeserializeOwned;

/// Decode `params` into `T`; an error names the key path inside `params` and the reason.
pub fn decode<T: DeserializeOwned>(params: &toml::Table) -> SolverResult<T> {
    serde_path_to_error::deserialize(params.clone()).map_err(|e| {
        let path = e.path().to_string();
        let (key, reason) = explain(&path, e.inner().message());
        SolverError::config(key, reason)
    })
}

/// The full key and a readable reason from serde's path and message. serde reports a missing
/// field at its parent; the key named is the field itself.
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
        && let Some((_, expected)) = rest.split_once("`, expected ")
    {
        let expected = expected.replace('`', "").replace("one of ", "");
        return (key, format!("unknown key (expected one of: {expected})"));
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

    fn err_of(text: &str) -> (String, String) {
        let t: toml::Table = toml::from_str(text).unwrap_or_default();
        match decode::<Params>(&t) {
            Err(SolverError::Config { key, reason }) => (key, reason),
            other => panic!("expected a config error for {text:?}, got {other:?}"),
        }
    }

    #[test]
    fn every_kind_of_bad_key_is_named_in_full() {
        let (k, r) = err_of("young = \"abc\"");
        assert_eq!(k, "young");
        assert!(r.contains("invalid type"), "{r}");
        let (k, r) = err_of("young = 1.0\n[materials.air]\neos = \"ideal\"\ngama = 1.4");
        assert_eq!(k, "materials.air.gama");
        assert_eq!(r, "unknown key (expected one of: eos or gamma)");
        let (k, r) = err_of("young = 1.0\n[materials.air]\ngamma = 1.4");
        assert_eq!((k.as_str(), r.as_str()), ("materials.air.eos", "missing"));
        let (k, _) = err_of("young = 1.0\n[[interfaces]]\nname = 3");
        assert_eq!(k, "interfaces[0].name");
        let (k, r) = err_of("yung = 1.0");
        assert_eq!(k, "yung");
        assert!(
            r.starts_with("unknown key (expected one of: young, "),
            "{r}"
        );
        let (k, r) = err_of("");
        assert_eq!((k.as_str(), r.as_str()), ("young", "missing"));
    }
}
