//! The solid node's side of the Lagrange-multiplier coupling: a linear subdomain
//! (`mechanics::time::Subdomain`, seed 003 §4) presented to the scheme
//! (`protocol::scheme::lagrange`), which solves the interface problem.
//!
//! How a model takes part in `kind = "lagrange"` (as `bar-1d` does): in `Solver::setup`, for
//! the binding of kind `Lagrange`, read the system step and method with
//! `protocol::scheme::lagrange::wire::request(inbox, interface)`, build a `Subdomain` of its
//! linear system (its own integrator, its `substeps` per system step, one `InterfaceDof` per
//! interface unknown with sign +1 and local multiplier index 0, 1, ... in the order of its
//! interface points, then per point its components), keep it as a [`SubdomainSide`], return
//! it from `Solver::lagrange_side`, and list `lagrange_operator` among the fields the
//! interface provides (`velocity` too, and `force` among those it accepts). The runtime does
//! the rest; `advance` only reports the window from the subdomain's state.

use mechanics::time::{Gs4, Subdomain};
use protocol::scheme::lagrange::LagrangeSide;
use protocol::{LimitApplies, LimitKind, WindowLimit};

/// The resonance limit of a side that takes `substeps` steps of `coef` (named `integrator`)
/// per window on a mesh whose explicit critical step is `critical` (docs/architecture.md,
/// "Sub-cycling resonance"): under `gs4` and `ph`, a window whose steps pass it puts a mode
/// of the mesh at a whole number of periods per window. None when the integrator has no
/// resonance at that count or damps it.
pub fn resonance_limit(
    coef: &Gs4,
    integrator: &str,
    substeps: usize,
    critical: f64,
) -> Option<WindowLimit> {
    let max_step = coef.resonance_free_step(substeps, critical)?;
    Some(WindowLimit {
        applies: LimitApplies::LagrangeSideGs4OrPh,
        integrator: integrator.to_string(),
        substeps: substeps as u64,
        max_step,
        key: Some("params.substeps".into()),
        kind: LimitKind::Resonance,
    })
}

/// The same check where the node chose its own `substeps` for the `window` (no limit
/// could be stated before the run): the warning the node gives at set-up, or None.
pub fn resonance_warning(
    coef: &Gs4,
    integrator: &str,
    substeps: usize,
    window: f64,
    critical: f64,
) -> Option<String> {
    let l = resonance_limit(coef, integrator, substeps, critical)?;
    let step = window / substeps as f64;
    (step > l.max_step).then(|| {
        format!(
            "as a lagrange side it steps {integrator} {substeps} times per window of {window:e} s \
             ({step:.4e} s), past {:.4e} s, where a mode of its mesh turns whole periods in one \
             window and the window-end constraint cannot hold it: the multipliers may lose \
             accuracy. Clear of it: a smaller run.window or step, or a dissipative design \
             (\"Sub-cycling resonance\" in docs/architecture.md)",
            l.max_step
        )
    })
}

/// A subdomain as one side of a `lagrange` coupling.
#[derive(Debug)]
pub struct SubdomainSide(pub Subdomain);

impl LagrangeSide for SubdomainSide {
    fn multiplier_ids(&self) -> &[usize] {
        self.0.multiplier_ids()
    }
    fn coupling_steps(&self) -> usize {
        self.0.coupling_steps()
    }
    fn operator(&self) -> &[f64] {
        self.0.operator()
    }
    fn initial(&mut self, free: &mut [f64], op: &mut [f64]) {
        self.0.initial(free, op)
    }
    fn set_initial(&mut self, lambda0: &[f64]) {
        self.0.set_initial(lambda0)
    }
    fn free_step(&mut self, v_start: &mut [f64], v_free: &mut [f64]) {
        self.0.free_step(v_start, v_free)
    }
    fn correct(&mut self, lambda: &[f64]) {
        self.0.correct(lambda)
    }
    fn interface_work(&self) -> f64 {
        self.0.interface_work
    }
    fn save_state(&self) -> Result<Vec<u8>, String> {
        protocol::checkpoint::encode_state(&self.0.save()).map_err(|e| e.to_string())
    }
    fn load_state(&mut self, bytes: &[u8]) -> Result<(), String> {
        let s = protocol::checkpoint::decode_state(bytes).map_err(|e| e.to_string())?;
        self.0.restore(s).map_err(|e| e.to_string())
    }
}
