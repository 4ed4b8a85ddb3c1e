//! Time integration of linear second-order systems M ü + C u̇ + K u = f (seed 003 §4):
//! the GS4-II family (`gs4`), the linear system and its factorised effective matrix
//! (`linear`), and one subdomain's side of the Lagrange-multiplier multi-time-step coupling
//! (`subdomain`, seed 003 §4.1–§4.3).

pub mod gs4;
pub mod linear;
pub mod subdomain;

pub use gs4::{Design, Gs4, Gs4Error, IntegratorSpec};

/// The septic (C³) ramp from 0 to 1 over x ∈ [0, 1]: 35x⁴ − 84x⁵ + 70x⁶ − 20x⁷, whose first
/// three derivatives vanish at both ends, so a load ramped by it leaves a second-order
/// integrator second order (a step or a C¹ ramp would excite what the order cannot follow).
/// `x` outside [0, 1] is clamped.
pub fn septic_ramp(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x.powi(4) * (35.0 + x * (-84.0 + x * (70.0 - 20.0 * x)))
}
pub use linear::{Csr, LinearSystem, SparseLlt, State, Stepper};
pub use subdomain::{CouplingMethod, InterfaceDof, Subdomain, SubdomainState};
