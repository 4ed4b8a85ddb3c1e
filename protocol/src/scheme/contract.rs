//! What every coupling scheme fixes, as the [`Scheme`] trait whose defaults are the
//! driver/responder contract, and the field vocabulary the schemes share (which fields are
//! motion, how many components each has).

use crate::fieldset::FieldSet;
use crate::mapping::Mapping;
use wire::message::{Field, InterfaceMesh, Role};

/// What a coupling scheme fixes. The defaults are the driver/responder contract that
/// `kinematic` and `immersed` share; a scheme overrides what differs. Every method is
/// allocation-free except where it builds a message or a mapping.
pub trait Scheme: Sync {
    /// The fields the driver and the responder send (`driver_fields`, `responder_fields`)
    /// when the case file does not list them; for a lagrange coupling what every side
    /// provides and accepts.
    fn default_fields(&self) -> (&'static [&'static str], &'static [&'static str]);

    /// Windows between a peer's output and the window of `role` that consumes it, under the
    /// serial (`serial`) or parallel schedule: the driver's input (the responder's loads)
    /// arrives at the next sync time; the responder's (the driver's motion) in the same
    /// window when serial, a window later when parallel.
    fn input_lag(&self, role: Role, serial: bool) -> u64 {
        match role {
            Role::Driver => 1,
            Role::Responder => u64::from(!serial),
        }
    }

    /// Whether the responder needs its driver's output of the same window, so that the serial
    /// schedule advances the driver first.
    fn responder_after_driver(&self, serial: bool) -> bool {
        serial
    }

    /// Why the parallel schedule (every input lagged by a window) cannot run the scheme.
    fn parallel_refusal(&self) -> Option<&'static str> {
        None
    }

    /// Whether a coupling of the scheme can end before the run (`decouple_at`/`_when`).
    fn decouples(&self) -> bool {
        false
    }

    /// Whether the coupling joins N ≥ 2 sides (`sides` in the case, each bound as a driver)
    /// through an interface problem the coordinator solves, rather than a driver and a
    /// responder: each side talks to the coordinator only (its data topic's one reader), not
    /// to a peer node; the coordinator keeps the scheme's hub, checkpoints its state and
    /// checks no field contract on the sides' data (the hub reads it).
    fn coordinator_solved(&self) -> bool {
        false
    }

    /// Whether the responder's interface points are tied to the driver's by nearest point,
    /// so that on equal point counts each pair must coincide.
    fn ties_points(&self) -> bool {
        false
    }

    /// The peer output window that window `window` (0 = set-up) of a side with `role` and
    /// `input_lag` consumes, when the coupling is decoupled before window `until`; None:
    /// nothing.
    fn input_window(
        &self,
        role: Role,
        input_lag: u64,
        until: Option<u64>,
        window: u64,
    ) -> Option<u64> {
        driver_responder_input(role, input_lag, until, window)
    }

    /// The fields the side with `role` sends every window, by the scheme's contract.
    fn sends(&self, role: Role) -> &'static [&'static str] {
        let (driver, responder) = self.default_fields();
        match role {
            Role::Driver => driver,
            Role::Responder => responder,
        }
    }

    /// Whether the side with `role` moves its interface along its peer's motion
    /// ([`Follow`](super::kinematic::Follow)) and sends back its interface force, rather than sending its
    /// motion and taking its peer's loads.
    fn follows(&self, _role: Role) -> bool {
        false
    }

    /// Whether the responder's interface is a boundary layer of the driver's material (the
    /// overlap scheme): its points follow the driver and carry no mass of their own (the
    /// driver's elements carry it), and the responder sends the force its own material exerts
    /// on them, corrected each window so that the driver receives exactly the impulse the
    /// responder's material took.
    fn boundary_layer(&self) -> bool {
        false
    }

    /// Fields the side with `role` sends at set-up besides its window fields.
    fn setup_sends(&self, _role: Role) -> &'static [&'static str] {
        &[]
    }

    /// Fields the side with `role` receives at set-up besides its peer's window fields.
    fn setup_receives(&self, role: Role) -> &'static [&'static str] {
        self.setup_sends(match role {
            Role::Driver => Role::Responder,
            Role::Responder => Role::Driver,
        })
    }

    /// Whether a window's inbox may lack the loads of a side that takes them: before its
    /// peer's first output (the peer sends nothing at set-up) and after a decoupling.
    fn loads_may_be_absent(&self) -> bool {
        false
    }

    /// Whether the node's peer mesh must have arrived before set-up.
    fn needs_peer_mesh(&self) -> bool {
        false
    }

    /// The responder's mapping from the driver's interface mesh `driver` onto its own
    /// (None: the fields travel as they are).
    fn responder_map(
        &self,
        _driver: &InterfaceMesh,
        _own: &InterfaceMesh,
    ) -> Result<Option<Mapping>, String> {
        Ok(None)
    }

    /// Whether the node sends its outbox at the end of window `window` (0 = set-up).
    fn sends_at_window_end(&self, _window: u64) -> bool {
        true
    }

    /// Put field `field` received on `interface` into the inbox, in the solver's layout.
    fn receive(
        &self,
        _role: Role,
        _map: Option<&Mapping>,
        interface: &str,
        field: &Field,
        inbox: &mut FieldSet,
    ) -> Result<(), String> {
        inbox.insert(interface, field.clone());
        Ok(())
    }

    /// The wire form of output field `field` (in the driver's layout); `scratch` is a reused
    /// buffer.
    fn send(
        &self,
        _role: Role,
        _map: Option<&Mapping>,
        field: &Field,
        _scratch: &mut Vec<f64>,
    ) -> Result<Field, String> {
        Ok(field.clone())
    }
}

/// Fields mapped with `W` (interpolated motion) — every other field is a load mapped with `Wᵀ`.
pub const MOTION_FIELDS: &[&str] = &[
    "position",
    "velocity",
    "displacement",
    "acceleration",
    "rotation",
    "normal",
    "angular_velocity",
];

/// Whether field `name` is motion (mapped with `W`), not a load.
pub fn is_motion(name: &str) -> bool {
    MOTION_FIELDS.contains(&name)
}

/// Values per point of the field names the schemes exchange (PROTOCOL.md 5.3, `Field`):
/// vectors have 3 components whatever the model's dimension (a bar's force is `[f, 0, 0]`),
/// scalars 1. A receiver sizes its inputs by them, so a sender must keep to them.
pub const FIELD_COMPONENTS: &[(&str, u32)] = &[
    ("position", 3),
    ("velocity", 3),
    ("displacement", 3),
    ("acceleration", 3),
    ("rotation", 3),
    ("normal", 3),
    ("angular_velocity", 3),
    ("force", 3),
    ("moment", 3),
    ("mass", 1),
    ("stiffness", 1),
    ("volume", 1),
];

/// The components per point of field `name` by [`FIELD_COMPONENTS`] (None: a name outside
/// it, whose sender says how many).
pub fn components_of(name: &str) -> Option<u32> {
    FIELD_COMPONENTS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|&(_, c)| c)
}

/// The driver/responder input rule (docs/architecture.md): at set-up the driver waits for its
/// responder's set-up fields (the kinematic coupling's mass and stiffness) and the responder
/// sets up at once, whatever the schedule (in `parallel` both sides lag, and both waiting
/// would deadlock); window `window` consumes the peer's window `window - input_lag`, unless
/// that comes after a decoupling before window `until`.
pub fn driver_responder_input(
    role: Role,
    input_lag: u64,
    until: Option<u64>,
    window: u64,
) -> Option<u64> {
    if window == 0 {
        return (role == Role::Driver).then_some(0);
    }
    let k = window.checked_sub(input_lag)?;
    // After a decoupling only what the peer produced before it is still consumed.
    match until {
        Some(u) if k >= u => None,
        _ => Some(k),
    }
}
