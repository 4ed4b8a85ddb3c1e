//! JWL equation of state for detonation products (seed 002 eq. 13; the README's case sections TNT constants):
//! `p = A (1 - ω/(R1 V)) e^{-R1 V} + B (1 - ω/(R2 V)) e^{-R2 V} + ω ρ e`, `V = ρ0/ρ`, e the
//! specific internal energy (so ω E/V with E = ρ0 e per initial volume). The Chapman–Jouguet
//! state is where the Rayleigh line from (V=1, p=0) is tangent to the Hugoniot from E0.

use super::Eos;

#[derive(Debug, Clone, PartialEq)]
pub struct Jwl {
    pub rho0: f64,
    pub a: f64,
    pub b: f64,
    pub r1: f64,
    pub r2: f64,
    pub omega: f64,
    /// Detonation energy per unit initial volume (J/m³).
    pub e0: f64,
}

impl Jwl {
    /// TNT constants of the README's case sections.
    pub fn tnt() -> Self {
        Jwl {
            rho0: 1630.0,
            a: 3.712e11,
            b: 3.231e9,
            r1: 4.15,
            r2: 0.95,
            omega: 0.30,
            e0: 7.0e9,
        }
    }

    /// Reference (cold) pressure as a function of the relative volume V = ρ0/ρ.
    pub fn p_ref_v(&self, v: f64) -> f64 {
        self.a * (1.0 - self.omega / (self.r1 * v)) * (-self.r1 * v).exp()
            + self.b * (1.0 - self.omega / (self.r2 * v)) * (-self.r2 * v).exp()
    }

    /// d p_ref / d V.
    pub fn dp_ref_dv(&self, v: f64) -> f64 {
        let w = self.omega;
        let t1 = self.a * (-self.r1 * v).exp() * (w / (self.r1 * v * v) - self.r1 + w / v);
        let t2 = self.b * (-self.r2 * v).exp() * (w / (self.r2 * v * v) - self.r2 + w / v);
        t1 + t2
    }

    /// Pressure on the Hugoniot from the unreacted state (V=1, p=0, E=E0) at relative
    /// volume V: E = E0 + ½ p (1 - V) per initial volume (Rankine–Hugoniot energy jump).
    pub fn hugoniot_pressure(&self, v: f64) -> f64 {
        (self.p_ref_v(v) + self.omega * self.e0 / v) / (1.0 - self.omega * (1.0 - v) / (2.0 * v))
    }

    /// Chapman–Jouguet state (V/V0, p, D): minimum over V of the Rayleigh-line slope
    /// D² = p / (ρ0 (1 - V)) along the Hugoniot (tangency), by golden-section search.
    pub fn cj_state(&self) -> (f64, f64, f64) {
        let d2 = |v: f64| self.hugoniot_pressure(v) / (self.rho0 * (1.0 - v));
        let (mut lo, mut hi) = (0.3_f64, 0.99_f64);
        let g = 0.5 * (5.0_f64.sqrt() - 1.0);
        let mut x1 = hi - g * (hi - lo);
        let mut x2 = lo + g * (hi - lo);
        let (mut f1, mut f2) = (d2(x1), d2(x2));
        for _ in 0..200 {
            if f1 < f2 {
                hi = x2;
                x2 = x1;
                f2 = f1;
                x1 = hi - g * (hi - lo);
                f1 = d2(x1);
            } else {
                lo = x1;
                x1 = x2;
                f1 = f2;
                x2 = lo + g * (hi - lo);
                f2 = d2(x2);
            }
            if hi - lo < 1e-13 {
                break;
            }
        }
        let v = 0.5 * (lo + hi);
        let p = self.hugoniot_pressure(v);
        (v, p, d2(v).sqrt())
    }

    /// Specific internal energy (J/kg) of the CJ state, for initialising products.
    pub fn cj_specific_energy(&self) -> f64 {
        let (v, p, _) = self.cj_state();
        (self.e0 + 0.5 * p * (1.0 - v)) / self.rho0
    }
}

impl Eos for Jwl {
    #[inline(always)]
    fn gruneisen(&self) -> f64 {
        self.omega
    }
    #[inline(always)]
    fn p_ref(&self, rho: f64) -> f64 {
        self.p_ref_v(self.rho0 / rho)
    }
    #[inline(always)]
    fn dp_ref(&self, rho: f64) -> f64 {
        let v = self.rho0 / rho;
        // dV/dρ = -V/ρ
        -self.dp_ref_dv(v) * v / rho
    }
}
