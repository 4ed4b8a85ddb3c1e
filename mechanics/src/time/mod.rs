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
    /// t/T: a constant rate of loading up to T (e.g. a stress rate), then held.
    Linear,
}

impl Ramp {
    /// Its name in a case file.
    pub fn name(self) -> &'static str {
        match self {
            Ramp::Step => "step",
            Ramp::Sin2 => "sin2",
            Ramp::Septic => "septic",
            Ramp::Linear => "linear",
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
            Ramp::Linear => (t / time).clamp(0.0, 1.0),
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
                "only applies with a ramp (ramp = \"sin2\", \"septic\" or \"linear\")".into(),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The ramps against their closed forms at the ends and the middle: 0 at t = 0, 1 from
    /// T on (held), ½ at T/2 for both (the septic ramp is odd about (½, ½): 35/16 − 84/32 +
    /// 70/64 − 20/128 = ½; sin²(π/4) = ½), and the step 1 throughout.
    #[test]
    fn ramps_start_at_zero_end_at_one_and_cross_one_half_midway() {
        let t = 0.2;
        for r in [Ramp::Sin2, Ramp::Septic, Ramp::Linear] {
            assert_eq!(r.factor(0.0, t), 0.0, "{r:?}");
            assert!((r.factor(0.5 * t, t) - 0.5).abs() < 1e-15, "{r:?}");
            assert_eq!(r.factor(t, t), 1.0, "{r:?}");
            assert_eq!(r.factor(3.0 * t, t), 1.0, "{r:?}");
        }
        // the septic ramp's first derivative vanishes at both ends: its rise over the
        // first and last 1 % of T is of order x⁴, against 1 % for a linear ramp
        let r = Ramp::Septic;
        assert!(r.factor(0.01 * t, t) < 1e-6);
        assert!(1.0 - r.factor(0.99 * t, t) < 1e-6);
        assert_eq!(Ramp::Step.factor(0.0, t), 1.0);
    }

    /// A ramp time goes with every ramp but a step, and only with them.
    #[test]
    fn a_ramp_time_goes_with_a_ramp_only() {
        assert_eq!(LoadRamp::new(Ramp::Step, None), Ok(LoadRamp::STEP));
        assert_eq!(
            LoadRamp::new(Ramp::Step, Some(1.0)).unwrap_err().0,
            "ramp_time"
        );
        for bad in [
            None,
            Some(0.0),
            Some(-1.0),
            Some(f64::NAN),
            Some(f64::INFINITY),
        ] {
            assert_eq!(LoadRamp::new(Ramp::Septic, bad).unwrap_err().0, "ramp_time");
        }
        let l = LoadRamp::new(Ramp::Sin2, Some(2.0)).unwrap();
        assert_eq!((l.ramp, l.time), (Ramp::Sin2, 2.0));
        assert_eq!(l.at(1.0), Ramp::Sin2.factor(1.0, 2.0));
    }
}
