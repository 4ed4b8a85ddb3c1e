//! Time integration of linear second-order systems M ü + C u̇ + K u = f (seed 003 §4):
//! the GS4-II family (`gs4`), the linear system and its factorised effective matrix
//! (`linear`), and one subdomain's side of the Lagrange-multiplier multi-time-step coupling
//! (`subdomain`, seed 003 §4.1–§4.3).

pub mod gs4;
pub mod linear;
pub mod subdomain;

pub use gs4::{Design, Gs4, Gs4Error, IntegratorSpec};
pub use linear::{Csr, LinearSystem, SparseLlt, State, Stepper};
pub use subdomain::{CouplingMethod, InterfaceDof, Subdomain, SubdomainState};
