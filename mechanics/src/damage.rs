//! Bond damage laws behind one trait (seed 000 App. C): the damage-dependent part ω_D of the
//! influence state, eq. (C.1) ω = ω_r ω_D(D). Members: brittle breaking by von Mises stress,
//! ductile softening by the equivalent plastic-strain ramp (ε_th, ε_cr) of eq. (C.2), and the
//! bond-stretch criterion of the prototype microelastic brittle material (Silling 2000).
//! Irreversibility (ω_D non-increasing, App. C) is enforced by [`DamageModel::update`].
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

/// What a damage law may look at for one bond (quantities associated with the bond, e.g. the
/// average of the two end points' values for a point-wise material model).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BondInput {
    /// Bond stretch s = |y|/|ξ| − 1.
    pub stretch: f64,
    /// Von Mises equivalent stress associated with the bond (Pa).
    pub von_mises: f64,
    /// Equivalent plastic strain associated with the bond.
    pub eq_plastic_strain: f64,
    /// Cumulative failure indicator associated with the bond (the Johnson–Cook D of a
    /// point law that has one, e.g. [`crate::blast_solid`]; 0 otherwise).
    pub failure: f64,
}

/// A bond damage law: the intact fraction ω_D ∈ [0, 1] for a bond's current state.
pub trait DamageModel: Send + Sync + std::fmt::Debug {
    /// ω_D for this state, ignoring history (1 intact, 0 broken).
    fn intact_fraction(&self, input: &BondInput) -> f64;

    /// New ω_D of a bond that had `old`: never increases (seed 000 App. C irreversibility).
    #[inline]
    fn update(&self, old: f64, input: &BondInput) -> f64 {
        if old <= 0.0 {
            return 0.0;
        }
        old.min(self.intact_fraction(input))
    }

    /// `Some(s0)` when the law is exactly "broken for good once the stretch exceeds s0"
    /// (and reads nothing else): a bond kernel may then test |y|²/|ξ|² > (1 + s0)² instead
    /// of forming the stretch, saving a square root and a division per bond (the same test
    /// pd-bond uses). `Some(∞)` for a law that never breaks a bond. `None` (the default):
    /// call [`DamageModel::update`].
    #[inline]
    fn stretch_limit(&self) -> Option<f64> {
        None
    }

    /// Checks the parameters; on error returns (key, reason).
    fn validate(&self) -> Result<(), (String, String)>;

    /// Config name of the law.
    fn name(&self) -> &'static str;
}

/// No damage: bonds never break.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NoDamage;

impl DamageModel for NoDamage {
    fn intact_fraction(&self, _: &BondInput) -> f64 {
        1.0
    }
    #[inline]
    fn stretch_limit(&self) -> Option<f64> {
        Some(f64::INFINITY)
    }
    fn validate(&self) -> Result<(), (String, String)> {
        Ok(())
    }
    fn name(&self) -> &'static str {
        "none"
    }
}

/// Prototype microelastic brittle: a bond breaks for good once its stretch exceeds s0.
/// s0 = √(5 G0 / (9 K δ)) in 3-D (the README's case sections, Silling & Askari 2005).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CriticalStretch {
    pub critical_stretch: f64,
}

impl CriticalStretch {
    /// s0 from the fracture energy G0 (J/m²), bulk modulus K and horizon δ (3-D).
    pub fn from_fracture_energy_3d(g0: f64, bulk: f64, horizon: f64) -> Self {
        CriticalStretch {
            critical_stretch: (5.0 * g0 / (9.0 * bulk * horizon)).sqrt(),
        }
    }
    /// s0 from G0 for the 2-D bond-based model: s0 = √(4π G0 / (9 E δ)) (Ha & Bobaru 2010).
    pub fn from_fracture_energy_2d(g0: f64, young: f64, horizon: f64) -> Self {
        CriticalStretch {
            critical_stretch: (4.0 * std::f64::consts::PI * g0 / (9.0 * young * horizon)).sqrt(),
        }
    }
}

impl DamageModel for CriticalStretch {
    #[inline]
    fn intact_fraction(&self, input: &BondInput) -> f64 {
        if input.stretch > self.critical_stretch {
            0.0
        } else {
            1.0
        }
    }
    #[inline]
    fn stretch_limit(&self) -> Option<f64> {
        Some(self.critical_stretch)
    }
    fn validate(&self) -> Result<(), (String, String)> {
        if !(self.critical_stretch.is_finite() && self.critical_stretch > 0.0) {
            return Err((
                "critical_stretch".into(),
                format!("must be > 0, got {}", self.critical_stretch),
            ));
        }
        Ok(())
    }
    fn name(&self) -> &'static str {
        "critical_stretch"
    }
}

/// Brittle (seed 000 App. C): a bond breaks sharply once its von Mises stress exceeds σ_cr.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrittleVonMises {
    pub critical_stress: f64,
}

impl DamageModel for BrittleVonMises {
    #[inline]
    fn intact_fraction(&self, input: &BondInput) -> f64 {
        if input.von_mises > self.critical_stress {
            0.0
        } else {
            1.0
        }
    }
    fn validate(&self) -> Result<(), (String, String)> {
        if !(self.critical_stress.is_finite() && self.critical_stress > 0.0) {
            return Err((
                "critical_stress".into(),
                format!("must be > 0, got {}", self.critical_stress),
            ));
        }
        Ok(())
    }
    fn name(&self) -> &'static str {
        "von_mises"
    }
}

/// Failure by a point law's cumulative indicator (the Johnson–Cook D = Σ Δε̄ᵖ/ε_f of
/// [`crate::blast_solid`]): a bond breaks for good once the indicator associated with it —
/// the mean of its two end points' — reaches 1. The indicator itself is accumulated by the
/// point law, which holds the failure constants.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FailureIndicator;

impl DamageModel for FailureIndicator {
    #[inline]
    fn intact_fraction(&self, input: &BondInput) -> f64 {
        if input.failure >= 1.0 { 0.0 } else { 1.0 }
    }
    fn validate(&self) -> Result<(), (String, String)> {
        Ok(())
    }
    fn name(&self) -> &'static str {
        "johnson_cook"
    }
}

/// Ductile (seed 000 eq. C.2): ω_D = 1 − D with D ramping linearly from 0 at ε̄ᵖ = ε_th to
/// 1 at ε̄ᵖ = ε_cr.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DuctilePlasticStrain {
    /// ε̄ᵖ_th: plastic strain at which damage starts.
    pub threshold: f64,
    /// ε̄ᵖ_cr: plastic strain at which the bond is fully damaged.
    pub critical: f64,
}

impl DamageModel for DuctilePlasticStrain {
    #[inline]
    fn intact_fraction(&self, input: &BondInput) -> f64 {
        let p = input.eq_plastic_strain;
        // eq. (C.2)
        let d = if p <= self.threshold {
            0.0
        } else if p >= self.critical {
            1.0
        } else {
            (p - self.threshold) / (self.critical - self.threshold)
        };
        1.0 - d
    }
    fn validate(&self) -> Result<(), (String, String)> {
        if !(self.threshold.is_finite() && self.threshold >= 0.0) {
            return Err((
                "eps_threshold".into(),
                format!("must be >= 0, got {}", self.threshold),
            ));
        }
        if !(self.critical.is_finite() && self.critical > self.threshold) {
            return Err((
                "eps_threshold".into(),
                format!(
                    "must be below eps_critical = {}, got {}",
                    self.critical, self.threshold
                ),
            ));
        }
        Ok(())
    }
    fn name(&self) -> &'static str {
        "plastic_strain"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ductile_ramp_matches_c2() {
        let d = DuctilePlasticStrain {
            threshold: 0.18,
            critical: 0.2,
        };
        let at = |p: f64| {
            d.intact_fraction(&BondInput {
                eq_plastic_strain: p,
                ..Default::default()
            })
        };
        assert_eq!(at(0.1), 1.0);
        assert_eq!(at(0.18), 1.0);
        assert!((at(0.19) - 0.5).abs() < 1e-12);
        assert_eq!(at(0.2), 0.0);
        assert_eq!(at(0.5), 0.0);
    }

    #[test]
    fn damage_is_irreversible() {
        let d = CriticalStretch {
            critical_stretch: 0.01,
        };
        let mut w = 1.0;
        for s in [0.005, 0.02, 0.0, -0.01, 0.005] {
            w = d.update(
                w,
                &BondInput {
                    stretch: s,
                    ..Default::default()
                },
            );
        }
        assert_eq!(w, 0.0);
        let dd = DuctilePlasticStrain {
            threshold: 0.1,
            critical: 0.2,
        };
        let mut w = 1.0;
        for p in [0.15, 0.12] {
            w = dd.update(
                w,
                &BondInput {
                    eq_plastic_strain: p,
                    ..Default::default()
                },
            );
        }
        assert!((w - 0.5).abs() < 1e-12, "softening must not heal: {w}");
    }

    #[test]
    fn brittle_von_mises_breaks_above_critical() {
        let d = BrittleVonMises {
            critical_stress: 3e9,
        };
        let f = |vm| {
            d.intact_fraction(&BondInput {
                von_mises: vm,
                ..Default::default()
            })
        };
        assert_eq!(f(2.9e9), 1.0);
        assert_eq!(f(3.1e9), 0.0);
    }

    #[test]
    fn validation_names_the_key() {
        let d = DuctilePlasticStrain {
            threshold: 0.3,
            critical: 0.2,
        };
        assert_eq!(d.validate().unwrap_err().0, "eps_threshold");
        let c = CriticalStretch {
            critical_stretch: -1.0,
        };
        assert_eq!(c.validate().unwrap_err().0, "critical_stretch");
    }

    #[test]
    fn critical_stretch_from_fracture_energy() {
        // Silling–Askari 2005: s0 = sqrt(5 G0 / (9 K δ)).
        let c = CriticalStretch::from_fracture_energy_3d(9.0, 5.0, 1.0);
        assert!((c.critical_stretch - 1.0).abs() < 1e-15);
    }
}
