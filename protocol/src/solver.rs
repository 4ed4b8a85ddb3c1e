//! The `Solver` trait (docs/architecture.md): what every node implements. It is independent of any
//! transport, so the participant runtime, the replay tool and unit tests all drive a solver
//! the same way, in-process.
//!
//! Data cross the trait per interface as named flat arrays (`Field`), in the solver's own
//! point layout: the participant runtime maps between the peer's layout and this one.

pub use crate::error::{SolverError, SolverResult};
pub use crate::fieldset::{FieldSet, Inbox, Outbox};
use crate::message::{Binding, InterfaceMesh, StepReport};
use std::path::Path;

/// One coupling window `[t0, t1]`; windows count from 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    pub index: u64,
    pub t0: f64,
    pub t1: f64,
    pub write_output: bool,
}

/// Where a node's integrator cannot choose its own step, the largest window it is stable at
/// (`NODE --describe` states it, so that `cosim validate` refuses an unstable set-up before
/// anything runs), or clear of the sub-cycling resonance (warned of). A node that sub-cycles
/// at its own stable step has no stability limit.
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
    /// What a longer step does: blow up (refused) or resonate (warned of). Absent:
    /// stability.
    #[serde(default)]
    pub kind: LimitKind,
}

/// What stepping beyond a [`WindowLimit`] does.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LimitKind {
    /// The integrator is unstable: `cosim` refuses the window.
    #[default]
    Stability,
    /// A mode of the side turns whole periods in one window, where the window-end constraint
    /// of `gs4` and `ph` cannot hold it (docs/architecture.md, "Sub-cycling resonance"):
    /// `cosim` warns.
    Resonance,
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

/// A solver factory that owns what it needs: the C participant library's callback table, a
/// Python object. Called once, after the coordinator's `Welcome` (or for `--describe`, with
/// [`BuildOptions::DESCRIBE`]).
pub type BoxedFactory =
    Box<dyn FnOnce(&str, &toml::Table, &BuildOptions) -> SolverResult<Box<dyn Solver>>>;
