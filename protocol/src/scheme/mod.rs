//! Coupling schemes, one module each, holding what is particular to the scheme: its field
//! contract, the coordinator's schedule for it (input lags, same-window order) and its node
//! side (what each side sends, what it does with what arrives; docs/architecture.md).
//!
//! * [`kinematic`]: `kind = "kinematic"`, the kinematic (sync-force) scheme (§5.1);
//! * [`immersed`]: `kind = "immersed"`, the immersed boundary scheme (§5.2);
//! * [`lagrange`]: `kind = "lagrange"`, Lagrange multipliers solved by the coordinator
//!   (§5.3): its contract, its node side, its interface solver and the coordinator's hub;
//! * [`overlap`]: `kind = "overlap"`, a fine patch replacing a region of a coarse mesh, its
//!   boundary layer following the mesh (§5.4).
//!
//! [`of`] gives a kind's [`Scheme`]; the coordinator's validation and bindings and the
//! participant runtime ask it instead of matching on the kind.

pub mod immersed;
pub mod kinematic;
pub mod lagrange;
pub mod overlap;

mod contract;

pub use contract::{
    FIELD_COMPONENTS, MOTION_FIELDS, Scheme, components_of, driver_responder_input, is_motion,
};

use wire::message::CouplingKind;

/// The scheme of a coupling kind.
pub fn of(kind: CouplingKind) -> &'static dyn Scheme {
    match kind {
        CouplingKind::Kinematic => &kinematic::Kinematic,
        CouplingKind::Immersed => &immersed::Immersed,
        CouplingKind::Lagrange => &lagrange::Lagrange,
        CouplingKind::Overlap => &overlap::Overlap,
    }
}
