//! The kinematic scheme's node side within a window: how a responder's interface points
//! follow the driver's motion between the sync times.

use serde::{Deserialize, Serialize};

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
