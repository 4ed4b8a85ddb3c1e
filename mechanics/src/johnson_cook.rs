//! Johnson–Cook visco-plastic J2 material with adiabatic heating, and the Johnson–Cook
//! cumulative failure law, for metals under explosive loading (docs/physics.md, "Blast
//! materials").
//!
//! Small-strain rate form in the conventions of [`crate::j2`]: Voigt [`Sym`] stresses with
//! tensor shear, an elastic predictor and a radial return. The flow stress (Johnson & Cook
//! 1983) is
//!
//! σ_Y(ε̄ᵖ, ε̄̇ᵖ, T) = [A + B (ε̄ᵖ)ⁿ] [1 + C ln ε̇*] [1 − (T*)ᵐ],
//! ε̇* = max(ε̄̇ᵖ/ε̇₀, 1), T* = clamp((T − T_room)/(T_melt − T_room), 0, 1),
//!
//! so the rate factor is 1 at or below the reference rate and the strength vanishes at the
//! melting temperature. The return is backward Euler in ε̄ᵖ and in the plastic rate
//! (ε̄̇ᵖ = Δε̄ᵖ/Δt) and explicit in the temperature (T of the start of the step); the heat of
//! the step, ΔT = β σ_Y Δε̄ᵖ/(ρ c_p), is added afterwards (Taylor & Quinney fraction β).
//!
//! The pressure is either elastic ([`JohnsonCook::update`]) or left to the caller, e.g. from
//! the Mie–Grüneisen equation of state of [`crate::mie_gruneisen`]
//! ([`JohnsonCook::update_deviatoric`] then [`JohnsonCookState::set_pressure`]).
//!
//! The failure law (Johnson & Cook 1985) accumulates D = Σ Δε̄ᵖ/ε_f with
//! ε_f = [D1 + D2 exp(D3 σ*)] [1 + D4 ln ε̇*] [1 + D5 T*], σ* = σ_m/σ_vm; the point has failed
//! once D ≥ 1 ([`JohnsonCookFailure`]).
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use crate::j2::{Sym, ddot, deviator, trace};

/// Johnson–Cook visco-plastic material: isotropic elasticity, the Johnson–Cook flow stress
/// and adiabatic heating (SI units: Pa, K, 1/s, kg/m³, J/(kg K)).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JohnsonCook {
    /// Young's modulus E.
    pub young: f64,
    /// Poisson's ratio ν, in (−1, 0.5).
    pub poisson: f64,
    /// A: quasi-static yield stress at ε̄ᵖ = 0 and room temperature.
    pub yield_stress: f64,
    /// B: strain-hardening coefficient (term B (ε̄ᵖ)ⁿ).
    pub hardening_modulus: f64,
    /// n: strain-hardening exponent, in (0, 1].
    pub hardening_exponent: f64,
    /// C: strain-rate coefficient (factor 1 + C ln ε̇*).
    pub rate_coefficient: f64,
    /// m: thermal-softening exponent (factor 1 − (T*)ᵐ).
    pub thermal_exponent: f64,
    /// ε̇₀: reference plastic strain rate (1/s); at or below it the rate factor is 1.
    pub ref_strain_rate: f64,
    /// T_room: temperature at which A, B, n were fitted (K); T* = 0 at and below it.
    pub room_temperature: f64,
    /// T_melt: melting temperature (K); T* = 1 and no strength at and above it.
    pub melt_temperature: f64,
    /// ρ: mass density (kg/m³), of the reference configuration, for the heating.
    pub density: f64,
    /// c_p: specific heat (J/(kg K)), for the heating.
    pub specific_heat: f64,
    /// β: Taylor–Quinney fraction of plastic work turned into heat, in [0, 1]; 0 switches
    /// the heating off.
    pub taylor_quinney: f64,
}

/// Stress, accumulated equivalent plastic strain, last plastic rate and temperature of one
/// Johnson–Cook material point.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JohnsonCookState {
    /// Cauchy stress (Pa), Voigt order, tensor shear.
    pub stress: Sym,
    /// Accumulated equivalent plastic strain ε̄ᵖ.
    pub eq_plastic_strain: f64,
    /// Equivalent plastic strain rate of the last step, Δε̄ᵖ/Δt (1/s; 0 after an elastic step).
    pub plastic_strain_rate: f64,
    /// Temperature T (K).
    pub temperature: f64,
}

impl JohnsonCookState {
    /// A stress-free, virgin point at temperature `temperature` (K).
    pub fn at_temperature(temperature: f64) -> Self {
        JohnsonCookState {
            temperature,
            ..Default::default()
        }
    }

    /// Pressure p = −tr σ/3 (positive in compression).
    #[inline]
    pub fn pressure(&self) -> f64 {
        -trace(&self.stress) / 3.0
    }

    /// Replaces the mean stress by −p, keeping the deviator: σ = s − p I (e.g. p from an
    /// equation of state after [`JohnsonCook::update_deviatoric`]).
    #[inline]
    pub fn set_pressure(&mut self, pressure: f64) {
        let m = trace(&self.stress) / 3.0;
        for k in 0..3 {
            self.stress[k] += -pressure - m;
        }
    }
}

/// Stress triaxiality σ* = σ_m/σ_vm = −p/q of a stress (σ_m = tr σ/3, q the von Mises
/// stress), the argument of the Johnson–Cook failure strain. For q = 0 it is ±∞ with the
/// sign of σ_m, and 0 for the zero stress.
#[inline]
pub fn triaxiality(stress: &Sym) -> f64 {
    let m = trace(stress) / 3.0;
    let s = deviator(stress);
    let q = (1.5 * ddot(&s, &s)).sqrt();
    if q > 0.0 {
        m / q
    } else if m > 0.0 {
        f64::INFINITY
    } else if m < 0.0 {
        f64::NEG_INFINITY
    } else {
        0.0
    }
}

/// Homologous temperature T* = (T − T_room)/(T_melt − T_room), clamped to [0, 1].
#[inline]
fn homologous(temperature: f64, room: f64, melt: f64) -> f64 {
    ((temperature - room) / (melt - room)).clamp(0.0, 1.0)
}

impl JohnsonCook {
    /// AISI 4340 steel: the Johnson–Cook strength constants A = 792 MPa, B = 510 MPa,
    /// n = 0.26, C = 0.014, m = 1.03 and T_melt = 1793 K, with the density 7830 kg/m³ and
    /// specific heat 477 J/(kg K) listed beside them (Johnson G.R., Cook W.H., A constitutive
    /// model and data for metals subjected to large strains, high strain rates and high
    /// temperatures, Proc. 7th Int. Symp. on Ballistics, The Hague, 1983, 541–547, Table 1).
    /// ε̇₀ = 1 /s; T_room = 273 K is the reference temperature adopted for the blast
    /// application here. The elastic constants E = 205 GPa, ν = 0.29 are not part of the
    /// Johnson–Cook fit: they are the handbook values for 4340 (ASM data, "typical for
    /// steel"). β = 0.9 is the customary Taylor–Quinney fraction (Taylor G.I., Quinney H.,
    /// The latent energy remaining in a metal after cold working, Proc. R. Soc. Lond. A 143
    /// (1934) 307–326).
    pub fn steel_4340() -> Self {
        JohnsonCook {
            young: 205e9,
            poisson: 0.29,
            yield_stress: 792e6,
            hardening_modulus: 510e6,
            hardening_exponent: 0.26,
            rate_coefficient: 0.014,
            thermal_exponent: 1.03,
            ref_strain_rate: 1.0,
            room_temperature: 273.0,
            melt_temperature: 1793.0,
            density: 7830.0,
            specific_heat: 477.0,
            taylor_quinney: 0.9,
        }
    }

    /// Shear modulus G = E / (2(1+ν)).
    #[inline]
    pub fn shear_modulus(&self) -> f64 {
        self.young / (2.0 * (1.0 + self.poisson))
    }

    /// Bulk modulus K = E / (3(1−2ν)).
    #[inline]
    pub fn bulk_modulus(&self) -> f64 {
        self.young / (3.0 * (1.0 - 2.0 * self.poisson))
    }

    /// Homologous temperature T* = (T − T_room)/(T_melt − T_room), clamped to [0, 1].
    #[inline]
    pub fn homologous_temperature(&self, temperature: f64) -> f64 {
        homologous(temperature, self.room_temperature, self.melt_temperature)
    }

    /// Thermal factor Θ(T) = 1 − (T*)ᵐ ∈ [0, 1].
    #[inline]
    pub fn thermal_factor(&self, temperature: f64) -> f64 {
        let t = self.homologous_temperature(temperature);
        if t <= 0.0 {
            1.0
        } else {
            1.0 - t.powf(self.thermal_exponent)
        }
    }

    /// Johnson–Cook flow stress σ_Y = [A + B (ε̄ᵖ)ⁿ] [1 + C ln max(ε̄̇ᵖ/ε̇₀, 1)] [1 − (T*)ᵐ]
    /// (Johnson & Cook 1983, eq. 1, with the rate factor held at 1 below ε̇₀).
    #[inline]
    pub fn flow_stress(
        &self,
        eq_plastic_strain: f64,
        plastic_strain_rate: f64,
        temperature: f64,
    ) -> f64 {
        let h = self.yield_stress
            + self.hardening_modulus * eq_plastic_strain.max(0.0).powf(self.hardening_exponent);
        let ratio = plastic_strain_rate / self.ref_strain_rate;
        let r = if ratio > 1.0 {
            1.0 + self.rate_coefficient * ratio.ln()
        } else {
            1.0
        };
        h * r * self.thermal_factor(temperature)
    }

    /// Checks the parameters; on error returns (key, reason).
    pub fn validate(&self) -> Result<(), (String, String)> {
        let bad = |k: &str, r: String| Err((k.to_string(), r));
        let positive = [
            ("young", self.young),
            ("yield_stress", self.yield_stress),
            ("ref_strain_rate", self.ref_strain_rate),
            ("thermal_exponent", self.thermal_exponent),
            ("room_temperature", self.room_temperature),
            ("density", self.density),
            ("specific_heat", self.specific_heat),
        ];
        for (k, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(k, format!("must be > 0, got {v}"));
            }
        }
        if !(self.poisson.is_finite() && self.poisson > -1.0 && self.poisson < 0.5) {
            return bad(
                "poisson",
                format!("must be in (-1, 0.5), got {}", self.poisson),
            );
        }
        for (k, v) in [
            ("hardening_modulus", self.hardening_modulus),
            ("rate_coefficient", self.rate_coefficient),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(k, format!("must be >= 0, got {v}"));
            }
        }
        if !(self.hardening_exponent > 0.0 && self.hardening_exponent <= 1.0) {
            return bad(
                "hardening_exponent",
                format!("must be in (0, 1], got {}", self.hardening_exponent),
            );
        }
        check_melt_above_room(self.room_temperature, self.melt_temperature)?;
        if !(self.taylor_quinney >= 0.0 && self.taylor_quinney <= 1.0) {
            return bad(
                "taylor_quinney",
                format!("must be in [0, 1], got {}", self.taylor_quinney),
            );
        }
        Ok(())
    }

    /// Full update for a strain increment over `dt` (> 0): elastic predictor (isotropic
    /// Hooke, bulk modulus for the pressure) and the return of [`JohnsonCook::return_map`].
    /// Returns Δε̄ᵖ ≥ 0.
    #[inline]
    pub fn update(&self, state: &mut JohnsonCookState, dstrain: &Sym, dt: f64) -> f64 {
        let dp = self.bulk_modulus() * trace(dstrain);
        for k in 0..3 {
            state.stress[k] += dp;
        }
        self.update_deviatoric(state, dstrain, dt)
    }

    /// Deviatoric update for a strain increment over `dt` (> 0): s* = s + 2G dev Δε, then
    /// the return of [`JohnsonCook::return_map`]; the mean stress is left as it was, for
    /// the caller to set from an equation of state ([`JohnsonCookState::set_pressure`]).
    /// Returns Δε̄ᵖ ≥ 0.
    #[inline]
    pub fn update_deviatoric(&self, state: &mut JohnsonCookState, dstrain: &Sym, dt: f64) -> f64 {
        let g2 = 2.0 * self.shear_modulus();
        let de = deviator(dstrain);
        for k in 0..6 {
            state.stress[k] += g2 * de[k];
        }
        self.return_map(state, dt)
    }

    /// Radial return of a trial stress already in `state.stress` (e.g. after a Jaumann
    /// rotation), over a step `dt` (> 0). Returns Δε̄ᵖ ≥ 0; updates the deviator,
    /// ε̄ᵖ, the plastic rate and the temperature; the mean stress is untouched.
    ///
    /// With q* the trial von Mises stress, the step is plastic when q* > σ_Y(ε̄ᵖ_n, 0, T_n);
    /// then Δε̄ᵖ > 0 solves the consistency condition
    ///
    /// r(Δε̄ᵖ) = q* − 3G Δε̄ᵖ − σ_Y(ε̄ᵖ_n + Δε̄ᵖ, Δε̄ᵖ/Δt, T_n) = 0
    ///
    /// (the deviator shrinks along its own direction, s = s* (1 − 3G Δε̄ᵖ/q*), Simo & Hughes,
    /// Computational Inelasticity, §3.3). r is strictly decreasing, with r(0) > 0 and a root
    /// in (0, min{(q* − σ_Y0)/(3G), ((q*/Θ − A)/B)^{1/n} − ε̄ᵖ_n}] (σ_Y0 = σ_Y at Δε̄ᵖ = 0;
    /// each bound drops a non-negative part of σ_Y or of 3G Δε̄ᵖ). It is found by Newton's
    /// method started from the previous step's plastic rate (or the upper bound) and kept in
    /// the bracket, falling back to bisection — geometric while the bracket spans decades —
    /// when a step leaves the bracket or does not halve the step before last. This covers the
    /// infinite slope of (ε̄ᵖ)ⁿ at ε̄ᵖ = 0 for n < 1 (roots there can lie many decades below
    /// the bound) and the kink of the rate factor at ε̄̇ᵖ = ε̇₀. It stops at |r| ≤ 2 ulp of q*
    /// or a bracket a few ulps wide. At T ≥ T_melt (Θ = 0) the deviator goes to zero.
    ///
    /// The temperature then rises by ΔT = β q Δε̄ᵖ/(ρ c_p), with q = σ_Y the returned von
    /// Mises stress: q Δε̄ᵖ = σ : Δεᵖ is the plastic work of the step.
    #[inline]
    pub fn return_map(&self, state: &mut JohnsonCookState, dt: f64) -> f64 {
        debug_assert!(dt > 0.0, "the step must be positive");
        let m = trace(&state.stress) / 3.0;
        let s = deviator(&state.stress);
        let q_trial = (1.5 * ddot(&s, &s)).sqrt();
        let g3 = 3.0 * self.shear_modulus();
        let theta = self.thermal_factor(state.temperature);
        let p_n = state.eq_plastic_strain;
        let dp = if !(theta > 0.0) {
            // Molten: no strength, the whole deviator is plastic.
            q_trial / g3
        } else {
            let sy0 = self.flow_stress(p_n, 0.0, state.temperature);
            if !(q_trial > sy0) {
                state.plastic_strain_rate = 0.0;
                return 0.0;
            }
            let hint = state.plastic_strain_rate * dt;
            self.solve_consistency(q_trial, p_n, dt, theta, g3, sy0, hint)
        };
        let q = (q_trial - g3 * dp).max(0.0);
        let scale = if q_trial > 0.0 { q / q_trial } else { 0.0 };
        for k in 0..3 {
            state.stress[k] = m + s[k] * scale;
        }
        for k in 3..6 {
            state.stress[k] = s[k] * scale;
        }
        state.eq_plastic_strain = p_n + dp;
        state.plastic_strain_rate = dp / dt;
        state.temperature += self.taylor_quinney * q * dp / (self.density * self.specific_heat);
        dp
    }

    /// r(x) = q* − 3G x − σ_Y(ε̄ᵖ_n + x, x/Δt, T_n) and dr/dx, with Θ = Θ(T_n) given.
    #[inline]
    fn residual(&self, x: f64, q_trial: f64, p_n: f64, dt: f64, theta: f64, g3: f64) -> (f64, f64) {
        let p = p_n + x;
        let n = self.hardening_exponent;
        let b = self.hardening_modulus;
        let h = self.yield_stress + b * p.powf(n);
        // n B p^(n−1): +∞ at p = 0 for n < 1 (0^0 = 1 for n = 1).
        let dh = if b > 0.0 {
            n * b * p.powf(n - 1.0)
        } else {
            0.0
        };
        let ratio = x / (dt * self.ref_strain_rate);
        let (rate, drate) = if ratio > 1.0 {
            (
                1.0 + self.rate_coefficient * ratio.ln(),
                self.rate_coefficient / x,
            )
        } else {
            (1.0, 0.0)
        };
        let sy = h * rate * theta;
        let dsy = (dh * rate + h * drate) * theta;
        (q_trial - g3 * x - sy, -g3 - dsy)
    }

    /// Root of [`JohnsonCook::residual`] in its bracket (see [`JohnsonCook::return_map`]).
    #[inline]
    fn solve_consistency(
        &self,
        q_trial: f64,
        p_n: f64,
        dt: f64,
        theta: f64,
        g3: f64,
        sy0: f64,
        hint: f64,
    ) -> f64 {
        let tol = 2.0 * f64::EPSILON * q_trial;
        let elastic_bound = (q_trial - sy0) / g3;
        let mut lo = 0.0;
        let mut hi = elastic_bound;
        if self.hardening_modulus > 0.0 {
            // σ_Y ≥ [A + B(ε̄ᵖ_n + x)ⁿ] Θ, so r < −3G x < 0 beyond the x where the bracket
            // vanishes: (ε̄ᵖ_n + x)ⁿ = (ε̄ᵖ_n)ⁿ + (q* − σ_Y0)/(BΘ).
            let n = self.hardening_exponent;
            let c = p_n.powf(n) + (q_trial - sy0) / (self.hardening_modulus * theta);
            let hardening_bound = c.powf(1.0 / n) - p_n;
            if hardening_bound > 0.0 && hardening_bound < hi {
                hi = hardening_bound;
            }
        }
        let (mut r, mut dr) = self.residual(hi, q_trial, p_n, dt, theta, g3);
        if r >= 0.0 && hi < elastic_bound {
            // Round-off put the hardening bound at or below the root: it becomes the lower
            // end, the elastic bound the upper.
            lo = hi;
            hi = elastic_bound;
            (r, dr) = self.residual(hi, q_trial, p_n, dt, theta, g3);
        }
        if r >= 0.0 {
            // r(hi) < 0 in exact arithmetic, so r(hi) ≥ 0 is round-off: hi is the root to
            // within it (|dr/dx| ≥ 3G).
            return hi;
        }
        let mut x = hi;
        if hint > lo && hint < hi {
            // Start from the previous step's plastic rate: on a steady path it is close.
            x = hint;
            (r, dr) = self.residual(x, q_trial, p_n, dt, theta, g3);
        }
        let mut step_old = f64::INFINITY;
        let mut step = hi - lo;
        for _ in 0..400 {
            if r.abs() <= tol {
                return x;
            }
            if r > 0.0 {
                lo = x;
            } else {
                hi = x;
            }
            let newton = x - r / dr;
            let use_newton = dr.is_finite()
                && dr < 0.0
                && newton > lo
                && newton < hi
                && (2.0 * (newton - x)).abs() <= step_old.abs();
            step_old = step;
            // Bisection: geometric over a wide bracket (roots may lie many decades below
            // the bound when n is small), arithmetic otherwise.
            let next = if use_newton {
                newton
            } else if lo == 0.0 {
                hi * (1.0 / 1024.0)
            } else if hi > 4.0 * lo {
                lo.sqrt() * hi.sqrt()
            } else {
                lo + 0.5 * (hi - lo)
            };
            step = next - x;
            if next <= lo || next >= hi || hi - lo <= 4.0 * f64::EPSILON * hi {
                return x;
            }
            x = next;
            (r, dr) = self.residual(x, q_trial, p_n, dt, theta, g3);
        }
        x
    }
}

/// The homologous temperature needs T_melt > T_room (both laws check it).
fn check_melt_above_room(room: f64, melt: f64) -> Result<(), (String, String)> {
    if !(melt.is_finite() && melt > room) {
        return Err((
            "melt_temperature".into(),
            format!("must be above room_temperature = {room}, got {melt}"),
        ));
    }
    Ok(())
}

/// Johnson–Cook cumulative failure law (Johnson G.R., Cook W.H., Fracture characteristics of
/// three metals subjected to various strains, strain rates, temperatures and pressures, Eng.
/// Fract. Mech. 21 (1985) 31–48):
///
/// ε_f = max([D1 + D2 exp(D3 σ*)] [1 + D4 ln ε̇*] [1 + D5 T*], ε_f,min),
/// D ← D + Δε̄ᵖ/ε_f, failed once D ≥ 1,
///
/// with σ* = σ_m/σ_vm the stress triaxiality ([`triaxiality`]), ε̇* = max(ε̄̇ᵖ/ε̇₀, 1) (held
/// at 1 below the reference rate, as the flow stress) and T* the homologous temperature
/// clamped to [0, 1]. The floor ε_f,min > 0 keeps the increment finite where the fit turns
/// non-positive (for the 4340 constants at σ* ≳ 1.93).
///
/// The damage D is a plain number the caller keeps per point (0 virgin, non-decreasing); the
/// law does not cap it, so the strain at which it crosses 1 can be read off. To soften a
/// peridynamic bond with it, use [`JohnsonCookFailure::intact_fraction`] as ω_D (this is a
/// history variable, unlike the memoryless laws of [`crate::damage`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JohnsonCookFailure {
    /// D1.
    pub d1: f64,
    /// D2.
    pub d2: f64,
    /// D3 (multiplies the triaxiality in the exponent).
    pub d3: f64,
    /// D4 (rate term).
    pub d4: f64,
    /// D5 (temperature term).
    pub d5: f64,
    /// ε̇₀: reference plastic strain rate (1/s).
    pub ref_strain_rate: f64,
    /// T_room (K).
    pub room_temperature: f64,
    /// T_melt (K).
    pub melt_temperature: f64,
    /// ε_f,min > 0: floor on the failure strain.
    pub min_failure_strain: f64,
}

impl JohnsonCookFailure {
    /// AISI 4340 steel: D1 = −0.80, D2 = 2.10, D3 = −0.5, D4 = 0.002, D5 = 0.61 (Johnson G.R.,
    /// Cook W.H., Fracture characteristics of three metals subjected to various strains,
    /// strain rates, temperatures and pressures, Eng. Fract. Mech. 21 (1985) 31–48, Table 2),
    /// with ε̇₀ = 1 /s, T_room = 273 K and T_melt = 1793 K as in
    /// [`JohnsonCook::steel_4340`]. The floor ε_f,min = 1e-6 is ours (a numerical guard, not
    /// a material constant).
    pub fn steel_4340() -> Self {
        JohnsonCookFailure {
            d1: -0.80,
            d2: 2.10,
            d3: -0.5,
            d4: 0.002,
            d5: 0.61,
            ref_strain_rate: 1.0,
            room_temperature: 273.0,
            melt_temperature: 1793.0,
            min_failure_strain: 1e-6,
        }
    }

    /// Failure strain ε_f(σ*, ε̄̇ᵖ, T) (see the type's documentation).
    #[inline]
    pub fn failure_strain(
        &self,
        triaxiality: f64,
        plastic_strain_rate: f64,
        temperature: f64,
    ) -> f64 {
        let e = if self.d3 == 0.0 {
            1.0
        } else {
            (self.d3 * triaxiality).exp()
        };
        let ratio = plastic_strain_rate / self.ref_strain_rate;
        let rate = if ratio > 1.0 {
            1.0 + self.d4 * ratio.ln()
        } else {
            1.0
        };
        let t = homologous(temperature, self.room_temperature, self.melt_temperature);
        let ef = (self.d1 + self.d2 * e) * rate * (1.0 + self.d5 * t);
        if ef > self.min_failure_strain {
            ef
        } else {
            self.min_failure_strain
        }
    }

    /// New damage after a plastic increment: D + Δε̄ᵖ/ε_f(σ*, ε̄̇ᵖ, T), for the step's
    /// triaxiality, plastic rate and temperature. Not capped at 1.
    #[inline]
    pub fn accumulate(
        &self,
        damage: f64,
        deq_plastic_strain: f64,
        triaxiality: f64,
        plastic_strain_rate: f64,
        temperature: f64,
    ) -> f64 {
        if !(deq_plastic_strain > 0.0) {
            return damage;
        }
        damage
            + deq_plastic_strain
                / self.failure_strain(triaxiality, plastic_strain_rate, temperature)
    }

    /// Whether a point with damage D has failed: D ≥ 1.
    #[inline]
    pub fn failed(damage: f64) -> bool {
        damage >= 1.0
    }

    /// Intact fraction 1 − D clamped to [0, 1] (ω_D for a bond or point).
    #[inline]
    pub fn intact_fraction(damage: f64) -> f64 {
        (1.0 - damage).clamp(0.0, 1.0)
    }

    /// Checks the parameters; on error returns (key, reason).
    pub fn validate(&self) -> Result<(), (String, String)> {
        let bad = |k: &str, r: String| Err((k.to_string(), r));
        for (k, v) in [
            ("d1", self.d1),
            ("d2", self.d2),
            ("d3", self.d3),
            ("d4", self.d4),
            ("d5", self.d5),
        ] {
            if !v.is_finite() {
                return bad(k, format!("must be finite, got {v}"));
            }
        }
        for (k, v) in [
            ("ref_strain_rate", self.ref_strain_rate),
            ("room_temperature", self.room_temperature),
            ("min_failure_strain", self.min_failure_strain),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(k, format!("must be > 0, got {v}"));
            }
        }
        check_melt_above_room(self.room_temperature, self.melt_temperature)?;
        Ok(())
    }
}

/// Mott's statistical scatter of a failure strain (Mott, Proc. R. Soc. A 189 (1947) 300–308):
/// a point fails at f times the law's failure strain, with f distributed as
/// P(f) = 1 − exp(−(C/γ) e^{γf}), C fixed so that half the points fail below f = 1 (the form
/// AUTODYN's stochastic failure takes), i.e. P(f) = 1 − exp(−ln 2 · e^{γ(f − 1)}): a Gumbel
/// law of median 1 and scale 1/γ (standard deviation π/(γ√6)). Each point's factor comes from
/// its index and `seed` alone, so a run, its restart and every thread count draw the same.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MottScatter {
    /// γ > 0: the larger, the narrower the scatter.
    pub gamma: f64,
    /// Seed of the draw.
    pub seed: u64,
    /// Floor on f (> 0), as a fraction of the law's failure strain.
    pub min_fraction: f64,
}

impl MottScatter {
    /// f for point `index`: the inverse of P at a uniform deviate from (seed, index).
    pub fn factor(&self, index: u64) -> f64 {
        let u = uniform(self.seed, index);
        // P(f) = u  ⇔  f = 1 + ln(−ln(1 − u)/ln 2)/γ
        let f = 1.0 + ((-(-u).ln_1p()) / std::f64::consts::LN_2).ln() / self.gamma;
        f.max(self.min_fraction)
    }

    /// P(f): the probability that a point's factor is below `f` (before the floor).
    pub fn cdf(&self, f: f64) -> f64 {
        1.0 - (-std::f64::consts::LN_2 * (self.gamma * (f - 1.0)).exp()).exp()
    }

    /// Checks the parameters; on error (key, reason), the keys as the case's `mott` table
    /// names them.
    pub fn validate(&self) -> Result<(), (String, String)> {
        if !(self.gamma > 0.0 && self.gamma.is_finite()) {
            return Err(("gamma".into(), format!("must be > 0, got {}", self.gamma)));
        }
        if !(self.min_fraction > 0.0 && self.min_fraction < 1.0) {
            return Err((
                "min_fraction".into(),
                format!("must be in (0, 1), got {}", self.min_fraction),
            ));
        }
        Ok(())
    }
}

/// A uniform deviate in (0, 1) from (seed, index): SplitMix64 of the pair, its top 53 bits,
/// offset by half a unit so that neither end is drawn.
fn uniform(seed: u64, index: u64) -> f64 {
    let mut z = seed
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(index.wrapping_mul(0xD1B5_4A32_D192_ED03))
        .wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::j2::von_mises;

    /// The Johnson–Cook flow stress written out from the published form, for the checks.
    fn sy_exact(m: &JohnsonCook, p: f64, rate: f64, t: f64) -> f64 {
        let ts =
            ((t - m.room_temperature) / (m.melt_temperature - m.room_temperature)).clamp(0.0, 1.0);
        let rate_factor = if rate > m.ref_strain_rate {
            1.0 + m.rate_coefficient * (rate / m.ref_strain_rate).ln()
        } else {
            1.0
        };
        (m.yield_stress + m.hardening_modulus * p.powf(m.hardening_exponent))
            * rate_factor
            * (1.0 - ts.powf(m.thermal_exponent))
    }

    /// A deviatoric strain increment whose direction turns with the step index, scaled to
    /// an equivalent strain increment √(2/3 Δe:Δe) of `size`.
    fn turning_increment(step: usize, size: f64) -> Sym {
        let t = step as f64;
        let mut d = [
            1.0,
            -0.5 + 0.3 * (t / 400.0).sin(),
            0.0,
            0.2 * (t / 300.0).sin(),
            0.1,
            0.3 * (t / 200.0).cos(),
        ];
        d[2] = -d[0] - d[1];
        let eq = (2.0 / 3.0 * ddot(&d, &d)).sqrt();
        d.map(|x| x * size / eq)
    }

    /// Heating off: along a non-proportional deviatoric path at constant equivalent strain
    /// rate, every plastic step ends on σ_vm = σ_Y(ε̄ᵖ, Δε̄ᵖ/Δt, T) to 1e-12, every elastic
    /// step inside σ_Y(ε̄ᵖ, 0, T). Rates 1e3, 1 (the rate factor's kink) and 1e-4 /s, at
    /// room temperature and at 800 K.
    #[test]
    fn path_stays_on_rate_dependent_surface() {
        let mut m = JohnsonCook::steel_4340();
        m.taylor_quinney = 0.0;
        let n = 2000;
        let de = 1e-4;
        let mut checked = 0;
        for dt in [1e-7, 1e-4, 1.0] {
            for t0 in [273.0, 800.0] {
                let mut st = JohnsonCookState::at_temperature(t0);
                let (mut plastic, mut elastic) = (0, 0);
                let mut worst: f64 = 0.0;
                for k in 0..n {
                    let dp = m.update(&mut st, &turning_increment(k, de), dt);
                    let vm = von_mises(&st.stress);
                    assert_eq!(st.temperature, t0);
                    if dp > 0.0 {
                        let sy = sy_exact(&m, st.eq_plastic_strain, dp / dt, t0);
                        worst = worst.max((vm - sy).abs() / sy);
                        assert_eq!(st.plastic_strain_rate, dp / dt);
                        plastic += 1;
                    } else {
                        assert!(vm <= sy_exact(&m, st.eq_plastic_strain, 0.0, t0));
                        elastic += 1;
                    }
                }
                assert!(worst < 1e-12, "dt={dt} T={t0}: {worst:e}");
                assert_eq!(plastic + elastic, n);
                assert!(plastic >= 1950, "dt={dt} T={t0}: {plastic} plastic steps");
                checked += plastic;
            }
        }
        assert!(checked >= 6 * 1950, "{checked}");
    }

    /// Heating on (β = 0.9): the temperature equals T₀ + Σ β σ_Y Δε̄ᵖ/(ρ c_p) summed here
    /// from the closed-form σ_Y at each step's end (the step's plastic work), to 1e-12,
    /// and the stress stays on the surface of the step's starting temperature.
    #[test]
    fn adiabatic_heating_matches_plastic_work() {
        let m = JohnsonCook::steel_4340();
        let dt = 1e-6;
        let t0 = 293.0;
        let mut st = JohnsonCookState::at_temperature(t0);
        let mut t_ind = t0;
        let mut plastic = 0;
        let n = 3000;
        for k in 0..n {
            let dp = m.update(&mut st, &turning_increment(k, 2e-4), dt);
            if dp > 0.0 {
                let sy = sy_exact(&m, st.eq_plastic_strain, dp / dt, t_ind);
                let vm = von_mises(&st.stress);
                assert!((vm - sy).abs() <= 1e-12 * sy, "step {k}: {vm} vs {sy}");
                t_ind += 0.9 * sy * dp / (7830.0 * 477.0);
                plastic += 1;
            }
            assert!(
                (st.temperature - t_ind).abs() <= 1e-12 * t_ind,
                "step {k}: {} vs {t_ind}",
                st.temperature
            );
        }
        assert!(plastic >= 2980, "{plastic}");
        assert!(t_ind - t0 > 100.0, "the path must heat: {}", t_ind - t0);
    }

    /// The return over many random trial states: plastic strain histories from virgin
    /// (ε̄ᵖ = 0, where (ε̄ᵖ)ⁿ has an infinite slope for n < 1) to 0.5, overshoots of the yield
    /// stress from 1e-14 to 10×, steps from 1 ns to 1 s, temperatures up to and beyond
    /// melting, previous plastic rates (the starting guess) from none to 1e8 /s, and four
    /// hardening laws. Each plastic return ends on the surface:
    /// |σ_vm − σ_Y(ε̄ᵖ, Δε̄ᵖ/Δt, T)| ≤ 1e-12 σ_Y, with σ_vm = q* − 3G Δε̄ᵖ to 1e-12 q*, the
    /// deviator along the trial one and the mean stress unchanged.
    #[test]
    fn return_is_consistent_for_random_states() {
        let mut rng = fastrand::Rng::with_seed(12345);
        let base = JohnsonCook::steel_4340();
        let variants = [
            (0.26, 510e6, 0.014),
            (1.0, 510e6, 0.014),
            (0.05, 2e9, 0.05),
            (0.5, 0.0, 0.0),
        ];
        let per_variant = 5000;
        let (mut plastic, mut virgin, mut molten, mut elastic) = (0, 0, 0, 0);
        for (n, b, c) in variants {
            let m = JohnsonCook {
                hardening_exponent: n,
                hardening_modulus: b,
                rate_coefficient: c,
                taylor_quinney: 0.0,
                ..base
            };
            let g3 = 3.0 * m.shear_modulus();
            for _ in 0..per_variant {
                let p_n = match (rng.f64() * 4.0) as u32 {
                    0 | 1 => 0.0,
                    2 => 1e-10 * rng.f64(),
                    _ => 0.5 * rng.f64(),
                };
                let t = match (rng.f64() * 10.0) as u32 {
                    0 => 273.0,
                    1 => 1793.0 + 100.0 * rng.f64(),
                    _ => 273.0 + 0.99 * 1520.0 * rng.f64(),
                };
                let dt = 10f64.powf(-9.0 + 9.0 * rng.f64());
                let over = [1e-14, 1e-8, 1e-3, 1.0, 10.0][(rng.f64() * 5.0) as usize];
                let sy0 = sy_exact(&m, p_n, 0.0, t).max(1e6);
                let q_target = sy0 * (1.0 + over * rng.f64());
                let mut s = [0.0; 6];
                for x in s.iter_mut() {
                    *x = rng.f64() - 0.5;
                }
                let tr = (s[0] + s[1] + s[2]) / 3.0;
                for x in s.iter_mut().take(3) {
                    *x -= tr;
                }
                let q0 = (1.5 * ddot(&s, &s)).sqrt();
                let mean = 1e9 * (rng.f64() - 0.5);
                let mut trial = s.map(|x| x * q_target / q0);
                for x in trial.iter_mut().take(3) {
                    *x += mean;
                }
                // The previous step's rate, the solver's starting guess: none, or anything.
                let previous_rate = if rng.f64() < 0.5 {
                    0.0
                } else {
                    10f64.powf(-6.0 + 14.0 * rng.f64())
                };
                let mut st = JohnsonCookState {
                    stress: trial,
                    eq_plastic_strain: p_n,
                    plastic_strain_rate: previous_rate,
                    temperature: t,
                };
                let q_trial = von_mises(&trial);
                let dp = m.return_map(&mut st, dt);
                assert!(dp >= 0.0);
                let vm = von_mises(&st.stress);
                let m1 = (st.stress[0] + st.stress[1] + st.stress[2]) / 3.0;
                let m0 = (trial[0] + trial[1] + trial[2]) / 3.0;
                assert!((m1 - m0).abs() <= 1e-14 * (m0.abs() + q_trial));
                if dp == 0.0 {
                    assert!(q_trial <= sy_exact(&m, p_n, 0.0, t) * (1.0 + 1e-15));
                    assert_eq!(st.stress, trial);
                    assert_eq!(st.plastic_strain_rate, 0.0);
                    elastic += 1;
                    continue;
                }
                if t >= 1793.0 {
                    assert!(vm <= 1e-12 * q_trial, "molten: {vm}");
                    assert!((dp - q_trial / g3).abs() <= 1e-15 * dp);
                    molten += 1;
                    continue;
                }
                let sy = sy_exact(&m, st.eq_plastic_strain, dp / dt, t);
                let f = (vm - sy).abs() / sy;
                assert!(
                    f <= 1e-12,
                    "n={n} p_n={p_n} T={t} dt={dt} over={over}: f = {f:e}"
                );
                assert!((vm - (q_trial - g3 * dp)).abs() <= 1e-12 * q_trial);
                let sd = deviator(&st.stress);
                let s_trial = deviator(&trial);
                for k in 0..6 {
                    assert!((sd[k] - s_trial[k] * vm / q_trial).abs() <= 1e-12 * q_trial);
                }
                plastic += 1;
                if p_n == 0.0 && n < 1.0 && b > 0.0 {
                    virgin += 1;
                }
            }
        }
        assert_eq!(plastic + elastic + molten, 4 * per_variant);
        assert!(plastic >= 15000, "{plastic} plastic returns");
        assert!(virgin >= 3000, "{virgin} returns from ε̄ᵖ = 0 with n < 1");
        assert!(molten >= 1500, "{molten} molten returns");
    }

    /// With n = 1, C = 0 at room temperature the law is linear isotropic hardening: the same
    /// path gives the stresses of [`crate::j2::J2Material`] (σ_y0 = A, H_iso = B).
    #[test]
    fn linear_rate_independent_case_is_j2() {
        let m = JohnsonCook {
            hardening_exponent: 1.0,
            rate_coefficient: 0.0,
            taylor_quinney: 0.0,
            ..JohnsonCook::steel_4340()
        };
        let j2 = crate::j2::J2Material {
            young: m.young,
            poisson: m.poisson,
            yield_stress: m.yield_stress,
            iso_hardening: m.hardening_modulus,
            kin_hardening: 0.0,
        };
        let mut a = JohnsonCookState::at_temperature(273.0);
        let mut b = crate::j2::J2State::default();
        for k in 0..500 {
            let mut de = turning_increment(k, 1e-4);
            de[0] += 2e-5; // some volumetric strain too
            let da = m.update(&mut a, &de, 1e-6);
            let db = j2.update(&mut b, &de);
            assert!((da - db).abs() <= 1e-12 * db.max(1e-12));
            for c in 0..6 {
                assert!((a.stress[c] - b.stress[c]).abs() <= 1e-12 * 1e9, "{k} {c}");
            }
        }
        assert!(a.eq_plastic_strain > 0.04);
    }

    /// `update` = `update_deviatoric` + the elastic pressure K tr Δε; `set_pressure` keeps
    /// the deviator; an elastic step is Hooke's law.
    #[test]
    fn pressure_split_and_elastic_step() {
        let m = JohnsonCook::steel_4340();
        let de = [5e-3, -1e-3, 1.5e-3, 2.5e-3, -5e-4, 1e-3];
        let mut a = JohnsonCookState::at_temperature(300.0);
        let mut b = a;
        let dpa = m.update(&mut a, &de, 1e-6);
        let dpb = m.update_deviatoric(&mut b, &de, 1e-6);
        assert!(dpa > 0.0);
        assert_eq!(dpa, dpb);
        let p = -m.bulk_modulus() * (de[0] + de[1] + de[2]);
        b.set_pressure(p);
        for c in 0..6 {
            assert!((a.stress[c] - b.stress[c]).abs() <= 1e-15 * 1e9);
        }
        assert!((a.pressure() - p).abs() <= 1e-15 * p.abs());
        // Elastic step.
        let mut e = JohnsonCookState::at_temperature(300.0);
        let small = [1e-4, 0.0, 0.0, 0.0, 0.0, 0.0];
        assert_eq!(m.update(&mut e, &small, 1e-6), 0.0);
        let g = m.young / (2.0 * (1.0 + m.poisson));
        let lambda = m.young * m.poisson / ((1.0 + m.poisson) * (1.0 - 2.0 * m.poisson));
        assert!((e.stress[0] - (lambda + 2.0 * g) * 1e-4).abs() <= 1e-12 * e.stress[0]);
        assert!((e.stress[1] - lambda * 1e-4).abs() <= 1e-12 * e.stress[1]);
        assert_eq!(e.temperature, 300.0);
    }

    /// Johnson–Cook failure strain written out from the published form, with the floor.
    fn ef_exact(f: &JohnsonCookFailure, sigma: f64, rate: f64, t: f64) -> f64 {
        let ts =
            ((t - f.room_temperature) / (f.melt_temperature - f.room_temperature)).clamp(0.0, 1.0);
        let r = if rate > f.ref_strain_rate {
            rate / f.ref_strain_rate
        } else {
            1.0
        };
        let e = (f.d1 + f.d2 * (f.d3 * sigma).exp()) * (1.0 + f.d4 * r.ln()) * (1.0 + f.d5 * ts);
        e.max(f.min_failure_strain)
    }

    /// At constant triaxiality, rate and temperature D grows linearly, D = ε̄ᵖ/ε_f (to 1e-12
    /// at every step), and reaches 1 at ε̄ᵖ = ε_f (1e-12), where `failed` switches on; one
    /// case is below the reference rate, one on the floor.
    #[test]
    fn failure_strain_reached_at_d_equal_one() {
        let f = JohnsonCookFailure::steel_4340();
        let cases = [
            (1.0 / 3.0, 1e3, 300.0),
            (-0.2, 0.5, 273.0),
            (1.0, 1e5, 900.0),
            (0.0, 10.0, 2000.0),
            (2.5, 10.0, 400.0), // the fit is negative here: ε_f is the floor
        ];
        for (sigma, rate, t) in cases {
            let ef = ef_exact(&f, sigma, rate, t);
            assert!(ef > 0.0);
            let n = 1000;
            let dp = 1.37 * ef / n as f64;
            let mut d = 0.0;
            let mut crossed = None;
            for j in 1..=n {
                let d_old = d;
                d = f.accumulate(d, dp, sigma, rate, t);
                let exact = j as f64 * dp / ef;
                assert!(
                    (d - exact).abs() <= 1e-12 * exact,
                    "{sigma}: {d} vs {exact}"
                );
                if crossed.is_none() && JohnsonCookFailure::failed(d) {
                    assert!(!JohnsonCookFailure::failed(d_old));
                    let p_cross = (j - 1) as f64 * dp + (1.0 - d_old) / (d - d_old) * dp;
                    crossed = Some(p_cross);
                }
            }
            let p_cross = crossed.expect("must fail");
            assert!(
                (p_cross - ef).abs() <= 1e-12 * ef,
                "σ*={sigma}: {p_cross} vs {ef}"
            );
            assert_eq!(JohnsonCookFailure::intact_fraction(d), 0.0);
        }
        assert_eq!(ef_exact(&f, 2.5, 10.0, 400.0), f.min_failure_strain);
        // No plastic increment, no damage.
        assert_eq!(f.accumulate(0.3, 0.0, 0.5, 1.0, 300.0), 0.3);
    }

    /// σ* of uniaxial tension, compression and shear: 1/3, −1/3, 0.
    #[test]
    fn triaxiality_of_simple_states() {
        let s = 4e8;
        assert!((triaxiality(&[s, 0.0, 0.0, 0.0, 0.0, 0.0]) - 1.0 / 3.0).abs() < 1e-15);
        assert!((triaxiality(&[-s, 0.0, 0.0, 0.0, 0.0, 0.0]) + 1.0 / 3.0).abs() < 1e-15);
        assert_eq!(triaxiality(&[0.0, 0.0, 0.0, 0.0, 0.0, s]), 0.0);
        assert_eq!(triaxiality(&[s, s, s, 0.0, 0.0, 0.0]), f64::INFINITY);
    }

    #[test]
    fn validate_names_the_key() {
        let ok = JohnsonCook::steel_4340();
        assert!(ok.validate().is_ok());
        type Spoil = fn(&mut JohnsonCook);
        let cases: [(&str, Spoil); 11] = [
            ("young", |m| m.young = 0.0),
            ("poisson", |m| m.poisson = 0.5),
            ("yield_stress", |m| m.yield_stress = -1.0),
            ("hardening_modulus", |m| m.hardening_modulus = -1.0),
            ("hardening_exponent", |m| m.hardening_exponent = 1.5),
            ("hardening_exponent", |m| m.hardening_exponent = 0.0),
            ("rate_coefficient", |m| m.rate_coefficient = f64::NAN),
            ("ref_strain_rate", |m| m.ref_strain_rate = 0.0),
            ("melt_temperature", |m| m.melt_temperature = 200.0),
            ("taylor_quinney", |m| m.taylor_quinney = 1.1),
            ("specific_heat", |m| m.specific_heat = 0.0),
        ];
        for (key, spoil) in cases {
            let mut m = ok;
            spoil(&mut m);
            assert_eq!(m.validate().unwrap_err().0, key);
        }
        let f = JohnsonCookFailure::steel_4340();
        assert!(f.validate().is_ok());
        let mut g = f;
        g.min_failure_strain = 0.0;
        assert_eq!(g.validate().unwrap_err().0, "min_failure_strain");
        let mut g = f;
        g.d3 = f64::INFINITY;
        assert_eq!(g.validate().unwrap_err().0, "d3");
        let mut g = f;
        g.melt_temperature = 273.0;
        assert_eq!(g.validate().unwrap_err().0, "melt_temperature");
    }

    #[test]
    fn mott_factors_follow_their_distribution_and_repeat() {
        let m = MottScatter {
            gamma: 20.0,
            seed: 7,
            min_fraction: 0.1,
        };
        let n = 200_000u64;
        let mut f: Vec<f64> = (0..n).map(|i| m.factor(i)).collect();
        // the same index draws the same factor; another seed others
        assert_eq!(m.factor(12_345), f[12_345]);
        let other = MottScatter { seed: 8, ..m };
        assert!(
            (0..100)
                .filter(|&i| other.factor(i) == f[i as usize])
                .count()
                == 0
        );
        f.sort_by(f64::total_cmp);
        // the empirical distribution against P at nine quantiles: within 4 standard errors
        // of a binomial proportion (sqrt(p(1-p)/n) ≤ 1.2e-3)
        let mut checked = 0;
        for q in [0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99] {
            let x = f[(q * n as f64) as usize];
            let p = m.cdf(x);
            assert!(
                (p - q).abs() < 4.0 * (q * (1.0 - q) / n as f64).sqrt(),
                "{q}: P({x}) = {p}"
            );
            checked += 1;
        }
        assert_eq!(checked, 9);
        // median 1, standard deviation π/(γ√6)
        assert!((f[(n / 2) as usize] - 1.0).abs() < 2e-3);
        let mean = f.iter().sum::<f64>() / n as f64;
        let sd = (f.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        let want = std::f64::consts::PI / (20.0 * 6f64.sqrt());
        assert!((sd / want - 1.0).abs() < 0.02, "sd {sd} against {want}");
        // the floor
        let wide = MottScatter { gamma: 0.5, ..m };
        assert!((0..10_000).all(|i| wide.factor(i) >= 0.1));
        assert!((0..10_000).any(|i| wide.factor(i) == 0.1));
    }
}
