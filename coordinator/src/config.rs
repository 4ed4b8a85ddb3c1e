//! Case files (docs/architecture.md): parse, then validate everything that can be checked before
//! any process starts. Every error names the key path and the reason, e.g.
//! `run.window: must be > 0 and ≤ run.end_time (0.001), got 0`.

use protocol::CouplingKind;
use protocol::scheme;
use protocol::transport::TransportKind;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A configuration error: the key path and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key}: {reason}")]
pub struct ConfigError {
    pub key: String,
    pub reason: String,
}

fn err(key: impl Into<String>, reason: impl Into<String>) -> ConfigError {
    ConfigError {
        key: key.into(),
        reason: reason.into(),
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Schedule {
    Serial,
    Parallel,
}

#[derive(Debug, Clone)]
pub struct RunConfig {
    pub name: String,
    pub end_time: f64,
    pub window: f64,
    pub schedule: Schedule,
    pub transport: TransportKind,
    /// Output directory (relative paths are taken from the working directory).
    pub output: PathBuf,
    /// Write node output (VTK) every this many windows; 0 = only at the end.
    pub output_every: u64,
    pub heartbeat_ms: u64,
    /// A node silent for this long is declared hung (s).
    pub heartbeat_timeout: f64,
    /// A window in which every running node has waited this long for a peer's input is
    /// stopped as a deadlock, s.
    pub stall_timeout: f64,
    /// zenoh endpoint the coordinator listens on (several hosts: a routable address).
    pub listen: String,
    /// How long the coordinator waits for its remote nodes to join, s.
    pub join_timeout: f64,
    /// How long a launched node may take from its launch to its `Hello`, s (an interpreter
    /// importing its libraries on a busy machine can take seconds; no heartbeat is expected
    /// before it).
    pub start_timeout: f64,
    /// Record `Fields` messages of every `record_every`-th window only (1 = all).
    pub record_every: u64,
    /// Checkpoint every node (and the coordinator) at the end of every this many windows;
    /// 0 = never.
    pub checkpoint_every: u64,
    /// Which field pictures the run draws when it ends.
    pub pictures: Pictures,
    /// The divergence guard: a run whose total energy exceeds `energy_bound` times its
    /// initial energy plus the external work, plus `energy_floor` (J), is stopped as
    /// diverged; 0 turns the bound off (non-finite values still stop it).
    pub energy_bound: f64,
    pub energy_floor: f64,
}

/// `run.pictures`: the field pictures a finished run draws from its VTK series.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Pictures {
    /// None (a batch job that only needs the data).
    None,
    /// The last frames: `fields.png`, and each node alone in `fields_<node>.png`.
    #[default]
    End,
    /// Those, and every written frame of every node alone in `frames/<node>_<k>.png`.
    Frames,
}

#[derive(Debug, Clone)]
pub struct NodeConfig {
    pub name: String,
    /// Executable name or path, as written in the case.
    pub solver: String,
    /// Resolved executable (None for remote nodes).
    pub exe: Option<PathBuf>,
    pub model: String,
    pub params: toml::Table,
    pub remote: bool,
    /// Interfaces the solver offers, from its executable's `--describe` (None: a remote
    /// node not on this host, checked when it joins).
    pub interfaces: Option<Vec<String>>,
    /// Per interface (as `interfaces`), the fields it provides and accepts.
    pub fields: Vec<(Vec<String>, Vec<String>)>,
    /// Per interface (as `interfaces`), its number of points.
    pub points: Vec<u64>,
    /// Where its explicit integrator does not choose its own step, from its `--describe`.
    pub window_limits: Vec<protocol::WindowLimit>,
    /// Interface point positions (m) by interface name, from its `--describe` (those it gave).
    pub positions: BTreeMap<String, Vec<[f64; 3]>>,
}

#[derive(Debug, Clone)]
pub struct CouplingConfig {
    pub name: String,
    pub kind: CouplingKind,
    pub driver: (String, String),
    pub responder: (String, String),
    /// Fields the driver sends each window.
    pub driver_fields: Vec<String>,
    /// Fields the responder sends each window (and at set-up).
    pub responder_fields: Vec<String>,
    /// When the coupling ends (seed 000 §4): the driver (the solid) goes on alone, the
    /// responder (the fluid) is finished once none of its couplings is left.
    pub decouple: Decouple,
    /// `kind = "lagrange"`: every subdomain (node, interface), N ≥ 2 (the first two are also
    /// `driver` and `responder`), and the method; empty and None otherwise.
    pub sides: Vec<(String, String)>,
    pub method: Option<protocol::scheme::lagrange::Method>,
    /// How far apart the matched points of a kinematic coupling's two sides may lie, as a
    /// fraction of the interface's point spacing ([`point_spacing`]).
    pub point_tolerance: f64,
}

impl CouplingConfig {
    /// Every (node, interface) of the coupling: the sides of a lagrange coupling, else the
    /// driver and the responder.
    pub fn members(&self) -> Vec<&(String, String)> {
        if self.sides.is_empty() {
            vec![&self.driver, &self.responder]
        } else {
            self.sides.iter().collect()
        }
    }

    /// [`CouplingConfig::members`], each with its key in the coupling's table (`driver`,
    /// `responder`, `sides[k]`).
    pub fn keyed_members(&self) -> Vec<(String, &(String, String))> {
        let keys: Vec<String> = if self.sides.is_empty() {
            vec!["driver".into(), "responder".into()]
        } else {
            (0..self.sides.len())
                .map(|k| format!("sides[{k}]"))
                .collect()
        };
        keys.into_iter().zip(self.members()).collect()
    }
}

/// Decoupling rule of a coupling: at a time, or when a node's reported quantity reaches a
/// level (`decouple_when = "ring.damaged_particles >= 100"`), whichever comes first.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Decouple {
    pub at: Option<f64>,
    /// (node, reported scalar, threshold).
    pub when: Option<(String, String, f64)>,
}

impl Decouple {
    pub fn is_set(&self) -> bool {
        self.at.is_some() || self.when.is_some()
    }
}

#[derive(Debug, Clone)]
pub struct Case {
    pub path: PathBuf,
    pub text: String,
    pub run: RunConfig,
    pub nodes: Vec<NodeConfig>,
    pub couplings: Vec<CouplingConfig>,
    /// Names of the `[variants.NAME]` of the case (`cosim run --variant NAME`).
    pub variants: Vec<String>,
    /// What validation found close to a limit without refusing it (an explicit step within
    /// 5 % of its stable one); `cosim validate` and `cosim run` print them.
    pub warnings: Vec<String>,
}

const RUN_KEYS: &[&str] = &[
    "name",
    "end_time",
    "window",
    "schedule",
    "transport",
    "output",
    "output_every",
    "heartbeat_ms",
    "heartbeat_timeout",
    "stall_timeout",
    "listen",
    "join_timeout",
    "start_timeout",
    "record_every",
    "checkpoint_every",
    "pictures",
    "energy_bound",
    "energy_floor",
];
const NODE_KEYS: &[&str] = &["solver", "model", "params", "remote"];
const COUPLING_KEYS: &[&str] = &[
    "name",
    "kind",
    "driver",
    "responder",
    "driver_fields",
    "responder_fields",
    "decouple_at",
    "decouple_when",
    "sides",
    "method",
    "point_tolerance",
];

fn check_keys(t: &toml::Table, prefix: &str, allowed: &[&str]) -> Result<(), ConfigError> {
    for k in t.keys() {
        if !allowed.contains(&k.as_str()) {
            return Err(err(
                format!("{prefix}{k}"),
                format!("unknown key (expected one of: {})", allowed.join(", ")),
            ));
        }
    }
    Ok(())
}

fn get_str(t: &toml::Table, prefix: &str, k: &str) -> Result<Option<String>, ConfigError> {
    match t.get(k) {
        None => Ok(None),
        Some(toml::Value::String(s)) => Ok(Some(s.clone())),
        Some(v) => Err(err(
            format!("{prefix}{k}"),
            format!("must be a string, got {}", v.type_str()),
        )),
    }
}

fn need_str(t: &toml::Table, prefix: &str, k: &str) -> Result<String, ConfigError> {
    get_str(t, prefix, k)?.ok_or_else(|| err(format!("{prefix}{k}"), "missing"))
}

fn get_f64(t: &toml::Table, prefix: &str, k: &str) -> Result<Option<f64>, ConfigError> {
    match t.get(k) {
        None => Ok(None),
        Some(toml::Value::Float(f)) => Ok(Some(*f)),
        Some(toml::Value::Integer(i)) => Ok(Some(*i as f64)),
        Some(v) => Err(err(
            format!("{prefix}{k}"),
            format!("must be a number, got {}", v.type_str()),
        )),
    }
}

fn get_u64(t: &toml::Table, prefix: &str, k: &str) -> Result<Option<u64>, ConfigError> {
    match t.get(k) {
        None => Ok(None),
        Some(toml::Value::Integer(i)) if *i >= 0 => Ok(Some(*i as u64)),
        Some(v) => Err(err(
            format!("{prefix}{k}"),
            format!("must be a non-negative integer, got {v}"),
        )),
    }
}

fn get_strings(t: &toml::Table, prefix: &str, k: &str) -> Result<Option<Vec<String>>, ConfigError> {
    match t.get(k) {
        None => Ok(None),
        Some(toml::Value::Array(a)) => a
            .iter()
            .map(|v| {
                v.as_str()
                    .map(str::to_string)
                    .ok_or_else(|| err(format!("{prefix}{k}"), "must be an array of strings"))
            })
            .collect::<Result<Vec<_>, _>>()
            .map(Some),
        Some(v) => Err(err(
            format!("{prefix}{k}"),
            format!("must be an array, got {}", v.type_str()),
        )),
    }
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

fn valid_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 32
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// Where a node executable is: a path (relative to the case file), or a name beside `cosim`.
pub fn resolve_exe(solver: &str, case_dir: &Path) -> Option<PathBuf> {
    let p = Path::new(solver);
    if solver.contains('/') {
        let p = if p.is_absolute() {
            p.to_path_buf()
        } else {
            case_dir.join(p)
        };
        return p.is_file().then_some(p);
    }
    let here = std::env::current_exe().ok()?;
    let cand = here.parent()?.join(solver);
    cand.is_file().then_some(cand)
}

/// Default fields of a coupling kind, as its scheme declares them: (driver sends,
/// responder sends).
pub fn default_fields(kind: CouplingKind) -> (Vec<String>, Vec<String>) {
    let v = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let (d, r) = scheme::of(kind).default_fields();
    (v(d), v(r))
}

/// Parse and validate a case file; `overrides` are `node.key=value` settings applied to
/// node params (from the command line).
pub fn load(path: &Path) -> Result<Case, ConfigError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| err(path.display().to_string(), format!("cannot read: {e}")))?;
    parse(&text, path)
}

pub fn parse(text: &str, path: &Path) -> Result<Case, ConfigError> {
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
    check_keys(&doc, "", &["run", "nodes", "couplings", "variants"])?;
    let variants = variant_names(&doc)?;
    let case_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let run_t = match doc.get("run") {
        Some(toml::Value::Table(t)) => t.clone(),
        Some(_) => return Err(err("run", "must be a table")),
        None => return Err(err("run", "missing [run] table")),
    };
    let p = "run.";
    check_keys(&run_t, p, RUN_KEYS)?;
    let name = get_str(&run_t, p, "name")?.unwrap_or_else(|| "run".into());
    if !valid_name(&name) {
        return Err(err(
            "run.name",
            format!("must be 1–32 characters of [A-Za-z0-9_-], got '{name}'"),
        ));
    }
    let end_time = get_f64(&run_t, p, "end_time")?.ok_or_else(|| err("run.end_time", "missing"))?;
    if !(end_time.is_finite() && end_time > 0.0) {
        return Err(err("run.end_time", format!("must be > 0, got {end_time}")));
    }
    let window = get_f64(&run_t, p, "window")?.ok_or_else(|| err("run.window", "missing"))?;
    if !(window.is_finite() && window > 0.0 && window <= end_time) {
        return Err(err(
            "run.window",
            format!("must be > 0 and ≤ run.end_time ({end_time}), got {window}"),
        ));
    }
    if end_time / window > 1e9 {
        return Err(err(
            "run.window",
            format!("gives {:.3e} windows; at most 1e9", end_time / window),
        ));
    }
    let schedule = match get_str(&run_t, p, "schedule")?.as_deref() {
        None | Some("serial") => Schedule::Serial,
        Some("parallel") => Schedule::Parallel,
        Some(o) => {
            return Err(err(
                "run.schedule",
                format!("must be \"serial\" or \"parallel\", got \"{o}\""),
            ));
        }
    };
    let transport = match get_str(&run_t, p, "transport")?.as_deref() {
        None => TransportKind::Shm,
        Some(s) => match s.parse::<TransportKind>() {
            Ok(TransportKind::Local) => {
                return Err(err(
                    "run.transport",
                    "\"local\" is in-process only (tests); use shm or zenoh",
                ));
            }
            Ok(k) => k,
            Err(e) => return Err(err("run.transport", e)),
        },
    };
    let output = PathBuf::from(get_str(&run_t, p, "output")?.unwrap_or_else(|| "out".into()));
    let output_every = get_u64(&run_t, p, "output_every")?.unwrap_or(0);
    let heartbeat_ms = get_u64(&run_t, p, "heartbeat_ms")?.unwrap_or(200);
    if !(10..=60_000).contains(&heartbeat_ms) {
        return Err(err(
            "run.heartbeat_ms",
            format!("must be in 10..=60000, got {heartbeat_ms}"),
        ));
    }
    let heartbeat_timeout = get_f64(&run_t, p, "heartbeat_timeout")?.unwrap_or(3.0);
    if !(heartbeat_timeout.is_finite() && heartbeat_timeout * 1000.0 > 2.0 * heartbeat_ms as f64) {
        return Err(err(
            "run.heartbeat_timeout",
            format!(
                "must exceed two heartbeats ({} s), got {heartbeat_timeout}",
                2.0 * heartbeat_ms as f64 / 1000.0
            ),
        ));
    }
    let stall_timeout = get_f64(&run_t, p, "stall_timeout")?.unwrap_or(30.0);
    if !(stall_timeout.is_finite() && stall_timeout > heartbeat_timeout) {
        return Err(err(
            "run.stall_timeout",
            format!(
                "must exceed run.heartbeat_timeout ({heartbeat_timeout} s), got {stall_timeout}"
            ),
        ));
    }
    let listen = get_str(&run_t, p, "listen")?.unwrap_or_else(|| "tcp/127.0.0.1:0".into());
    let join_timeout = get_f64(&run_t, p, "join_timeout")?.unwrap_or(300.0);
    if !(join_timeout.is_finite() && join_timeout > 0.0) {
        return Err(err(
            "run.join_timeout",
            format!("must be > 0 s, got {join_timeout}"),
        ));
    }
    let start_timeout = get_f64(&run_t, p, "start_timeout")?.unwrap_or(60.0);
    if !(start_timeout.is_finite() && start_timeout > 0.0) {
        return Err(err(
            "run.start_timeout",
            format!("must be > 0 s, got {start_timeout}"),
        ));
    }
    let record_every = get_u64(&run_t, p, "record_every")?.unwrap_or(1).max(1);
    let checkpoint_every = get_u64(&run_t, p, "checkpoint_every")?.unwrap_or(0);
    let pictures = match get_str(&run_t, p, "pictures")?.as_deref() {
        None | Some("end") => Pictures::End,
        Some("frames") => Pictures::Frames,
        Some("none") => Pictures::None,
        Some(o) => {
            return Err(err(
                "run.pictures",
                format!("must be \"end\", \"frames\" or \"none\", got \"{o}\""),
            ));
        }
    };
    let energy_bound = get_f64(&run_t, p, "energy_bound")?.unwrap_or(crate::guard::DEFAULT_FACTOR);
    if !(energy_bound == 0.0 || energy_bound.is_finite() && energy_bound > 1.0) {
        return Err(err(
            "run.energy_bound",
            format!(
                "must be > 1 (a multiple of the initial energy plus the external work), or 0 to turn the bound off, got {energy_bound}"
            ),
        ));
    }
    let energy_floor = get_f64(&run_t, p, "energy_floor")?.unwrap_or(crate::guard::DEFAULT_FLOOR);
    if !(energy_floor.is_finite() && energy_floor >= 0.0) {
        return Err(err(
            "run.energy_floor",
            format!("must be ≥ 0 J, got {energy_floor}"),
        ));
    }

    // Nodes.
    let nodes_t = match doc.get("nodes") {
        Some(toml::Value::Table(t)) => t.clone(),
        Some(_) => return Err(err("nodes", "must be a table of [nodes.<name>] tables")),
        None => {
            return Err(err(
                "nodes",
                "missing: a case needs at least one [nodes.<name>]",
            ));
        }
    };
    if nodes_t.is_empty() {
        return Err(err("nodes", "a case needs at least one [nodes.<name>]"));
    }
    let mut nodes = Vec::new();
    for (nname, v) in &nodes_t {
        let p = format!("nodes.{nname}.");
        if !valid_name(nname) || nname == "coordinator" {
            return Err(err(
                format!("nodes.{nname}"),
                "node names are 1–32 characters of [A-Za-z0-9_-] and not 'coordinator'",
            ));
        }
        let t = v
            .as_table()
            .ok_or_else(|| err(format!("nodes.{nname}"), "must be a table"))?;
        check_keys(t, &p, NODE_KEYS)?;
        let solver = need_str(t, &p, "solver")?;
        let model = need_str(t, &p, "model")?;
        let remote = match t.get("remote") {
            None => false,
            Some(toml::Value::Boolean(b)) => *b,
            Some(_) => return Err(err(format!("{p}remote"), "must be true or false")),
        };
        let params = match t.get("params") {
            None => toml::Table::new(),
            Some(toml::Value::Table(t)) => t.clone(),
            Some(toml::Value::String(f)) => {
                let fp = case_dir.join(f);
                let s = std::fs::read_to_string(&fp).map_err(|e| {
                    err(
                        format!("{p}params"),
                        format!("cannot read {}: {e}", fp.display()),
                    )
                })?;
                toml::from_str(&s).map_err(|e| {
                    err(
                        format!("{p}params"),
                        format!("{}: {}", fp.display(), e.message()),
                    )
                })?
            }
            Some(_) => return Err(err(format!("{p}params"), "must be a table or a file name")),
        };
        let exe = if remote {
            None
        } else {
            Some(resolve_exe(&solver, &case_dir).ok_or_else(|| {
                err(
                    format!("{p}solver"),
                    format!("no executable '{solver}' beside cosim or at that path (build it: cargo build --release --workspace)"),
                )
            })?)
        };
        nodes.push(NodeConfig {
            name: nname.clone(),
            solver,
            exe,
            model,
            params,
            remote,
            interfaces: None,
            fields: Vec::new(),
            points: Vec::new(),
            window_limits: Vec::new(),
            positions: BTreeMap::new(),
        });
    }

    // Couplings.
    let mut couplings = Vec::new();
    let list = match doc.get("couplings") {
        None => Vec::new(),
        Some(toml::Value::Array(a)) => a.clone(),
        Some(_) => return Err(err("couplings", "must be an array of [[couplings]] tables")),
    };
    let mut names = std::collections::BTreeSet::new();
    for (i, v) in list.iter().enumerate() {
        let p = format!("couplings[{i}].");
        let t = v
            .as_table()
            .ok_or_else(|| err(format!("couplings[{i}]"), "must be a table"))?;
        check_keys(t, &p, COUPLING_KEYS)?;
        let kind = match need_str(t, &p, "kind")?.as_str() {
            "kinematic" => CouplingKind::Kinematic,
            "immersed" => CouplingKind::Immersed,
            "lagrange" => CouplingKind::Lagrange,
            o => {
                return Err(err(
                    format!("{p}kind"),
                    format!("must be \"kinematic\", \"immersed\" or \"lagrange\", got \"{o}\""),
                ));
            }
        };
        let member = |key: &str, s: &str| -> Result<(String, String), ConfigError> {
            let (n, i) = s
                .split_once('.')
                .ok_or_else(|| err(key, format!("must be \"node.interface\", got \"{s}\"")))?;
            if !nodes.iter().any(|x| x.name == n) {
                return Err(err(key, format!("unknown node '{n}'")));
            }
            Ok((n.to_string(), i.to_string()))
        };
        let split = |key: &str| -> Result<(String, String), ConfigError> {
            member(&format!("{p}{key}"), &need_str(t, &p, key)?)
        };
        let (sides, method) = if kind == CouplingKind::Lagrange {
            lagrange_sides(t, &p, &member)?
        } else {
            for k in ["sides", "method"] {
                if t.contains_key(k) {
                    return Err(err(
                        format!("{p}{k}"),
                        "only a lagrange coupling takes it (kind = \"lagrange\")",
                    ));
                }
            }
            (Vec::new(), None)
        };
        let (driver, responder) = match sides.as_slice() {
            [a, b, ..] => (a.clone(), b.clone()),
            _ => (split("driver")?, split("responder")?),
        };
        if driver.0 == responder.0 {
            return Err(err(
                format!("{p}responder"),
                "a node cannot couple to itself",
            ));
        }
        let name =
            get_str(t, &p, "name")?.unwrap_or_else(|| format!("{}-{}", driver.0, responder.0));
        if !valid_name(&name) {
            return Err(err(
                format!("{p}name"),
                format!("must be 1–32 characters of [A-Za-z0-9_-], got '{name}'"),
            ));
        }
        if !names.insert(name.clone()) {
            return Err(err(
                format!("{p}name"),
                format!("duplicate coupling name '{name}'"),
            ));
        }
        let mut decouple = Decouple {
            at: get_f64(t, &p, "decouple_at")?,
            when: None,
        };
        if let Some(at) = decouple.at
            && !(at.is_finite() && at > 0.0)
        {
            return Err(err(
                format!("{p}decouple_at"),
                format!("must be a time > 0, got {at}"),
            ));
        }
        if let Some(w) = get_str(t, &p, "decouple_when")? {
            decouple.when =
                Some(parse_when(&w, &nodes).map_err(|r| err(format!("{p}decouple_when"), r))?);
        }
        if decouple.is_set() && !scheme::of(kind).decouples() {
            let key = if decouple.at.is_some() {
                "decouple_at"
            } else {
                "decouple_when"
            };
            return Err(err(
                format!("{p}{key}"),
                "only an immersed coupling can be decoupled (the solid goes on alone, seed 000 §4)",
            ));
        }
        let point_tolerance = get_f64(t, &p, "point_tolerance")?.unwrap_or(DEFAULT_POINT_TOLERANCE);
        if !(point_tolerance.is_finite() && point_tolerance > 0.0) {
            return Err(err(
                format!("{p}point_tolerance"),
                format!("must be a number > 0, got {point_tolerance}"),
            ));
        }
        let (df, rf) = default_fields(kind);
        couplings.push(CouplingConfig {
            point_tolerance,
            sides,
            method,
            decouple,
            name,
            kind,
            driver,
            responder,
            driver_fields: get_strings(t, &p, "driver_fields")?.unwrap_or(df),
            responder_fields: get_strings(t, &p, "responder_fields")?.unwrap_or(rf),
        });
    }
    check_one_coupling_per_interface(&couplings)?;
    for (i, c) in couplings.iter().enumerate() {
        if c.kind != CouplingKind::Lagrange {
            continue;
        }
        // Every subdomain steps the system step exactly: the run is whole windows.
        let w = end_time / window;
        if (w - w.round()).abs() > 1e-9 * w.max(1.0) {
            return Err(err(
                "run.end_time",
                format!(
                    "must be a whole number of windows for the lagrange coupling couplings[{i}] (each window is a system step), got {w} windows"
                ),
            ));
        }
        for (k, (node, _)) in c.sides.iter().enumerate() {
            // The device path has no lagrange side (its state lives on the device between
            // windows): refused here rather than once the nodes are set up.
            let params = nodes.iter().find(|n: &&NodeConfig| &n.name == node);
            if params
                .and_then(|n| n.params.get("device"))
                .and_then(|d| d.as_str())
                == Some("gpu")
            {
                return Err(err(
                    format!("nodes.{node}.params.device"),
                    format!(
                        "node '{node}' is a side of the lagrange coupling couplings[{i}], which runs on the cpu: use device = \"cpu\""
                    ),
                ));
            }
            if let Some(j) = couplings[..i].iter().position(|o| {
                o.kind == CouplingKind::Lagrange && o.sides.iter().any(|s| &s.0 == node)
            }) {
                return Err(err(
                    format!("couplings[{i}].sides[{k}]"),
                    format!(
                        "node '{node}' is already a side of the lagrange coupling couplings[{j}] (a node takes one)"
                    ),
                ));
            }
        }
    }
    if schedule == Schedule::Parallel
        && let Some((i, why)) = couplings
            .iter()
            .enumerate()
            .find_map(|(i, c)| Some((i, scheme::of(c.kind).parallel_refusal()?)))
    {
        return Err(err(
            "run.schedule".to_string(),
            format!("{why} couplings[{i}] (docs/architecture.md); use \"serial\""),
        ));
    }
    let mut case = Case {
        path: path.to_path_buf(),
        text: text.to_string(),
        run: RunConfig {
            name,
            end_time,
            window,
            schedule,
            transport,
            output,
            output_every,
            heartbeat_ms,
            heartbeat_timeout,
            stall_timeout,
            listen,
            join_timeout,
            start_timeout,
            record_every,
            checkpoint_every,
            pictures,
            energy_bound,
            energy_floor,
        },
        nodes,
        couplings,
        variants,
        warnings: Vec::new(),
    };
    check_solvers(&mut case)?;
    Ok(case)
}

/// Share of its largest stable step from which an explicit step is warned of.
const NEAR_LIMIT: f64 = 0.95;

/// Refuse a window at which a lagrange side's explicit integrator, whose steps per window are
/// fixed, would step beyond its largest stable step (it would blow up within a few windows),
/// naming `run.window`, the largest window that works and the substeps that would; warn of
/// one within 5 % of it. A node that sub-cycles at its own stable step states no limit.
fn check_stability(case: &Case) -> Result<Vec<String>, ConfigError> {
    use protocol::LimitApplies;
    let window = case.run.window;
    let mut warnings = Vec::new();
    for (i, c) in case.couplings.iter().enumerate() {
        if c.kind != CouplingKind::Lagrange {
            continue;
        }
        let gs4_or_ph = c.method != Some(scheme::lagrange::Method::Gc);
        for (node, _) in &c.sides {
            let Some(n) = case.nodes.iter().find(|n| &n.name == node) else {
                continue;
            };
            for l in &n.window_limits {
                let holds = match l.applies {
                    LimitApplies::LagrangeSide => true,
                    LimitApplies::LagrangeSideGs4OrPh => gs4_or_ph,
                };
                // A limit without a positive step (NaN included) states nothing to check.
                if !holds || l.max_step.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                    continue;
                }
                let step = window / l.substeps.max(1) as f64;
                let ratio = step / l.max_step;
                let what = format!(
                    "node '{node}' (a side of the lagrange coupling couplings[{i}] '{}') steps {} {} time{} per window: at run.window = {window:e} s a step is {step:.4e} s, {ratio:.3} × its largest stable step {:.4e} s",
                    c.name,
                    l.integrator,
                    l.substeps,
                    if l.substeps == 1 { "" } else { "s" },
                    l.max_step,
                );
                if ratio > 1.0 + 1e-12 {
                    let fix = match &l.key {
                        Some(k) => format!(
                            "; or set nodes.{node}.{k} = {}",
                            (window / l.max_step - 1e-9).ceil().max(1.0)
                        ),
                        None => String::new(),
                    };
                    return Err(err(
                        "run.window",
                        format!(
                            "{what}: unstable. The largest run.window that works is {:.6e} s{fix}",
                            l.max_window()
                        ),
                    ));
                }
                if ratio > NEAR_LIMIT {
                    warnings.push(format!(
                        "{what}: within {:.0} % of the limit, stable only while nothing stiffens it",
                        (1.0 - NEAR_LIMIT) * 100.0
                    ));
                }
            }
        }
    }
    Ok(warnings)
}

/// Refuse an interface that two couplings take: each would apply its own loads and count its
/// own interface work, so the run would move and book the same interface twice.
fn check_one_coupling_per_interface(couplings: &[CouplingConfig]) -> Result<(), ConfigError> {
    let mut taken: BTreeMap<&(String, String), (usize, &str)> = BTreeMap::new();
    for (i, c) in couplings.iter().enumerate() {
        for (key, m) in c.keyed_members() {
            if let Some((j, other)) = taken.insert(m, (i, &c.name)) {
                return Err(err(
                    format!("couplings[{i}].{key}"),
                    format!(
                        "interface {}.{} is already coupled by couplings[{j}] ('{other}'): an interface takes one coupling",
                        m.0, m.1
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Default of `couplings[i].point_tolerance`: matched points may lie a thousandth of the
/// interface's point spacing apart (two meshes of one line or surface agree to round-off).
pub const DEFAULT_POINT_TOLERANCE: f64 = 1e-3;

/// The length the distance between matched points is judged against: the interface's mean
/// point spacing along its extent (the diagonal of the bounding box of both sides' points
/// over their count less one), or 1 m for a single point, which has no extent.
pub fn point_spacing(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let n = a.len().max(b.len());
    if n < 2 {
        return 1.0;
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for x in a.iter().chain(b) {
        for d in 0..3 {
            lo[d] = lo[d].min(x[d]);
            hi[d] = hi[d].max(x[d]);
        }
    }
    let diagonal = (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
    diagonal / (n - 1) as f64
}

/// Refuse a kinematic coupling whose sides hold as many points each (a point-to-point
/// binding) but a responder point lies farther from its nearest driver point (the point the
/// runtime's nearest-point mapping would tie it to) than `point_tolerance` of the interface's
/// point spacing: the coupling would tie points that are not the same (a shifted node or
/// mesh). Checked where both nodes gave their positions; sides of different counts are
/// non-matching meshes, mapped by design.
fn check_coincident(case: &Case) -> Result<(), ConfigError> {
    for (i, c) in case.couplings.iter().enumerate() {
        if c.kind != CouplingKind::Kinematic {
            continue;
        }
        let at = |(node, iface): &(String, String)| {
            case.nodes
                .iter()
                .find(|n| &n.name == node)
                .and_then(|n| n.positions.get(iface))
        };
        let (Some(d), Some(r)) = (at(&c.driver), at(&c.responder)) else {
            continue;
        };
        if d.len() != r.len() || d.is_empty() {
            continue;
        }
        let limit = c.point_tolerance * point_spacing(d, r);
        let dist =
            |p: &[f64; 3], q: &[f64; 3]| (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>().sqrt();
        for (k, q) in r.iter().enumerate() {
            // The nearest driver point; a NaN distance is never within the limit.
            let (j, gap) = d.iter().map(|p| dist(p, q)).enumerate().fold(
                (0, f64::INFINITY),
                |best, (j, g)| {
                    if g < best.1 || g.is_nan() {
                        (j, g)
                    } else {
                        best
                    }
                },
            );
            if gap.is_nan() || gap > limit {
                return Err(err(
                    format!("couplings[{i}]"),
                    format!(
                        "coupling '{}': point {k} of {}.{} at {q:?} is {gap:.4e} m from the nearest point ({j}) of {}.{} at {:?}, more than point_tolerance = {} × the interface's point spacing = {limit:.4e} m: the two sides do not coincide (a shifted node or mesh?)",
                        c.name,
                        c.responder.0,
                        c.responder.1,
                        c.driver.0,
                        c.driver.1,
                        d[j],
                        c.point_tolerance
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Ask every node executable found on this host to describe itself (in parallel): its own
/// validation names a bad parameter, and its interfaces let us check the couplings before
/// anything is launched. A remote node not on this host is checked when it joins.
fn check_solvers(case: &mut Case) -> Result<(), ConfigError> {
    let case_dir = case
        .path
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let checked =
        crate::describe::describe_nodes(&case.nodes, &case_dir, crate::describe::DESCRIBE_TIMEOUT)?;
    for (n, c) in case.nodes.iter_mut().zip(checked) {
        if let crate::describe::Checked::Described(d) = c {
            n.fields = d
                .interfaces
                .iter()
                .map(|i| (i.provides.clone(), i.accepts.clone()))
                .collect();
            n.points = d.interfaces.iter().map(|i| i.points).collect();
            n.interfaces = Some(d.interfaces.into_iter().map(|i| i.name).collect());
            n.window_limits = d.window_limits;
            n.positions = d.positions;
        }
    }
    check_coincident(case)?;
    case.warnings = check_stability(case)?;
    check_interfaces(case, |node| {
        case.nodes
            .iter()
            .find(|n| n.name == node)
            .and_then(|n| n.interfaces.clone())
    })?;
    check_fields(case, |node, iface| {
        let cfg = case.nodes.iter().find(|x| x.name == node)?;
        let pos = cfg.interfaces.as_ref()?.iter().position(|x| x == iface)?;
        cfg.fields
            .get(pos)
            .map(|(p, a)| (p.as_slice(), a.as_slice()))
    })
}

/// Check remote node `node`, which was not described before the run, by the interfaces of
/// its `Describe` at the handshake: every coupling it is a member of
/// must find its interface and the fields the scheme needs, refused as before the run.
pub fn check_joined(
    case: &Case,
    node: &str,
    described: &[protocol::message::InterfaceDescription],
) -> Result<(), ConfigError> {
    let only = |n: &str| n == node;
    check_interfaces(case, |n| {
        only(n).then(|| described.iter().map(|i| i.name.clone()).collect())
    })?;
    check_fields(case, |n, iface| {
        let d = described.iter().find(|i| only(n) && i.name == iface)?;
        Some((d.provides.as_slice(), d.accepts.as_slice()))
    })
}

/// Refuse a coupling member naming an interface its node does not offer; `offered` gives a
/// node's interfaces (None: not known yet, a remote node checked when it joins).
fn check_interfaces(
    case: &Case,
    offered: impl Fn(&str) -> Option<Vec<String>>,
) -> Result<(), ConfigError> {
    for (i, c) in case.couplings.iter().enumerate() {
        for (key, (node, iface)) in c.keyed_members() {
            if let Some(list) = offered(node)
                && !list.iter().any(|x| x == iface)
            {
                return Err(err(
                    format!("couplings[{i}].{key}"),
                    format!(
                        "node '{node}' has no interface '{iface}' (it offers: {})",
                        if list.is_empty() {
                            "none".to_string()
                        } else {
                            list.join(", ")
                        }
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// One field list a coupling member must offer (the scheme's declaration, docs/architecture.md).
#[derive(Debug, Clone, PartialEq)]
pub struct Need<'a> {
    /// The key that sets the list (`driver_fields`, `sides[1]`, ...).
    pub key: String,
    pub member: &'a (String, String),
    /// True: the member must provide the fields; false: accept them.
    pub provide: bool,
    pub fields: Vec<String>,
}

/// What each member of coupling `c` must provide and accept: a kinematic or immersed driver
/// provides the driver fields and accepts the responder's, the responder the other way
/// round; every side of a lagrange coupling provides and accepts what
/// `protocol::scheme::lagrange` declares.
pub fn required_fields(c: &CouplingConfig) -> Vec<Need<'_>> {
    let need = |key: String, member, provide, fields: Vec<String>| Need {
        key,
        member,
        provide,
        fields,
    };
    if c.kind == CouplingKind::Lagrange {
        let (provides, accepts) = scheme::of(c.kind).default_fields();
        let own = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        return c
            .sides
            .iter()
            .enumerate()
            .flat_map(|(k, s)| {
                [
                    need(format!("sides[{k}]"), s, true, own(provides)),
                    need(format!("sides[{k}]"), s, false, own(accepts)),
                ]
            })
            .collect();
    }
    let (d, r) = ("driver_fields".to_string(), "responder_fields".to_string());
    vec![
        need(d.clone(), &c.driver, true, c.driver_fields.clone()),
        need(r.clone(), &c.driver, false, c.responder_fields.clone()),
        need(r, &c.responder, true, c.responder_fields.clone()),
        need(d, &c.responder, false, c.driver_fields.clone()),
    ]
}

/// Refuse a coupling whose node does not provide or accept a field its scheme needs, by the
/// node's own description: the key, the coupling, the node, the field.
/// `fields` gives what a node's interface provides and accepts (None: not known yet, a remote
/// node checked when it joins).
fn check_fields<'d>(
    case: &Case,
    fields: impl Fn(&str, &str) -> Option<(&'d [String], &'d [String])>,
) -> Result<(), ConfigError> {
    for (i, c) in case.couplings.iter().enumerate() {
        for n in required_fields(c) {
            let (node, iface) = n.member;
            let Some((provides, accepts)) = fields(node, iface) else {
                continue;
            };
            let (have, verb) = if n.provide {
                (provides, "provide")
            } else {
                (accepts, "accept")
            };
            if let Some(f) = n.fields.iter().find(|f| !have.contains(f)) {
                return Err(err(
                    format!("couplings[{i}].{}", n.key),
                    format!(
                        "the {} coupling '{}' needs node '{node}' (interface '{iface}') to {verb} field '{f}'; it {verb}s: {}",
                        c.kind.as_str(),
                        c.name,
                        if have.is_empty() {
                            "none".to_string()
                        } else {
                            have.join(", ")
                        }
                    ),
                ));
            }
        }
    }
    Ok(())
}

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

/// `"node.quantity >= level"` (or `>`): a scalar a node reports every window.
fn parse_when(s: &str, nodes: &[NodeConfig]) -> Result<(String, String, f64), String> {
    let form = "must read \"NODE.QUANTITY >= LEVEL\" (a quantity the node reports)";
    let (lhs, rhs) = s
        .split_once(">=")
        .or_else(|| s.split_once('>'))
        .ok_or_else(|| format!("{form}, got \"{s}\""))?;
    let (node, q) = lhs
        .trim()
        .split_once('.')
        .ok_or_else(|| format!("{form}, got \"{s}\""))?;
    if !nodes.iter().any(|n| n.name == node) {
        return Err(format!("unknown node '{node}'"));
    }
    if q.is_empty() {
        return Err(format!("{form}, got \"{s}\""));
    }
    let level: f64 = rhs
        .trim()
        .parse()
        .map_err(|_| format!("level '{}' is not a number", rhs.trim()))?;
    if !level.is_finite() {
        return Err(format!("level must be finite, got {level}"));
    }
    Ok((node.to_string(), q.to_string(), level))
}

/// Names of the case's variants (`[variants.NAME]` tables with `description` and `set`),
/// checked for shape.
pub fn variant_names(doc: &toml::Table) -> Result<Vec<String>, ConfigError> {
    let Some(v) = doc.get("variants") else {
        return Ok(Vec::new());
    };
    let t = v
        .as_table()
        .ok_or_else(|| err("variants", "must be a table of [variants.NAME] tables"))?;
    let mut names = Vec::new();
    for (name, body) in t {
        let key = format!("variants.{name}");
        let b = body
            .as_table()
            .ok_or_else(|| err(&key, "must be a table with `description` and `set`"))?;
        check_keys(
            b,
            &format!("{key}."),
            &["description", "set", "remove", "nodes", "couplings"],
        )?;
        if let Some(d) = b.get("description")
            && !d.is_str()
        {
            return Err(err(format!("{key}.description"), "must be a string"));
        }
        variant_sets(doc, name)?;
        names.push(name.clone());
    }
    Ok(names)
}

/// The `set` list of variant `name`: `NODE.KEY=VALUE` or `run.KEY=VALUE` strings.
pub fn variant_sets(doc: &toml::Table, name: &str) -> Result<Vec<String>, ConfigError> {
    let all = doc.get("variants").and_then(|v| v.as_table());
    let Some(b) = all.and_then(|t| t.get(name)).and_then(|b| b.as_table()) else {
        let known: Vec<&str> = all
            .map(|t| t.keys().map(String::as_str).collect())
            .unwrap_or_default();
        return Err(err(
            format!("--variant {name}"),
            if known.is_empty() {
                "the case has no [variants]".to_string()
            } else {
                format!("no such variant (the case has {})", known.join(", "))
            },
        ));
    };
    let key = format!("variants.{name}.set");
    let Some(set) = b.get("set") else {
        return Ok(Vec::new());
    };
    let arr = set
        .as_array()
        .ok_or_else(|| err(&key, "must be an array of \"NODE.KEY=VALUE\" strings"))?;
    arr.iter()
        .enumerate()
        .map(|(i, s)| match s.as_str() {
            Some(s) if s.contains('=') && s.split('=').next().is_some_and(|k| k.contains('.')) => {
                Ok(s.to_string())
            }
            _ => Err(err(
                format!("{key}[{i}]"),
                "must be a \"NODE.KEY=VALUE\", \"run.KEY=VALUE\" or \"couplings.NAME.KEY=VALUE\" string",
            )),
        })
        .collect()
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
    let coupling_name = |t: &toml::Value| -> String {
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
    };
    if let Some(r) = v.get("remove") {
        let arr = r.as_array().ok_or_else(|| {
            err(
                format!("{key}.remove"),
                "must be an array of \"nodes.NAME\" or \"couplings.NAME\" strings",
            )
        })?;
        for (i, item) in arr.iter().enumerate() {
            let k = format!("{key}.remove[{i}]");
            let Some((table, what)) = item.as_str().and_then(|s| s.split_once('.')) else {
                return Err(err(
                    k,
                    "must be a \"nodes.NAME\" or \"couplings.NAME\" string",
                ));
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
                _ => {
                    return Err(err(
                        k,
                        "must be a \"nodes.NAME\" or \"couplings.NAME\" string",
                    ));
                }
            }
        }
    }
    if let Some(n) = v.get("nodes") {
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
    }
    if let Some(c) = v.get("couplings") {
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
    }
    Ok(())
}

/// The sides and method of a lagrange coupling table at `p` (`couplings[i].`): N ≥ 2 sides
/// "node.interface", each node once (one interface per node and coupling), and no
/// driver/responder keys.
#[allow(clippy::type_complexity)]
fn lagrange_sides(
    t: &toml::Table,
    p: &str,
    member: &dyn Fn(&str, &str) -> Result<(String, String), ConfigError>,
) -> Result<
    (
        Vec<(String, String)>,
        Option<protocol::scheme::lagrange::Method>,
    ),
    ConfigError,
> {
    for k in ["driver", "responder", "driver_fields", "responder_fields"] {
        if t.contains_key(k) {
            return Err(err(
                format!("{p}{k}"),
                "a lagrange coupling names its subdomains in `sides` (no driver or responder)",
            ));
        }
    }
    let list = get_strings(t, p, "sides")?.ok_or_else(|| {
        err(
            format!("{p}sides"),
            "missing (e.g. [\"left.tip\", \"right.root\"])",
        )
    })?;
    if list.len() < 2 {
        return Err(err(
            format!("{p}sides"),
            format!("needs at least two subdomains, got {}", list.len()),
        ));
    }
    let mut sides: Vec<(String, String)> = Vec::new();
    for (k, s) in list.iter().enumerate() {
        let side = member(&format!("{p}sides[{k}]"), s)?;
        if sides.iter().any(|x| x.0 == side.0) {
            return Err(err(
                format!("{p}sides[{k}]"),
                format!(
                    "node '{}' is already a side of this coupling (one interface per node)",
                    side.0
                ),
            ));
        }
        sides.push(side);
    }
    let method = match get_str(t, p, "method")? {
        None => protocol::scheme::lagrange::Method::Gs4,
        Some(m) => m
            .parse()
            .map_err(|e: String| err(format!("{p}method"), e))?,
    };
    Ok((sides, Some(method)))
}

/// The split bar's coupling `mid`, for tests: `left.tip` drives `right.tip` kinematically
/// with the scheme's default fields.
#[cfg(test)]
pub(crate) fn split_bar_coupling() -> CouplingConfig {
    CouplingConfig {
        name: "mid".into(),
        kind: CouplingKind::Kinematic,
        driver: ("left".into(), "tip".into()),
        responder: ("right".into(), "tip".into()),
        driver_fields: vec!["position".into(), "velocity".into()],
        responder_fields: vec!["force".into()],
        decouple: Decouple::default(),
        sides: Vec::new(),
        method: None,
        point_tolerance: DEFAULT_POINT_TOLERANCE,
    }
}

/// Bindings of one node: its side of every coupling.
pub fn bindings_of(case: &Case, node: &str) -> Vec<protocol::Binding> {
    let mut v = Vec::new();
    for c in &case.couplings {
        if c.kind == CouplingKind::Lagrange {
            // Every side exchanges with the coordinator, which solves the interface problem.
            for (n, iface) in c.sides.iter().filter(|s| s.0 == node) {
                let _ = n;
                v.push(protocol::Binding {
                    coupling: c.name.clone(),
                    kind: c.kind,
                    interface: iface.clone(),
                    role: protocol::Role::Driver,
                    peer: protocol::scheme::lagrange::wire::PEER.to_string(),
                    peer_interface: String::new(),
                    sends: c.driver_fields.clone(),
                    receives: c.responder_fields.clone(),
                    input_lag: scheme::of(c.kind).input_lag(protocol::Role::Driver, true),
                });
            }
            continue;
        }
        // The lags are the scheme's (serial: the driver's motion feeds the responder in the
        // same window; the responder's force reaches the driver at the next sync time).
        let sch = scheme::of(c.kind);
        let serial = case.run.schedule == Schedule::Serial;
        if c.driver.0 == node {
            v.push(protocol::Binding {
                coupling: c.name.clone(),
                kind: c.kind,
                interface: c.driver.1.clone(),
                role: protocol::Role::Driver,
                peer: c.responder.0.clone(),
                peer_interface: c.responder.1.clone(),
                sends: c.driver_fields.clone(),
                receives: c.responder_fields.clone(),
                input_lag: sch.input_lag(protocol::Role::Driver, serial),
            });
        }
        if c.responder.0 == node {
            v.push(protocol::Binding {
                coupling: c.name.clone(),
                kind: c.kind,
                interface: c.responder.1.clone(),
                role: protocol::Role::Responder,
                peer: c.driver.0.clone(),
                peer_interface: c.driver.1.clone(),
                sends: c.responder_fields.clone(),
                receives: c.driver_fields.clone(),
                input_lag: sch.input_lag(protocol::Role::Responder, serial),
            });
        }
    }
    v
}

/// Node order within a window implied by the same-window dependencies (drivers before their
/// responders); an error if they form a cycle.
pub fn window_order(case: &Case) -> Result<Vec<String>, ConfigError> {
    let names: Vec<String> = case.nodes.iter().map(|n| n.name.clone()).collect();
    let mut deps: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    let serial = case.run.schedule == Schedule::Serial;
    for c in case
        .couplings
        .iter()
        .filter(|c| scheme::of(c.kind).responder_after_driver(serial))
    {
        deps.entry(c.responder.0.as_str())
            .or_default()
            .push(c.driver.0.as_str());
    }
    let mut order: Vec<String> = Vec::new();
    let mut left: Vec<&str> = names.iter().map(String::as_str).collect();
    while !left.is_empty() {
        let ready: Vec<&str> = left
            .iter()
            .copied()
            .filter(|n| {
                deps.get(n)
                    .is_none_or(|d| d.iter().all(|x| order.iter().any(|o| o == x)))
            })
            .collect();
        if ready.is_empty() {
            return Err(err(
                "couplings",
                format!(
                    "the serial schedule has a cycle of same-window dependencies among {}",
                    left.join(", ")
                ),
            ));
        }
        for r in &ready {
            order.push(r.to_string());
        }
        left.retain(|n| !ready.contains(n));
    }
    Ok(order)
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
