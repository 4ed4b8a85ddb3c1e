//! The kinematic scheme (`kind = "kinematic"`, sync-force coupling, docs/architecture.md.1): the driver
//! sends its interface motion, the responder follows it and sends back the interface force,
//! which reaches the driver at the next sync time. A responder whose interface differs from
//! the driver's maps motion with `v_r = W v_d` and its loads with `f_d = Wᵀ f_r`. Within a
//! window the responder follows the driver's motion interpolated in time ([`Follow`], the
//! node side, in `follow.rs`).

mod follow;

pub use follow::{Follow, Path};

use super::contract::{Scheme, is_motion};
use crate::fieldset::FieldSet;
use crate::mapping::Mapping;
use wire::message::{Field, InterfaceMesh, Role};

/// What the driver sends by default: its interface motion.
pub const DRIVER_FIELDS: &[&str] = &["position", "velocity"];
/// What the responder sends by default: the interface force.
pub const RESPONDER_FIELDS: &[&str] = &["force"];
/// What the responder sends at set-up besides its force: per point its coupling mass and a
/// stiffness bound, which the driver adds to its interface and its stable step.
pub const RESPONDER_SETUP: &[&str] = &["mass", "stiffness"];

/// The scheme's contract: driver and responder, the responder's force lagged a window.
pub struct Kinematic;

impl Scheme for Kinematic {
    fn ties_points(&self) -> bool {
        true
    }

    fn default_fields(&self) -> (&'static [&'static str], &'static [&'static str]) {
        (DRIVER_FIELDS, RESPONDER_FIELDS)
    }

    fn parallel_refusal(&self) -> Option<&'static str> {
        Some(
            "\"parallel\" lags every input by a window, which is unstable for the kinematic coupling",
        )
    }

    fn needs_peer_mesh(&self) -> bool {
        true
    }

    fn follows(&self, role: Role) -> bool {
        role == Role::Responder
    }

    fn setup_sends(&self, role: Role) -> &'static [&'static str] {
        match role {
            Role::Driver => &[],
            Role::Responder => RESPONDER_SETUP,
        }
    }

    fn responder_map(
        &self,
        driver: &InterfaceMesh,
        own: &InterfaceMesh,
    ) -> Result<Option<Mapping>, String> {
        let same = own.positions.len() == driver.positions.len()
            && own
                .positions
                .iter()
                .zip(&driver.positions)
                .all(|(a, b)| a == b);
        if same {
            return Ok(None);
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
        let (Some(m), Role::Responder) = (map, role) else {
            inbox.insert(interface, field.clone());
            return Ok(());
        };
        if !is_motion(&field.name) {
            return Err(format!(
                "a responder receives motion only, got '{}'",
                field.name
            ));
        }
        let c = field.components.max(1) as usize;
        let dst = inbox.put(interface, &field.name, c as u32, m.n_responder());
        m.map_motion(&field.values, c, dst)
            .map_err(|e| format!("field {}: {e}", field.name))
    }

    fn send(
        &self,
        role: Role,
        map: Option<&Mapping>,
        field: &Field,
        scratch: &mut Vec<f64>,
    ) -> Result<Field, String> {
        let (Some(m), Role::Responder) = (map, role) else {
            return Ok(field.clone());
        };
        if is_motion(&field.name) {
            return Err(format!(
                "a responder sends loads only, not '{}'",
                field.name
            ));
        }
        let c = field.components.max(1) as usize;
        scratch.clear();
        scratch.resize(m.n_driver() * c, 0.0);
        m.map_load(&field.values, c, scratch)
            .map_err(|e| format!("field {}: {e}", field.name))?;
        Ok(Field {
            name: field.name.clone(),
            components: field.components,
            values: scratch.clone(),
        })
    }
}
