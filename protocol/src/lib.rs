//! The contracts of the co-simulation: messages and their versioned codec, the transports
//! that carry them (iceoryx2 shared memory, zenoh, in-process), the `Solver` trait every node
//! implements, the participant runtime that runs a `Solver` as a node, and interface mapping.

pub mod codec;
pub mod mapping;
pub mod message;
pub mod participant;
pub mod solver;
pub mod stop;
pub mod transport;
pub mod watchdog;

pub use codec::{CodecError, Envelope, PROTOCOL_VERSION, decode, encode};
pub use message::*;
pub use solver::*;
