//! The GS4-II family of one-step, second-order integrators (seed 003 §4, eq. 66–70; Zhou and
//! Tamma 2004) as a plain struct of coefficients, and its designs U0(ρ₁, ρ₂, ρₛ) named by the
//! spectral radii of the two principal roots and the spurious root at Ω = ωΔt → ∞.
//!
//! One step solves for Δa = a_{n+1} − a_n (seed 003 eq. 67):
//! `M ã + C ṽ + K ũ = (1 − W₁) f_n + W₁ f_{n+1}` with
//! `ũ = u_n + Λ₁W₁ Δt v_n + Λ₂W₂ Δt² a_n + Λ₃W₃ Δt² Δa`, `ṽ = v_n + Λ₄W₁ Δt a_n + Λ₅W₂ Δt Δa`,
//! `ã = a_n + Λ₆W₁ Δa`, then updates (eq. 68)
//! `u_{n+1} = u_n + λ₁ Δt v_n + λ₂ Δt² a_n + λ₃ Δt² Δa`, `v_{n+1} = v_n + λ₄ Δt a_n + λ₅ Δt Δa`.
//!
//! The U0 designs (zero-order displacement overshoot) take the weights of a time point
//! inside the step (Λ₁W₁ = Λ₄W₁ = W₁, Λ₂W₂ = W₁/2, Λ₃W₃ = W₁λ₃, Λ₅W₂ = W₁λ₅, λ₁ = λ₄ = 1,
//! λ₂ = 1/2). Their characteristic polynomial at Ω → ∞ factors into
//! `(λ − αf/(αf − 1)) (λ₃ λ² + (1 + αf − αm − 2λ₃) λ + λ₃ − αf + αm)` (αf = 1 − W₁,
//! αm = 1 − Λ₆W₁); asking for roots −ρₛ and −ρ₁, −ρ₂ gives
//! `W₁ = 1/(1 + ρₛ)`, `λ₃ = 1/((1 + ρ₁)(1 + ρ₂))`,
//! `Λ₆W₁ = W₁ + (1 − ρ₁ρ₂) λ₃`, `λ₅ = 1/2 + (1 − ρ₁ρ₂) λ₃` (second order: λ₅ = 1/2 + Λ₆W₁ − W₁).
//! U0(1,1,0) is Newmark's average acceleration, U0(ρ,ρ,0) the WBZ-like designs (U0(0,0,0) the
//! most dissipative), U0(ρ,ρ,(1−ρ)/(2ρ)) the HHT-like ones (αm = 0), U0(ρ,ρ,ρ) the
//! generalized-α method. The explicit member is U0(1,1,0)'s: central differences with the
//! force at the step end (Λ₃W₃ = Λ₅W₂ = λ₃ = 0, λ₅ = 1/2), whose effective matrix is M.

use serde::Deserialize;
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum Gs4Error {
    /// A bad design or parameter: the key and why.
    #[error("{key}: {reason}")]
    Config { key: String, reason: String },
}

fn config(key: &str, reason: impl Into<String>) -> Gs4Error {
    Gs4Error::Config {
        key: key.into(),
        reason: reason.into(),
    }
}

/// Coefficients of one GS4-II member (seed 003 eq. 67–68).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gs4 {
    pub w1: f64,
    pub l1w1: f64,
    pub l2w2: f64,
    pub l3w3: f64,
    pub l4w1: f64,
    pub l5w2: f64,
    pub l6w1: f64,
    pub lam1: f64,
    pub lam2: f64,
    pub lam3: f64,
    pub lam4: f64,
    pub lam5: f64,
    /// True when the effective matrix is Λ₆W₁ M + Λ₅W₂ Δt C alone (no stiffness).
    pub explicit: bool,
}

/// A design: the three spectral radii at infinity (principal ρ₁, ρ₂; spurious ρₛ).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Design {
    pub rho1: f64,
    pub rho2: f64,
    pub rho_s: f64,
}

impl Design {
    /// Parses "U0(ρ₁,ρ₂,ρₛ)" or a family name with `rho_inf`: "newmark" (U0(1,1,0)),
    /// "wbz" (U0(ρ,ρ,0)), "hht" (U0(ρ,ρ,(1−ρ)/(2ρ)), ρ ∈ [1/2, 1]), "generalized-alpha"
    /// (U0(ρ,ρ,ρ)). `key` names the design's key path in errors.
    pub fn parse(key: &str, design: &str, rho_inf: Option<f64>) -> Result<Self, Gs4Error> {
        let s = design.trim();
        let rho_key = format!("{}.rho_inf", key.rsplit_once('.').map_or("", |p| p.0));
        let rho_key = rho_key.trim_start_matches('.').to_string();
        let need_rho = |name: &str| -> Result<f64, Gs4Error> {
            let r = rho_inf.ok_or_else(|| {
                config(
                    &rho_key,
                    format!("design \"{name}\" needs rho_inf in [0, 1]"),
                )
            })?;
            if (0.0..=1.0).contains(&r) {
                Ok(r)
            } else {
                Err(config(&rho_key, format!("must be in [0, 1], got {r}")))
            }
        };
        let d = if let Some(args) = s.strip_prefix("U0(").and_then(|r| r.strip_suffix(')')) {
            if rho_inf.is_some() {
                return Err(config(
                    &rho_key,
                    "not used with an explicit U0(ρ₁,ρ₂,ρₛ) design; remove it",
                ));
            }
            let parts: Vec<&str> = args.split(',').map(str::trim).collect();
            if parts.len() != 3 {
                return Err(config(key, format!("U0 takes three radii, got \"{s}\"")));
            }
            let mut r = [0.0; 3];
            for (ri, p) in r.iter_mut().zip(&parts) {
                *ri = p
                    .parse::<f64>()
                    .map_err(|_| config(key, format!("\"{p}\" in \"{s}\" is not a number")))?;
            }
            Design {
                rho1: r[0],
                rho2: r[1],
                rho_s: r[2],
            }
        } else {
            match s {
                "newmark" => Design {
                    rho1: 1.0,
                    rho2: 1.0,
                    rho_s: 0.0,
                },
                "wbz" => {
                    let r = need_rho(s)?;
                    Design {
                        rho1: r,
                        rho2: r,
                        rho_s: 0.0,
                    }
                }
                "hht" => {
                    let r = need_rho(s)?;
                    if r < 0.5 {
                        return Err(config(
                            &rho_key,
                            format!("the HHT-like design needs rho_inf in [1/2, 1], got {r}"),
                        ));
                    }
                    Design {
                        rho1: r,
                        rho2: r,
                        rho_s: (1.0 - r) / (2.0 * r),
                    }
                }
                "generalized-alpha" => {
                    let r = need_rho(s)?;
                    Design {
                        rho1: r,
                        rho2: r,
                        rho_s: r,
                    }
                }
                other => {
                    return Err(config(
                        key,
                        format!(
                            "unknown design \"{other}\": use \"U0(ρ₁,ρ₂,ρₛ)\", \"newmark\", \
                             \"wbz\", \"hht\" or \"generalized-alpha\""
                        ),
                    ));
                }
            }
        };
        for (name, r) in [("ρ₁", d.rho1), ("ρ₂", d.rho2), ("ρₛ", d.rho_s)] {
            if !(0.0..=1.0).contains(&r) {
                return Err(config(key, format!("{name} must be in [0, 1], got {r}")));
            }
        }
        Ok(d)
    }
}

impl Gs4 {
    /// The implicit U0(ρ₁, ρ₂, ρₛ) member (formulas in the module doc).
    pub fn u0(d: Design) -> Self {
        let w1 = 1.0 / (1.0 + d.rho_s);
        let lam3 = 1.0 / ((1.0 + d.rho1) * (1.0 + d.rho2));
        let shift = (1.0 - d.rho1 * d.rho2) * lam3;
        let l6w1 = w1 + shift;
        let lam5 = 0.5 + shift;
        Gs4 {
            w1,
            l1w1: w1,
            l2w2: 0.5 * w1,
            l3w3: w1 * lam3,
            l4w1: w1,
            l5w2: w1 * lam5,
            l6w1,
            lam1: 1.0,
            lam2: 0.5,
            lam3,
            lam4: 1.0,
            lam5,
            explicit: false,
        }
    }

    /// The explicit member of U0(1,1,0): central differences, force at the step end.
    pub fn central_difference() -> Self {
        Gs4 {
            w1: 1.0,
            l1w1: 1.0,
            l2w2: 0.5,
            l3w3: 0.0,
            l4w1: 1.0,
            l5w2: 0.0,
            l6w1: 1.0,
            lam1: 1.0,
            lam2: 0.5,
            lam3: 0.0,
            lam4: 1.0,
            lam5: 0.5,
            explicit: true,
        }
    }

    /// The one-step map of an undamped mode of frequency ω at Ω = ωΔt on the scaled state
    /// (u, Δt v, Δt² a): column j is the step from the j-th unit state (the module doc's
    /// update with M = 1, C = 0, K = ω², no load).
    pub fn amplification(&self, omega_dt: f64) -> nalgebra::Matrix3<f64> {
        let o2 = omega_dt * omega_dt;
        let mut m = nalgebra::Matrix3::zeros();
        for j in 0..3 {
            let mut x = [0.0; 3];
            x[j] = 1.0;
            let [u, v, a] = x;
            let da = -(a + o2 * (u + self.l1w1 * v + self.l2w2 * a)) / (self.l6w1 + o2 * self.l3w3);
            m[(0, j)] = u + self.lam1 * v + self.lam2 * a + self.lam3 * da;
            m[(1, j)] = v + self.lam4 * a + self.lam5 * da;
            m[(2, j)] = a + da;
        }
        m
    }

    /// Modulus and phase per step of the principal root at Ω = ωΔt: the complex root of
    /// [`Self::amplification`] in the upper half plane, phase in (0, π); once the principal
    /// pair has met on the negative real axis, the larger negative root with phase π; None
    /// when no root has either (the mode no longer oscillates).
    pub fn principal_root(&self, omega_dt: f64) -> Option<(f64, f64)> {
        let ev = self.amplification(omega_dt).complex_eigenvalues();
        let scale = ev.iter().fold(0.0f64, |m, z| m.max(z.norm()));
        if let Some(z) = ev.iter().find(|z| z.im > 1e-12 * scale) {
            return Some((z.norm(), z.arg()));
        }
        ev.iter()
            .filter(|z| z.re < -1e-12 * scale)
            .map(|z| z.norm())
            .max_by(f64::total_cmp)
            .map(|r| (r, std::f64::consts::PI))
    }

    /// The sub-cycling resonance of `substeps` steps (docs/architecture.md, "Sub-cycling
    /// resonance"): the smallest Ω = ωΔt at which an undamped mode's principal root turns a
    /// whole period in `substeps` steps (substeps · phase = 2π), so that the mode returns to
    /// the same state at every end of a window of `substeps` steps, and the share of its
    /// amplitude that survives those steps (rᵐ, 1 for a non-dissipative design). None for fewer
    /// than three steps when no stable Ω gets there (one step never; two steps would need a
    /// phase of π per step).
    pub fn resonance(&self, substeps: usize) -> Option<Resonance> {
        if substeps < 2 {
            return None;
        }
        let m = substeps as f64;
        let target = 2.0 * std::f64::consts::PI / m;
        // The explicit member is stable below Ω = 2; an implicit one at every Ω.
        let top = if self.explicit {
            2.0 * (1.0 - 1e-12)
        } else {
            1e4
        };
        let past = |o: f64| self.principal_root(o).is_some_and(|(_, p)| p >= target);
        let mut lo: f64 = 1e-3;
        let mut hi = loop {
            let next = (lo * 1.01).min(top);
            if past(next) {
                break next;
            }
            if next >= top {
                return None;
            }
            lo = next;
        };
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if past(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        let (r, _) = self.principal_root(hi)?;
        Some(Resonance {
            omega_dt: hi,
            surviving: r.powf(m),
        })
    }

    /// The largest step of `substeps` steps per window that keeps every mode of a mesh
    /// whose explicit critical step (2/ω_max) is at least `critical` below the resonance:
    /// Ω_res · critical / 2. None when the member has no resonance at that count or damps
    /// it (less than [`RESONANCE_SURVIVAL`] of the mode survives the window).
    pub fn resonance_free_step(&self, substeps: usize, critical: f64) -> Option<f64> {
        let r = self.resonance(substeps)?;
        (r.surviving >= RESONANCE_SURVIVAL).then_some(0.5 * r.omega_dt * critical)
    }

    /// The member a parsed spec asks for; `key` is the spec's key path.
    pub fn from_spec(key: &str, spec: &IntegratorSpec) -> Result<Self, Gs4Error> {
        if spec.scheme != "gs4" {
            return Err(config(
                &format!("{key}.scheme"),
                format!("must be \"gs4\", got \"{}\"", spec.scheme),
            ));
        }
        let d = Design::parse(&format!("{key}.design"), &spec.design, spec.rho_inf)?;
        if spec.implicit {
            Ok(Gs4::u0(d))
        } else if d
            == (Design {
                rho1: 1.0,
                rho2: 1.0,
                rho_s: 0.0,
            })
        {
            Ok(Gs4::central_difference())
        } else {
            Err(config(
                &format!("{key}.implicit"),
                format!(
                    "false needs design U0(1,1,0) (central differences); the explicit members \
                     of other designs are not implemented, got {:?}",
                    spec.design
                ),
            ))
        }
    }
}

/// Where a sub-cycled member meets its resonance ([`Gs4::resonance`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Resonance {
    /// Ω = ωΔt of the first resonant mode.
    pub omega_dt: f64,
    /// Share of that mode's amplitude left after the window's steps (rᵐ).
    pub surviving: f64,
}

/// Below this share of its amplitude surviving a window the resonant mode is damped out
/// before the window-end constraint's blindness to it matters (an amplification of at most
/// 1/(1 − ½) = 2 of what the coupling lets through).
pub const RESONANCE_SURVIVAL: f64 = 0.5;

/// The `integrator` table of a structural model:
/// `{ scheme = "gs4", design = "U0(1,1,0)", rho_inf = 1.0, implicit = false }`.
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct IntegratorSpec {
    /// The integrator family: "gs4" (GS4-II, seed 003 §4).
    pub scheme: String,
    /// The member of the family: "U0(ρ1,ρ2,ρs)" spectral radii, or a named design with
    /// `rho_inf`: "newmark" (U0(1,1,0)), "wbz", "hht" or "generalized-alpha". Explicit
    /// (`implicit = false`) U0(1,1,0) is central differences.
    #[serde(default = "default_design")]
    pub design: String,
    /// Spectral radius at infinite step ρ∞ ∈ [0, 1] of the named designs wbz, hht (ρ∞ ≥ 1/2)
    /// and generalized-alpha.
    #[serde(default)]
    pub rho_inf: Option<f64>,
    /// Solve each step implicitly (sparse Cholesky, factorised once) instead of explicitly.
    #[serde(default)]
    pub implicit: bool,
}

fn default_design() -> String {
    "U0(1,1,0)".into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_designs_are_their_u0_radii() {
        let n = Design::parse("d", "newmark", None).unwrap();
        assert_eq!((n.rho1, n.rho2, n.rho_s), (1.0, 1.0, 0.0));
        let g = Gs4::u0(n);
        // Newmark's average acceleration: W₁ = Λ₆W₁ = 1, β = 1/4, γ = 1/2.
        assert_eq!((g.w1, g.l6w1, g.lam3, g.lam5), (1.0, 1.0, 0.25, 0.5));
        // WBZ at ρ∞ = 0: αm = −1, β = 1, γ = 3/2 (Wood, Bossak, Zienkiewicz 1980).
        let w = Gs4::u0(Design::parse("d", "U0(0,0,0)", None).unwrap());
        assert_eq!((w.w1, w.l6w1, w.lam3, w.lam5), (1.0, 2.0, 1.0, 1.5));
        // HHT at ρ∞ = 0.8: α = (1−ρ)/(1+ρ) = 1/9, αm = 0, γ = 1/2 + α, β = (1+α)²/4.
        let h = Gs4::u0(Design::parse("d", "hht", Some(0.8)).unwrap());
        let a = 1.0 / 9.0;
        assert!((h.w1 - (1.0 - a)).abs() < 1e-15 && (h.l6w1 - 1.0).abs() < 1e-15);
        assert!((h.lam5 - (0.5 + a)).abs() < 1e-15);
        assert!((h.lam3 - (1.0 + a) * (1.0 + a) / 4.0).abs() < 1e-15);
        // Generalized-α (Chung and Hulbert 1993): αm = (2ρ−1)/(ρ+1), αf = ρ/(ρ+1).
        let r = 0.6;
        let ga = Gs4::u0(Design::parse("d", "generalized-alpha", Some(r)).unwrap());
        assert!((1.0 - ga.l6w1 - (2.0 * r - 1.0) / (r + 1.0)).abs() < 1e-15);
        assert!((1.0 - ga.w1 - r / (r + 1.0)).abs() < 1e-15);
    }

    /// The principal root's phase against the closed forms of the two members that have one
    /// (trapezoidal rule 2 atan(Ω/2), central differences 2 asin(Ω/2), both of modulus 1),
    /// and the resonance of m steps where m times that phase is 2π: Ω = 2 tan(π/m) and
    /// 2 sin(π/m); two steps have none.
    #[test]
    fn the_resonance_of_sub_cycled_steps_is_where_m_steps_turn_a_whole_period() {
        let nm = Gs4::u0(Design::parse("d", "newmark", None).unwrap());
        let cd = Gs4::central_difference();
        let pi = std::f64::consts::PI;
        for o in [0.1, 0.5, 1.0, 1.9] {
            let (r, p) = nm.principal_root(o).unwrap();
            assert!((r - 1.0).abs() < 1e-12 && (p - 2.0 * (o / 2.0).atan()).abs() < 1e-12);
            let (r, p) = cd.principal_root(o).unwrap();
            assert!((r - 1.0).abs() < 1e-12 && (p - 2.0 * (o / 2.0).asin()).abs() < 1e-12);
        }
        for m in [3usize, 4, 5, 8, 16] {
            let a = nm.resonance(m).unwrap();
            let want = 2.0 * (pi / m as f64).tan();
            assert!((a.omega_dt - want).abs() < 1e-9 * want, "{m}: {a:?} {want}");
            assert!((a.surviving - 1.0).abs() < 1e-9, "{m}: {a:?}");
            let b = cd.resonance(m).unwrap();
            let want = 2.0 * (pi / m as f64).sin();
            assert!((b.omega_dt - want).abs() < 1e-9 * want, "{m}: {b:?} {want}");
        }
        assert_eq!(nm.resonance(2), None);
        assert_eq!(cd.resonance(2), None);
        assert_eq!(nm.resonance(1), None);
        // Dissipative designs: the mode is damped by rᵐ < 1 there, and more so the lower ρ∞.
        let damped = |d: &str| {
            Gs4::u0(Design::parse("d", d, None).unwrap())
                .resonance(4)
                .unwrap()
                .surviving
        };
        let (a, b, c) = (
            damped("U0(0.8,0.8,0.8)"),
            damped("U0(0.5,0.5,0.5)"),
            damped("U0(0,0,0)"),
        );
        assert!(1.0 > a && a > b && b > c && c > 0.0, "{a} {b} {c}");
        assert!(a > RESONANCE_SURVIVAL && c < RESONANCE_SURVIVAL, "{a} {c}");
    }

    #[test]
    fn bad_designs_name_their_key() {
        let e = Design::parse("nodes.a.params.integrator.design", "U0(1,2,0)", None);
        assert!(
            e.unwrap_err()
                .to_string()
                .starts_with("nodes.a.params.integrator.design: ρ₂")
        );
        let e = Design::parse("nodes.a.params.integrator.design", "wbz", None).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("nodes.a.params.integrator.rho_inf:"),
            "{e}"
        );
        let e = Design::parse("x.design", "U0(1,1,0)", Some(0.5)).unwrap_err();
        assert!(e.to_string().starts_with("x.rho_inf:"), "{e}");
        let e = Design::parse("x.design", "trapezoid", None).unwrap_err();
        assert!(e.to_string().contains("unknown design"), "{e}");
        let spec = IntegratorSpec {
            scheme: "gs4".into(),
            design: "wbz".into(),
            rho_inf: Some(0.5),
            implicit: false,
        };
        let e = Gs4::from_spec("p.integrator", &spec).unwrap_err();
        assert!(e.to_string().starts_with("p.integrator.implicit:"), "{e}");
    }
}
