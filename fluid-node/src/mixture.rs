//! Five-equation mixture closure in mechanical equilibrium (Allaire, Clerc & Kokh 2002; the
//! equilibrium state seed 002 eq. 28–30 reach by relaxation). With Mie–Grüneisen phases,
//! ρe = Σ α_k [(p - p_ref,k(ρ_k))/Γ_k + ρ_k e_ref,k], linear in p; the mixture sound speed is
//! ξ c² = Σ y_k ξ_k c_k² with ξ_k = 1/Γ_k, ξ = Σ α_k ξ_k.

use crate::eos::{Eos, Material};

/// Volume fractions below this carry no phase-density-dependent terms (a trace phase).
pub const TRACE: f64 = 1e-8;

/// Kernel-ready material: the EOS plus its precomputed constants.
#[derive(Debug, Clone)]
pub struct Phase {
    pub eos: Material,
    /// 1/Γ.
    pub inv_g: f64,
    /// True when p_ref, e_ref are constants (ideal, stiffened).
    pub constant: bool,
    /// -p_ref/Γ for constant-reference phases.
    pub off: f64,
}

impl Phase {
    pub fn new(eos: Material) -> Self {
        let g = eos.gruneisen();
        let constant = eos.is_constant_ref();
        let off = if constant { -eos.p_ref(1.0) / g } else { 0.0 };
        Phase {
            eos,
            inv_g: 1.0 / g,
            constant,
            off,
        }
    }

    /// α (ρ e_ref - p_ref/Γ) for phase density ρ_k = ar/α.
    #[inline(always)]
    fn offset(&self, ar: f64, al: f64) -> f64 {
        if self.constant {
            al * self.off
        } else if al > TRACE {
            let rk = ar / al;
            al * (rk * self.eos.e_ref(rk) - self.eos.p_ref(rk) * self.inv_g)
        } else {
            0.0
        }
    }

    /// α ξ ρ_k c_k².
    #[inline(always)]
    fn axrc2(&self, ar: f64, al: f64, p: f64) -> f64 {
        if self.constant {
            al * self.inv_g * self.eos.rho_c2(1.0, p)
        } else if al > TRACE {
            al * self.inv_g * self.eos.rho_c2(ar / al, p)
        } else {
            0.0
        }
    }
}

/// Mixture pressure from partial densities, volume fractions and ρe.
#[inline(always)]
pub fn pressure<const NM: usize>(
    ph: &[Phase; NM],
    ar: &[f64; NM],
    al: &[f64; NM],
    rhoe: f64,
) -> f64 {
    if NM == 1 {
        return (rhoe - ph[0].offset(ar[0], 1.0)) / ph[0].inv_g;
    }
    let mut xi = 0.0;
    let mut off = 0.0;
    for k in 0..NM {
        xi += al[k] * ph[k].inv_g;
        off += ph[k].offset(ar[k], al[k]);
    }
    (rhoe - off) / xi
}

/// ρe of the mixture at pressure p.
#[inline(always)]
pub fn rhoe<const NM: usize>(ph: &[Phase; NM], ar: &[f64; NM], al: &[f64; NM], p: f64) -> f64 {
    if NM == 1 {
        return p * ph[0].inv_g + ph[0].offset(ar[0], 1.0);
    }
    let mut xi = 0.0;
    let mut off = 0.0;
    for k in 0..NM {
        xi += al[k] * ph[k].inv_g;
        off += ph[k].offset(ar[k], al[k]);
    }
    p * xi + off
}

/// Mixture c² (frozen five-equation speed); non-positive or NaN marks an inadmissible state.
#[inline(always)]
pub fn sound_speed2<const NM: usize>(
    ph: &[Phase; NM],
    ar: &[f64; NM],
    al: &[f64; NM],
    rho: f64,
    p: f64,
) -> f64 {
    if NM == 1 {
        return ph[0].eos.rho_c2(rho, p) / rho;
    }
    let mut xi = 0.0;
    let mut s = 0.0;
    for k in 0..NM {
        xi += al[k] * ph[k].inv_g;
        s += ph[k].axrc2(ar[k], al[k], p);
    }
    s / (rho * xi)
}
