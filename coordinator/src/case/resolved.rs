//! The case as a run uses it: every value checked and defaulted, every node's executable
//! found and its description in hand.

use protocol::CouplingKind;
use protocol::transport::TransportKind;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A configuration error: the key path and why.
/// A refused case: the key path at fault (empty for the case file as a whole) and why.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    pub key: String,
    pub reason: String,
}

impl std::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.key.is_empty() {
            write!(f, "{}", self.reason)
        } else {
            write!(f, "{}: {}", self.key, self.reason)
        }
    }
}

impl std::error::Error for ConfigError {}

pub(crate) fn err(key: impl Into<String>, reason: impl Into<String>) -> ConfigError {
    ConfigError {
        key: key.into(),
        reason: reason.into(),
    }
}

/// "unknown NODE_OR_VARIANT 'x' (did you mean 'y'? the case has: a, b)": what a name that
/// is not among `known` reads like in an error.
pub(crate) fn unknown<'a>(
    what: &str,
    name: &str,
    known: impl Iterator<Item = &'a str> + Clone,
) -> String {
    let hint = protocol::params::did_you_mean(name, known.clone())
        .map(|k| format!("did you mean '{k}'? "))
        .unwrap_or_default();
    let all: Vec<&str> = known.collect();
    format!(
        "unknown {what} '{name}' ({hint}the case has: {})",
        all.join(", ")
    )
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
    /// `[run.balance]`: the largest momentum residual (share of its scale) and energy
    /// residual (share of the largest energy or work, either sign) a run may reach before
    /// it ends with a warning.
    pub balance_momentum: f64,
    pub balance_energy: f64,
    /// `run.print`: (node, scalar) pairs printed from the nodes' last reports at the end.
    pub print: Vec<(String, String)>,
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

/// Default of `couplings[i].point_tolerance`: matched points may lie a thousandth of the
/// interface's point spacing apart (two meshes of one line or surface agree to round-off).
pub const DEFAULT_POINT_TOLERANCE: f64 = 1e-3;

/// Number of windows of a case (the last one may be shorter).
pub fn window_count(case: &Case) -> u64 {
    ((case.run.end_time / case.run.window) - 1e-9)
        .ceil()
        .max(1.0) as u64
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
