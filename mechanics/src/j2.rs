//! Small-strain 3-D J2 (von Mises) plasticity with linear isotropic and linear kinematic
//! (Prager) hardening: elastic predictor + radial return (seed 000 App. B; Simo & Hughes,
//! Computational Inelasticity, Box 3.2), and the Jaumann objective stress rotation (seed 000
//! eq. B.1) used by the rate-form peridynamic models.
//!
//! Hardening convention (both moduli are *uniaxial plastic moduli*):
//! * isotropic: the yield stress grows as σ_y(ε̄ᵖ) = σ_y0 + H_iso ε̄ᵖ;
//! * kinematic (Prager): the back stress evolves as dα = (2/3) H_kin dεᵖ, i.e. H_kin = C of
//!   the Prager/Armstrong–Frederick law dα = (2/3) C dεᵖ (Simo–Hughes write this
//!   (2/3) H' with H' = H_kin).
//!
//! In uniaxial stress the plastic tangent is then dσ/dε̄ᵖ = H_iso + H_kin, so a mixed
//! hardening with total modulus H and isotropic fraction β is `iso_hardening = β H`,
//! `kin_hardening = (1 − β) H`.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

/// Symmetric tensors in Voigt order [xx, yy, zz, yz, xz, xy], tensor (not engineering) shear.
pub type Sym = [f64; 6];

/// Linear elastic – linear hardening J2 material (SI units: Pa).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct J2Material {
    /// Young's modulus E.
    pub young: f64,
    /// Poisson's ratio ν, in (−1, 0.5).
    pub poisson: f64,
    /// Initial uniaxial yield stress σ_y0.
    pub yield_stress: f64,
    /// Isotropic hardening modulus H_iso (σ_y = σ_y0 + H_iso ε̄ᵖ).
    pub iso_hardening: f64,
    /// Kinematic hardening modulus H_kin (dα = (2/3) H_kin dεᵖ).
    pub kin_hardening: f64,
}

/// Stress, back stress and accumulated equivalent plastic strain of one material point.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct J2State {
    pub stress: Sym,
    pub back_stress: Sym,
    pub eq_plastic_strain: f64,
}

/// Double contraction a : b of two symmetric tensors in tensor-shear Voigt order.
#[inline]
pub fn ddot(a: &Sym, b: &Sym) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + 2.0 * (a[3] * b[3] + a[4] * b[4] + a[5] * b[5])
}

/// Trace of a symmetric tensor.
#[inline]
pub fn trace(a: &Sym) -> f64 {
    a[0] + a[1] + a[2]
}

/// Deviatoric part.
#[inline]
pub fn deviator(a: &Sym) -> Sym {
    let m = trace(a) / 3.0;
    [a[0] - m, a[1] - m, a[2] - m, a[3], a[4], a[5]]
}

/// Von Mises equivalent stress √(3/2 s:s).
#[inline]
pub fn von_mises(s: &Sym) -> f64 {
    let d = deviator(s);
    (1.5 * ddot(&d, &d)).sqrt()
}

/// Symmetric tensor → full 3×3 matrix.
#[inline]
pub fn to_matrix(a: &Sym) -> [[f64; 3]; 3] {
    [[a[0], a[5], a[4]], [a[5], a[1], a[3]], [a[4], a[3], a[2]]]
}

/// Symmetric part of a 3×3 matrix → Voigt (tensor shear).
#[inline]
pub fn from_matrix(m: &[[f64; 3]; 3]) -> Sym {
    [
        m[0][0],
        m[1][1],
        m[2][2],
        0.5 * (m[1][2] + m[2][1]),
        0.5 * (m[0][2] + m[2][0]),
        0.5 * (m[0][1] + m[1][0]),
    ]
}

impl J2Material {
    /// Shear modulus μ = E / (2(1+ν)).
    pub fn shear_modulus(&self) -> f64 {
        self.young / (2.0 * (1.0 + self.poisson))
    }

    /// Bulk modulus K = E / (3(1−2ν)).
    pub fn bulk_modulus(&self) -> f64 {
        self.young / (3.0 * (1.0 - 2.0 * self.poisson))
    }

    /// Elastic strain energy density ½ σ : C⁻¹ : σ = p²/(2K) + s:s/(4μ) of a stress (J/m³;
    /// p = tr σ/3, s = dev σ): the energy the elastic part of the strain stores (the
    /// isotropic Hooke law of [`J2Material::elastic_increment`]).
    pub fn elastic_energy(&self, stress: &Sym) -> f64 {
        let p = trace(stress) / 3.0;
        let s = deviator(stress);
        p * p / (2.0 * self.bulk_modulus()) + ddot(&s, &s) / (4.0 * self.shear_modulus())
    }

    /// Checks the parameters; on error returns (key, reason).
    pub fn validate(&self) -> Result<(), (String, String)> {
        let bad = |k: &str, r: String| Err((k.to_string(), r));
        if !(self.young.is_finite() && self.young > 0.0) {
            return bad("young", format!("must be > 0, got {}", self.young));
        }
        if !(self.poisson.is_finite() && self.poisson > -1.0 && self.poisson < 0.5) {
            return bad(
                "poisson",
                format!("must be in (-1, 0.5), got {}", self.poisson),
            );
        }
        if !(self.yield_stress.is_finite() && self.yield_stress > 0.0) {
            return bad(
                "yield_stress",
                format!("must be > 0, got {}", self.yield_stress),
            );
        }
        if !(self.iso_hardening.is_finite() && self.iso_hardening >= 0.0) {
            return bad(
                "iso_hardening",
                format!("must be >= 0, got {}", self.iso_hardening),
            );
        }
        if !(self.kin_hardening.is_finite() && self.kin_hardening >= 0.0) {
            return bad(
                "kin_hardening",
                format!("must be >= 0, got {}", self.kin_hardening),
            );
        }
        Ok(())
    }

    /// Elastic stress increment for a strain increment (Hooke, isotropic).
    #[inline]
    pub fn elastic_increment(&self, dstrain: &Sym) -> Sym {
        let mu = self.shear_modulus();
        let lambda = self.bulk_modulus() - 2.0 / 3.0 * mu;
        let tr = lambda * trace(dstrain);
        [
            tr + 2.0 * mu * dstrain[0],
            tr + 2.0 * mu * dstrain[1],
            tr + 2.0 * mu * dstrain[2],
            2.0 * mu * dstrain[3],
            2.0 * mu * dstrain[4],
            2.0 * mu * dstrain[5],
        ]
    }

    /// Elastic predictor + radial return for a strain increment; returns the plastic
    /// multiplier increment Δε̄ᵖ (equivalent plastic strain increment, ≥ 0).
    ///
    /// Simo–Hughes Box 3.2: ξ* = dev(σ*) − α, f* = ‖ξ*‖ − √(2/3)(σ_y0 + H_iso ε̄ᵖ);
    /// Δγ = f* / (2μ + (2/3)(H_iso + H_kin)), n = ξ*/‖ξ*‖;
    /// σ = σ* − 2μ Δγ n, α += (2/3) H_kin Δγ n, ε̄ᵖ += √(2/3) Δγ.
    pub fn update(&self, state: &mut J2State, dstrain: &Sym) -> f64 {
        let de = self.elastic_increment(dstrain);
        let mut trial = state.stress;
        for k in 0..6 {
            trial[k] += de[k];
        }
        state.stress = trial;
        self.return_map(state)
    }

    /// Plane-stress update (σ_zz = 0; σ_xz = σ_yz = 0 come from 2-D kinematics): the
    /// in-plane increment `dstrain` (its zz entry is ignored) plus the through-thickness
    /// increment Δε_zz that makes the radial-return stress σ_zz vanish, found by secant
    /// iteration from the elastic value. The same backward-Euler J2 problem as the
    /// projected return of Simo & Taylor (1986), solved in 3-D stress space. Returns
    /// (Δε̄ᵖ, Δε_zz).
    pub fn update_plane_stress(&self, state: &mut J2State, dstrain: &Sym) -> (f64, f64) {
        let mu = self.shear_modulus();
        let lambda = self.bulk_modulus() - 2.0 / 3.0 * mu;
        let m = lambda + 2.0 * mu;
        let mut de = *dstrain;
        let residual = |dzz: f64, de: &mut Sym| -> (f64, J2State, f64) {
            de[2] = dzz;
            let mut s = *state;
            let dp = self.update(&mut s, de);
            (s.stress[2], s, dp)
        };
        // Elastic guess: σ_zz + λ(Δε_xx + Δε_yy) + (λ + 2μ) Δε_zz = 0.
        let mut x0 = -(state.stress[2] + lambda * (dstrain[0] + dstrain[1])) / m;
        let (mut r0, mut best, mut dp) = residual(x0, &mut de);
        let scale = best.stress.iter().fold(0.0f64, |a, &b| a.max(b.abs())) * 1e-14;
        if r0.abs() <= scale {
            *state = best;
            return (dp, x0);
        }
        let mut x1 = x0 - r0 / m;
        for _ in 0..50 {
            let (r1, s1, dp1) = residual(x1, &mut de);
            best = s1;
            dp = dp1;
            if r1.abs() <= scale || r1 == r0 {
                break;
            }
            let x2 = x1 - r1 * (x1 - x0) / (r1 - r0);
            x0 = x1;
            r0 = r1;
            x1 = x2;
        }
        best.stress[2] = 0.0;
        *state = best;
        (dp, x1)
    }

    /// Radial return of a trial state already stored in `state.stress` (used when the trial
    /// stress comes from a rate form with Jaumann rotation). Returns Δε̄ᵖ.
    pub fn return_map(&self, state: &mut J2State) -> f64 {
        let mu = self.shear_modulus();
        let s = deviator(&state.stress);
        let mut xi = [0.0; 6];
        for k in 0..6 {
            xi[k] = s[k] - state.back_stress[k];
        }
        let norm = ddot(&xi, &xi).sqrt();
        let sqrt23 = (2.0f64 / 3.0).sqrt();
        let radius = sqrt23 * (self.yield_stress + self.iso_hardening * state.eq_plastic_strain);
        let f = norm - radius;
        if f <= 0.0 || norm == 0.0 {
            return 0.0;
        }
        let dgamma = f / (2.0 * mu + 2.0 / 3.0 * (self.iso_hardening + self.kin_hardening));
        let inv = 1.0 / norm;
        for k in 0..6 {
            let n = xi[k] * inv;
            state.stress[k] -= 2.0 * mu * dgamma * n;
            state.back_stress[k] += 2.0 / 3.0 * self.kin_hardening * dgamma * n;
        }
        let dp = sqrt23 * dgamma;
        state.eq_plastic_strain += dp;
        dp
    }
}

/// Plastic work density σ : Δεᵖ of a return that gave `deqp` = Δε̄ᵖ (J/m³), from the
/// returned `state`: Δεᵖ = Δγ n with Δγ = √(3/2) Δε̄ᵖ and n = (dev σ − α)/‖dev σ − α‖, the
/// flow direction of the radial return (Simo–Hughes Box 3.2; n is the same before and after
/// the return). Includes the work stored by kinematic hardening (α : Δεᵖ).
#[inline]
pub fn plastic_work(state: &J2State, deqp: f64) -> f64 {
    if !(deqp > 0.0) {
        return 0.0;
    }
    let s = deviator(&state.stress);
    let mut xi = [0.0; 6];
    for k in 0..6 {
        xi[k] = s[k] - state.back_stress[k];
    }
    let norm = ddot(&xi, &xi).sqrt();
    if !(norm > 0.0) {
        return 0.0;
    }
    (1.5f64).sqrt() * deqp * ddot(&s, &xi) / norm
}

/// The spin W = ½(L − Lᵀ) of a velocity gradient L and the strain increment D Δt (Voigt order
/// xx, yy, zz, yz, xz, xy) over a step Δt: what [`jaumann_rotate_skew`] and
/// [`J2Material::update`] take from a rate-form model's L.
#[inline]
pub fn spin_and_strain_step(l: &[[f64; 3]; 3], dt: f64) -> ([[f64; 3]; 3], Sym) {
    let spin = std::array::from_fn(|a| std::array::from_fn(|c| 0.5 * (l[a][c] - l[c][a])));
    let de: Sym = [
        l[0][0] * dt,
        l[1][1] * dt,
        l[2][2] * dt,
        0.5 * (l[1][2] + l[2][1]) * dt,
        0.5 * (l[0][2] + l[2][0]) * dt,
        0.5 * (l[0][1] + l[1][0]) * dt,
    ];
    (spin, de)
}

/// Same update as [`jaumann_rotate`] for a skew `spin`, in fewer operations (W σ − σ W =
/// P + Pᵀ with P = W σ, using W_aa = 0); equal to it up to round-off, not bit for bit.
#[inline]
pub fn jaumann_rotate_skew(s: &mut Sym, spin: &[[f64; 3]; 3], dt: f64) {
    let (w01, w02, w12) = (spin[0][1], spin[0][2], spin[1][2]);
    let [sxx, syy, szz, syz, sxz, sxy] = *s;
    // P = W σ, W = [[0, w01, w02], [−w01, 0, w12], [−w02, −w12, 0]].
    let p00 = w01 * sxy + w02 * sxz;
    let p01 = w01 * syy + w02 * syz;
    let p02 = w01 * syz + w02 * szz;
    let p10 = -w01 * sxx + w12 * sxz;
    let p11 = -w01 * sxy + w12 * syz;
    let p12 = -w01 * sxz + w12 * szz;
    let p20 = -w02 * sxx - w12 * sxy;
    let p21 = -w02 * sxy - w12 * syy;
    let p22 = -w02 * sxz - w12 * syz;
    s[0] += dt * 2.0 * p00;
    s[1] += dt * 2.0 * p11;
    s[2] += dt * 2.0 * p22;
    s[3] += dt * (p12 + p21);
    s[4] += dt * (p02 + p20);
    s[5] += dt * (p01 + p10);
}

/// Jaumann (objective) rotation of a stress over dt with spin W (skew 3x3): σ += dt (W σ − σ W).
/// Seed 000 eq. (B.1); forward Euler in the rotation, first order in dt.
pub fn jaumann_rotate(s: &mut Sym, spin: &[[f64; 3]; 3], dt: f64) {
    let m = to_matrix(s);
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let mut acc = 0.0;
            for k in 0..3 {
                acc += spin[i][k] * m[k][j] - m[i][k] * spin[k][j];
            }
            r[i][j] = acc;
        }
    }
    let d = from_matrix(&r);
    for k in 0..6 {
        s[k] += dt * d[k];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steel(h_iso: f64, h_kin: f64) -> J2Material {
        J2Material {
            young: 200e9,
            poisson: 0.3,
            yield_stress: 300e6,
            iso_hardening: h_iso,
            kin_hardening: h_kin,
        }
    }

    /// Closed form of σ_xx along uniaxial strain ε (monotonic), linear hardening H = H_iso + H_kin:
    /// elastic (K + 4μ/3) ε up to ε_y = σ_y/(2μ); then tangent K + (4/3) μ H / (3μ + H).
    fn uniaxial_strain_sxx(m: &J2Material, eps: f64) -> f64 {
        let mu = m.shear_modulus();
        let k = m.bulk_modulus();
        let h = m.iso_hardening + m.kin_hardening;
        let ey = m.yield_stress / (2.0 * mu);
        if eps <= ey {
            (k + 4.0 / 3.0 * mu) * eps
        } else {
            k * eps + 2.0 / 3.0 * m.yield_stress + 4.0 / 3.0 * mu * h / (3.0 * mu + h) * (eps - ey)
        }
    }

    #[test]
    fn uniaxial_strain_path_matches_closed_form() {
        for (hi, hk) in [(0.0, 0.0), (2e9, 0.0), (0.0, 2e9), (1e9, 3e9)] {
            let m = steel(hi, hk);
            let mut st = J2State::default();
            let n = 400;
            let eps_max = 0.01;
            let de = eps_max / n as f64;
            for step in 1..=n {
                m.update(&mut st, &[de, 0.0, 0.0, 0.0, 0.0, 0.0]);
                let eps = de * step as f64;
                let exact = uniaxial_strain_sxx(&m, eps);
                let rel = (st.stress[0] - exact).abs() / exact.abs();
                assert!(
                    rel < 1e-10,
                    "H=({hi},{hk}) eps={eps}: {} vs {exact}",
                    st.stress[0]
                );
                // Lateral stresses: σ_yy = σ_xx − q with q the current yield size (+ back stress).
                assert!((st.stress[1] - st.stress[2]).abs() < 1e-6);
            }
            // Equivalent plastic strain: from the consistency condition in closed form.
            let mu = m.shear_modulus();
            let h = hi + hk;
            let ey = m.yield_stress / (2.0 * mu);
            let p_exact = 2.0 * mu * (eps_max - ey) / (3.0 * mu + h);
            assert!((st.eq_plastic_strain - p_exact).abs() < 1e-12 * (1.0 + p_exact));
        }
    }

    #[test]
    fn single_step_radial_return_closed_form() {
        // A general (non-radial) strain increment from a pre-stressed, back-stressed state.
        let m = steel(1.5e9, 0.7e9);
        let mut st = J2State {
            stress: [50e6, -20e6, 10e6, 5e6, -8e6, 12e6],
            back_stress: [10e6, -4e6, -6e6, 1e6, 0.0, -2e6],
            eq_plastic_strain: 0.01,
        };
        let de = [3e-3, -1e-3, 0.5e-3, 0.8e-3, -0.4e-3, 1.1e-3];
        let s0 = st;
        let mu = m.shear_modulus();
        let k = m.bulk_modulus();
        let dp = m.update(&mut st, &de);
        // Closed form, written out independently of the implementation.
        let tr = de[0] + de[1] + de[2];
        let mut trial = s0.stress;
        for c in 0..6 {
            let dev = if c < 3 { de[c] - tr / 3.0 } else { de[c] };
            trial[c] += (if c < 3 { k * tr } else { 0.0 }) + 2.0 * mu * dev;
        }
        let p = (trial[0] + trial[1] + trial[2]) / 3.0;
        let mut xi = trial;
        for c in 0..3 {
            xi[c] -= p;
        }
        for c in 0..6 {
            xi[c] -= s0.back_stress[c];
        }
        let nx = (xi[0].powi(2)
            + xi[1].powi(2)
            + xi[2].powi(2)
            + 2.0 * (xi[3].powi(2) + xi[4].powi(2) + xi[5].powi(2)))
        .sqrt();
        let r = (2.0f64 / 3.0).sqrt() * (300e6 + 1.5e9 * 0.01);
        assert!(nx > r, "the increment must be plastic");
        let dg = (nx - r) / (2.0 * mu + 2.0 / 3.0 * 2.2e9);
        for c in 0..6 {
            let n = xi[c] / nx;
            let s_exact = trial[c] - 2.0 * mu * dg * n;
            let a_exact = s0.back_stress[c] + 2.0 / 3.0 * 0.7e9 * dg * n;
            assert!((st.stress[c] - s_exact).abs() < 1e-10 * 300e6);
            assert!((st.back_stress[c] - a_exact).abs() < 1e-10 * 300e6);
        }
        assert!((dp - (2.0f64 / 3.0).sqrt() * dg).abs() < 1e-16);
        // On the updated yield surface.
        let mut xi1 = deviator(&st.stress);
        for c in 0..6 {
            xi1[c] -= st.back_stress[c];
        }
        let f = ddot(&xi1, &xi1).sqrt()
            - (2.0f64 / 3.0).sqrt() * (300e6 + 1.5e9 * st.eq_plastic_strain);
        assert!(f.abs() < 1e-8 * 300e6, "f = {f}");
    }

    #[test]
    fn elastic_step_is_hooke() {
        let m = steel(1e9, 1e9);
        let mut st = J2State::default();
        let dp = m.update(&mut st, &[1e-4, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(dp, 0.0);
        let mu = m.shear_modulus();
        let lambda = m.bulk_modulus() - 2.0 / 3.0 * mu;
        assert!((st.stress[0] - (lambda + 2.0 * mu) * 1e-4).abs() < 1e-6);
        assert!((st.stress[1] - lambda * 1e-4).abs() < 1e-6);
    }

    /// Bauschinger effect: after loading in uniaxial strain to ε1 and reversing, reverse
    /// yield occurs after a strain drop of 2σ_y/(2μ) = σ_y/μ for pure kinematic hardening
    /// (the elastic range keeps size 2σ_y0) and (σ_y0 + H p1)/μ for pure isotropic hardening.
    #[test]
    fn bauschinger_kinematic_vs_isotropic() {
        let h = 5e9;
        let e1 = 0.006;
        for kinematic in [true, false] {
            let m = if kinematic {
                steel(0.0, h)
            } else {
                steel(h, 0.0)
            };
            let mu = m.shear_modulus();
            let mut st = J2State::default();
            let n = 100;
            for _ in 0..n {
                m.update(&mut st, &[e1 / n as f64, 0.0, 0.0, 0.0, 0.0, 0.0]);
            }
            let p1 = st.eq_plastic_strain;
            let drop = if kinematic {
                m.yield_stress / mu
            } else {
                (m.yield_stress + h * p1) / mu
            };
            // Just inside the elastic range: no plastic flow.
            let mut a = st;
            let dp = m.update(&mut a, &[-drop * (1.0 - 1e-6), 0.0, 0.0, 0.0, 0.0, 0.0]);
            assert_eq!(dp, 0.0, "kinematic={kinematic}");
            // Just past it: plastic flow.
            let mut b = st;
            let dp = m.update(&mut b, &[-drop * (1.0 + 1e-3), 0.0, 0.0, 0.0, 0.0, 0.0]);
            assert!(dp > 0.0, "kinematic={kinematic}");
            // Further reverse loading follows the hardening slope (4/3)μH/(3μ+H) in s_xx.
            let mut c = st;
            let extra = 0.002;
            m.update(&mut c, &[-(drop + extra), 0.0, 0.0, 0.0, 0.0, 0.0]);
            let sdev = |s: &Sym| s[0] - (s[0] + s[1] + s[2]) / 3.0;
            let exact = sdev(&st.stress)
                - 4.0 / 3.0 * mu * drop
                - 4.0 / 3.0 * mu * h / (3.0 * mu + h) * extra;
            assert!(
                (sdev(&c.stress) - exact).abs() < 1e-10 * m.yield_stress,
                "kinematic={kinematic}: {} vs {exact}",
                sdev(&c.stress)
            );
        }
    }

    /// Pure spin about z for time t rotates σ to R σ Rᵀ; the explicit Jaumann update converges
    /// to it at first order in dt.
    #[test]
    fn jaumann_rotation_converges_to_rigid_rotation() {
        let omega: f64 = 1.0;
        let t = 0.5;
        let w = [[0.0, -omega, 0.0], [omega, 0.0, 0.0], [0.0, 0.0, 0.0]];
        let s0: Sym = [100.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let th = omega * t;
        let (c, s) = (th.cos(), th.sin());
        let exact: Sym = [100.0 * c * c, 100.0 * s * s, 0.0, 0.0, 0.0, 100.0 * c * s];
        let err = |n: usize| {
            let mut st = s0;
            for _ in 0..n {
                jaumann_rotate(&mut st, &w, t / n as f64);
            }
            (0..6).map(|k| (st[k] - exact[k]).abs()).fold(0.0, f64::max)
        };
        let (e1, e2) = (err(1000), err(2000));
        let order = (e1 / e2).log2();
        assert!(e2 < 0.05, "error {e2}");
        assert!((order - 1.0).abs() < 0.05, "order {order}");
        // Von Mises stress is invariant under the rotation up to O(dt).
        let mut st = s0;
        for _ in 0..2000 {
            jaumann_rotate(&mut st, &w, t / 2000.0);
        }
        assert!((von_mises(&st) - 100.0).abs() < 0.1);
    }

    #[test]
    fn validate_names_the_key() {
        let mut m = steel(0.0, 0.0);
        assert!(m.validate().is_ok());
        m.poisson = 0.5;
        assert_eq!(m.validate().unwrap_err().0, "poisson");
        m = steel(0.0, -1.0);
        assert_eq!(m.validate().unwrap_err().0, "kin_hardening");
        m = steel(0.0, 0.0);
        m.young = 0.0;
        assert_eq!(m.validate().unwrap_err().0, "young");
    }

    /// Plane stress: the 3-D radial return with Δε_zz solved for σ_zz = 0 agrees with the
    /// independent projected return of `j2_plane_stress` (Simo & Taylor) along a biaxial,
    /// shearing, then reversing strain path, with both hardening kinds; elastic steps give
    /// E/(1−ν²) exactly.
    #[test]
    fn plane_stress_update_matches_projected_return() {
        use crate::j2_plane_stress::{J2PlaneStress, PlaneStressPoint};
        let m = steel(1e9, 2e9);
        let ps = J2PlaneStress {
            youngs: m.young,
            poisson: m.poisson,
            yield_stress: m.yield_stress,
            h_iso: m.iso_hardening,
            h_kin: m.kin_hardening,
        };
        let mut a = J2State::default();
        let mut b = PlaneStressPoint::default();
        let mut worst: f64 = 0.0;
        let mut plastic = 0.0;
        for step in 0..400 {
            let t = step as f64;
            let d = if step < 250 { 1e-5 } else { -1.2e-5 };
            let de = [d, 0.4 * d * (t * 0.01).cos(), 0.0, 0.0, 0.0, 0.3 * d];
            let (dp, _) = m.update_plane_stress(&mut a, &de);
            plastic += dp;
            ps.update(&mut b, [de[0], de[1], 2.0 * de[5]]);
            let s3 = [a.stress[0], a.stress[1], a.stress[5]];
            for c in 0..3 {
                worst = worst.max((s3[c] - b.stress[c]).abs() / m.yield_stress);
            }
            assert!(a.stress[2].abs() < 1e-6, "σ_zz = {}", a.stress[2]);
            worst = worst.max((a.eq_plastic_strain - b.eqps).abs());
        }
        assert!(plastic > 1e-3, "the path must yield");
        assert!(worst < 1e-9, "{worst:e}");
        // Elastic: σ_xx = E/(1−ν²) ε, σ_yy = ν σ_xx.
        let e = steel(0.0, 0.0);
        let mut st = J2State::default();
        e.update_plane_stress(&mut st, &[1e-4, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let sxx = e.young / (1.0 - e.poisson * e.poisson) * 1e-4;
        assert!((st.stress[0] - sxx).abs() < 1e-12 * sxx);
        assert!((st.stress[1] - e.poisson * sxx).abs() < 1e-12 * sxx);
    }

    /// A velocity gradient splits into its spin and its rate of deformation: W is skew, D
    /// symmetric, and (D + W) Δt gives L Δt back in every component.
    #[test]
    fn a_velocity_gradient_is_its_spin_plus_its_rate_of_deformation() {
        let l = [[0.3, -1.2, 0.7], [2.1, -0.4, 0.05], [-0.9, 1.6, 0.25]];
        let dt = 1e-3;
        let (w, de) = spin_and_strain_step(&l, dt);
        let d = to_matrix(&de);
        for a in 0..3 {
            for c in 0..3 {
                assert_eq!(w[a][c], -w[c][a], "W is skew at ({a}, {c})");
                assert!(
                    (d[a][c] + w[a][c] * dt - l[a][c] * dt).abs() < 1e-18,
                    "({a}, {c}): D + W = {} against L = {}",
                    d[a][c] + w[a][c] * dt,
                    l[a][c] * dt
                );
            }
        }
    }

    /// The skew-spin Jaumann update equals the general one to round-off.
    #[test]
    fn skew_jaumann_matches_general() {
        let s0: Sym = [3.0e8, -1.0e8, 0.5e8, 0.7e8, -0.2e8, 1.1e8];
        let w = [[0.0, 0.3, -0.7], [-0.3, 0.0, 0.45], [0.7, -0.45, 0.0]];
        let (mut a, mut b) = (s0, s0);
        jaumann_rotate(&mut a, &w, 1e-3);
        jaumann_rotate_skew(&mut b, &w, 1e-3);
        for c in 0..6 {
            assert!(
                (a[c] - b[c]).abs() < 1e-15 * 3.0e8,
                "{c}: {} vs {}",
                a[c],
                b[c]
            );
        }
        assert!(
            (a[0] - s0[0]).abs() > 1e3,
            "the spin must rotate the stress"
        );
    }
}
