//! The `mc-spg` parameter table (`[nodes.<name>.params]`): serde types with
//! `deny_unknown_fields` and a validation that names the offending key (the set-up stage of
//! the node, OpenRadioss "starter" style). Units are SI (m, kg, s, Pa).

use protocol::{SolverError, SolverResult};
use serde::Deserialize;

/// Velocity smoothing variant (seed 004 §2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Smoothing {
    /// The momentum-consistent gather/scatter pair of eq. 2–11 (MC-SPG), with the smoothing
    /// kernel of particle I corrected so that its mass-weighted gather reproduces linear
    /// fields (conserves linear *and* angular momentum; see `model.rs`).
    #[default]
    Consistent,
    /// Eq. 2–5 read literally with the RK shape function `φ_I(X_J)` of row J: the gather
    /// weights (eq. 3) reproduce constants only, so linear momentum is conserved but angular
    /// momentum drifts. Kept to show that the angular momentum test can fail.
    Shepard,
    /// Plain kernel averaging `v_I = Σ_J φ_J(X_I) v̂_J`, `v̂ += Δt f/m̂` (not momentum
    /// consistent; kept to show that the momentum test can fail).
    Average,
    /// No smoothing (bare direct nodal integration, unstable zero-energy modes).
    None,
}

/// Geometry of the particle set.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Geometry {
    /// A box `[origin, origin + size]` filled with a cubic lattice of `spacing`.
    Block { origin: [f64; 3], size: [f64; 3] },
    /// Seed 004 §4.2: two plates of `thickness` (default 1 mm), `width` × `length` each,
    /// overlapping over `overlap` around a rigid bolt of `bolt_radius` with heads of
    /// `head_radius` and `head_height`.
    BoltedPlates {
        #[serde(default = "default_plate_thickness")]
        thickness: f64,
        width: f64,
        length: f64,
        overlap: f64,
        bolt_radius: f64,
        head_radius: f64,
        head_height: f64,
    },
}

fn default_plate_thickness() -> f64 {
    1.0e-3
}

/// Axis-aligned box region `[lo, hi]`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Region {
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

impl Region {
    pub fn contains(&self, p: &[f64; 3]) -> bool {
        (0..3).all(|d| p[d] >= self.lo[d] && p[d] <= self.hi[d])
    }
}

/// Prescribed velocity on the particles of a region, ramped linearly over `ramp` seconds.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct VelocityBc {
    pub name: String,
    pub region: Region,
    pub velocity: [f64; 3],
    #[serde(default)]
    pub ramp: f64,
}

/// The responder side of a kinematic coupling (ARCHITECTURE §5; seed 004 eq. 29–33).
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CouplingParams {
    /// This node's interface name (the binding's `interface`).
    #[serde(default = "default_interface")]
    pub interface: String,
    /// The coupling particles: every particle inside one of these regions.
    pub regions: Vec<Region>,
    /// Quad connectivity of the driver's interface mesh (4 node indices per cell), when the
    /// set-up inbox does not carry a `cells` field.
    #[serde(default)]
    pub cells: Vec<[u32; 4]>,
}

fn default_interface() -> String {
    "shell".to_string()
}

/// The whole parameter table of model `mc-spg`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Params {
    pub geometry: Geometry,
    /// Particle spacing (m).
    pub spacing: f64,
    /// Kernel support radius (m); must exceed `spacing`.
    pub kernel_support: f64,
    pub density: f64,
    pub young: f64,
    pub poisson: f64,
    pub yield_stress: f64,
    #[serde(default)]
    pub iso_hardening: f64,
    /// Kinematic (Prager) plastic modulus H_kin; alternatively give `tangent_modulus` E_t
    /// and H_kin = E E_t / (E − E_t).
    #[serde(default)]
    pub kin_hardening: Option<f64>,
    #[serde(default)]
    pub tangent_modulus: Option<f64>,
    /// Critical pair-averaged effective plastic strain for bond failure (eq. 17).
    pub eps_crit: f64,
    /// Critical stretch ratio (eq. 15, 17): bonds fail only when stretched beyond it.
    #[serde(default = "one")]
    pub e_crit: f64,
    /// Steps between re-anchoring of the adaptive anisotropic Lagrangian kernel (eq. 12–14).
    #[serde(default = "default_reanchor")]
    pub reanchor_every: u64,
    #[serde(default)]
    pub smoothing: Smoothing,
    /// Courant factor on spacing / dilatational wave speed.
    #[serde(default = "default_cfl")]
    pub cfl: f64,
    /// Mass scaling: raise particle masses so the stable step is at least this (s).
    #[serde(default)]
    pub mass_scaling_dt: Option<f64>,
    #[serde(default)]
    pub velocity_bc: Vec<VelocityBc>,
    #[serde(default)]
    pub coupling: Option<CouplingParams>,
    /// Write the joint force history CSV every this many windows (0: every window).
    #[serde(default)]
    pub history_every: u64,
}

fn one() -> f64 {
    1.0
}
fn default_reanchor() -> u64 {
    // With the material-distance kernel weights (shape.rs) re-anchoring no longer disturbs a
    // balanced stress field: uniaxial tension stays within 0.1 % of the J2 law re-anchoring
    // every 25 steps (tests/tension.rs).
    100
}
fn default_cfl() -> f64 {
    0.4
}

fn positive(key: &str, v: f64) -> SolverResult<()> {
    if v > 0.0 && v.is_finite() {
        Ok(())
    } else {
        Err(SolverError::config(key, format!("must be > 0, got {v}")))
    }
}

impl Params {
    /// Parse a TOML table (unknown keys refused) and validate.
    pub fn from_table(t: &toml::Table) -> SolverResult<Self> {
        let p: Params = t
            .clone()
            .try_into()
            .map_err(|e: toml::de::Error| SolverError::config("params", e.to_string()))?;
        p.validate()?;
        Ok(p)
    }

    /// The J2 material of the particles.
    pub fn material(&self) -> mechanics::j2::J2Material {
        let kin = match (self.kin_hardening, self.tangent_modulus) {
            (Some(h), _) => h,
            (None, Some(et)) => self.young * et / (self.young - et),
            (None, None) => 0.0,
        };
        mechanics::j2::J2Material {
            young: self.young,
            poisson: self.poisson,
            yield_stress: self.yield_stress,
            iso_hardening: self.iso_hardening,
            kin_hardening: kin,
        }
    }

    pub fn validate(&self) -> SolverResult<()> {
        positive("spacing", self.spacing)?;
        positive("kernel_support", self.kernel_support)?;
        if self.kernel_support <= self.spacing {
            return Err(SolverError::config(
                "kernel_support",
                format!(
                    "must exceed the particle spacing {} (a first-order kernel needs neighbours), got {}",
                    self.spacing, self.kernel_support
                ),
            ));
        }
        if self.kernel_support > 4.0 * self.spacing {
            return Err(SolverError::config(
                "kernel_support",
                format!(
                    "must be at most 4 spacings, got {} / {}",
                    self.kernel_support, self.spacing
                ),
            ));
        }
        positive("density", self.density)?;
        if !(self.eps_crit > 0.0) {
            return Err(SolverError::config(
                "eps_crit",
                format!("must be > 0, got {}", self.eps_crit),
            ));
        }
        if !(self.e_crit >= 1.0) {
            return Err(SolverError::config(
                "e_crit",
                format!(
                    "must be ≥ 1 (no failure under compression), got {}",
                    self.e_crit
                ),
            ));
        }
        if let Some(et) = self.tangent_modulus {
            if self.kin_hardening.is_some() {
                return Err(SolverError::config(
                    "tangent_modulus",
                    "give either kin_hardening or tangent_modulus",
                ));
            }
            if !(et >= 0.0 && et < self.young) {
                return Err(SolverError::config(
                    "tangent_modulus",
                    format!("must be in [0, young), got {et}"),
                ));
            }
        }
        self.material()
            .validate()
            .map_err(|(k, r)| SolverError::config(k, r))?;
        if self.reanchor_every == 0 {
            return Err(SolverError::config("reanchor_every", "must be ≥ 1"));
        }
        if !(self.cfl > 0.0 && self.cfl <= 1.0) {
            return Err(SolverError::config(
                "cfl",
                format!("must be in (0, 1], got {}", self.cfl),
            ));
        }
        if let Some(dt) = self.mass_scaling_dt {
            positive("mass_scaling_dt", dt)?;
        }
        match &self.geometry {
            Geometry::Block { size, .. } => {
                for (d, s) in size.iter().enumerate() {
                    positive(&format!("geometry.size[{d}]"), *s)?;
                    if *s < self.spacing {
                        return Err(SolverError::config(
                            format!("geometry.size[{d}]"),
                            format!(
                                "must hold at least two particles (≥ spacing {}), got {s}",
                                self.spacing
                            ),
                        ));
                    }
                }
            }
            Geometry::BoltedPlates {
                thickness,
                width,
                length,
                overlap,
                bolt_radius,
                head_radius,
                head_height,
            } => {
                positive("geometry.thickness", *thickness)?;
                positive("geometry.width", *width)?;
                positive("geometry.length", *length)?;
                positive("geometry.overlap", *overlap)?;
                positive("geometry.bolt_radius", *bolt_radius)?;
                positive("geometry.head_height", *head_height)?;
                if head_radius <= bolt_radius {
                    return Err(SolverError::config(
                        "geometry.head_radius",
                        "must exceed bolt_radius",
                    ));
                }
                if 2.0 * head_radius >= overlap.min(*width) {
                    return Err(SolverError::config(
                        "geometry.head_radius",
                        "bolt head must fit in the overlap",
                    ));
                }
                if overlap > length {
                    return Err(SolverError::config(
                        "geometry.overlap",
                        "must not exceed length",
                    ));
                }
            }
        }
        for (k, bc) in self.velocity_bc.iter().enumerate() {
            if bc.ramp < 0.0 {
                return Err(SolverError::config(
                    format!("velocity_bc[{k}].ramp"),
                    "must be ≥ 0",
                ));
            }
        }
        if let Some(c) = &self.coupling
            && c.regions.is_empty()
        {
            return Err(SolverError::config(
                "coupling.regions",
                "no coupling region given",
            ));
        }
        Ok(())
    }
}
