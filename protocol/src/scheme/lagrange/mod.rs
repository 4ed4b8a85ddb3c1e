//! The Lagrange-multiplier multi-time-step coupling (seed 003 §4–§5; docs/architecture.md.3):
//! N ≥ 2 subdomains, each with its own integrator and step, tied by velocity continuity
//! Σᵢ Bᵢ vᵢ = 0 on matching interface nodes. This module solves the interface problem — in
//! one place, with no solver crate — and fixes what each subdomain's side must do
//! ([`LagrangeSide`], `side.rs`): condense its interface response once at set-up, take a free step,
//! correct with the multipliers it is sent.
//!
//! Per system step (the coarsest subdomain's step ΔT) and method:
//! * `gs4` / `ph`: every side takes its free step over ΔT (its mᵢ substeps, the multipliers
//!   ramped linearly from λ_n with the unknown increment set to zero) and reports Bᵢ v_free;
//!   `(Σᵢ Pᵢᵀ Bᵢ Hᵢ Pᵢ) Δλ = −Σᵢ Pᵢᵀ Bᵢ v_free,ᵢ` gives λ_{n+1} = λ_n + Δλ (the multiplier
//!   at the system time level, seed 003 §4.1), sent back to correct each side.
//! * `gc` (Gravouil–Combescure): at each step j of the finest subdomain, a side whose own
//!   step spans rᵢ fine steps contributes its interface velocity interpolated at θ = (j mod
//!   rᵢ + 1)/rᵢ between its start and its (linked) end,
//!   `(Σᵢ θᵢ Pᵢᵀ Bᵢ Hᵢ Pᵢ) λ_j = −Σᵢ Pᵢᵀ ((1 − θᵢ) Bᵢ v_start,ᵢ + θᵢ Bᵢ v_free,ᵢ)`,
//!   and the sides whose step ends at j correct with λ_j.
//!
//! The interface matrices depend on the steps only, so they are factorised once (dense LU
//! with partial pivoting: interfaces are small).

pub mod hub;
pub(crate) mod node;
mod side;
mod solver;
pub mod wire;

pub use hub::{Hub, HubState};
pub use side::LagrangeSide;
pub use solver::{DenseLu, InterfaceSolver, SideSetup};

use std::str::FromStr;
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum LagrangeError {
    #[error("lagrange coupling: {0}")]
    Setup(String),
    #[error("lagrange coupling: the interface matrix is singular (pivot {pivot:e} at row {row})")]
    Singular { row: usize, pivot: f64 },
}

/// Fields every side's interface must provide: its velocity and its condensed operator
/// (the handshake checks them against the node's description).
pub const PROVIDES: &[&str] = &["velocity", "lagrange_operator"];
/// Fields every side's interface must accept: the multipliers are forces on it.
pub const ACCEPTS: &[&str] = &["force"];

/// The scheme's contract (docs/architecture.md.3): every side exchanges with the coordinator,
/// which solves the interface problem; nothing is lagged and no side waits for another.
pub struct Lagrange;

impl super::contract::Scheme for Lagrange {
    fn default_fields(&self) -> (&'static [&'static str], &'static [&'static str]) {
        (PROVIDES, ACCEPTS)
    }

    fn input_lag(&self, _role: crate::message::Role, _serial: bool) -> u64 {
        0
    }

    fn responder_after_driver(&self, _serial: bool) -> bool {
        false
    }

    fn coordinator_solved(&self) -> bool {
        true
    }

    /// Set-up waits for the coordinator's request; in a window the multipliers are
    /// exchanged inside it (the runtime's `lagrange_*` steps), not taken as an input.
    fn input_window(
        &self,
        _role: crate::message::Role,
        _input_lag: u64,
        _until: Option<u64>,
        window: u64,
    ) -> Option<u64> {
        (window == 0).then_some(0)
    }

    /// Only the set-up fields go at a window's end; in a window a side sends step by step.
    fn sends_at_window_end(&self, window: u64) -> bool {
        window == 0
    }
}

/// `method = "gs4" | "gc" | "ph"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    Gs4,
    Gc,
    Ph,
}

impl FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "gs4" => Ok(Method::Gs4),
            "gc" => Ok(Method::Gc),
            "ph" => Ok(Method::Ph),
            other => Err(format!(
                "must be \"gs4\", \"gc\" or \"ph\", got \"{other}\""
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_parse_and_bad_ones_are_named() {
        assert_eq!("gs4".parse::<Method>(), Ok(Method::Gs4));
        assert_eq!("gc".parse::<Method>(), Ok(Method::Gc));
        assert_eq!("ph".parse::<Method>(), Ok(Method::Ph));
        assert!(
            "newmark"
                .parse::<Method>()
                .unwrap_err()
                .contains("\"newmark\"")
        );
    }
}
