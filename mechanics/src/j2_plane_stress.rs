//! Plane-stress J2 plasticity with linear isotropic and kinematic hardening: the projected
//! return mapping of Simo & Taylor (1986) / Simo & Hughes, *Computational Inelasticity* §3.4,
//! used by the shell integration points of the macro-shell node (seed 004 §3, eq. 26: the
//! stress σ₀ of the macro-scale shells) and by anything else that needs σ_zz = 0.
//!
//! # Conventions
//! * Voigt vectors in the plane: stress `[σxx, σyy, σxy]`, strain `[εxx, εyy, γxy]` with the
//!   *engineering* shear strain γxy = 2εxy. σzz = σxz = σyz = 0 at the material point.
//! * Yield function (von Mises written in plane-stress space): with the relative stress
//!   ξ = σ − α,  f = ½ ξᵀ P ξ − ⅓ R²,  P = ⅓[[2,−1,0],[−1,2,0],[0,0,6]], so ½ξᵀPξ = J₂(ξ)
//!   and f ≤ 0 ⇔ √(3 J₂) ≤ R.
//! * Isotropic hardening (linear): R(ε̄ᵖ) = σy + H_iso ε̄ᵖ, with ε̄ᵖ the equivalent plastic
//!   strain, ε̄̇ᵖ = √(⅔ ε̇ᵖ:ε̇ᵖ).
//! * Kinematic hardening (linear Prager): the 3-D deviatoric back stress is β = ⅔ H_kin εᵖ.
//!   Because β has a non-zero zz component, it is carried here as the *plane-stress
//!   equivalent* α = [2βxx+βyy, βxx+2βyy, βxy] (β shifted by −βzz·I, which leaves its deviator
//!   unchanged), so that J₂(σ − α) with σzz = αzz = 0 equals the 3-D J₂(σ − β). Its rate is
//!   α̇ = ⅔ H_kin γ̇ ξ (Simo & Hughes Box 3.4), with the flow ε̇ᵖ = γ̇ P ξ.
//! * In uniaxial stress both moduli add: σ = σy + (H_iso + H_kin) εᵖ, i.e. the tangent modulus
//!   is E_t = E H/(E + H) with H = H_iso + H_kin; conversely H = E E_t/(E − E_t). Seed 004's
//!   "kinematic hardening E_t = 1 GPa" is H_iso = 0, H_kin = E E_t/(E − E_t).

/// Material constants of the plane-stress J2 model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct J2PlaneStress {
    /// Young's modulus E.
    pub youngs: f64,
    /// Poisson's ratio ν.
    pub poisson: f64,
    /// Initial yield stress σy (uniaxial).
    pub yield_stress: f64,
    /// Linear isotropic plastic modulus H_iso (dR/dε̄ᵖ).
    pub h_iso: f64,
    /// Linear kinematic plastic modulus H_kin (β = ⅔ H_kin εᵖ).
    pub h_kin: f64,
}

/// The state of one material point that the update changes.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PlaneStressPoint {
    /// Stress `[σxx, σyy, σxy]`.
    pub stress: [f64; 3],
    /// Plane-stress equivalent back stress α (see the module notes).
    pub back: [f64; 3],
    /// Equivalent plastic strain ε̄ᵖ.
    pub eqps: f64,
}

/// What one update returns besides the new state.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct UpdateInfo {
    /// Plastic multiplier increment Δγ (0 when elastic).
    pub dgamma: f64,
    /// Total through-thickness strain increment Δεzz (elastic + plastic) that keeps σzz = 0.
    pub d_eps_zz: f64,
}

impl J2PlaneStress {
    /// Shear modulus G = E / 2(1+ν).
    pub fn shear_modulus(&self) -> f64 {
        self.youngs / (2.0 * (1.0 + self.poisson))
    }

    /// Plane-stress elastic stiffness times a strain vector `[εxx, εyy, γxy]`.
    #[inline]
    pub fn elastic(&self, de: [f64; 3]) -> [f64; 3] {
        let c = self.youngs / (1.0 - self.poisson * self.poisson);
        [
            c * (de[0] + self.poisson * de[1]),
            c * (self.poisson * de[0] + de[1]),
            self.shear_modulus() * de[2],
        ]
    }

    /// Current yield radius R(ε̄ᵖ).
    #[inline]
    pub fn yield_radius(&self, eqps: f64) -> f64 {
        self.yield_stress + self.h_iso * eqps
    }

    /// Strain-driven update for the strain increment `de = [Δεxx, Δεyy, Δγxy]`: elastic
    /// predictor, then, if f > 0, the closed-form projected return for a given Δγ and a scalar
    /// Newton iteration (safeguarded by bisection) on the consistency condition.
    #[inline]
    pub fn update(&self, p: &mut PlaneStressPoint, de: [f64; 3]) -> UpdateInfo {
        let (e, nu) = (self.youngs, self.poisson);
        let g = self.shear_modulus();
        let ds = self.elastic(de);
        let tr = [
            p.stress[0] + ds[0],
            p.stress[1] + ds[1],
            p.stress[2] + ds[2],
        ];
        let xi = [tr[0] - p.back[0], tr[1] - p.back[1], tr[2] - p.back[2]];
        // Components of ξ on the common eigenvectors of C and P.
        let a1 = (xi[0] + xi[1]) * (xi[0] + xi[1]) / 12.0;
        let a2 = 0.25 * (xi[0] - xi[1]) * (xi[0] - xi[1]) + xi[2] * xi[2];
        let f2_trial = a1 + a2; // = J2(ξ_trial)
        let r_n = self.yield_radius(p.eqps);
        let elastic_dzz = |dsig0: f64, dsig1: f64| -nu / e * (dsig0 + dsig1);
        if f2_trial <= r_n * r_n / 3.0 {
            p.stress = tr;
            return UpdateInfo {
                dgamma: 0.0,
                d_eps_zz: elastic_dzz(ds[0], ds[1]),
            };
        }
        // Eigenvalues of (⅔H_kin I + C P): mode 1 (ξxx+ξyy) and modes 2, 3 (deviatoric).
        let hk = 2.0 / 3.0 * self.h_kin;
        let l1 = e / (3.0 * (1.0 - nu)) + hk;
        let l2 = 2.0 * g + hk;
        let sq3 = 3.0_f64.sqrt();
        // ψ(Δγ) = f̄(Δγ) − R(ε̄ᵖ_n + Δγ (2/√3) f̄)/√3, with f̄² = a1/(1+l1Δγ)² + a2/(1+l2Δγ)².
        let eval = |dg: f64| -> (f64, f64) {
            let d1 = 1.0 + l1 * dg;
            let d2 = 1.0 + l2 * dg;
            let f2 = a1 / (d1 * d1) + a2 / (d2 * d2);
            let f = f2.sqrt();
            let df2 = -2.0 * l1 * a1 / (d1 * d1 * d1) - 2.0 * l2 * a2 / (d2 * d2 * d2);
            let df = df2 / (2.0 * f);
            let r = self.yield_radius(p.eqps + dg * 2.0 / sq3 * f);
            let dr = self.h_iso * 2.0 / sq3 * (f + dg * df);
            (f - r / sq3, df - dr / sq3)
        };
        // ψ(0) > 0 and ψ is decreasing; find an upper bracket, then Newton with bisection.
        let mut lo = 0.0;
        let mut hi = 1.0 / l2;
        while eval(hi).0 > 0.0 {
            lo = hi;
            hi *= 4.0;
        }
        let mut dg = 0.5 * (lo + hi);
        for _ in 0..60 {
            let (psi, dpsi) = eval(dg);
            if psi > 0.0 {
                lo = dg;
            } else {
                hi = dg;
            }
            let mut next = dg - psi / dpsi;
            if !(next > lo && next < hi && next.is_finite()) {
                next = 0.5 * (lo + hi);
            }
            if (next - dg).abs() <= 1e-15 * next.abs().max(1e-300) {
                dg = next;
                break;
            }
            dg = next;
        }
        let d1 = 1.0 + l1 * dg;
        let d2 = 1.0 + l2 * dg;
        let s_sum = (xi[0] + xi[1]) / d1;
        let s_dif = (xi[0] - xi[1]) / d2;
        let x = [0.5 * (s_sum + s_dif), 0.5 * (s_sum - s_dif), xi[2] / d2];
        let f = (s_sum * s_sum / 12.0 + 0.25 * s_dif * s_dif + x[2] * x[2]).sqrt();
        // Plastic strain increment Δεᵖ = Δγ P ξ; back stress α += ⅔H_kin Δγ ξ.
        let dep = [
            dg * (2.0 * x[0] - x[1]) / 3.0,
            dg * (2.0 * x[1] - x[0]) / 3.0,
            dg * 2.0 * x[2],
        ];
        for (b, xk) in p.back.iter_mut().zip(x) {
            *b += hk * dg * xk;
        }
        let new = [x[0] + p.back[0], x[1] + p.back[1], x[2] + p.back[2]];
        let dsig = [new[0] - p.stress[0], new[1] - p.stress[1]];
        p.stress = new;
        p.eqps += dg * 2.0 / sq3 * f;
        UpdateInfo {
            dgamma: dg,
            d_eps_zz: elastic_dzz(dsig[0], dsig[1]) - (dep[0] + dep[1]),
        }
    }

    /// von Mises equivalent of the relative stress, √(3 J₂(σ − α)).
    pub fn equivalent(&self, p: &PlaneStressPoint) -> f64 {
        let xi = [
            p.stress[0] - p.back[0],
            p.stress[1] - p.back[1],
            p.stress[2] - p.back[2],
        ];
        (3.0 * ((xi[0] + xi[1]).powi(2) / 12.0 + 0.25 * (xi[0] - xi[1]).powi(2) + xi[2] * xi[2]))
            .sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const E: f64 = 210e9;
    const NU: f64 = 0.3;
    const SY: f64 = 250e6;

    fn mat(h_iso: f64, h_kin: f64) -> J2PlaneStress {
        J2PlaneStress {
            youngs: E,
            poisson: NU,
            yield_stress: SY,
            h_iso,
            h_kin,
        }
    }

    /// Uniaxial stress driven by εxx: each increment iterates on Δεyy (secant) until σyy = 0,
    /// as a strip with free edges would. Returns the state after the increment.
    fn uniaxial_step(m: &J2PlaneStress, p: &mut PlaneStressPoint, dexx: f64) {
        let mut lo = -2.0 * dexx.abs() - 1e-12;
        let mut hi = 2.0 * dexx.abs() + 1e-12;
        let mut trial = *p;
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            trial = *p;
            m.update(&mut trial, [dexx, mid, 0.0]);
            if trial.stress[1] > 0.0 {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        *p = trial;
    }

    #[test]
    fn uniaxial_curve_follows_bilinear_law() {
        // σ = σy + E_t (ε − σy/E) with E_t = E H/(E + H), H = H_iso + H_kin, for three splits.
        for (hi, hk) in [(2e9, 0.0), (0.0, 2e9), (1.2e9, 0.8e9)] {
            let m = mat(hi, hk);
            let h = hi + hk;
            let et = E * h / (E + h);
            let mut p = PlaneStressPoint::default();
            let n = 400;
            let eps_max = 0.02;
            for k in 1..=n {
                uniaxial_step(&m, &mut p, eps_max / n as f64);
                let eps = eps_max * k as f64 / n as f64;
                let exact = if eps <= SY / E {
                    E * eps
                } else {
                    SY + et * (eps - SY / E)
                };
                let err = (p.stress[0] - exact).abs() / exact;
                assert!(
                    err < 1e-9,
                    "H_iso {hi} H_kin {hk} eps {eps}: {} vs {exact}",
                    p.stress[0]
                );
                assert!(p.stress[1].abs() < 1e-6 * SY);
            }
            // Equivalent plastic strain: εᵖ = ε − σ/E in uniaxial stress.
            let exact_ep = eps_max - p.stress[0] / E;
            assert!((p.eqps - exact_ep).abs() < 1e-9 * exact_ep);
        }
    }

    #[test]
    fn unloading_is_elastic_and_reverse_yield_shows_bauschinger() {
        // Pure kinematic hardening: after loading to σmax the elastic range is 2σy wide, so
        // reverse yield starts at σmax − 2σy (closed form of linear Prager hardening).
        let m = mat(0.0, 5e9);
        let mut p = PlaneStressPoint::default();
        for _ in 0..100 {
            uniaxial_step(&m, &mut p, 1e-4);
        }
        let smax = p.stress[0];
        let ep = p.eqps;
        // Unload elastically by Δε = −1.5σy/E: Δσ = E Δε exactly, no plastic flow.
        let de = -1.5 * SY / E;
        let n = 50;
        for _ in 0..n {
            uniaxial_step(&m, &mut p, de / n as f64);
        }
        assert!(((p.stress[0] - smax) - E * de).abs() < 1e-9 * smax);
        assert_eq!(p.eqps, ep);
        // Continue into compression until reverse yield: first plastic step at σmax − 2σy.
        let mut last = p.stress[0];
        loop {
            let before = p.eqps;
            uniaxial_step(&m, &mut p, -1e-6);
            if p.eqps > before {
                // Yield crossed within this increment: the yield point lies between
                // `last` and the elastic prediction.
                let ry = smax - 2.0 * SY;
                assert!(last >= ry - 1e-6 * SY && last - E * 1e-6 <= ry + 1e-6 * SY);
                break;
            }
            last = p.stress[0];
            assert!(last > smax - 3.0 * SY, "no reverse yield found");
        }
    }

    #[test]
    fn equibiaxial_and_shear_yield_at_von_mises_values() {
        // Perfect plasticity: equibiaxial stress yields at σ = σy, pure shear at τ = σy/√3.
        let m = mat(0.0, 0.0);
        let mut p = PlaneStressPoint::default();
        let d = 1e-4;
        for _ in 0..100 {
            m.update(&mut p, [d, d, 0.0]);
        }
        assert!((p.stress[0] - SY).abs() < 1e-9 * SY && (p.stress[1] - SY).abs() < 1e-9 * SY);
        let mut q = PlaneStressPoint::default();
        for _ in 0..100 {
            m.update(&mut q, [0.0, 0.0, 2.0 * d]);
        }
        assert!((q.stress[2] - SY / 3f64.sqrt()).abs() < 1e-9 * SY);
        assert!(q.stress[0].abs() < 1e-6 && q.stress[1].abs() < 1e-6);
    }

    #[test]
    fn return_lands_on_yield_surface_and_plastic_flow_is_isochoric() {
        let m = mat(1e9, 3e9);
        let mut p = PlaneStressPoint::default();
        let mut ezz_total = 0.0;
        let mut e_tot = [0.0; 3];
        let path = [
            [3e-3, -1e-3, 2e-3],
            [-1e-3, 4e-3, -3e-3],
            [2e-3, 2e-3, 1e-3],
        ];
        for de in path {
            let info = m.update(&mut p, de);
            ezz_total += info.d_eps_zz;
            for k in 0..3 {
                e_tot[k] += de[k];
            }
            if info.dgamma > 0.0 {
                let r = m.yield_radius(p.eqps);
                assert!((m.equivalent(&p) - r).abs() < 1e-10 * r);
            }
        }
        // Elastic strains from the stress; the plastic part must have zero trace in 3-D.
        let (s, nu) = (p.stress, NU);
        let ee_xx = (s[0] - nu * s[1]) / E;
        let ee_yy = (s[1] - nu * s[0]) / E;
        let ee_zz = -nu / E * (s[0] + s[1]);
        let tr_p = (e_tot[0] - ee_xx) + (e_tot[1] - ee_yy) + (ezz_total - ee_zz);
        assert!(tr_p.abs() < 1e-12, "plastic volume change {tr_p}");
    }
}
