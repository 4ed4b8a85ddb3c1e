//! `NODE --describe`: a node's description (or the parameter error, with its key path) as
//! one line of JSON on stdout, built without opening a device or a transport. The coordinator
//! validates every node of a case through it; PROTOCOL.md ("Node command line") is the contract.

use crate::message::InterfaceDescription;
use crate::solver::BoxedFactory;
use crate::solver::{BuildOptions, SolverError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

/// Exit code of `NODE --describe` for a bad parameter or model (the JSON names the key).
pub const EXIT_BAD_PARAMETER: i32 = 2;
/// Exit code of `NODE --describe` when building failed for another reason.
pub const EXIT_FAILED: i32 = 1;

/// What `NODE --describe` prints: exactly one of the two.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DescribeAnswer {
    Description(NodeDescriptionJson),
    Error(DescribeError),
}

/// The node as it would join a run with these parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NodeDescriptionJson {
    /// The executable's own name (`solid-node`, ...).
    pub binary: String,
    pub model: String,
    pub units: String,
    /// The solver's stable time step before coupling (s); null when it has none.
    pub stable_dt: Option<f64>,
    pub interfaces: Vec<InterfaceDescription>,
    pub warnings: Vec<String>,
    /// Where its explicit integrator does not choose its own step: the largest stable
    /// window, and when that holds (absent: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub window_limits: Vec<crate::solver::WindowLimit>,
    /// Each interface's point positions (m), by interface name, for interfaces of at most
    /// [`MAX_DESCRIBED_POINTS`] points (absent: none given): the coordinator refuses coupled
    /// points that do not coincide before anything starts.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub positions: BTreeMap<String, Vec<[f64; 3]>>,
}

/// The most points of an interface whose positions a description carries: enough for every
/// point-to-point interface, while a large immersed point cloud stays out of the JSON.
pub const MAX_DESCRIBED_POINTS: usize = 10_000;

/// Why the node refused: `key` is relative to the node (`model`, `params.young`,
/// `params.materials.air.gamma`; `params` for the table as a whole), null when the failure
/// is not a parameter's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DescribeError {
    pub key: Option<String>,
    pub reason: String,
}

/// The node-relative key of a factory's config error (`model`, or a key inside `params`).
pub fn node_key(key: &str) -> String {
    if key == "model" || key == "params" || key.starts_with("params.") {
        key.to_string()
    } else {
        format!("params.{key}")
    }
}

/// Read the params (a file, or stdin for `None` / `-`), build the solver describe-only and
/// answer. Returns the answer and the exit code; nothing is printed here.
pub fn describe(
    binary: &str,
    factory: BoxedFactory,
    model: &str,
    params: Option<&Path>,
) -> (DescribeAnswer, i32) {
    let bad = |key: &str, reason: String| {
        (
            DescribeAnswer::Error(DescribeError {
                key: Some(key.to_string()),
                reason,
            }),
            EXIT_BAD_PARAMETER,
        )
    };
    let text = match params {
        Some(p) if p != Path::new("-") => match std::fs::read_to_string(p) {
            Ok(t) => t,
            Err(e) => return bad("params", format!("cannot read {}: {e}", p.display())),
        },
        _ => {
            let mut t = String::new();
            if let Err(e) = std::io::stdin().read_to_string(&mut t) {
                return bad("params", format!("cannot read standard input: {e}"));
            }
            t
        }
    };
    let table: toml::Table = match toml::from_str(&text) {
        Ok(t) => t,
        Err(e) => {
            let line = e
                .span()
                .map(|s| text[..s.start.min(text.len())].lines().count().max(1));
            let at = line.map(|l| format!(" (line {l})")).unwrap_or_default();
            return bad("params", format!("not valid TOML: {}{at}", e.message()));
        }
    };
    match factory(model, &table, &BuildOptions::DESCRIBE) {
        Ok(s) => {
            let d = s.describe();
            let dt = s.stable_dt();
            let positions = d
                .interfaces
                .iter()
                .filter(|i| i.points <= MAX_DESCRIBED_POINTS)
                .filter_map(|i| Some((i.name.clone(), s.interface(&i.name).ok()?.positions)))
                .collect();
            let json = NodeDescriptionJson {
                binary: binary.to_string(),
                model: d.model,
                units: d.units,
                stable_dt: dt.is_finite().then_some(dt),
                interfaces: d
                    .interfaces
                    .into_iter()
                    .map(|i| InterfaceDescription {
                        name: i.name,
                        points: i.points as u64,
                        provides: i.provides,
                        accepts: i.accepts,
                    })
                    .collect(),
                warnings: s.warnings(),
                window_limits: s.window_limits(),
                positions,
            };
            (DescribeAnswer::Description(json), 0)
        }
        Err(SolverError::Config { key, reason }) => bad(&node_key(&key), reason),
        Err(e) => (
            DescribeAnswer::Error(DescribeError {
                key: None,
                reason: e.to_string(),
            }),
            EXIT_FAILED,
        ),
    }
}

/// `NODE --describe` in a node's `main`: print the answer (JSON on stdout; a readable line on
/// stderr for an error, prefixed `nodes.NAME.` when `node` is known) and return the exit code.
pub fn describe_main(
    binary: &str,
    factory: BoxedFactory,
    model: &str,
    params: Option<&Path>,
    node: Option<&str>,
) -> i32 {
    let (answer, code) = describe(binary, factory, model, params);
    if let DescribeAnswer::Error(e) = &answer {
        let at = match (node, &e.key) {
            (Some(n), Some(k)) => format!("nodes.{n}.{k}: "),
            (None, Some(k)) => format!("{k}: "),
            (_, None) => String::new(),
        };
        crate::log_line!("{binary}: {at}{}", e.reason);
    }
    match serde_json::to_string(&answer) {
        Ok(s) => println!("{s}"),
        Err(e) => {
            crate::log_line!("{binary}: cannot encode the description: {e}");
            return EXIT_FAILED;
        }
    }
    code
}

/// Read what a node printed for `--describe`: the last line of stdout that is a JSON object.
pub fn parse_answer(stdout: &str) -> Option<DescribeAnswer> {
    stdout
        .lines()
        .rev()
        .map(str::trim)
        .filter(|l| l.starts_with('{'))
        .find_map(|l| serde_json::from_str(l).ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_round_trip_through_one_json_line() {
        let a = DescribeAnswer::Error(DescribeError {
            key: Some("params.young".into()),
            reason: "invalid type".into(),
        });
        let s = serde_json::to_string(&a).unwrap_or_default();
        assert_eq!(
            s,
            r#"{"error":{"key":"params.young","reason":"invalid type"}}"#
        );
        assert_eq!(parse_answer(&format!("noise\n{s}\n")), Some(a));
        assert_eq!(parse_answer("no json here"), None);
    }

    #[test]
    fn keys_are_made_node_relative() {
        assert_eq!(node_key("model"), "model");
        assert_eq!(node_key("young"), "params.young");
        assert_eq!(
            node_key("materials.air.gamma"),
            "params.materials.air.gamma"
        );
        assert_eq!(node_key("params"), "params");
    }
}
