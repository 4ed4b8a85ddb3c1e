//! What a solver reports when it cannot go on (a bad parameter, a bad coupling input, a
//! state become unphysical), and why the participant runtime around it stopped.

use thiserror::Error;

#[derive(Debug, Error)]
pub enum SolverError {
    /// Bad parameter: the key path and why (`nodes.left.params.elements: must be > 0, got 0`).
    #[error("{key}: {reason}")]
    Config { key: String, reason: String },
    /// A coupling input is missing or has the wrong size.
    #[error("interface {interface}: {reason}")]
    Interface { interface: String, reason: String },
    /// The state became unphysical (negative density, NaN, ...): where and when.
    #[error("diverged at t = {time:e}: {reason}")]
    Diverged { time: f64, reason: String },
    /// Transparent: the I/O error is the message, not also its source (a chain printed with
    /// `{:#}` would say it twice).
    #[error(transparent)]
    Io(#[from] std::io::Error),
    #[error("{0}")]
    Other(String),
}

impl SolverError {
    pub fn config(key: impl Into<String>, reason: impl Into<String>) -> Self {
        SolverError::Config {
            key: key.into(),
            reason: reason.into(),
        }
    }
    pub fn interface(interface: impl Into<String>, reason: impl Into<String>) -> Self {
        SolverError::Interface {
            interface: interface.into(),
            reason: reason.into(),
        }
    }
}

pub type SolverResult<T> = Result<T, SolverError>;

/// Why the participant runtime around a solver stopped.
#[derive(Debug, Error)]
pub enum EngineError {
    #[error("{0}")]
    Solver(#[from] SolverError),
    #[error("coupling {coupling}: {reason}")]
    Coupling { coupling: String, reason: String },
    /// A non-finite value in what the node was about to send (never sent).
    #[error(transparent)]
    Diverged(#[from] crate::diverged::Divergence),
}

impl EngineError {
    pub fn coupling(coupling: impl Into<String>, reason: impl Into<String>) -> Self {
        EngineError::Coupling {
            coupling: coupling.into(),
            reason: reason.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An I/O error says its text once, however the chain is printed.
    #[test]
    fn an_io_error_is_said_once() {
        let e = SolverError::from(std::io::Error::other("No space left on device"));
        assert_eq!(e.to_string(), "No space left on device");
        let chain = format!("{:#}", anyhow::Error::from(e));
        assert_eq!(chain, "No space left on device");
    }
}
