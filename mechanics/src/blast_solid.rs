//! The blast solid: a metal point under explosive loading as hydrocodes model it
//! (docs/physics.md, "Blast materials") — Johnson–Cook strength with adiabatic heating
//! ([`crate::johnson_cook`]), the pressure from the Mie–Grüneisen equation of state
//! ([`crate::mie_gruneisen`]) or, without one, from the bulk modulus, and the Johnson–Cook
//! cumulative failure indicator D. A [`StressLaw`], so every solver written over that trait
//! runs it.
//!
//! One step of length Δt with J = det F at its end:
//!
//! 1. the stress is rotated with the spin (Jaumann; the mean stress is unchanged by it);
//! 2. the deviator takes the Johnson–Cook elastic predictor and radial return
//!    ([`JohnsonCook::update_deviatoric`]), which also heats the point;
//! 3. with an equation of state the pressure solves, together with the energy,
//!    p = f(μ) + Γ(μ) E and E = E₀ + W_v + w_e + W_p, W_v ← W_v − ½ (pₙ + p)(J − Jₙ)
//!    (p is linear in E, so the pair has a closed form): W_v is the work of the pressure per
//!    unit reference volume, trapezoidal in J, w_e = s:s/(4G) the deviator's elastic energy
//!    and W_p the plastic work, so E is all the work done on the point. Without one, the
//!    mean stress takes K tr Δε;
//! 4. with a failure law, D += Δε̄ᵖ/ε_f(σ*, ε̄̇ᵖ, T) at the step's end state.
//!
//! The point stores w_e + W_v (w_e + p²/(2K) without an equation of state); its plastic
//! work is what heats it.
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::j2::{Sym, ddot, deviator, jaumann_rotate, trace, von_mises};
use crate::johnson_cook::{JohnsonCook, JohnsonCookFailure, JohnsonCookState, triaxiality};
use crate::mie_gruneisen::MieGruneisen;
use crate::stress_law::StressLaw;

/// Johnson–Cook strength, an optional Mie–Grüneisen pressure and an optional Johnson–Cook
/// failure law, at one density (the strength's `density`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlastSolid {
    pub strength: JohnsonCook,
    /// The pressure's equation of state; None: p from the bulk modulus (rate form).
    pub eos: Option<MieGruneisen>,
    /// The failure indicator's law; None: D stays 0.
    pub failure: Option<JohnsonCookFailure>,
    /// Temperature of a virgin point (K).
    pub initial_temperature: f64,
}

/// What a blast-solid point carries.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BlastPoint {
    /// Stress, ε̄ᵖ, the last plastic rate and the temperature.
    pub jc: JohnsonCookState,
    /// J = det F at the end of the last step (1 at rest).
    pub jac: f64,
    /// W_v = −∫ p dJ: work of the pressure per unit reference volume since the start (J/m³).
    pub volume_work: f64,
    /// W_p: plastic work density since the start (J/m³).
    pub plastic_work: f64,
    /// Johnson–Cook failure indicator D = Σ Δε̄ᵖ/ε_f (0 without a failure law).
    pub damage: f64,
    /// The point fails at (1 + `failure_shift`) times the law's failure strain (a scatter
    /// such as [`crate::johnson_cook::MottScatter`]'s f − 1; 0: the law's own).
    pub failure_shift: f64,
}

impl BlastSolid {
    /// Checks the parameters; on error returns (key, reason), the key as a case names it
    /// under the strength (`johnson_cook.`), the equation of state (`eos.`) or the failure
    /// law (`damage.`).
    pub fn validate(&self) -> Result<(), (String, String)> {
        let under = |p: &str, (k, r): (String, String)| (format!("{p}.{k}"), r);
        self.strength
            .validate()
            .map_err(|e| under("johnson_cook", e))?;
        if let Some(eos) = &self.eos {
            eos.validate().map_err(|e| under("eos", e))?;
            if eos.density != self.strength.density {
                return Err((
                    "eos.density".into(),
                    format!(
                        "{} differs from the solid's density {}",
                        eos.density, self.strength.density
                    ),
                ));
            }
        }
        if let Some(f) = &self.failure {
            f.validate().map_err(|e| under("damage", e))?;
        }
        let t = self.initial_temperature;
        if !(t.is_finite() && t > 0.0) {
            return Err((
                "johnson_cook.initial_temperature".into(),
                format!("must be > 0, got {t}"),
            ));
        }
        Ok(())
    }

    /// Internal energy per unit reference volume E = E₀ + W_v + w_e + W_p of a point
    /// (J/m³), the E of the equation of state.
    pub fn internal_energy(&self, st: &BlastPoint) -> f64 {
        let e0 = self.eos.map_or(0.0, |e| e.initial_energy);
        e0 + st.volume_work + self.deviatoric_energy(&st.jc.stress) + st.plastic_work
    }

    /// w_e = s:s/(4G) of a stress's deviator.
    fn deviatoric_energy(&self, stress: &Sym) -> f64 {
        let s = deviator(stress);
        ddot(&s, &s) / (4.0 * self.strength.shear_modulus())
    }
}

impl StressLaw for BlastSolid {
    type State = BlastPoint;

    fn initial_state(&self) -> BlastPoint {
        let mut st = BlastPoint {
            jc: JohnsonCookState::at_temperature(self.initial_temperature),
            jac: 1.0,
            ..Default::default()
        };
        if let Some(eos) = &self.eos {
            // p = γ₀ E₀ at the reference density
            st.jc
                .set_pressure(eos.pressure(eos.density, eos.initial_energy));
        }
        st
    }

    /// The step of the module documentation. Plane stress is not integrated (its
    /// through-thickness iteration is J2's alone).
    #[inline]
    fn step(
        &self,
        st: &mut BlastPoint,
        de: &Sym,
        spin: &[[f64; 3]; 3],
        dt: f64,
        jac: f64,
        plane_stress: bool,
    ) -> f64 {
        debug_assert!(!plane_stress, "the blast solid has no plane-stress update");
        jaumann_rotate(&mut st.jc.stress, spin, dt);
        let p_n = st.jc.pressure();
        let dp = match &self.eos {
            None => self.strength.update(&mut st.jc, de, dt),
            Some(_) => self.strength.update_deviatoric(&mut st.jc, de, dt),
        };
        // q Δε̄ᵖ = σ : Δεᵖ, with q the returned von Mises stress
        let wp = if dp > 0.0 {
            von_mises(&st.jc.stress) * dp
        } else {
            0.0
        };
        st.plastic_work += wp;
        if let Some(eos) = &self.eos {
            let dj = jac - st.jac;
            let (f, gamma) = eos.linear_in_energy(eos.density / jac);
            // E without the step's pressure work, then p (1 + ½Γ ΔJ) = f + Γ (E_b − ½ pₙ ΔJ)
            let e_b = eos.initial_energy
                + st.volume_work
                + self.deviatoric_energy(&st.jc.stress)
                + st.plastic_work;
            let p = (f + gamma * (e_b - 0.5 * p_n * dj)) / (1.0 + 0.5 * gamma * dj);
            st.volume_work -= 0.5 * (p_n + p) * dj;
            st.jc.set_pressure(p);
        }
        st.jac = jac;
        if let Some(fail) = &self.failure {
            st.damage = fail.accumulate(
                st.damage,
                dp / (1.0 + st.failure_shift),
                triaxiality(&st.jc.stress),
                st.jc.plastic_strain_rate,
                st.jc.temperature,
            );
        }
        wp
    }

    #[inline]
    fn stress(st: &BlastPoint) -> &Sym {
        &st.jc.stress
    }

    #[inline]
    fn eq_plastic_strain(st: &BlastPoint) -> f64 {
        st.jc.eq_plastic_strain
    }

    #[inline]
    fn failure(st: &BlastPoint) -> f64 {
        st.damage
    }

    fn set_failure_factor(st: &mut BlastPoint, factor: f64) {
        st.failure_shift = factor - 1.0;
    }

    fn stored_energy(&self, st: &BlastPoint) -> f64 {
        let w = self.deviatoric_energy(&st.jc.stress);
        match &self.eos {
            Some(_) => w + st.volume_work,
            None => {
                let p = trace(&st.jc.stress) / 3.0;
                w + p * p / (2.0 * self.strength.bulk_modulus())
            }
        }
    }

    fn elastic_constants(&self) -> (f64, f64) {
        (self.strength.young, self.strength.poisson)
    }

    /// K + 4G/3, K the larger of the strength's bulk modulus and ρ₀C₀² of the equation of
    /// state (its slope at the reference state).
    fn wave_modulus(&self) -> f64 {
        let k = self.strength.bulk_modulus();
        let k = self
            .eos
            .map_or(k, |e| k.max(e.density * e.sound_speed * e.sound_speed));
        k + 4.0 / 3.0 * self.strength.shear_modulus()
    }

    fn plane_stress(&self) -> bool {
        false
    }

    fn scalar_names(&self) -> &'static [&'static str] {
        if self.failure.is_some() {
            &["temperature", "failure_index"]
        } else {
            &["temperature"]
        }
    }

    fn scalar(st: &BlastPoint, k: usize) -> f64 {
        match k {
            0 => st.jc.temperature,
            _ => st.damage,
        }
    }
}

// The case-file forms of the blast solid's laws, shared by every solver that takes them.

fn default_ref_strain_rate() -> f64 {
    1.0
}
fn default_taylor_quinney() -> f64 {
    0.9
}

/// The Johnson–Cook constants beyond A (`yield_stress`) and the elastic constants.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JohnsonCookParams {
    /// B: strain-hardening coefficient (Pa).
    pub hardening_modulus: f64,
    /// n: strain-hardening exponent, in (0, 1].
    pub hardening_exponent: f64,
    /// C: strain-rate coefficient.
    pub rate_coefficient: f64,
    /// m: thermal-softening exponent.
    pub thermal_exponent: f64,
    /// ε̇₀: reference plastic strain rate (1/s); the rate factor is 1 at or below it.
    #[serde(default = "default_ref_strain_rate")]
    pub ref_strain_rate: f64,
    /// T_room: temperature of the fit (K); no thermal softening at or below it.
    pub room_temperature: f64,
    /// T_melt: melting temperature (K); no strength at or above it.
    pub melt_temperature: f64,
    /// c_p: specific heat (J/(kg K)), for the adiabatic heating.
    pub specific_heat: f64,
    /// β: fraction of the plastic work turned into heat, in [0, 1].
    #[serde(default = "default_taylor_quinney")]
    pub taylor_quinney: f64,
    /// Temperature of the solid at the start (K); absent: `room_temperature`.
    #[serde(default)]
    pub initial_temperature: Option<f64>,
}

/// An equation of state for the pressure of a solid.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum EosParams {
    /// Mie–Grüneisen about the shock Hugoniot of the fit Us = C₀ + S₁up + S₂up²/Us +
    /// S₃up³/Us², at the solid's `density`.
    MieGruneisen {
        /// C₀: bulk sound speed (m/s).
        sound_speed: f64,
        /// S₁.
        s1: f64,
        /// S₂.
        #[serde(default)]
        s2: f64,
        /// S₃.
        #[serde(default)]
        s3: f64,
        /// γ₀: Grüneisen coefficient.
        gamma0: f64,
        /// a: volume correction, Γ = γ₀ + aμ.
        #[serde(default)]
        volume_correction: f64,
        /// E₀: internal energy per unit reference volume at the start (J/m³).
        #[serde(default)]
        initial_energy: f64,
    },
}

impl BlastSolid {
    /// The blast solid of a case's parameters: `elastic` = (E, ν, A = the yield stress,
    /// ρ) from the solid's top-level keys, the Johnson–Cook constants `jc`, the pressure's
    /// equation of state `eos` (None: the bulk modulus) and a failure law. Errors name the
    /// key as the case writes it (`young`, `johnson_cook.melt_temperature`, `eos.s1`, …).
    pub fn from_params(
        elastic: (f64, f64, f64, f64),
        jc: &JohnsonCookParams,
        eos: Option<&EosParams>,
        failure: Option<JohnsonCookFailure>,
    ) -> Result<BlastSolid, (String, String)> {
        let (young, poisson, yield_stress, density) = elastic;
        let strength = JohnsonCook {
            young,
            poisson,
            yield_stress,
            hardening_modulus: jc.hardening_modulus,
            hardening_exponent: jc.hardening_exponent,
            rate_coefficient: jc.rate_coefficient,
            thermal_exponent: jc.thermal_exponent,
            ref_strain_rate: jc.ref_strain_rate,
            room_temperature: jc.room_temperature,
            melt_temperature: jc.melt_temperature,
            density,
            specific_heat: jc.specific_heat,
            taylor_quinney: jc.taylor_quinney,
        };
        let eos = eos.map(|e| match *e {
            EosParams::MieGruneisen {
                sound_speed,
                s1,
                s2,
                s3,
                gamma0,
                volume_correction,
                initial_energy,
            } => MieGruneisen {
                density,
                sound_speed,
                s1,
                s2,
                s3,
                gamma0,
                volume_correction,
                initial_energy,
            },
        });
        let solid = BlastSolid {
            strength,
            eos,
            failure,
            initial_temperature: jc.initial_temperature.unwrap_or(jc.room_temperature),
        };
        // the strength's own keys are the case's top-level ones
        solid.validate().map_err(|(k, r)| {
            let top = ["young", "poisson", "yield_stress", "density"];
            match k.strip_prefix("johnson_cook.") {
                Some(t) if top.contains(&t) => (t.to_string(), r),
                _ => (k, r),
            }
        })?;
        Ok(solid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solid() -> BlastSolid {
        BlastSolid {
            strength: JohnsonCook::steel_4340(),
            eos: Some(MieGruneisen::steel()),
            failure: Some(JohnsonCookFailure::steel_4340()),
            initial_temperature: 293.0,
        }
    }

    const NO_SPIN: [[f64; 3]; 3] = [[0.0; 3]; 3];

    /// A compression and release with shear, in 2 000 steps: at every step the pressure is
    /// the equation of state's at ρ₀/J and the internal energy E₀ + W_v + w_e + W_p the point
    /// books (to 1e-12 of the pressure), and the deviator, ε̄ᵖ and temperature are those of
    /// the bare Johnson–Cook law driven by the same increments (to rounding: the deviator is
    /// carried inside a stress with a pressure of the same size).
    #[test]
    fn the_pressure_is_the_equation_of_states_and_the_deviator_the_strengths() {
        let m = solid();
        let eos = m.eos.unwrap();
        let mut st = m.initial_state();
        let mut bare = JohnsonCookState::at_temperature(m.initial_temperature);
        let (n, dt) = (2000, 1e-8);
        let mut jac = 1.0;
        let mut plastic_steps = 0;
        for i in 0..n {
            let t = i as f64 / n as f64;
            // volumetric strain rate: compress to J ≈ 0.9, then release; shear all along
            let dv = if t < 0.5 { -2e-4 } else { 1.6e-4 };
            let de = [
                dv / 3.0 + 4e-5,
                dv / 3.0 - 2e-5,
                dv / 3.0 - 2e-5,
                1e-5,
                0.0,
                3e-5,
            ];
            jac *= 1.0 + dv;
            let wp = m.step(&mut st, &de, &NO_SPIN, dt, jac, false);
            let dp = m.strength.update_deviatoric(&mut bare, &de, dt);
            plastic_steps += usize::from(dp > 0.0);
            assert!(wp >= 0.0);
            let p = eos.pressure(eos.density / jac, m.internal_energy(&st));
            let got = st.jc.pressure();
            assert!(
                (got - p).abs() <= 1e-12 * p.abs().max(1e6),
                "step {i}: {got} vs {p}"
            );
            let (a, b) = (deviator(&st.jc.stress), deviator(&bare.stress));
            for k in 0..6 {
                assert!(
                    (a[k] - b[k]).abs() <= 1e-6 * (1.0 + b[k].abs()),
                    "step {i} s{k}"
                );
            }
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs();
            assert!(
                close(st.jc.eq_plastic_strain, bare.eq_plastic_strain),
                "step {i}"
            );
            assert!(close(st.jc.temperature, bare.temperature), "step {i}");
        }
        assert!(plastic_steps > 1000, "{plastic_steps} plastic steps");
        assert!(st.jc.eq_plastic_strain > 0.05);
    }

    /// Along an elastic isotropic compression the booked pressure work W_v converges to
    /// −∫ p dJ of the equation of state integrated finely (the isentrope dE/dJ = −p(ρ₀/J, E),
    /// by classical Runge–Kutta on 20 000 steps): second order in the step.
    #[test]
    fn the_pressure_work_is_the_isentropes_to_second_order() {
        let mut m = solid();
        // no strength: a hydrostatic path never yields anyway, and no failure
        m.failure = None;
        let eos = m.eos.unwrap();
        let j_end = 0.85;
        let rhs = |j: f64, e: f64| -eos.pressure(eos.density / j, e);
        let exact = crate::mie_gruneisen::tests::rk4(&rhs, 1.0, 0.0, j_end, 20_000);
        let booked = |steps: usize| {
            let mut st = m.initial_state();
            let dj = (j_end - 1.0) / steps as f64;
            for i in 0..steps {
                let (j0, j1) = (1.0 + dj * i as f64, 1.0 + dj * (i + 1) as f64);
                let ev = (j1 / j0).ln() / 3.0;
                m.step(
                    &mut st,
                    &[ev, ev, ev, 0.0, 0.0, 0.0],
                    &NO_SPIN,
                    1e-9,
                    j1,
                    false,
                );
            }
            assert_eq!(st.jc.eq_plastic_strain, 0.0);
            st.volume_work
        };
        let (e1, e2) = (booked(100), booked(200));
        let (r1, r2) = ((e1 - exact).abs(), (e2 - exact).abs());
        assert!(r1 / exact < 1e-4, "{e1} vs {exact}");
        let order = (r1 / r2).log2();
        assert!((order - 2.0).abs() < 0.1, "order {order} ({r1:e}, {r2:e})");
    }

    /// The failure indicator is Σ Δε̄ᵖ/ε_f of the failure law at each step's end state,
    /// summed here independently (to 1e-12), and reaches 1 in a long shear.
    #[test]
    fn the_failure_indicator_sums_the_plastic_increments_over_the_failure_strain() {
        // without the equation of state, so that the heating does not pressurise the point
        // (at J = 1 the Mie–Grüneisen pressure is Γ E) and σ* stays 0
        let m = BlastSolid {
            eos: None,
            ..solid()
        };
        let f = m.failure.unwrap();
        let mut st = m.initial_state();
        // a twin whose failure strain is scattered to 1.3 times the law's
        let mut twin = m.initial_state();
        BlastSolid::set_failure_factor(&mut twin, 1.3);
        let mut d = 0.0;
        let mut steps = 0;
        while st.damage < 1.0 {
            let p0 = st.jc.eq_plastic_strain;
            // isochoric stretch and shear (J = 1): σ* = 0
            let de = [1e-4, -5e-5, -5e-5, 0.0, 0.0, 2e-4];
            m.step(&mut st, &de, &NO_SPIN, 1e-7, 1.0, false);
            m.step(&mut twin, &de, &NO_SPIN, 1e-7, 1.0, false);
            let dp = st.jc.eq_plastic_strain - p0;
            if dp > 0.0 {
                let ef = f.failure_strain(
                    triaxiality(&st.jc.stress),
                    st.jc.plastic_strain_rate,
                    st.jc.temperature,
                );
                d += dp / ef;
            }
            assert!(
                (st.damage - d).abs() <= 1e-12 * d.max(1e-3),
                "{} vs {d}",
                st.damage
            );
            // the twin flows alike and fails at 1.3 times the strain
            assert_eq!(twin.jc, st.jc);
            assert!((twin.damage * 1.3 - st.damage).abs() <= 1e-12 * st.damage.max(1e-3));
            steps += 1;
            assert!(steps < 100_000, "no failure: {st:?}");
        }
        assert!(steps > 100, "{steps} steps");
        assert!(st.jc.temperature > m.initial_temperature + 50.0);
    }

    #[test]
    fn bad_parameters_are_named_under_their_table() {
        let mut m = solid();
        m.strength.yield_stress = -1.0;
        assert_eq!(m.validate().unwrap_err().0, "johnson_cook.yield_stress");
        let mut m = solid();
        m.eos.as_mut().unwrap().density = 7000.0;
        assert_eq!(m.validate().unwrap_err().0, "eos.density");
        let mut m = solid();
        m.initial_temperature = f64::NAN;
        assert_eq!(
            m.validate().unwrap_err().0,
            "johnson_cook.initial_temperature"
        );
        assert!(solid().validate().is_ok());
    }
}
