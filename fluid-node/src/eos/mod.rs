//! Equations of state behind one trait (seed 002 §2.2, eq. 12–14). Every EOS here is written in
//! Mie–Grüneisen form `p = p_ref(ρ) + Γ ρ (e - e_ref(ρ))` with a constant Grüneisen
//! coefficient Γ, so that the pressure of a five-equation mixture in mechanical equilibrium is
//! linear in p and needs no iteration (Allaire, Clerc & Kokh 2002; seed 002 eq. 28–30 solve
//! the same equilibrium by Newton for the six-equation model).

pub mod ideal;
pub mod jwl;
pub mod stiffened;

pub use ideal::IdealGas;
pub use jwl::Jwl;
pub use stiffened::StiffenedGas;

/// An equation of state in Mie–Grüneisen form.
pub trait Eos {
    /// Grüneisen coefficient Γ = (1/ρ) (∂p/∂e)_ρ (constant).
    fn gruneisen(&self) -> f64;
    /// Reference pressure p_ref(ρ) (Pa).
    fn p_ref(&self, rho: f64) -> f64;
    /// d p_ref / d ρ (m²/s²).
    fn dp_ref(&self, rho: f64) -> f64;
    /// Reference specific internal energy e_ref(ρ) (J/kg); zero for every EOS here.
    fn e_ref(&self, _rho: f64) -> f64 {
        0.0
    }
    /// d e_ref / d ρ.
    fn de_ref(&self, _rho: f64) -> f64 {
        0.0
    }
    /// Pressure from density and specific internal energy.
    fn pressure(&self, rho: f64, e: f64) -> f64 {
        self.p_ref(rho) + self.gruneisen() * rho * (e - self.e_ref(rho))
    }
    /// Specific internal energy from density and pressure.
    fn internal_energy(&self, rho: f64, p: f64) -> f64 {
        self.e_ref(rho) + (p - self.p_ref(rho)) / (self.gruneisen() * rho)
    }
    /// ρ c² at (ρ, p): c² = p_ref' - Γ ρ e_ref' + ((Γ+1) p - p_ref)/ρ for Mie–Grüneisen.
    fn rho_c2(&self, rho: f64, p: f64) -> f64 {
        let g = self.gruneisen();
        rho * (self.dp_ref(rho) - g * rho * self.de_ref(rho)) + (g + 1.0) * p - self.p_ref(rho)
    }
    /// Temperature from (ρ, p) when the EOS has one.
    fn temperature(&self, _rho: f64, _p: f64) -> Option<f64> {
        None
    }
    /// Density from temperature and pressure when the EOS has a thermal relation.
    fn density_from_temperature(&self, _t: f64, _p: f64) -> Option<f64> {
        None
    }
    /// Smallest admissible pressure (the state with ρc² > 0 must lie above it).
    fn min_pressure(&self) -> f64 {
        0.0
    }
}

/// One material: enum dispatch over the EOS family so the cell kernels inline.
#[derive(Debug, Clone, PartialEq)]
pub enum Material {
    Ideal(IdealGas),
    Stiffened(StiffenedGas),
    Jwl(Jwl),
}

macro_rules! dispatch {
    ($self:ident, $m:ident => $e:expr) => {
        match $self {
            Material::Ideal($m) => $e,
            Material::Stiffened($m) => $e,
            Material::Jwl($m) => $e,
        }
    };
}

impl Eos for Material {
    #[inline(always)]
    fn gruneisen(&self) -> f64 {
        dispatch!(self, m => m.gruneisen())
    }
    #[inline(always)]
    fn p_ref(&self, rho: f64) -> f64 {
        dispatch!(self, m => m.p_ref(rho))
    }
    #[inline(always)]
    fn dp_ref(&self, rho: f64) -> f64 {
        dispatch!(self, m => m.dp_ref(rho))
    }
    #[inline(always)]
    fn rho_c2(&self, rho: f64, p: f64) -> f64 {
        dispatch!(self, m => m.rho_c2(rho, p))
    }
    fn temperature(&self, rho: f64, p: f64) -> Option<f64> {
        dispatch!(self, m => m.temperature(rho, p))
    }
    fn density_from_temperature(&self, t: f64, p: f64) -> Option<f64> {
        dispatch!(self, m => m.density_from_temperature(t, p))
    }
    fn min_pressure(&self) -> f64 {
        dispatch!(self, m => m.min_pressure())
    }
}

impl Material {
    /// True when p_ref and e_ref are constants (ideal and stiffened gases): the mixture
    /// pressure then needs no phase densities.
    #[inline(always)]
    pub fn is_constant_ref(&self) -> bool {
        !matches!(self, Material::Jwl(_))
    }
}
