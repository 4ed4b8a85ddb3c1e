//! The `mc-spg` parameter table (`[nodes.<name>.params]`): serde types with
//! `deny_unknown_fields` and a validation that names the offending key (the set-up stage of
//! the node, OpenRadioss "starter" style). Units are SI (m, kg, s, Pa).

use mechanics::tensor::Vector3;
use protocol::{SolverError, SolverResult};
use serde::Deserialize;

/// How a rigid fastener holds the plates (`fastener`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default, schemars::JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Fastener {
    /// Bonded to the material around it (a thread-formed screw).
    #[default]
    Bonded,
    /// Bearing contact only (a bolt in a hole).
    Bearing,
}

/// Velocity smoothing variant (seed 004 §2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default, schemars::JsonSchema)]
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
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Geometry {
    /// A box `[origin, origin + size]` filled with a cubic lattice of `spacing`.
    Block {
        /// Lower corner (m).
        origin: [f64; 3],
        /// Edge lengths (m).
        size: [f64; 3],
    },
    /// Seed 004 §4.2: two plates of `thickness` (default 1 mm), `width` × `length` each,
    /// overlapping over `overlap` around a rigid bolt of `bolt_radius` with heads of
    /// `head_radius` and `head_height`.
    BoltedPlates {
        /// Plate thickness (m).
        #[serde(default = "default_plate_thickness")]
        thickness: f64,
        /// Plate width (m).
        width: f64,
        /// Plate length (m).
        length: f64,
        /// Length over which the plates overlap (m).
        overlap: f64,
        /// Bolt radius (m).
        bolt_radius: f64,
        /// Radius of the bolt heads (m).
        head_radius: f64,
        /// Height of the bolt heads (m).
        head_height: f64,
    },
}

fn default_plate_thickness() -> f64 {
    1.0e-3
}

/// Axis-aligned box region `[lo, hi]`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Region {
    /// Lower corner (m).
    pub lo: [f64; 3],
    /// Upper corner (m).
    pub hi: [f64; 3],
}

impl Region {
    pub fn contains(&self, p: &[f64; 3]) -> bool {
        (0..3).all(|d| p[d] >= self.lo[d] && p[d] <= self.hi[d])
    }
}

/// Prescribed velocity on the particles of a region, ramped linearly over `ramp` seconds.
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VelocityBc {
    /// The condition's name (its reaction force is reported under it).
    pub name: String,
    /// The particles inside this box.
    pub region: Region,
    /// Velocity (m/s).
    pub velocity: [f64; 3],
    /// Time over which the velocity ramps up from zero (s).
    #[serde(default)]
    pub ramp: f64,
}

/// Solid elements for the base material around an SPG core (seed 004 §4.2: SPG only where
/// failure is expected). The lattice cells outside every `core` box become 8-node
/// hexahedra on the cells' corners; the cells inside keep SPG particles, which sit on the
/// cells' corners too, so the two share their nodes on the boundary between them.
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SolidParams {
    /// Boxes whose cells keep SPG particles (a cell is in when its centre is inside one).
    pub core: Vec<Region>,
    /// Scale of the hexahedra's hourglass stiffness (1: the stiffness that bends a
    /// box-shaped element exactly; 0 switches hourglass control off).
    #[serde(default = "one")]
    pub hourglass: f64,
}

/// A coupling region: the free particles inside `[lo, hi]`; a named region's summed
/// constraint force is reported every window (`force_<name>_x`, ..., `force_<name>`).
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CouplingRegion {
    /// The region's name (its force is reported as `force_<name>`).
    #[serde(default)]
    pub name: String,
    /// Lower corner (m).
    pub lo: [f64; 3],
    /// Upper corner (m).
    pub hi: [f64; 3],
}

impl CouplingRegion {
    pub fn contains(&self, p: &[f64; 3]) -> bool {
        (0..3).all(|d| p[d] >= self.lo[d] && p[d] <= self.hi[d])
    }
}

/// The responder side of a kinematic coupling (docs/architecture.md; seed 004 eq. 29–33).
///
/// The node works in its own layout, one point per coupling particle: the participant
/// runtime maps the driver's shell-node motion onto the particles with the shell's shape
/// functions at each particle's projection (`v_r = W v_d`, eq. 29–30; the projection is done
/// once, on the reference meshes) and maps the particle loads back with `Wᵀ` (eq. 33).
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CouplingParams {
    /// This node's interface name (the binding's `interface`).
    #[serde(default = "default_interface")]
    pub interface: String,
    /// The coupling particles: every free particle inside one of these regions.
    pub regions: Vec<CouplingRegion>,
}

fn default_interface() -> String {
    "shell".to_string()
}

/// One copy of the joint geometry in the model (several joints in one node, e.g. the crash
/// tube's fasteners): its local frame (`origin`, and the directions of its local x and z axes;
/// y completes a right-handed frame) and optional fastener overrides (`bolt_radius`,
/// `head_radius`: a screw instead of a bolt). Coupling regions are given in the local frame
/// and apply to every placement; a placement's region forces are reported as
/// `force_<placement>_<region>...`.
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Placement {
    /// The placement's name.
    pub name: String,
    /// Origin of the local frame (m).
    #[serde(default)]
    pub origin: [f64; 3],
    /// Direction of the local x axis.
    #[serde(default = "ex")]
    pub x_axis: [f64; 3],
    /// Direction of the local z axis.
    #[serde(default = "ez")]
    pub z_axis: [f64; 3],
    /// Fastener radius of this placement (m).
    pub bolt_radius: Option<f64>,
    /// Head radius of this placement's fastener (m).
    pub head_radius: Option<f64>,
}

fn ex() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}
fn ez() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

impl Placement {
    /// Rotation of the placement: its local x, y, z axes in global coordinates; None when
    /// the axes are zero or parallel.
    pub fn frame(&self) -> Option<[[f64; 3]; 3]> {
        let unit = |a: Vector3<f64>| {
            let l = a.norm();
            (l > 0.0 && l.is_finite()).then(|| a.map(|c| c / l))
        };
        let z = unit(self.z_axis.into())?;
        let xd = unit(self.x_axis.into())?;
        let d = xd.dot(&z);
        if d.abs() > 1.0 - 1e-9 {
            return None;
        }
        let x = unit(xd - z.map(|c| d * c))?;
        let y = z.cross(&x);
        Some([x.into(), y.into(), z.into()])
    }

    /// Local → global.
    pub fn apply(&self, f: &[[f64; 3]; 3], p: &[f64; 3]) -> [f64; 3] {
        std::array::from_fn(|d| self.origin[d] + f[0][d] * p[0] + f[1][d] * p[1] + f[2][d] * p[2])
    }
}

/// The whole parameter table of model `mc-spg`.
#[derive(Debug, Clone, Deserialize, PartialEq, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// The particle set: a block or the bolted plates.
    pub geometry: Geometry,
    /// Particle spacing (m).
    pub spacing: f64,
    /// Kernel support radius (m); must exceed `spacing`.
    pub kernel_support: f64,
    /// Density (kg/m³).
    pub density: f64,
    /// Young's modulus (Pa).
    pub young: f64,
    /// Poisson's ratio (1).
    pub poisson: f64,
    /// Initial yield stress (Pa).
    pub yield_stress: f64,
    /// Linear isotropic hardening modulus (Pa).
    #[serde(default)]
    pub iso_hardening: f64,
    /// Kinematic (Prager) plastic modulus H_kin; alternatively give `tangent_modulus` E_t
    /// and H_kin = E E_t / (E − E_t).
    #[serde(default)]
    pub kin_hardening: Option<f64>,
    /// Tangent modulus E_t (Pa), instead of `kin_hardening`.
    #[serde(default)]
    pub tangent_modulus: Option<f64>,
    /// Johnson–Cook strength with adiabatic heating in place of the linear hardening above:
    /// the flow stress [A + B (ε̄ᵖ)ⁿ][1 + C ln ε̇*][1 − (T*)ᵐ] with A = `yield_stress`, and
    /// `young`, `poisson`, `density` the joint's (the same table as a peridynamic node's
    /// `johnson_cook`). Bonds still fail by `eps_crit` and `e_crit`.
    #[serde(default)]
    pub johnson_cook: Option<mechanics::blast_solid::JohnsonCookParams>,
    /// The pressure's equation of state, with `johnson_cook`: `{ kind = "mie_gruneisen", … }`;
    /// absent: the pressure follows the bulk modulus.
    #[serde(default)]
    pub eos: Option<mechanics::blast_solid::EosParams>,
    /// Critical pair-averaged effective plastic strain for bond failure (eq. 17).
    pub eps_crit: f64,
    /// Critical stretch ratio (eq. 15, 17): bonds fail only when stretched beyond it.
    #[serde(default = "one")]
    pub e_crit: f64,
    /// Separation after bond failure: a particle keeping less than this share of its
    /// kernel weight (eq. 16, broken bonds weigh zero) is cut loose — it carries no stress
    /// and moves on as a free lump of mass. 0 (default): only when its remaining support is
    /// singular or has collapsed onto a plane or a line (whatever this value). Values near 1 erode particles at their first broken bonds (robust through
    /// tearing, as in the joint examples, but it weakens a damaged zone under compression).
    #[serde(default)]
    pub separation_weight: f64,
    /// How a rigid fastener holds the plates: "bonded" (default: it shares kernel rows with
    /// the material around it, as a thread-formed screw that interlocks with the plate) or
    /// "bearing" (a bolt in a hole: no bonds, a penalty contact on the hole wall and under
    /// the heads, so it carries load only by bearing).
    #[serde(default)]
    pub fastener: Fastener,
    /// Penalty stiffness of the "bearing" contact per particle pair (N/m); default
    /// E × spacing, the axial stiffness of one particle column.
    #[serde(default)]
    pub contact_stiffness: Option<f64>,
    /// Steps between re-anchoring of the adaptive anisotropic Lagrangian kernel (eq. 12–14).
    #[serde(default = "default_reanchor")]
    pub reanchor_every: u64,
    /// Stabilisation of the nodal integration (seed 004).
    #[serde(default)]
    pub smoothing: Smoothing,
    /// Courant factor on spacing / dilatational wave speed.
    #[serde(default = "default_cfl")]
    pub cfl: f64,
    /// Mass scaling: raise particle masses so the stable step is at least this (s).
    #[serde(default)]
    pub mass_scaling_dt: Option<f64>,
    /// Prescribed velocities of regions (grips, supports).
    #[serde(default)]
    pub velocity_bc: Vec<VelocityBc>,
    /// The responder side of a kinematic coupling with a shell node.
    #[serde(default)]
    pub coupling: Option<CouplingParams>,
    /// Copies of the geometry (default: one, in the global frame, unnamed).
    #[serde(default)]
    pub placements: Vec<Placement>,
    /// Write the joint force history CSV every this many windows (0: every window).
    #[serde(default)]
    pub history_every: u64,
    /// Hexahedra for the material outside an SPG core (absent: all particles).
    #[serde(default)]
    pub solid: Option<SolidParams>,
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

/// Most particles a joint node's geometry may hold.
pub const MAX_PARTICLES: f64 = 2e8;

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
        let p: Params = protocol::params::decode(t)?;
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

    /// The Johnson–Cook blast solid of `johnson_cook` and `eos`, None without them. Errors
    /// name the key.
    pub fn blast_solid(&self) -> SolverResult<Option<mechanics::blast_solid::BlastSolid>> {
        let Some(jc) = &self.johnson_cook else {
            if self.eos.is_some() {
                return Err(SolverError::config("eos", "applies with johnson_cook only"));
            }
            return Ok(None);
        };
        for (key, given) in [
            ("iso_hardening", self.iso_hardening != 0.0),
            ("kin_hardening", self.kin_hardening.is_some()),
            ("tangent_modulus", self.tangent_modulus.is_some()),
        ] {
            if given {
                return Err(SolverError::config(
                    key,
                    "is J2's linear hardening: with johnson_cook the flow stress is Johnson–Cook's",
                ));
            }
        }
        if self.solid.is_some() {
            return Err(SolverError::config(
                "solid",
                "the hexahedra take J2 plasticity only, not johnson_cook",
            ));
        }
        let elastic = (self.young, self.poisson, self.yield_stress, self.density);
        mechanics::blast_solid::BlastSolid::from_params(elastic, jc, self.eos.as_ref(), None)
            .map(Some)
            .map_err(|(k, r)| SolverError::config(k, r))
    }

    /// The geometry of one placement (its fastener overrides applied).
    pub fn geometry_for(&self, pl: Option<&Placement>) -> Geometry {
        let mut g = self.geometry.clone();
        if let (
            Some(pl),
            Geometry::BoltedPlates {
                bolt_radius,
                head_radius,
                ..
            },
        ) = (pl, &mut g)
        {
            if let Some(r) = pl.bolt_radius {
                *bolt_radius = r;
            }
            if let Some(r) = pl.head_radius {
                *head_radius = r;
            }
        }
        g
    }

    fn validate_geometry(&self, g: &Geometry) -> SolverResult<()> {
        match g {
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
        // the particles the geometry asks for must fit in memory: refuse before generating
        let volume = match &self.geometry {
            Geometry::Block { size, .. } => size[0] * size[1] * size[2],
            Geometry::BoltedPlates {
                thickness,
                width,
                length,
                ..
            } => 2.0 * thickness * width * length,
        };
        let particles = volume / self.spacing.powi(3);
        if !(particles <= MAX_PARTICLES) {
            return Err(SolverError::config(
                "geometry",
                format!(
                    "holds about {particles:.3e} particles at spacing {}: more than the {MAX_PARTICLES:.0e} a node takes",
                    self.spacing
                ),
            ));
        }
        Ok(())
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
        self.blast_solid()?;
        if let Some(k) = self.contact_stiffness
            && !(k.is_finite() && k > 0.0)
        {
            return Err(SolverError::config(
                "contact_stiffness",
                format!("must be > 0, got {k}"),
            ));
        }
        if self.contact_stiffness.is_some() && self.fastener != Fastener::Bearing {
            return Err(SolverError::config(
                "contact_stiffness",
                "applies to fastener = \"bearing\" only",
            ));
        }
        if !(0.0..1.0).contains(&self.separation_weight) {
            return Err(SolverError::config(
                "separation_weight",
                format!("must be in [0, 1), got {}", self.separation_weight),
            ));
        }
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
        if let Some(sp) = &self.solid {
            if sp.core.is_empty() {
                return Err(SolverError::config(
                    "solid.core",
                    "give at least one box of SPG particles (without one, use no solid)",
                ));
            }
            for (k, r) in sp.core.iter().enumerate() {
                if !(0..3).all(|d| r.lo[d].is_finite() && r.hi[d].is_finite() && r.lo[d] < r.hi[d])
                {
                    return Err(SolverError::config(
                        format!("solid.core[{k}]"),
                        format!(
                            "must have lo < hi in every direction, got {:?} – {:?}",
                            r.lo, r.hi
                        ),
                    ));
                }
            }
            if !(sp.hourglass.is_finite() && sp.hourglass >= 0.0) {
                return Err(SolverError::config(
                    "solid.hourglass",
                    format!("must be ≥ 0, got {}", sp.hourglass),
                ));
            }
        }
        let mut names = std::collections::BTreeSet::new();
        for (k, pl) in self.placements.iter().enumerate() {
            if pl.name.is_empty()
                || !pl
                    .name
                    .chars()
                    .all(|ch| ch.is_ascii_alphanumeric() || ch == '_' || ch == '-')
            {
                return Err(SolverError::config(
                    format!("placements[{k}].name"),
                    "must be 1 or more of [A-Za-z0-9_-]",
                ));
            }
            if !names.insert(pl.name.clone()) {
                return Err(SolverError::config(
                    format!("placements[{k}].name"),
                    format!("'{}' is used twice", pl.name),
                ));
            }
            if pl.origin.iter().any(|v| !v.is_finite()) || pl.frame().is_none() {
                return Err(SolverError::config(
                    format!("placements[{k}]"),
                    "needs a finite origin and non-zero, non-parallel x_axis and z_axis",
                ));
            }
            if (pl.bolt_radius.is_some() || pl.head_radius.is_some())
                && !matches!(self.geometry, Geometry::BoltedPlates { .. })
            {
                return Err(SolverError::config(
                    format!("placements[{k}].bolt_radius"),
                    "only for geometry kind \"bolted-plates\"",
                ));
            }
            self.validate_geometry(&self.geometry_for(Some(pl)))
                .map_err(|e| match e {
                    SolverError::Config { key, reason } => {
                        SolverError::config(format!("placements[{k}] ({key})"), reason)
                    }
                    other => other,
                })?;
        }
        self.validate_geometry(&self.geometry)?;
        for (k, bc) in self.velocity_bc.iter().enumerate() {
            if bc.ramp < 0.0 {
                return Err(SolverError::config(
                    format!("velocity_bc[{k}].ramp"),
                    "must be ≥ 0",
                ));
            }
        }
        if let Some(c) = &self.coupling {
            if c.regions.is_empty() {
                return Err(SolverError::config(
                    "coupling.regions",
                    "no coupling region given",
                ));
            }
            for (k, r) in c.regions.iter().enumerate() {
                if (0..3).any(|d| !(r.lo[d] <= r.hi[d])) {
                    return Err(SolverError::config(
                        format!("coupling.regions[{k}]"),
                        "needs lo ≤ hi in every direction",
                    ));
                }
                if !r
                    .name
                    .chars()
                    .all(|ch| ch.is_ascii_alphanumeric() || ch == '_' || ch == '-')
                {
                    return Err(SolverError::config(
                        format!("coupling.regions[{k}].name"),
                        "only [A-Za-z0-9_-]",
                    ));
                }
            }
        }
        Ok(())
    }
}
