//! The contracts of the co-simulation: messages and their versioned codec, the transports
//! that carry them (iceoryx2 shared memory, zenoh, in-process), the `Solver` trait every node
//! implements, the participant runtime that runs a `Solver` as a node, and interface mapping.

/// `eprintln!` that cannot panic. A node's stderr is its log file: on a full disk the write
/// fails, and `eprintln!` would turn the message into a panic that hides it; this drops it.
#[macro_export]
macro_rules! log_line {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

pub mod checkpoint;
pub mod describe;
pub mod diverged;
pub mod error;
pub mod fieldset;
pub mod mapping;
pub mod memory;
pub mod params;
pub mod participant;
pub mod registry;
pub mod scheme;
pub mod solver;
pub mod stop;
pub mod transport;
pub mod watchdog;

// The wire types live in their own crate (`wire`, PROTOCOL.md); every path through
// `protocol` keeps working.
pub use solver::*;
pub use wire::message::*;
pub use wire::{self, codec, message};
pub use wire::{CodecError, Envelope, PROTOCOL_VERSION, decode, encode};
