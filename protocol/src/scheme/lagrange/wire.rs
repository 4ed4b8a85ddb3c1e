//! The scheme on the wire (no message type of its own: `Fields` on the coupling's data
//! topics, PROTOCOL.md §4.6). A side's node publishes on `cosim/<run>/<coupling>/<node>`,
//! the coordinator on `cosim/<run>/<coupling>/coordinator`:
//!
//! 1. coordinator, window 0: [`WINDOW`] (the system step, s) and [`METHOD`] (0 gs4, 1 gc,
//!    2 ph) — the node builds its side (its condensed operator depends on both);
//! 2. node, window 0: [`DOFS`], [`STEPS`], [`OPERATOR`], [`FREE0`], [`MASS0`] (local,
//!    unsigned: see [`SideSetup`]); the coordinator matches the sides' interface points by
//!    position into multipliers with signs;
//! 3. coordinator, window 0: [`STEP`] = 0 and one field per side node, named after it,
//!    with its initial multipliers; the node applies them;
//! 4. every coupling step c of window k: node → [`STEP`] = c, [`V_START`], [`V_FREE`];
//!    coordinator → [`STEP`] = j (the fine step solved), [`LAMBDA`] (global λ, N) and the
//!    multipliers of each side node whose step ends at j, under its name.
//!
//! gs4 and ph take one exchange per window (each side one coupling step); gc one per step
//! of the finest side.

use crate::message::{Field, Fields};
use crate::solver::{FieldSet, SolverError, SolverResult};

use super::{LagrangeSide, Method};

pub const WINDOW: &str = "lagrange_window";
pub const METHOD: &str = "lagrange_method";
pub const DOFS: &str = "lagrange_dofs";
pub const STEPS: &str = "lagrange_steps";
pub const OPERATOR: &str = "lagrange_operator";
pub const FREE0: &str = "lagrange_free0";
pub const MASS0: &str = "lagrange_mass0";
pub const STEP: &str = "step";
pub const V_START: &str = "v_start";
pub const V_FREE: &str = "v_free";
pub const LAMBDA: &str = "lambda";
/// The peer name of every side's binding: the coordinator solves the interface problem.
pub const PEER: &str = "coordinator";

pub fn method_code(m: Method) -> f64 {
    match m {
        Method::Gs4 => 0.0,
        Method::Gc => 1.0,
        Method::Ph => 2.0,
    }
}

/// What the coordinator asks of a side at set-up (message 1): the system step and the
/// method, from the set-up inbox of `interface`.
pub fn request(inbox: &FieldSet, interface: &str) -> SolverResult<(Method, f64)> {
    let w = inbox.require(interface, WINDOW, 1)?[0];
    let m = inbox.require(interface, METHOD, 1)?[0];
    if !(w.is_finite() && w > 0.0) {
        return Err(SolverError::interface(
            interface,
            format!("lagrange system step must be > 0, got {w}"),
        ));
    }
    let method = match m {
        0.0 => Method::Gs4,
        1.0 => Method::Gc,
        2.0 => Method::Ph,
        other => {
            return Err(SolverError::interface(
                interface,
                format!("unknown lagrange method code {other}"),
            ));
        }
    };
    Ok((method, w))
}

/// Message 1 (coordinator, window 0).
pub fn request_fields(coupling: &str, method: Method, window: f64) -> Fields {
    Fields {
        coupling: coupling.to_string(),
        window: 0,
        time: 0.0,
        fields: vec![scalar(WINDOW, window), scalar(METHOD, method_code(method))],
    }
}

pub fn scalar(name: &str, v: f64) -> Field {
    Field {
        name: name.to_string(),
        components: 1,
        values: vec![v],
    }
}

/// Message 2 (node, window 0): the side's set-up, into the outbox of `interface`.
pub fn setup_fields(side: &mut dyn LagrangeSide, interface: &str, out: &mut FieldSet) {
    let nl = side.multiplier_ids().len();
    out.put(interface, DOFS, 1, 1)[0] = nl as f64;
    out.put(interface, STEPS, 1, 1)[0] = side.coupling_steps() as f64;
    out.put(interface, OPERATOR, 1, nl * nl)
        .copy_from_slice(side.operator());
    let mut free0 = vec![0.0; nl];
    let mut mass0 = vec![0.0; nl * nl];
    side.initial(&mut free0, &mut mass0);
    out.put(interface, FREE0, 1, nl).copy_from_slice(&free0);
    out.put(interface, MASS0, 1, nl * nl)
        .copy_from_slice(&mass0);
}

/// The coupling step index of a node's message, or the fine step of a coordinator's.
pub fn step_of(f: &Fields) -> Option<usize> {
    let v = f.get(STEP)?.values.first().copied()?;
    (v >= 0.0 && v.fract() == 0.0 && v < u32::MAX as f64).then_some(v as usize)
}
