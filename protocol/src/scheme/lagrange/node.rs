//! The scheme's node side, as the participant runtime runs it: the side's set-up fields, its
//! free coupling steps, the corrections with the multipliers the coordinator sends and its
//! part of a checkpoint. Functions over the solver and the coupling's binding; the runtime
//! finds the binding and its buffered coordinator messages.

use super::LagrangeSide;
use super::wire;
use crate::checkpoint;
use crate::error::{EngineError, SolverError, SolverResult};
use crate::fieldset::FieldSet;
use crate::message::{Binding, Field, Fields};
use crate::solver::Solver;
use std::collections::VecDeque;

/// The solver's lagrange side on binding `b`'s interface; a model without one is refused.
fn side_of<'a>(
    solver: &'a mut dyn Solver,
    b: &Binding,
) -> Result<&'a mut dyn LagrangeSide, EngineError> {
    let model = solver.describe().model;
    solver.lagrange_side(&b.interface).ok_or_else(|| {
        EngineError::coupling(
            &b.coupling,
            format!("model '{model}' takes no lagrange coupling"),
        )
    })
}

/// After the solver's set-up: the side's set-up fields into the outbox.
pub fn setup(
    solver: &mut dyn Solver,
    b: &Binding,
    outbox: &mut FieldSet,
) -> Result<(), EngineError> {
    wire::setup_fields(side_of(solver, b)?, &b.interface, outbox);
    Ok(())
}

/// Coupling steps per window of the side.
pub fn steps(solver: &mut dyn Solver, b: &Binding) -> Option<usize> {
    solver
        .lagrange_side(&b.interface)
        .map(|s| s.coupling_steps())
}

/// Takes the next multipliers sent to node `me` for `window` (0: the initial ones) out of the
/// buffered coordinator messages, skipping those for other sides (and the set-up request,
/// used by then); None while they have not arrived.
pub fn take(pending: &mut VecDeque<Fields>, me: &str, window: u64) -> Option<Vec<f64>> {
    while pending.front().is_some_and(|f| f.window <= window) {
        let f = pending.pop_front()?;
        if f.window < window || wire::step_of(&f).is_none() {
            continue;
        }
        if let Some(v) = f.fields.into_iter().find(|x| x.name == me) {
            return Some(v.values);
        }
    }
    None
}

/// Applies the multipliers `lambda` of `window` (window 0: the initial ones, else the end of
/// the side's current coupling step), refusing a wrong count or a non-finite value.
pub fn correct(
    solver: &mut dyn Solver,
    b: &Binding,
    window: u64,
    lambda: &[f64],
) -> Result<(), EngineError> {
    let side = side_of(solver, b)?;
    let nl = side.multiplier_ids().len();
    if lambda.len() != nl || !lambda.iter().all(|x| x.is_finite()) {
        return Err(EngineError::coupling(
            &b.coupling,
            format!(
                "multipliers of window {window}: {} values (finite expected) for {nl}",
                lambda.len()
            ),
        ));
    }
    if window == 0 {
        side.set_initial(lambda);
    } else {
        side.correct(lambda);
    }
    Ok(())
}

/// The free coupling step `c` of `window`: the message with the side's interface velocities
/// at the step's start and end, sent at time `time`.
pub fn free_step(
    solver: &mut dyn Solver,
    b: &Binding,
    c: usize,
    window: u64,
    time: f64,
) -> Result<Fields, EngineError> {
    let side = side_of(solver, b)?;
    let nl = side.multiplier_ids().len();
    let mut v_start = vec![0.0; nl];
    let mut v_free = vec![0.0; nl];
    side.free_step(&mut v_start, &mut v_free);
    let vec = |name: &str, values: Vec<f64>| Field {
        name: name.to_string(),
        components: 1,
        values,
    };
    let f = Fields {
        coupling: b.coupling.clone(),
        window,
        time,
        fields: vec![
            wire::scalar(wire::STEP, c as f64),
            vec(wire::V_START, v_start),
            vec(wire::V_FREE, v_free),
        ],
    };
    crate::diverged::check_fields(&f)?;
    Ok(f)
}

/// The solver's state for a checkpoint: its own `save_state` and the side's coupling state
/// beside it (the pair in bincode, PROTOCOL.md §4.5).
pub fn save_state(solver: &mut dyn Solver, b: &Binding) -> SolverResult<Vec<u8>> {
    let own = solver.save_state()?;
    let side = solver
        .lagrange_side(&b.interface)
        .ok_or_else(|| SolverError::Other("the lagrange side is gone".into()))?
        .save_state()
        .map_err(|e| SolverError::Other(format!("lagrange side '{}': {e}", b.interface)))?;
    checkpoint::encode_state(&(own, side))
}

/// The inverse of [`save_state`], after set-up.
pub fn load_state(solver: &mut dyn Solver, b: &Binding, bytes: &[u8]) -> SolverResult<()> {
    let (own, side): (Vec<u8>, Vec<u8>) = checkpoint::decode_state(bytes)?;
    solver.load_state(&own)?;
    solver
        .lagrange_side(&b.interface)
        .ok_or_else(|| SolverError::Other("the lagrange side is gone".into()))?
        .load_state(&side)
        .map_err(|e| SolverError::Other(format!("lagrange side '{}': {e}", b.interface)))
}
