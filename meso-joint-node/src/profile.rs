//! Wall time per phase of the MC-SPG step, off unless enabled: the joint kernel's
//! 2-thread scaling is judged phase by phase (which phases run in parallel, which serially);
//! `examples/joint_profile.rs` prints the shares.

use std::time::Instant;

/// The phases of one step, in step order (`Model::velocity_phase`, `Model::position_phase`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Phase {
    /// Scatter update of the unsmoothed velocity (eq. 10–11, parallel).
    Scatter,
    /// Gather smoothing of the velocity (eq. 2–6, parallel).
    Gather,
    /// Rigid bodies, velocity boundary conditions and coupled particles.
    Kinematic,
    /// `x += Δt v`, `y += Δt v̂`, `u = x − X̂` (eq. 7, parallel).
    Positions,
    /// Deformation gradient, density and J2 update (eq. 8–14, parallel).
    Stress,
    /// Bond failure test and the rows it changes (eq. 15–17).
    Bonds,
    /// Re-anchoring of the kernel (every `reanchor_every` steps).
    Reanchor,
    /// Direct-nodal-integration internal force (eq. 28, parallel).
    Force,
    /// Bearing contact of rigid fasteners.
    Contact,
}

impl Phase {
    pub const ALL: [Phase; 9] = [
        Phase::Scatter,
        Phase::Gather,
        Phase::Kinematic,
        Phase::Positions,
        Phase::Stress,
        Phase::Bonds,
        Phase::Reanchor,
        Phase::Force,
        Phase::Contact,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Phase::Scatter => "scatter v̂",
            Phase::Gather => "gather v",
            Phase::Kinematic => "rigid/BC/coupled",
            Phase::Positions => "positions",
            Phase::Stress => "kinematics+J2",
            Phase::Bonds => "bond failure",
            Phase::Reanchor => "re-anchoring",
            Phase::Force => "internal force",
            Phase::Contact => "bearing contact",
        }
    }
}

/// Seconds spent in each [`Phase`], accumulated while enabled ([`PhaseClock::enable`]).
/// Disabled (the default), a lap is one branch.
#[derive(Debug, Clone, Default)]
pub struct PhaseClock {
    enabled: bool,
    last: Option<Instant>,
    /// Accumulated seconds, indexed by `Phase as usize`.
    pub secs: [f64; Phase::ALL.len()],
}

impl PhaseClock {
    /// Start accumulating (from zero).
    pub fn enable(&mut self) {
        *self = PhaseClock {
            enabled: true,
            ..Default::default()
        };
    }

    /// Mark the start of a timed stretch (the time before it is not counted).
    #[inline]
    pub fn begin(&mut self) {
        if self.enabled {
            self.last = Some(Instant::now());
        }
    }

    /// Charge the time since the last mark to `phase`.
    #[inline]
    pub fn lap(&mut self, phase: Phase) {
        if let (true, Some(t)) = (self.enabled, self.last) {
            let now = Instant::now();
            self.secs[phase as usize] += (now - t).as_secs_f64();
            self.last = Some(now);
        }
    }

    pub fn total(&self) -> f64 {
        self.secs.iter().sum()
    }
}
