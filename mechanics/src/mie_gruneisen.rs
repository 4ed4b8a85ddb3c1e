//! Mie–Grüneisen equation of state with a shock-Hugoniot reference curve, in the form used by
//! explicit hydrocodes (LS-DYNA `*EOS_GRUNEISEN`, Radioss `/EOS/GRUNEISEN`), for solids under
//! shock (docs/physics.md, "Blast materials").
//!
//! Energy convention: E is the internal energy **per unit reference volume** (J/m³ = Pa),
//! E = ρ₀ e with e the specific internal energy (J/kg). With μ = ρ/ρ₀ − 1,
//!
//! p = ρ₀C₀²μ [1 + (1 − γ₀/2)μ − (a/2)μ²] / [1 − (S₁−1)μ − S₂μ²/(μ+1) − S₃μ³/(μ+1)²]²
//!     + (γ₀ + aμ) E                                                     (μ > 0),
//! p = ρ₀C₀²μ + (γ₀ + aμ) E                                              (μ ≤ 0).
//!
//! What the compressed branch is: with the shock Hugoniot of the cubic Us–up fit
//! Us = C₀ + S₁up + S₂up²/Us + S₃up³/Us², whose pressure is
//! p_H(μ) = ρ₀C₀²μ(1+μ)/D(μ)² (D the bracket in the denominator above) and whose energy is,
//! from the Rankine–Hugoniot energy jump with p₀ = E₀ = 0, E_H(μ) = ½ p_H μ/(1+μ) (= ½ρ₀up²),
//! the formula is exactly
//!
//! p = p_H(μ) + Γ(μ) [E − E_H(μ)],   Γ(μ) = γ₀ + aμ,
//!
//! i.e. Mie–Grüneisen about the Hugoniot with ρΓ_G/ρ₀ = γ₀ + aμ (multiply out
//! p_H [1 − Γ μ/(2(1+μ))]). So on the Hugoniot (E = E_H) it gives p_H for any a; away from it
//! it is linear in E with slope γ₀ + aμ. The branches meet at μ = 0 with equal value γ₀E and
//! equal slope ρ₀C₀² + aE (C¹). The formula is meaningful while D(μ) > 0 (for S₂ = S₃ = 0:
//! μ < 1/(S₁ − 1)).
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

/// Mie–Grüneisen parameters (SI units).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MieGruneisen {
    /// ρ₀: reference density (kg/m³).
    pub density: f64,
    /// C₀: bulk sound speed, the intercept of the Us–up fit (m/s).
    pub sound_speed: f64,
    /// S₁: linear slope of the Us–up fit.
    pub s1: f64,
    /// S₂: quadratic coefficient of the Us–up fit.
    #[serde(default)]
    pub s2: f64,
    /// S₃: cubic coefficient of the Us–up fit.
    #[serde(default)]
    pub s3: f64,
    /// γ₀: Grüneisen coefficient at the reference state.
    pub gamma0: f64,
    /// a: first-order volume correction to γ₀ (Γ = γ₀ + aμ).
    #[serde(default)]
    pub volume_correction: f64,
    /// E₀: initial internal energy per unit reference volume (J/m³), the value a point
    /// starts from.
    #[serde(default)]
    pub initial_energy: f64,
}

impl MieGruneisen {
    /// Steel for blast loading: ρ₀ = 7830 kg/m³ (the 4340 density of Johnson & Cook 1983, as
    /// [`crate::johnson_cook::JohnsonCook::steel_4340`]), C₀ = 4569 m/s, S₁ = 1.49,
    /// S₂ = S₃ = 0, γ₀ = 2.17, a = 0.46, E₀ = 0. The Hugoniot set (C₀, S₁, γ₀, a) is the
    /// one tabulated for stainless steel in Steinberg's compilation (Steinberg D.J.,
    /// Equation of state and strength properties of selected materials, Lawrence Livermore
    /// National Laboratory report UCRL-MA-106439, 1996); check it against the grade at hand.
    pub fn steel() -> Self {
        MieGruneisen {
            density: 7830.0,
            sound_speed: 4569.0,
            s1: 1.49,
            s2: 0.0,
            s3: 0.0,
            gamma0: 2.17,
            volume_correction: 0.46,
            initial_energy: 0.0,
        }
    }

    /// Compression μ = ρ/ρ₀ − 1.
    #[inline]
    pub fn compression(&self, density: f64) -> f64 {
        density / self.density - 1.0
    }

    /// Reference curve of the energy-independent part, as a function of μ: (f, f') with
    /// p = f(μ) + (γ₀ + aμ)E. f = ρ₀C₀²μ N/D² for μ > 0 (N = 1 + (1 − γ₀/2)μ − (a/2)μ²),
    /// ρ₀C₀²μ for μ ≤ 0.
    #[inline]
    fn cold(&self, mu: f64) -> (f64, f64) {
        let k = self.density * self.sound_speed * self.sound_speed;
        if !(mu > 0.0) {
            return (k * mu, k);
        }
        let a = self.volume_correction;
        let n = 1.0 + (1.0 - 0.5 * self.gamma0) * mu - 0.5 * a * mu * mu;
        let dn = (1.0 - 0.5 * self.gamma0) - a * mu;
        let w = 1.0 / (1.0 + mu);
        let d = 1.0 - (self.s1 - 1.0) * mu - self.s2 * mu * mu * w - self.s3 * mu * mu * mu * w * w;
        let dd = -(self.s1 - 1.0)
            - self.s2 * mu * (2.0 + mu) * w * w
            - self.s3 * mu * mu * (3.0 + mu) * w * w * w;
        let inv_d2 = 1.0 / (d * d);
        let f = k * mu * n * inv_d2;
        let df = k * ((n + mu * dn) * inv_d2 - 2.0 * mu * n * dd * inv_d2 / d);
        (f, df)
    }

    /// The two terms of p = f + Γ E at density ρ: f = f(μ), the energy-independent part, and
    /// Γ = γ₀ + aμ (for a caller that solves for p and E together, p being linear in E).
    #[inline]
    pub fn linear_in_energy(&self, density: f64) -> (f64, f64) {
        let mu = self.compression(density);
        (self.cold(mu).0, self.gamma0 + self.volume_correction * mu)
    }

    /// Pressure p(ρ, E) (Pa), E per unit reference volume (J/m³); the formula of the module
    /// documentation.
    #[inline]
    pub fn pressure(&self, density: f64, energy: f64) -> f64 {
        let mu = self.compression(density);
        let (f, _) = self.cold(mu);
        f + (self.gamma0 + self.volume_correction * mu) * energy
    }

    /// Pressure and squared isentropic sound speed c² = ∂p/∂ρ|_s (m²/s²).
    ///
    /// Along an isentrope de = −p d(1/ρ) per unit mass, i.e. dE = p ρ₀/ρ² dρ per unit
    /// reference volume, so c² = ∂p/∂ρ|_E + (p ρ₀/ρ²) ∂p/∂E|_ρ
    /// = [f'(μ) + aE + (γ₀ + aμ) p/(1+μ)²]/ρ₀ (the usual ∂p/∂ρ|_e + (p/ρ²) ∂p/∂e|_ρ with
    /// ∂p/∂e = ρ₀ ∂p/∂E). At the reference state (μ = 0, E = 0) c = C₀.
    #[inline]
    pub fn pressure_and_sound_speed_squared(&self, density: f64, energy: f64) -> (f64, f64) {
        let mu = self.compression(density);
        let (f, df) = self.cold(mu);
        let a = self.volume_correction;
        let g = self.gamma0 + a * mu;
        let p = f + g * energy;
        let w = 1.0 / (1.0 + mu);
        let c2 = (df + a * energy + g * p * w * w) / self.density;
        (p, c2)
    }

    /// Pressure and isentropic sound speed c = √max(c², 0) (m/s), for the stable time step.
    /// c² can turn negative far in tension with a large energy; the caller that needs a
    /// positive speed there must bound it.
    #[inline]
    pub fn pressure_and_sound_speed(&self, density: f64, energy: f64) -> (f64, f64) {
        let (p, c2) = self.pressure_and_sound_speed_squared(density, energy);
        (p, c2.max(0.0).sqrt())
    }

    /// Isentropic sound speed c (m/s), see [`MieGruneisen::pressure_and_sound_speed`].
    #[inline]
    pub fn sound_speed(&self, density: f64, energy: f64) -> f64 {
        self.pressure_and_sound_speed(density, energy).1
    }

    /// Checks the parameters; on error returns (key, reason).
    pub fn validate(&self) -> Result<(), (String, String)> {
        let bad = |k: &str, r: String| Err((k.to_string(), r));
        for (k, v) in [("density", self.density), ("sound_speed", self.sound_speed)] {
            if !(v.is_finite() && v > 0.0) {
                return bad(k, format!("must be > 0, got {v}"));
            }
        }
        for (k, v) in [("s1", self.s1), ("gamma0", self.gamma0)] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(k, format!("must be >= 0, got {v}"));
            }
        }
        for (k, v) in [
            ("s2", self.s2),
            ("s3", self.s3),
            ("volume_correction", self.volume_correction),
            ("initial_energy", self.initial_energy),
        ] {
            if !v.is_finite() {
                return bad(k, format!("must be finite, got {v}"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// y(to) of y' = f(x, y), y(x) = y, by classical Runge–Kutta in `steps` equal steps.
    pub(crate) fn rk4(f: &dyn Fn(f64, f64) -> f64, x: f64, y: f64, to: f64, steps: usize) -> f64 {
        let h = (to - x) / steps as f64;
        let (mut x, mut y) = (x, y);
        for _ in 0..steps {
            let k1 = f(x, y);
            let k2 = f(x + 0.5 * h, y + 0.5 * h * k1);
            let k3 = f(x + 0.5 * h, y + 0.5 * h * k2);
            let k4 = f(x + h, y + h * k3);
            y += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            x += h;
        }
        y
    }

    /// Principal Hugoniot from the Rankine–Hugoniot jumps (p₀ = E₀ = 0) of a linear Us–up
    /// material, for particle speeds 50…2000 m/s: Us = C₀ + S₁up, ρ = ρ₀Us/(Us − up),
    /// p_H = ρ₀Us up, E_H = ½ρ₀up² (per reference volume). The EOS gives p(ρ, E_H) = p_H to
    /// 1e-10 at every sample, for the steel set (a = 0.46) and with a = 0, γ₀ = 1.
    #[test]
    fn principal_hugoniot_linear_us_up() {
        let steel = MieGruneisen::steel();
        let other = MieGruneisen {
            volume_correction: 0.0,
            gamma0: 1.0,
            ..steel
        };
        let mut samples = 0;
        for m in [steel, other] {
            for i in 0..=78 {
                let up = 50.0 + 25.0 * i as f64;
                let us = m.sound_speed + m.s1 * up;
                let rho = m.density * us / (us - up);
                let p_h = m.density * us * up;
                let e_h = 0.5 * m.density * up * up;
                let p = m.pressure(rho, e_h);
                assert!((p - p_h).abs() <= 1e-10 * p_h, "up={up}: {p} vs {p_h}");
                samples += 1;
            }
        }
        assert_eq!(samples, 158);
    }

    /// The same with a cubic Us–up fit (S₂, S₃ ≠ 0, hypothetical values): for η = up/Us the
    /// fit Us = C₀ + S₁up + S₂up²/Us + S₃up³/Us² gives Us = C₀/(1 − S₁η − S₂η² − S₃η³); then
    /// ρ = ρ₀/(1 − η), p_H = ρ₀Us up, E_H = ½ρ₀up². p(ρ, E_H) = p_H to 1e-10.
    #[test]
    fn principal_hugoniot_cubic_us_up() {
        let m = MieGruneisen {
            s2: 0.4,
            s3: -0.3,
            ..MieGruneisen::steel()
        };
        let mut samples = 0;
        for i in 1..=40 {
            let eta = 0.005 * i as f64;
            let us = m.sound_speed / (1.0 - m.s1 * eta - m.s2 * eta * eta - m.s3 * eta.powi(3));
            let up = eta * us;
            // The fit itself, as a check on the inversion.
            let fit =
                m.sound_speed + m.s1 * up + m.s2 * up * up / us + m.s3 * up.powi(3) / (us * us);
            assert!((fit - us).abs() <= 1e-12 * us);
            let rho = m.density / (1.0 - eta);
            let p_h = m.density * us * up;
            let e_h = 0.5 * m.density * up * up;
            let p = m.pressure(rho, e_h);
            assert!((p - p_h).abs() <= 1e-10 * p_h, "η={eta}: {p} vs {p_h}");
            samples += 1;
        }
        assert_eq!(samples, 40);
    }

    /// Off the Hugoniot the compressed branch is linear in E with slope γ₀ + aμ:
    /// p(ρ, E) − p(ρ, E_H) = (γ₀ + aμ)(E − E_H), to 1e-10 of the pressures involved.
    #[test]
    fn energy_dependence_is_gruneisen() {
        let m = MieGruneisen::steel();
        let mut samples = 0;
        for i in 1..=20 {
            let up = 100.0 * i as f64;
            let us = m.sound_speed + m.s1 * up;
            let rho = m.density * us / (us - up);
            let mu = rho / m.density - 1.0;
            let e_h = 0.5 * m.density * up * up;
            let p_h = m.density * us * up;
            for e in [0.0, 0.3 * e_h, 5.0 * e_h, -e_h] {
                let exact = p_h + (2.17 + 0.46 * mu) * (e - e_h);
                let p = m.pressure(rho, e);
                assert!((p - exact).abs() <= 1e-10 * (p_h + exact.abs()));
                samples += 1;
            }
        }
        assert_eq!(samples, 80);
    }

    /// μ ≤ 0: p = ρ₀C₀²μ + (γ₀ + aμ)E; at μ = 0 both branches give γ₀E, with equal slopes
    /// dp/dμ = ρ₀C₀² + aE (one-sided differences agree to 1e-6).
    #[test]
    fn tension_branch_and_continuity() {
        let m = MieGruneisen::steel();
        let k = 7830.0 * 4569.0f64 * 4569.0;
        for mu in [-0.3, -0.1, -1e-3, 0.0] {
            for e in [0.0, 1e8, -5e7] {
                let rho = 7830.0 * (1.0 + mu);
                let exact = k * mu + (2.17 + 0.46 * mu) * e;
                let p = m.pressure(rho, e);
                assert!(
                    (p - exact).abs() <= 1e-12 * (k * mu.abs() + e.abs()),
                    "{mu} {e}"
                );
            }
        }
        for e in [0.0, 1e8] {
            let h = 1e-7;
            let p0 = m.pressure(7830.0, e);
            assert!((p0 - 2.17 * e).abs() <= 1e-12 * e.abs().max(1.0));
            let right = (m.pressure(7830.0 * (1.0 + h), e) - p0) / h;
            let left = (p0 - m.pressure(7830.0 * (1.0 - h), e)) / h;
            let slope = k + 0.46 * e;
            assert!((right - slope).abs() <= 1e-6 * slope, "{right} vs {slope}");
            assert!((left - slope).abs() <= 1e-6 * slope, "{left} vs {slope}");
        }
    }

    /// c² against a centred difference of p along the isentrope dE = p ρ₀/ρ² dρ (dE = −p dV
    /// per unit reference volume), the isentrope integrated by RK4 over ±h: agreement to
    /// 1e-7 at compressed, expanded and reference states, and c = C₀ at ρ₀ with E = 0.
    #[test]
    fn sound_speed_matches_isentrope_difference() {
        let m = MieGruneisen {
            s2: 0.2,
            s3: 0.1,
            ..MieGruneisen::steel()
        };
        let rho0 = m.density;
        // dE/dρ along the isentrope.
        let rate = |rho: f64, e: f64| m.pressure(rho, e) * rho0 / (rho * rho);
        let isentrope = |rho: f64, e: f64, to: f64| rk4(&rate, rho, e, to, 20);
        let mut samples = 0;
        for mu in [-0.2, -0.05, 0.05, 0.2, 0.5] {
            for e in [0.0, 2e8, 2e9] {
                let rho = rho0 * (1.0 + mu);
                let d = 1e-4 * rho;
                let ep = isentrope(rho, e, rho + d);
                let em = isentrope(rho, e, rho - d);
                let fd = (m.pressure(rho + d, ep) - m.pressure(rho - d, em)) / (2.0 * d);
                let (_, c2) = m.pressure_and_sound_speed_squared(rho, e);
                assert!((c2 - fd).abs() <= 1e-7 * c2, "μ={mu} E={e}: {c2} vs {fd}");
                assert!((m.sound_speed(rho, e) - c2.sqrt()).abs() <= 1e-12 * c2.sqrt());
                samples += 1;
            }
        }
        assert_eq!(samples, 15);
        assert!((m.sound_speed(rho0, 0.0) - 4569.0).abs() <= 1e-12 * 4569.0);
    }

    #[test]
    fn validate_names_the_key() {
        let ok = MieGruneisen::steel();
        assert!(ok.validate().is_ok());
        type Spoil = fn(&mut MieGruneisen);
        let cases: [(&str, Spoil); 6] = [
            ("density", |m| m.density = 0.0),
            ("sound_speed", |m| m.sound_speed = -1.0),
            ("s1", |m| m.s1 = -0.1),
            ("gamma0", |m| m.gamma0 = f64::NAN),
            ("s2", |m| m.s2 = f64::INFINITY),
            ("volume_correction", |m| m.volume_correction = f64::NAN),
        ];
        for (key, spoil) in cases {
            let mut m = ok;
            spoil(&mut m);
            assert_eq!(m.validate().unwrap_err().0, key);
        }
    }
}
