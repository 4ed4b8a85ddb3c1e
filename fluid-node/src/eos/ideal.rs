//! Ideal gas, `p = (γ - 1) ρ e` (seed 002 eq. 12; its eq. 36 uses it for air and helium).

use super::Eos;

#[derive(Debug, Clone, PartialEq)]
pub struct IdealGas {
    pub gamma: f64,
    /// Specific gas constant R (J/(kg K)), for temperatures; 0 when not given.
    pub gas_constant: f64,
}

impl Eos for IdealGas {
    #[inline(always)]
    fn gruneisen(&self) -> f64 {
        self.gamma - 1.0
    }
    #[inline(always)]
    fn p_ref(&self, _rho: f64) -> f64 {
        0.0
    }
    #[inline(always)]
    fn dp_ref(&self, _rho: f64) -> f64 {
        0.0
    }
    #[inline(always)]
    fn rho_c2(&self, _rho: f64, p: f64) -> f64 {
        self.gamma * p
    }
    fn temperature(&self, rho: f64, p: f64) -> Option<f64> {
        (self.gas_constant > 0.0).then(|| p / (rho * self.gas_constant))
    }
    fn density_from_temperature(&self, t: f64, p: f64) -> Option<f64> {
        (self.gas_constant > 0.0).then(|| p / (t * self.gas_constant))
    }
}
