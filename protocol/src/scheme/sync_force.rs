//! The kinematic sync-force scheme (`kind = "kinematic"`, docs/architecture.md.1): the driver
//! sends its interface motion, the responder follows it and sends back the interface force,
//! which reaches the driver at the next sync time. A responder whose interface differs from
//! the driver's maps motion with `v_r = W v_d` and its loads with `f_d = Wᵀ f_r`. Within a
//! window the responder follows the driver's motion interpolated in time ([`Follow`]).

use super::Scheme;
use crate::mapping::Mapping;
use crate::participant::is_motion;
use crate::solver::FieldSet;
use serde::{Deserialize, Serialize};
use wire::message::{Field, InterfaceMesh, Role};

/// What the driver sends by default: its interface motion.
pub const DRIVER_FIELDS: &[&str] = &["position", "velocity"];
/// What the responder sends by default: the interface force.
pub const RESPONDER_FIELDS: &[&str] = &["force"];
/// What the responder sends at set-up besides its force: per point its coupling mass and a
/// stiffness bound, which the driver adds to its interface and its stable step.
pub const RESPONDER_SETUP: &[&str] = &["mass", "stiffness"];

pub struct SyncForce;

impl Scheme for SyncForce {
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

/// How a responder's interface points follow the driver through one window (seed 004 eq.
/// 31–32: the driver's motion interpolated in time between the sync times).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Path {
    /// The driver's velocity at the sync time, held over the window: after sub-step k of n
    /// (step Δt) a point is at `x₀ + ((k+1)Δt) v` — integrated from its window-start state
    /// `x₀`, not accumulated, so no drift builds up — and moves at `v`.
    #[default]
    Held,
    /// The driver's positions at the last and the next sync time, interpolated linearly:
    /// after sub-step k of n a point is at `(1 − s) x_n + s x_{n+1}`, `s = (k+1)/n`, and is
    /// moved there from where it is, `x`, at `(x(s) − x)/Δt`.
    Linear,
}

/// The responder's side of the sync-force scheme within a window: per interface point (a
/// fixed count, `c` components each, flat), its window-start state and what arrived for the
/// sync time (a velocity for [`Path::Held`], a position for [`Path::Linear`]); sub-step `k`
/// of `n` gives the position and the velocity to prescribe. Sized once; nothing allocates
/// per window.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Follow {
    path: Path,
    c: usize,
    start: Vec<f64>,
    end: Vec<f64>,
}

impl Follow {
    /// `points` points of `c` components each, all at rest at the origin.
    pub fn new(path: Path, points: usize, c: usize) -> Self {
        Follow {
            path,
            c,
            start: vec![0.0; points * c],
            end: vec![0.0; points * c],
        }
    }

    pub fn path(&self) -> Path {
        self.path
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.start.len().checked_div(self.c).unwrap_or(0)
    }

    pub fn is_empty(&self) -> bool {
        self.start.is_empty()
    }

    /// Point `q`'s state at the window start (`c` values).
    pub fn set_start(&mut self, q: usize, x: &[f64]) {
        self.start[q * self.c..(q + 1) * self.c].copy_from_slice(x);
    }

    /// What arrived for point `q` at the sync time (`c` values): its velocity ([`Path::Held`])
    /// or its position ([`Path::Linear`]).
    pub fn set_end(&mut self, q: usize, x: &[f64]) {
        self.end[q * self.c..(q + 1) * self.c].copy_from_slice(x);
    }

    /// Component `d` of point `q`'s position after sub-step `k` (0-based) of `n`, of step `dt`.
    #[inline]
    pub fn position(&self, q: usize, d: usize, k: u64, n: u64, dt: f64) -> f64 {
        let i = q * self.c + d;
        match self.path {
            Path::Held => self.start[i] + (k + 1) as f64 * dt * self.end[i],
            Path::Linear => {
                let s = (k + 1) as f64 / n as f64;
                (1.0 - s) * self.start[i] + s * self.end[i]
            }
        }
    }

    /// Component `d` of the velocity to prescribe on point `q`, now at `x`, over sub-step `k`
    /// of `n` (constant over the window for [`Path::Held`]).
    #[inline]
    pub fn velocity(&self, q: usize, d: usize, x: f64, k: u64, n: u64, dt: f64) -> f64 {
        match self.path {
            Path::Held => self.end[q * self.c + d],
            Path::Linear => (self.position(q, d, k, n, dt) - x) / dt,
        }
    }

    /// Close the window: along a [`Path::Linear`] the next one starts at this one's sync
    /// positions (the held path's start is set anew from the node's state each window).
    pub fn next_window(&mut self) {
        if self.path == Path::Linear {
            std::mem::swap(&mut self.start, &mut self.end);
        }
    }
}
