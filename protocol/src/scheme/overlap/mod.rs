//! The overlap scheme (`kind = "overlap"`, docs/architecture.md §4): a fine model (the
//! responder, a peridynamic patch) replaces a region of a coarse one (the driver, a finite
//! element mesh whose elements there are left out), and a boundary layer of the fine model's
//! points outside the region follows the coarse model's motion, interpolated with the coarse
//! shape functions (`v_r = W v_d`). Those points are the coarse model's material: they carry
//! no mass of their own. The responder sends back, per layer point, the force its own material
//! (the points inside the region) exerts on it, which the driver takes through `Wᵀ` at its
//! layer nodes. The force sent for window k is the impulse the region took over the window,
//! per unit time, plus half the pull's change over it, so that the driver receives exactly
//! the impulse the patch took, one window later.

use super::contract::Scheme;
use super::kinematic::Kinematic;
use crate::fieldset::FieldSet;
use crate::mapping::Mapping;
use wire::message::{Field, InterfaceMesh, Role};

/// What the driver sends by default: its layer nodes' motion.
pub const DRIVER_FIELDS: &[&str] = &["position", "velocity"];
/// What the responder sends by default: the force on its layer points.
pub const RESPONDER_FIELDS: &[&str] = &["force"];

/// The scheme's contract: the kinematic scheme's, with a massless boundary layer and an
/// impulse-conserving force.
pub struct Overlap;

impl Scheme for Overlap {
    fn default_fields(&self) -> (&'static [&'static str], &'static [&'static str]) {
        (DRIVER_FIELDS, RESPONDER_FIELDS)
    }

    fn parallel_refusal(&self) -> Option<&'static str> {
        Some(
            "\"parallel\" lags every input by a window, which is unstable for the overlap coupling",
        )
    }

    fn needs_peer_mesh(&self) -> bool {
        true
    }

    fn follows(&self, role: Role) -> bool {
        role == Role::Responder
    }

    fn boundary_layer(&self) -> bool {
        true
    }

    /// Always through the driver's shape functions: the layer points lie inside its cells.
    fn responder_map(
        &self,
        driver: &InterfaceMesh,
        own: &InterfaceMesh,
    ) -> Result<Option<Mapping>, String> {
        if driver
            .cells
            .as_ref()
            .is_none_or(|c| c.connectivity.is_empty())
        {
            return Err("the overlap driver's interface must be a mesh of cells".into());
        }
        Mapping::consistent(driver, &own.positions)
            .map(Some)
            .map_err(|e| format!("cannot map onto the driver's mesh: {e}"))
    }

    fn receive(
        &self,
        role: Role,
        map: Option<&Mapping>,
        interface: &str,
        field: &Field,
        inbox: &mut FieldSet,
    ) -> Result<(), String> {
        Kinematic.receive(role, map, interface, field, inbox)
    }

    fn send(
        &self,
        role: Role,
        map: Option<&Mapping>,
        field: &Field,
        scratch: &mut Vec<f64>,
    ) -> Result<Field, String> {
        Kinematic.send(role, map, field, scratch)
    }
}
