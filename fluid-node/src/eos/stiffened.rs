//! Stiffened gas for liquids, convention `p = (γ - 1) ρ e - γ p∞` (e.g. water γ 4.4,
//! p∞ 6.0e8 Pa; seed 002 §5.2 uses an EOS of this family for water).

use super::Eos;

#[derive(Debug, Clone, PartialEq)]
pub struct StiffenedGas {
    pub gamma: f64,
    /// p∞ (Pa).
    pub p_inf: f64,
    /// Specific gas constant used for T = (p + p∞)/(ρ R); 0 when not given.
    pub gas_constant: f64,
}

impl Eos for StiffenedGas {
    #[inline(always)]
    fn gruneisen(&self) -> f64 {
        self.gamma - 1.0
    }
    #[inline(always)]
    fn p_ref(&self, _rho: f64) -> f64 {
        -self.gamma * self.p_inf
    }
    #[inline(always)]
    fn dp_ref(&self, _rho: f64) -> f64 {
        0.0
    }
    #[inline(always)]
    fn rho_c2(&self, _rho: f64, p: f64) -> f64 {
        self.gamma * (p + self.p_inf)
    }
    fn temperature(&self, rho: f64, p: f64) -> Option<f64> {
        (self.gas_constant > 0.0).then(|| (p + self.p_inf) / (rho * self.gas_constant))
    }
    fn density_from_temperature(&self, t: f64, p: f64) -> Option<f64> {
        (self.gas_constant > 0.0).then(|| (p + self.p_inf) / (t * self.gas_constant))
    }
    fn min_pressure(&self) -> f64 {
        -self.p_inf
    }
}
