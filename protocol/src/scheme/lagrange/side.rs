//! The scheme's node side: what a subdomain's solver does for it.

/// What a subdomain's node does for the scheme, in the side's local multiplier order. In
/// process ([`InterfaceSolver::new`](super::InterfaceSolver::new)) the vectors are signed (Bᵢ x); through `cosim run` a
/// side keeps every sign +1 and the coordinator applies the signs (see [`wire`](super::wire)).
pub trait LagrangeSide {
    /// Global multiplier index of each local multiplier.
    fn multiplier_ids(&self) -> &[usize];
    /// Coupling steps per system step (1 for gs4/ph; the ratio mᵢ for gc).
    fn coupling_steps(&self) -> usize;
    /// Bᵢ Hᵢ, row-major: interface velocity at a coupling step's end per unit multiplier.
    fn operator(&self) -> &[f64];
    /// At t = 0: free interface acceleration and Bᵢ M⁻¹ Bᵢᵀ (row-major).
    fn initial(&mut self, free: &mut [f64], op: &mut [f64]);
    fn set_initial(&mut self, lambda0: &[f64]);
    /// Free coupling step: interface velocity at its start and at its end.
    fn free_step(&mut self, v_start: &mut [f64], v_free: &mut [f64]);
    /// Correct with the multipliers at the coupling step's end.
    fn correct(&mut self, lambda: &[f64]);
    /// Work done on the side by the interface forces since t = 0 (J).
    fn interface_work(&self) -> f64;
    /// Its coupling state at a window end, as bytes in its own versioned format, for a
    /// checkpoint (PROTOCOL.md §4.5): what `free_step` and `correct` carry from one system
    /// step to the next (the operators are built again at set-up). The runtime calls it
    /// after the solver's own `save_state`. The default: this side cannot checkpoint, and
    /// a checkpointed run stops at its first checkpoint with this reason.
    fn save_state(&self) -> Result<Vec<u8>, String> {
        Err("this lagrange side cannot save its coupling state".into())
    }
    /// Restore what [`Self::save_state`] wrote, after set-up (and after the solver's own
    /// `load_state`).
    fn load_state(&mut self, _bytes: &[u8]) -> Result<(), String> {
        Err("this lagrange side cannot load a coupling state".into())
    }
}
