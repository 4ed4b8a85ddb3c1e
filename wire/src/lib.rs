//! The wire contract of the co-simulation (PROTOCOL.md at the project root): the message
//! types every node and the coordinator exchange, and the versioned envelope codec that turns
//! them into bytes. Depends on serde, bincode and thiserror only, so any tool can link it.

pub mod codec;
pub mod message;

pub use codec::{
    CodecError, Envelope, EnvelopeRef, PROTOCOL_VERSION, decode, decode_done_into, decode_ref,
    encode,
};
pub use message::*;
