//! The immersed boundary scheme (`kind = "immersed"`, docs/architecture.md.2): the driver (the
//! solid) sends its particles' motion and volume, the responder (the fluid) immerses them in
//! its grid as they are (no interface mapping) and sends back the force on each particle. It
//! can end before the run: the solid goes on alone (seed 000 §4).

use super::contract::Scheme;

/// What the driver sends by default: its particles' motion and volume.
pub const DRIVER_FIELDS: &[&str] = &["position", "velocity", "volume"];
/// What the responder sends by default: the force on each particle.
pub const RESPONDER_FIELDS: &[&str] = &["force"];

pub struct Immersed;

impl Scheme for Immersed {
    fn default_fields(&self) -> (&'static [&'static str], &'static [&'static str]) {
        (DRIVER_FIELDS, RESPONDER_FIELDS)
    }

    fn decouples(&self) -> bool {
        true
    }

    /// The fluid sends nothing at set-up, and nothing after the decoupling.
    fn loads_may_be_absent(&self) -> bool {
        true
    }
}
