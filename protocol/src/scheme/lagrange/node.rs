//! The scheme's node side, as the participant runtime runs it: the side's set-up fields, its
//! free coupling steps and the corrections with the multipliers the coordinator sends.

use super::wire;
use crate::message::{Binding, Field, Fields};
use crate::participant::{EngineError, NodeEngine};
use crate::scheme;

impl NodeEngine {
    /// After the solver's set-up: each lagrange side's set-up fields into the outbox (a
    /// model without a lagrange side is refused).
    pub(crate) fn lagrange_setup(&mut self, bindings: &[Binding]) -> Result<(), EngineError> {
        for b in bindings
            .iter()
            .filter(|b| scheme::of(b.kind).coordinator_solved())
        {
            let Some(side) = self.solver.lagrange_side(&b.interface) else {
                return Err(EngineError::Coupling {
                    coupling: b.coupling.clone(),
                    reason: format!(
                        "model '{}' takes no lagrange coupling",
                        self.solver.describe().model
                    ),
                });
            };
            wire::setup_fields(side, &b.interface, &mut self.outbox);
        }
        Ok(())
    }

    /// The lagrange coupling of this node (one at most): its link index.
    pub(crate) fn lagrange_link(&self) -> Option<usize> {
        self.links
            .iter()
            .position(|l| scheme::of(l.b.kind).coordinator_solved())
    }

    /// Coupling steps per window of this node's lagrange side (None: no lagrange coupling).
    pub fn lagrange_steps(&mut self) -> Option<usize> {
        let i = self.lagrange_link()?;
        let iface = self.links[i].b.interface.clone();
        self.solver
            .lagrange_side(&iface)
            .map(|s| s.coupling_steps())
    }

    /// Takes the next multipliers sent to node `me` for `window` (0: the initial ones) out
    /// of the buffered coordinator messages, skipping those for other sides (and the set-up
    /// request, used by then); None while they have not arrived.
    fn lagrange_take(&mut self, me: &str, window: u64) -> Option<(usize, Vec<f64>)> {
        let i = self.lagrange_link()?;
        let l = &mut self.links[i];
        while l.pending.front().is_some_and(|f| f.window <= window) {
            let f = l.pending.pop_front()?;
            if f.window < window || wire::step_of(&f).is_none() {
                continue;
            }
            if let Some(v) = f.fields.into_iter().find(|x| x.name == me) {
                return Some((i, v.values));
            }
        }
        None
    }

    /// Applies the multipliers of `window` sent to node `me` once they are here (window 0:
    /// the initial ones, else the end of the side's current coupling step); false while
    /// they have not arrived.
    pub fn lagrange_correct(&mut self, me: &str, window: u64) -> Result<bool, EngineError> {
        let Some((i, lambda)) = self.lagrange_take(me, window) else {
            return Ok(false);
        };
        let (coupling, iface) = (
            self.links[i].b.coupling.clone(),
            self.links[i].b.interface.clone(),
        );
        let bad = |reason: String| EngineError::Coupling {
            coupling: coupling.clone(),
            reason,
        };
        let side = self
            .solver
            .lagrange_side(&iface)
            .ok_or_else(|| bad("the side is gone".into()))?;
        let nl = side.multiplier_ids().len();
        if lambda.len() != nl || !lambda.iter().all(|x| x.is_finite()) {
            return Err(bad(format!(
                "multipliers of window {window}: {} values (finite expected) for {nl}",
                lambda.len()
            )));
        }
        if window == 0 {
            side.set_initial(&lambda);
        } else {
            side.correct(&lambda);
        }
        Ok(true)
    }

    /// The free coupling step `c` of `window` on the lagrange side: the message with its
    /// interface velocities at the step's start and end, sent at time `time`.
    pub fn lagrange_free_step(
        &mut self,
        c: usize,
        window: u64,
        time: f64,
    ) -> Result<Fields, EngineError> {
        let Some(i) = self.lagrange_link() else {
            return Err(EngineError::Coupling {
                coupling: String::new(),
                reason: "no lagrange coupling".into(),
            });
        };
        let (coupling, iface) = (
            self.links[i].b.coupling.clone(),
            self.links[i].b.interface.clone(),
        );
        let Some(side) = self.solver.lagrange_side(&iface) else {
            return Err(EngineError::Coupling {
                coupling,
                reason: "the side is gone".into(),
            });
        };
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
            coupling,
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
}
