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

use mechanics::time::Subdomain;
use protocol::scheme::lagrange::LagrangeSide;

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
