//! The case file as written: serde types for every table and key, nothing resolved and no
//! I/O. An unknown, missing or mistyped key anywhere is refused here with its full path
//! (`couplings[1].decouple_whn: unknown key (expected one of: ...)`); what the values mean
//! and whether they fit together is [`super::validate`]'s. The same types give the JSON
//! Schema of case files (`cosim schema`, `docs/schema/case.json`), so what an editor
//! completes is what a run accepts.

use super::resolved::{ConfigError, err};
use protocol::CouplingKind;
use schemars::JsonSchema;
use serde::Deserialize;
use std::collections::BTreeMap;

/// A whole case file.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(title = "cosim case file")]
pub struct CaseFile {
    /// The run: its end, window, schedule, transport, output and guards.
    pub run: RunSection,
    /// The nodes, one `[nodes.NAME]` table each (NAME: 1–32 characters of A–Z a–z 0–9 _ -).
    pub nodes: BTreeMap<String, NodeSection>,
    /// The couplings between node interfaces, one `[[couplings]]` table each.
    #[serde(default)]
    pub couplings: Vec<CouplingSection>,
    /// Named variants of the case (`cosim run --variant NAME`).
    #[serde(default)]
    pub variants: BTreeMap<String, VariantSection>,
}

/// `[run]`.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RunSection {
    /// The run's name (1–32 characters of A–Z a–z 0–9 _ -); default "run".
    pub name: Option<String>,
    /// Simulated time at which the run ends, s (> 0).
    pub end_time: f64,
    /// The synchronisation window, s (> 0, ≤ end_time).
    pub window: f64,
    /// "serial" (default): a responder steps a window after its driver, on the driver's
    /// motion of that window; "parallel": every node steps at once on the last window's
    /// inputs.
    pub schedule: Option<ScheduleName>,
    /// "shm" (default: shared memory on this host) or "zenoh" (the network).
    pub transport: Option<TransportName>,
    /// Output directory, relative to the case file's folder (as every path a case file names);
    /// default "out". `cosim run --output DIR` and `--set run.output=DIR` are relative to the
    /// working directory.
    pub output: Option<String>,
    /// Write node output (VTK) every this many windows; 0 (default) = only at the end.
    pub output_every: Option<u64>,
    /// Heartbeat period of every node, ms (10–60000; default 200).
    pub heartbeat_ms: Option<u64>,
    /// A node silent for this long is declared hung, s (more than two heartbeats; default 3).
    pub heartbeat_timeout: Option<f64>,
    /// A window in which every running node has waited this long for a peer's input is
    /// stopped as a deadlock, s (more than heartbeat_timeout; default 30).
    pub stall_timeout: Option<f64>,
    /// zenoh endpoint the coordinator listens on (several hosts: a routable address);
    /// default "tcp/127.0.0.1:0".
    pub listen: Option<String>,
    /// How long the coordinator waits for its remote nodes to join, s (default 300).
    pub join_timeout: Option<f64>,
    /// How long a launched node may take from its launch to its first message, s
    /// (default 60).
    pub start_timeout: Option<f64>,
    /// Record the coupling fields of every this many windows only (default 1 = all).
    pub record_every: Option<u64>,
    /// Checkpoint every node and the coordinator every this many windows (default 0 =
    /// never); `cosim restart` continues from the last complete one.
    pub checkpoint_every: Option<u64>,
    /// Field pictures drawn when the run ends: "end" (default), "frames" or "none".
    pub pictures: Option<PicturesName>,
    /// Divergence guard: a run whose total energy exceeds this multiple of its initial
    /// energy plus the external work (plus energy_floor) is stopped as diverged; > 1, or 0
    /// to turn the bound off (non-finite values still stop a run).
    pub energy_bound: Option<f64>,
    /// Divergence guard: energy added to the bound, J (≥ 0).
    pub energy_floor: Option<f64>,
    /// Balance warnings: how large the momentum and energy residuals may grow before the
    /// run ends with a warning (its last line and summary.json `warnings`).
    pub balance: Option<BalanceSection>,
    /// Scalars of the nodes' last reports to print after the run's line, as "NODE.SCALAR"
    /// (e.g. "gas.bubble.first_speed", or an energy such as "tube.kinetic_energy"); they are
    /// in summary.json whatever this says.
    pub print: Option<Vec<String>>,
}

/// `[run.balance]`: thresholds of the balance warnings, as shares of the residuals' scales.
#[derive(Debug, Clone, Default, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BalanceSection {
    /// The largest momentum residual, as a share of the larger of the largest impulse any
    /// node saw and the largest gross momentum (default 1e-6; a booking that is right stays
    /// near round-off).
    pub momentum: Option<f64>,
    /// The largest energy residual, created or dissipated, as a share of the largest energy
    /// or work of the run (default 0.05).
    pub energy: Option<f64>,
}

/// `run.schedule`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum ScheduleName {
    Serial,
    Parallel,
}

/// `run.transport`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum TransportName {
    Shm,
    Zenoh,
}

/// `run.pictures`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum PicturesName {
    End,
    Frames,
    None,
}

/// `[nodes.NAME]`.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NodeSection {
    /// The node executable: a name beside `cosim` (solid-node, fluid-node,
    /// macro-shell-node, meso-joint-node) or a path relative to the case file.
    pub solver: String,
    /// The model the executable runs (`cosim params` lists the built-in ones).
    pub model: String,
    /// The model's parameters: a table, or the name of a TOML file holding it (relative to
    /// the case file). `cosim params MODEL` lists them.
    #[schemars(with = "ParamsSchema")]
    pub params: Option<toml::Value>,
    /// The node is started by hand on another host (`NODE --join`); default false.
    pub remote: Option<bool>,
}

/// What `params` may be, for the schema (the value is checked where it is read).
#[derive(JsonSchema)]
#[serde(untagged)]
#[allow(dead_code)]
enum ParamsSchema {
    Table(serde_json::Map<String, serde_json::Value>),
    File(String),
}

/// `[[couplings]]`.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CouplingSection {
    /// The coupling's name (1–32 characters of A–Z a–z 0–9 _ -); default
    /// "DRIVERNODE-RESPONDERNODE".
    pub name: Option<String>,
    /// "kinematic" (the driver's motion drives the responder, whose interface force acts
    /// back), "immersed" (a solid immersed in a fluid grid), "lagrange" (subdomains tied
    /// by interface multipliers the coordinator solves) or "overlap" (a fine patch in place
    /// of a region of a coarse mesh, its boundary layer following the mesh).
    #[schemars(with = "KindSchema")]
    pub kind: CouplingKind,
    /// The driving side, "NODE.INTERFACE" (kinematic, immersed and overlap).
    pub driver: Option<String>,
    /// The responding side, "NODE.INTERFACE" (kinematic, immersed and overlap).
    pub responder: Option<String>,
    /// Fields the driver sends each window (default: the scheme's).
    pub driver_fields: Option<Vec<String>>,
    /// Fields the responder sends each window and at set-up (default: the scheme's).
    pub responder_fields: Option<Vec<String>>,
    /// Immersed: end the coupling at this time, s; the solid goes on alone.
    pub decouple_at: Option<f64>,
    /// Immersed: end the coupling when a node's reported quantity reaches a level,
    /// "NODE.QUANTITY >= LEVEL".
    pub decouple_when: Option<String>,
    /// Lagrange: every subdomain, "NODE.INTERFACE", two or more.
    pub sides: Option<Vec<String>>,
    /// Lagrange: the interface method, "gs4" (default), "gc" or "ph".
    #[schemars(extend("enum" = ["gs4", "gc", "ph"]))]
    pub method: Option<String>,
    /// Kinematic: how far apart matched points of the two sides may lie, as a fraction of
    /// the interface's point spacing (> 0; default 1e-3).
    pub point_tolerance: Option<f64>,
}

/// `couplings[i].kind`, for the schema.
#[derive(JsonSchema)]
#[serde(rename_all = "lowercase")]
#[allow(dead_code)]
enum KindSchema {
    Kinematic,
    Immersed,
    Lagrange,
    Overlap,
}

/// `[variants.NAME]`: what the variant changes, applied in this order: `remove`, the nodes
/// and couplings it adds, then `set`.
#[derive(Debug, Clone, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VariantSection {
    /// One line saying what the variant is for (`cosim validate` lists it).
    pub description: Option<String>,
    /// Settings: "NODE.KEY=VALUE", "NODE.model=NAME", "NODE.solver=EXE", "run.KEY=VALUE"
    /// or "couplings.NAME.KEY=VALUE".
    pub set: Option<Vec<String>>,
    /// Nodes and couplings to drop: "nodes.NAME", "couplings.NAME".
    pub remove: Option<Vec<String>>,
    /// Nodes to add, as in the case's own `[nodes]`.
    pub nodes: Option<BTreeMap<String, NodeSection>>,
    /// Couplings to add, as in the case's own `[[couplings]]`.
    pub couplings: Option<Vec<CouplingSection>>,
}

/// Read a case file's text: its TOML document (what variants and `--set` edit) and the
/// typed case. A TOML syntax error is reported by the key it is at and its line.
pub fn read(text: &str) -> Result<(toml::Table, CaseFile), ConfigError> {
    let doc: toml::Table = toml::from_str(text).map_err(|e| {
        let start = e.span().map(|s| s.start.min(text.len())).unwrap_or(0);
        let line = text[..start].lines().count().max(1);
        match key_at(text, start) {
            Some(k) => err(k, format!("{} (line {line})", e.message())),
            None => err(
                format!("line {line}"),
                format!("not valid TOML: {}", e.message()),
            ),
        }
    })?;
    let case = typed(&doc)?;
    Ok((doc, case))
}

/// The typed case of a TOML document, each variant's `set` list of the form it takes.
pub fn typed(doc: &toml::Table) -> Result<CaseFile, ConfigError> {
    let file: CaseFile =
        protocol::params::decode_keyed(doc).map_err(|(key, reason)| err(key, reason))?;
    for (name, v) in &file.variants {
        if let Some(set) = &v.set {
            check_set_form(set, &format!("variants.{name}.set"))?;
        }
    }
    Ok(file)
}

/// Check that every entry of a `set` list at `key` reads `NODE.KEY=VALUE`, `run.KEY=VALUE`
/// or `couplings.NAME.KEY=VALUE`.
pub fn check_set_form(set: &[String], key: &str) -> Result<(), ConfigError> {
    for (i, s) in set.iter().enumerate() {
        if !(s.contains('=') && s.split('=').next().is_some_and(|k| k.contains('.'))) {
            return Err(err(
                format!("{key}[{i}]"),
                "must be a \"NODE.KEY=VALUE\", \"run.KEY=VALUE\" or \"couplings.NAME.KEY=VALUE\" string",
            ));
        }
    }
    Ok(())
}

/// The JSON Schema of case files, derived from the types above.
pub fn schema() -> serde_json::Value {
    let mut s = serde_json::to_value(schemars::schema_for!(CaseFile)).unwrap_or_default();
    if let Some(o) = s.as_object_mut() {
        o.insert(
            "description".into(),
            "A cosim case file (TOML): the run, its nodes, their couplings and named variants. Generated by `cosim schema` from the types cosim reads the case into.".into(),
        );
    }
    s
}

/// The key path a TOML error points at (the table header, or `table.key` of the line), so a
/// syntax-level error such as a duplicate table is still reported by key.
fn key_at(text: &str, pos: usize) -> Option<String> {
    let line_start = text[..pos].rfind('\n').map(|i| i + 1).unwrap_or(0);
    let line = text[line_start..].lines().next()?.trim();
    let header = |l: &str| {
        l.trim_start_matches('[')
            .trim_end_matches(']')
            .trim()
            .to_string()
    };
    if line.starts_with('[') {
        return Some(header(line));
    }
    let key = line.split('=').next()?.trim();
    if key.is_empty() {
        return None;
    }
    let table = text[..line_start]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .map(header);
    Some(match table {
        Some(t) => format!("{t}.{key}"),
        None => key.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::read;

    const GOOD: &str = "[run]\nend_time = 1e-3\nwindow = 1e-5\n[nodes.a]\nsolver = \"solid-node\"\nmodel = \"bar-1d\"\n";

    fn refused(text: &str) -> (String, String) {
        match read(text) {
            Err(e) => (e.key, e.reason),
            Ok(_) => panic!("accepted: {text}"),
        }
    }

    #[test]
    fn an_unknown_key_anywhere_is_named_in_full() {
        assert!(read(GOOD).is_ok());
        let (k, r) = refused(&format!(
            "{GOOD}[[couplings]]\nkind = \"kinematic\"\ndecouple_whn = \"a.x >= 1\"\n"
        ));
        assert_eq!(k, "couplings[0].decouple_whn");
        assert!(
            r.starts_with("unknown key (did you mean 'decouple_when'? expected one of: "),
            "{r}"
        );
        let (k, _) = refused(&GOOD.replace("window", "windw"));
        assert_eq!(k, "run.windw");
        let (k, _) = refused(&format!("{GOOD}remot = true\n"));
        assert_eq!(k, "nodes.a.remot");
        let (k, _) = refused(&format!(
            "{GOOD}[variants.v]\nset = []\n[variants.v.nodes.b]\nsolver = \"x\"\nmodel = \"y\"\nparms = {{}}\n"
        ));
        assert_eq!(k, "variants.v.nodes.b.parms");
        let (k, _) = refused(&format!("{GOOD}[extra]\n"));
        assert_eq!(k, "extra");
    }

    #[test]
    fn a_wrong_type_or_a_missing_key_is_named() {
        let (k, r) = refused(&GOOD.replace("1e-5", "\"short\""));
        assert_eq!(k, "run.window");
        assert!(r.contains("invalid type"), "{r}");
        let (k, r) = refused(&GOOD.replace("model = \"bar-1d\"\n", ""));
        assert_eq!((k.as_str(), r.as_str()), ("nodes.a.model", "missing"));
        let (k, r) = refused(&format!("{GOOD}[[couplings]]\nkind = \"glued\"\n"));
        assert_eq!(k, "couplings[0].kind");
        assert!(r.contains("kinematic"), "{r}");
        let (k, _) = refused(&GOOD.replace("[run]\n", "[run]\nschedule = \"fast\"\n"));
        assert_eq!(k, "run.schedule");
        let (k, _) = refused(&GOOD.replace("[run]\n", "[run]\noutput_every = -1\n"));
        assert_eq!(k, "run.output_every");
        let (k, r) = refused("[nodes.a]\nsolver = \"s\"\nmodel = \"m\"\n");
        assert_eq!((k.as_str(), r.as_str()), ("run", "missing"));
    }

    #[test]
    fn a_syntax_error_names_its_table_and_line() {
        let (k, r) = refused(&format!("{GOOD}[nodes.a]\n"));
        assert_eq!(k, "nodes.a");
        assert!(r.contains("line 7"), "{r}");
    }
}
