//! Time integration of linear second-order systems M ü + C u̇ + K u = f (seed 003 §4):
//! the GS4-II family (`gs4`), the linear system and its factorised effective matrix
//! (`linear`), and one subdomain's side of the Lagrange-multiplier multi-time-step coupling
//! (`subdomain`, seed 003 §4.1–§4.3).

pub mod gs4;
pub mod linear;
pub mod subdomain;

pub use gs4::{Design, Gs4, Gs4Error, IntegratorSpec};

/// The septic (C³) ramp from 0 to 1 over x ∈ [0, 1]: 35x⁴ − 84x⁵ + 70x⁶ − 20x⁷, whose first
/// three derivatives vanish at both ends, so a load ramped by it leaves a second-order
/// integrator second order (a step or a C¹ ramp would excite what the order cannot follow).
/// `x` outside [0, 1] is clamped.
pub fn septic_ramp(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x.powi(4) * (35.0 + x * (-84.0 + x * (70.0 - 20.0 * x)))
}

/// How a load starts (`ramp` in a case file, with its `ramp_time` T): at once, or reached
/// over T along a smooth ramp, then held.
#[derive(
    Debug,
    Clone,
    Copy,
    Default,
    PartialEq,
    Eq,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
#[serde(rename_all = "lowercase")]
pub enum Ramp {
    /// At once, from t = 0.
    #[default]
    Step,
    /// sin²(πt/2T): C¹.
    Sin2,
    /// 35x⁴ − 84x⁵ + 70x⁶ − 20x⁷ with x = t/T: C³, for second-order studies. An older
    /// spelling, `"ramp"`, is read as this one.
    #[serde(alias = "ramp")]
    Septic,
}

impl Ramp {
    /// Its name in a case file.
    pub fn name(self) -> &'static str {
        match self {
            Ramp::Step => "step",
            Ramp::Sin2 => "sin2",
            Ramp::Septic => "septic",
        }
    }

    /// The load factor at time t ≥ 0 of this ramp over `time`.
    pub fn factor(self, t: f64, time: f64) -> f64 {
        match self {
            Ramp::Step => 1.0,
            Ramp::Sin2 => {
                let x = (t / time).clamp(0.0, 1.0);
                (std::f64::consts::FRAC_PI_2 * x).sin().powi(2)
            }
            Ramp::Septic => septic_ramp(t / time),
        }
    }
}

/// A load's time history g(t) ∈ [0, 1]: its ramp over its ramp time (0 for a step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoadRamp {
    pub ramp: Ramp,
    pub time: f64,
}

impl LoadRamp {
    pub const STEP: LoadRamp = LoadRamp {
        ramp: Ramp::Step,
        time: 0.0,
    };

    /// `ramp` with its `ramp_time` (s) as a case gives them: a ramp time with every ramp but
    /// a step, and none with a step. Err: the key at fault (`"ramp_time"`) and why.
    pub fn new(ramp: Ramp, ramp_time: Option<f64>) -> Result<LoadRamp, (&'static str, String)> {
        match (ramp, ramp_time) {
            (Ramp::Step, None) => Ok(LoadRamp::STEP),
            (Ramp::Step, Some(_)) => Err((
                "ramp_time",
                "only applies with a ramp (ramp = \"sin2\" or \"septic\")".into(),
            )),
            (ramp, Some(time)) if time.is_finite() && time > 0.0 => Ok(LoadRamp { ramp, time }),
            (ramp, t) => Err((
                "ramp_time",
                format!(
                    "ramp = \"{}\" needs ramp_time > 0 (s), got {t:?}",
                    ramp.name()
                ),
            )),
        }
    }

    /// g(t).
    pub fn at(self, t: f64) -> f64 {
        self.ramp.factor(t, self.time)
    }
}
pub use linear::{Csr, LinearSystem, SparseLlt, State, Stepper};
pub use subdomain::{CouplingMethod, InterfaceDof, Subdomain, SubdomainState};
