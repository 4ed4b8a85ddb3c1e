//! The `Solver` trait (docs/architecture.md): what every node implements. It is independent of any
//! transport, so the participant runtime, the replay tool and unit tests all drive a solver
//! the same way, in-process.
//!
//! Data cross the trait per interface as named flat arrays (`Field`), in the solver's own
//! point layout: the participant runtime maps between the peer's layout and this one.

use crate::message::{Binding, Field, InterfaceMesh, StepReport};
use std::path::Path;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum SolverError {
    /// Bad parameter: the key path and why (`nodes.left.params.elements: must be > 0, got 0`).
    #[error("{key}: {reason}")]
    Config { key: String, reason: String },
    /// A coupling input is missing or has the wrong size.
    #[error("interface {interface}: {reason}")]
    Interface { interface: String, reason: String },
    /// The state became unphysical (negative density, NaN, ...): where and when.
    #[error("diverged at t = {time:e}: {reason}")]
    Diverged { time: f64, reason: String },
    /// Transparent: the I/O error is the message, not also its source (a chain printed with
    /// `{:#}` would say it twice).
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error("{0}")]
    Other(String),
}

impl SolverError {
    pub fn config(key: impl Into<String>, reason: impl Into<String>) -> Self {
        SolverError::Config {
            key: key.into(),
            reason: reason.into(),
        }
    }
    pub fn interface(interface: impl Into<String>, reason: impl Into<String>) -> Self {
        SolverError::Interface {
            interface: interface.into(),
            reason: reason.into(),
        }
    }
}

pub type SolverResult<T> = Result<T, SolverError>;

/// One coupling window `[t0, t1]`; windows count from 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    pub index: u64,
    pub t0: f64,
    pub t1: f64,
    pub write_output: bool,
}

/// Where a node's explicit integrator cannot choose its own step, the largest window it is
/// stable at (`NODE --describe` states it, so that `cosim validate` refuses an unstable
/// set-up before anything runs). A node that sub-cycles at its own stable step has none.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct WindowLimit {
    /// When the limit holds.
    pub applies: LimitApplies,
    /// The integrator, in words (`central differences`).
    pub integrator: String,
    /// Its steps per window where the limit holds.
    pub substeps: u64,
    /// The largest step it takes (s): its critical step, or the share of it that its
    /// parameters allow.
    pub max_step: f64,
    /// The node parameter that sets `substeps`, relative to the node (`params.substeps`);
    /// None when only the window can change.
    pub key: Option<String>,
}

impl WindowLimit {
    /// The largest stable window: `substeps` largest steps.
    pub fn max_window(&self) -> f64 {
        self.substeps as f64 * self.max_step
    }
}

/// When a [`WindowLimit`] holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LimitApplies {
    /// As a side of a lagrange coupling, whatever its method.
    LagrangeSide,
    /// As a side of a lagrange coupling with the `gs4` or `ph` method.
    LagrangeSideGs4OrPh,
}

/// What a solver is and what it offers.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeDescription {
    pub model: String,
    pub interfaces: Vec<InterfaceInfo>,
    pub units: String,
}

#[derive(Debug, Clone, PartialEq)]
pub struct InterfaceInfo {
    pub name: String,
    pub points: usize,
    pub provides: Vec<String>,
    pub accepts: Vec<String>,
}

/// Named per-interface fields, in the solver's own layout. Used both ways: the runtime fills
/// an `Inbox` before `advance`, the solver fills an `Outbox` during it. Buffers are kept
/// between windows so a steady run allocates nothing.
#[derive(Debug, Default, Clone)]
pub struct FieldSet {
    entries: Vec<(String, Field)>,
}

pub type Inbox = FieldSet;
pub type Outbox = FieldSet;

impl FieldSet {
    pub fn new() -> Self {
        Self::default()
    }

    /// The field `name` of `interface`, if present.
    pub fn get(&self, interface: &str, name: &str) -> Option<&Field> {
        self.entries
            .iter()
            .find(|(i, f)| i == interface && f.name == name)
            .map(|(_, f)| f)
    }

    /// The values of a field that must be there with `len` values.
    pub fn require(&self, interface: &str, name: &str, len: usize) -> SolverResult<&[f64]> {
        let f = self.get(interface, name).ok_or_else(|| {
            SolverError::interface(interface, format!("no '{name}' field received"))
        })?;
        if f.values.len() != len {
            return Err(SolverError::interface(
                interface,
                format!("'{name}' has {} values, expected {len}", f.values.len()),
            ));
        }
        Ok(&f.values)
    }

    /// A writable buffer of `points * components` values for `name` on `interface`, reused
    /// from the previous window when present (contents then hold the old values).
    pub fn put(
        &mut self,
        interface: &str,
        name: &str,
        components: u32,
        points: usize,
    ) -> &mut [f64] {
        let n = points * components as usize;
        let idx = match self
            .entries
            .iter()
            .position(|(i, f)| i == interface && f.name == name)
        {
            Some(i) => i,
            None => {
                self.entries.push((
                    interface.to_string(),
                    Field {
                        name: name.to_string(),
                        components,
                        values: Vec::with_capacity(n),
                    },
                ));
                self.entries.len() - 1
            }
        };
        let f = &mut self.entries[idx].1;
        f.components = components;
        f.values.resize(n, 0.0);
        &mut f.values
    }

    /// Insert a whole field.
    pub fn insert(&mut self, interface: &str, field: Field) {
        match self
            .entries
            .iter_mut()
            .find(|(i, f)| i == interface && f.name == field.name)
        {
            Some(e) => e.1 = field,
            None => self.entries.push((interface.to_string(), field)),
        }
    }

    /// Every field of one interface.
    pub fn fields_of<'a>(&'a self, interface: &'a str) -> impl Iterator<Item = &'a Field> + 'a {
        self.entries
            .iter()
            .filter(move |(i, _)| i == interface)
            .map(|(_, f)| f)
    }

    pub fn iter(&self) -> impl Iterator<Item = (&str, &Field)> {
        self.entries.iter().map(|(i, f)| (i.as_str(), f))
    }

    /// Forget every field (keeps nothing; use between runs, not between windows).
    /// Drop every field of `interface` (a decoupled coupling: nothing stale may linger).
    pub fn remove_interface(&mut self, interface: &str) {
        self.entries.retain(|(i, _)| i != interface);
    }

    pub fn clear(&mut self) {
        self.entries.clear();
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

/// The contract every node implements (docs/architecture.md).
pub trait Solver: Send {
    fn describe(&self) -> NodeDescription;

    /// The point set of one interface (with cells/normals/weights when the solver has them).
    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh>;

    /// Called once before the first window, after the couplings are known. `inbox` holds
    /// what peers sent at set-up (e.g. a responder's interface mass and stiffness bound, in
    /// this solver's layout); the solver writes its own set-up fields into `out` (e.g. the
    /// responder's mass, stiffness bound and constraint force at t0). Set-up runs in the
    /// coupling graph's order, so a driver sees its responders' set-up fields.
    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        let _ = (bindings, inbox, out);
        Ok(())
    }

    /// The solver's stable time step now (after set-up).
    fn stable_dt(&self) -> f64;

    /// The energies and momenta of the state after set-up (impulses and work zero): the
    /// start against which the coordinator's audit balances every later window. The default,
    /// all zero, is right only for a solver that starts at rest and unstressed.
    fn initial_report(&mut self) -> SolverResult<StepReport> {
        Ok(StepReport::default())
    }

    /// Advance from `w.t0` to exactly `w.t1`, sub-cycling at the solver's own stable step.
    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport>;

    /// Write output for ParaView under `dir` (VTK), for the state at time `t` after `window`;
    /// the runtime calls it with window 0 for the state after set-up (the series' t = 0
    /// frame), then after every output window.
    fn write_output(&self, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
        let _ = (t, window, dir);
        Ok(())
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        Err(SolverError::Other("this solver cannot checkpoint".into()))
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        let _ = bytes;
        Err(SolverError::Other("this solver cannot restart".into()))
    }
    /// The coupling on `interface` has ended (seed 000 §4 decoupling): from the next window
    /// on this solver gets no inputs there and what it sends there is dropped; it goes on
    /// alone. A solver that tolerates a missing input (an immersed solid takes no force)
    /// needs nothing; one that cannot go on must refuse here, and the run ends cleanly.
    fn decouple(&mut self, interface: &str) -> SolverResult<()> {
        let _ = interface;
        Ok(())
    }

    /// The node's side of a `lagrange` coupling on `interface` (seed 003 §4,
    /// [`crate::scheme::lagrange`]), built in `setup` from the coupling's request in the
    /// set-up inbox ([`crate::scheme::lagrange::wire::request`]: the system step and the
    /// method). The participant runtime does everything else — sends the side's condensed
    /// operator, takes its free coupling steps, exchanges them for the multipliers and
    /// corrects — before it calls `advance`, which then only reports the window. `None`:
    /// the model takes no lagrange coupling.
    fn lagrange_side(
        &mut self,
        interface: &str,
    ) -> Option<&mut dyn crate::scheme::lagrange::LagrangeSide> {
        let _ = interface;
        None
    }

    /// Where this solver's explicit integrator takes a step it does not choose itself, the
    /// largest window it is stable at ([`WindowLimit`]); none by default (a solver that
    /// sub-cycles at its own stable step).
    fn window_limits(&self) -> Vec<WindowLimit> {
        Vec::new()
    }

    /// Conditions the user should know about that do not stop the run, e.g. a GPU adapter
    /// without f64 (the node runs in f32). Sent with the node's description after set-up;
    /// the coordinator logs them and lists them in `summary.json`.
    fn warnings(&self) -> Vec<String> {
        Vec::new()
    }
}

/// How a factory builds its solver.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BuildOptions {
    /// Build only to describe the node (`NODE --describe`): check every parameter, the
    /// device-related ones included, and build what the description needs (interfaces, stable
    /// step), but open no device (no GPU instance or adapter) and start nothing.
    pub describe_only: bool,
}

impl BuildOptions {
    /// For a run: everything, devices included.
    pub const RUN: BuildOptions = BuildOptions {
        describe_only: false,
    };
    /// For `NODE --describe`.
    pub const DESCRIBE: BuildOptions = BuildOptions {
        describe_only: true,
    };
}

/// Builds a solver from its model name and TOML parameter table; each node binary has one.
pub type SolverFactory =
    fn(model: &str, params: &toml::Table, opts: &BuildOptions) -> SolverResult<Box<dyn Solver>>;

#[cfg(test)]
mod tests {
    use super::*;

    /// An I/O error says its text once, however the chain is printed.
    #[test]
    fn an_io_error_is_said_once() {
        let e = SolverError::from(std::io::Error::other("No space left on device"));
        assert_eq!(e.to_string(), "No space left on device");
        let chain = format!("{:#}", anyhow::Error::from(e));
        assert_eq!(chain, "No space left on device");
    }
}
