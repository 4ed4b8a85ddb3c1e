//! The parameter table of a peridynamic node (`[nodes.NAME.params]`): the types its TOML is
//! decoded into (every key, its default and its meaning; `cosim params` and the JSON Schema
//! derive from them). What the values mean for a body is checked as the solver is built.

use super::geometry::Shape;
use mechanics::blast_solid::BlastSolid;
pub use mechanics::blast_solid::{EosParams, JohnsonCookParams};
use mechanics::johnson_cook::JohnsonCookFailure;
use serde::Deserialize;
use std::collections::BTreeMap;

fn default_thickness() -> f64 {
    1.0
}
fn default_stabilization() -> f64 {
    0.5
}
fn default_cfl() -> f64 {
    0.5
}
fn default_rk_order() -> usize {
    2
}
fn default_rk_condition_floor() -> f64 {
    crate::pd::rk_ba::CONDITION_FLOOR
}
fn default_true() -> bool {
    true
}

/// The parameter table of a peridynamic node (`[nodes.X.params]`).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PdParams {
    /// "3d", "plane_stress" or "plane_strain".
    pub dimension: String,
    /// Out-of-plane thickness h in 2-D (m).
    #[serde(default = "default_thickness")]
    pub thickness: f64,
    /// Lattice spacing Δx (m).
    pub spacing: f64,
    /// Horizon δ (m).
    pub horizon: f64,
    /// Mass density ρ (kg/m³).
    pub density: f64,
    /// Young's modulus E (Pa).
    pub young: f64,
    /// Poisson's ratio ν (pd-bond: 1/4 in 3-D and plane strain, 1/3 in plane stress).
    pub poisson: f64,
    /// Initial yield stress (Pa); absent = elastic.
    #[serde(default)]
    pub yield_stress: Option<f64>,
    /// Linear isotropic hardening modulus H_iso (Pa) of the J2 plasticity.
    #[serde(default)]
    pub iso_hardening: f64,
    /// Linear kinematic hardening modulus H_kin (Pa) of the J2 plasticity.
    #[serde(default)]
    pub kin_hardening: f64,
    /// Johnson–Cook strength with adiabatic heating (pd-correspondence, pd-rk-ba): the flow
    /// stress [A + B (ε̄ᵖ)ⁿ][1 + C ln ε̇*][1 − (T*)ᵐ] with A = `yield_stress`, and `young`,
    /// `poisson`, `density` the solid's; absent: J2 with the linear hardening above.
    #[serde(default)]
    pub johnson_cook: Option<JohnsonCookParams>,
    /// The pressure's equation of state, with `johnson_cook`: `{ kind = "mie_gruneisen", … }`;
    /// absent: the pressure follows the bulk modulus.
    #[serde(default)]
    pub eos: Option<EosParams>,
    /// G of seed 001 eq. (186).
    #[serde(default = "default_stabilization")]
    pub stabilization: f64,
    /// Order n of the RK gradient of pd-rk-ba (1 or 2; seed 000 App. A).
    #[serde(default = "default_rk_order")]
    pub rk_order: usize,
    /// pd-rk-ba: the share of a particle's undamaged reference moment-matrix determinant
    /// (equilibrated) below which its gradient falls back from order n to linear, and from
    /// linear to none (default 1e-3). Larger values drop the order sooner in heavily damaged
    /// families.
    #[serde(default = "default_rk_condition_floor")]
    pub rk_condition_floor: f64,
    /// Bond-associative stabilization of pd-rk-ba (default true): stress, plasticity and
    /// damage at the bond, from the bond velocity gradient. `false` evaluates the stress at
    /// the particles from their point gradient, the force state σ_i Φ_ij — the unstabilized
    /// correspondence model, kept for stability studies; it takes no `damage`.
    #[serde(default = "default_true")]
    pub bond_associative: bool,
    /// Safety factor on the stable step.
    #[serde(default = "default_cfl")]
    pub cfl: f64,
    /// Bond breaking: `{ kind = "critical_stretch", critical_stretch = … }` and the others
    /// below; absent: no damage.
    #[serde(default)]
    pub damage: Option<DamageParams>,
    /// The shapes filled with particles on the lattice.
    pub bodies: Vec<Shape>,
    /// Shapes cut out of the bodies.
    #[serde(default)]
    pub holes: Vec<Shape>,
    /// Cracks already there at the start: polylines of points [x, y] (m), through the whole
    /// thickness in 3-D. No bond crosses them. The first one is followed: its last point is
    /// its tip, and every window reports `crack_tip_x`, `crack_tip_y` and `crack_length`
    /// (its own length plus how far broken bonds carry it on from the tip).
    #[serde(default)]
    pub cracks: Vec<Vec<[f64; 2]>>,
    /// No-fail zones: shapes whose particles' bonds never break. A bond with either end in
    /// one keeps its intact fraction whatever the damage law says (the usual peridynamic
    /// treatment of grips, supports and loads, where a load spread over one row of particles
    /// concentrates stretch that the real grip does not). Cracks given in `cracks` still cut
    /// through them, and a particle whose family degenerates elsewhere still lets go of them.
    #[serde(default)]
    pub no_fail: Vec<Shape>,
    /// Initial velocity (m/s) of the particles in a region.
    #[serde(default)]
    pub initial_velocity: Vec<RegionVelocity>,
    /// Velocity (m/s) held by the particles in a region for the whole run (a support or a
    /// driven grip).
    #[serde(default)]
    pub prescribed_velocity: Vec<RegionVelocity>,
    /// A pressure pulse on the face of a round hole.
    #[serde(default)]
    pub pressure_pulse: Option<PressurePulse>,
    /// Coupling interfaces: named sets of particles.
    #[serde(default)]
    pub interfaces: Vec<InterfaceParams>,
    /// Forces on the particles of regions (a line load on an edge: its total, spread
    /// equally over the region's particles).
    #[serde(default)]
    pub loads: Vec<PdLoad>,
    /// Rigid, frictionless, fixed walls: planes the particles cannot cross, each
    /// `{ point = [x, y, z], normal = [nx, ny, nz] }` with the normal pointing to the side
    /// the body is on (a Taylor bar's anvil). A particle touches a wall when its centre comes
    /// within half a spacing of the plane; the wall then stops its motion toward the plane
    /// and leaves the rest (no friction, no rebound of its own). Their impulse and work are
    /// the node's external ones, and every window reports their mean force `wall_force`.
    #[serde(default)]
    pub walls: Vec<WallParams>,
    /// Report the body's extent every window: `extent_x`, `extent_y` (and `extent_z` in 3-D),
    /// the span of the particles' current positions along each axis plus one spacing (k
    /// particles in a row measure kΔx); in 3-D also `extent_radial`, twice the largest
    /// distance of a particle from the z axis through the particles' mean x–y position plus
    /// one spacing — a Taylor bar's length (`extent_z`) and mushroom diameter.
    #[serde(default)]
    pub report_extent: bool,
    /// Named points whose displacement is reported every window (`<name>_ux`, `<name>_uy`,
    /// and `<name>_uz` in 3-D): the particle at the point, within half a spacing.
    #[serde(default)]
    pub points: BTreeMap<String, Vec<f64>>,
    /// Particle steps per window in a lagrange coupling (absent: as many as the stable step
    /// needs); gs4 and ph take exactly one (see `pd::lagrange`).
    #[serde(default)]
    pub substeps: Option<usize>,
    /// Smallest connected component (particles) counted in the `fragments` report scalar;
    /// smaller ones are `debris_particles`.
    #[serde(default = "default_fragment_min_size")]
    pub fragment_min_size: usize,
    /// A point (x, y) of an axis (along z) to measure fragments about: their `width` is then
    /// the arc they span at their mean radius, their `thickness` their radial extent (for
    /// pieces that have not turned). Absent (the default): the extents along each fragment's
    /// principal axes in the x–y plane, the longer one its width — what a caliper gives on a
    /// recovered piece, whichever way it has turned in flight.
    #[serde(default)]
    pub fragment_axis: Option<Vec<f64>>,
    /// "cpu" (default) or "gpu" (pd-bond and pd-correspondence).
    #[serde(default)]
    pub device: Option<String>,
    /// Arithmetic of the GPU kernels: "f64" (default: f64 where the adapter has
    /// `SHADER_F64`, else f32 with a warning) or "f32" (faster on consumer GPUs; about 1e-6
    /// relative accuracy, with a warning).
    #[serde(default)]
    pub precision: Option<String>,
    /// Most bonds the bodies may hold (both copies of a bond counted), checked before the
    /// body is built against particles × full family (an upper estimate; a body past it is
    /// refused naming `spacing`, or `horizon` when δ > 6 Δx). The default, 5·10⁷ (about
    /// 4·10⁵ particles in 3-D or 1.8·10⁶ in 2-D at δ = 3.015 Δx), keeps a body within about
    /// 11 GB of memory with every model (about 57 bytes a bond for pd-bond and
    /// pd-correspondence, 216 for pd-rk-ba); raise it for a larger body on a host with the
    /// memory.
    #[serde(default = "default_max_bonds")]
    pub max_bonds: u64,
}

impl PdParams {
    /// The blast solid the parameters give (Johnson–Cook strength, the equation of state
    /// and Johnson–Cook failure), None without `johnson_cook`. Errors name the key.
    pub fn blast_solid(&self) -> Result<Option<BlastSolid>, (String, String)> {
        let Some(jc) = &self.johnson_cook else {
            return Ok(None);
        };
        let Some(a) = self.yield_stress else {
            return Err((
                "yield_stress".into(),
                "required with johnson_cook: it is the Johnson–Cook A".into(),
            ));
        };
        let failure = match self.damage {
            Some(DamageParams::JohnsonCook {
                d1,
                d2,
                d3,
                d4,
                d5,
                min_failure_strain,
                ..
            }) => Some(JohnsonCookFailure {
                d1,
                d2,
                d3,
                d4,
                d5,
                ref_strain_rate: jc.ref_strain_rate,
                room_temperature: jc.room_temperature,
                melt_temperature: jc.melt_temperature,
                min_failure_strain,
            }),
            _ => None,
        };
        let elastic = (self.young, self.poisson, a, self.density);
        BlastSolid::from_params(elastic, jc, self.eos.as_ref(), failure).map(Some)
    }
}

fn default_fragment_min_size() -> usize {
    20
}

fn default_min_failure_strain() -> f64 {
    1e-6
}

fn default_min_fraction() -> f64 {
    0.1
}

/// Mott's scatter of the Johnson–Cook failure strain (`damage.mott`).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MottParams {
    /// γ (> 0): the spread of f is π/(γ√6) (standard deviation); larger is narrower.
    pub gamma: f64,
    /// Seed of the draw (each particle's f follows from the seed and its index alone, so a
    /// restart and every thread count draw the same).
    #[serde(default)]
    pub seed: u64,
    /// Floor on f, in (0, 1).
    #[serde(default = "default_min_fraction")]
    pub min_fraction: f64,
}

impl PdParams {
    /// Mott's scatter of the failure strain, when `damage` has one. Errors name the key.
    pub fn mott(&self) -> Result<Option<mechanics::johnson_cook::MottScatter>, (String, String)> {
        let Some(DamageParams::JohnsonCook { mott: Some(m), .. }) = &self.damage else {
            return Ok(None);
        };
        let scatter = mechanics::johnson_cook::MottScatter {
            gamma: m.gamma,
            seed: m.seed,
            min_fraction: m.min_fraction,
        };
        scatter
            .validate()
            .map_err(|(k, r)| (format!("damage.mott.{k}"), r))?;
        Ok(Some(scatter))
    }
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum DamageParams {
    /// No damage (a struct variant, so that a key given with it is refused: serde ignores
    /// extra keys on a unit variant of an internally tagged enum).
    None {},
    /// A bond breaks when its stretch exceeds `critical_stretch`.
    CriticalStretch {
        /// Critical bond stretch s₀ (1).
        critical_stretch: f64,
    },
    /// Bonds of a particle break when its von Mises stress exceeds `critical_stress`.
    VonMises {
        /// Critical von Mises stress (Pa).
        critical_stress: f64,
    },
    /// Damage grows with the equivalent plastic strain between the two values.
    PlasticStrain {
        /// Equivalent plastic strain at which damage starts (1).
        eps_threshold: f64,
        /// Equivalent plastic strain at which bonds are fully broken (1).
        eps_critical: f64,
    },
    /// Johnson–Cook failure (with `johnson_cook`): each particle accumulates
    /// D = Σ Δε̄ᵖ/ε_f, ε_f = [D1 + D2 exp(D3 σ*)][1 + D4 ln ε̇*][1 + D5 T*] (σ* the
    /// triaxiality; ε̇₀, T_room and T_melt those of `johnson_cook`); a bond breaks once the
    /// mean D of its two particles reaches 1.
    JohnsonCook {
        /// D1: the constant part of the failure strain.
        d1: f64,
        /// D2: the factor of exp(D3 σ*).
        d2: f64,
        /// D3: the triaxiality's coefficient in the exponent.
        d3: f64,
        /// D4: the rate term's coefficient, factor 1 + D4 ln ε̇*.
        d4: f64,
        /// D5: the temperature term's coefficient, factor 1 + D5 T*.
        d5: f64,
        /// Floor on ε_f (a numerical guard).
        #[serde(default = "default_min_failure_strain")]
        min_failure_strain: f64,
        /// Mott's statistical scatter of the failure strain: each particle fails at f times
        /// ε_f, f drawn from P(f) = 1 − exp(−ln 2 · e^{γ(f − 1)}) (median 1); absent: every
        /// particle at ε_f.
        #[serde(default)]
        mott: Option<MottParams>,
    },
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RegionVelocity {
    /// The particles inside this shape.
    pub region: Shape,
    /// Velocity (m/s).
    pub velocity: [f64; 3],
    /// The components held, letters of "xyz" ("y": held in y, free in x and z); all when
    /// absent. A particle in two regions is held in every component either holds.
    #[serde(default)]
    pub components: Option<String>,
}

/// Prescribed internal pressure pulse on the inner face of a round hole about the z axis
/// through `center` (stand-in for the gas of seed 000 §3.2): p(t) rises linearly from 0 to
/// `peak` over `rise`, then falls linearly to 0 at `duration` (`rise` = 0: a step down-ramp).
/// Applied as forces p·A·n on the particles of the first lattice layer outside the face,
/// A = Δx·h (2-D) or Δx² (3-D) of face per particle, n the outward radial direction.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PressurePulse {
    /// Only "inner" (the face of the hole of radius `inner_radius`).
    #[serde(default = "default_surface")]
    pub surface: String,
    /// A point of the hole's axis (m).
    pub center: [f64; 3],
    /// Radius of the hole (m).
    pub inner_radius: f64,
    /// Peak pressure (Pa).
    pub peak: f64,
    /// Rise time (s), ≥ 0 and < duration.
    #[serde(default)]
    pub rise: f64,
    /// Total duration (s).
    pub duration: f64,
}

fn default_surface() -> String {
    "inner".into()
}

impl PressurePulse {
    /// p(t).
    pub fn at(&self, t: f64) -> f64 {
        if t < 0.0 || t >= self.duration {
            0.0
        } else if t < self.rise {
            self.peak * t / self.rise
        } else {
            self.peak * (self.duration - t) / (self.duration - self.rise)
        }
    }
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct InterfaceParams {
    /// The interface's name (what a coupling's `driver`/`responder` names after the node).
    pub name: String,
    /// "all" or "surface"; restricted to `region` when given.
    #[serde(default = "default_select")]
    pub select: String,
    /// Only the particles inside this shape.
    #[serde(default)]
    pub region: Option<Shape>,
    /// Only the particles inside any of these shapes (with `region`: inside it or any of
    /// these), e.g. both cut edges of the middle subdomain of three in a row.
    #[serde(default)]
    pub regions: Vec<Shape>,
}

/// A rigid wall (`walls`).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct WallParams {
    /// A point of the wall's plane (m).
    pub point: [f64; 3],
    /// The plane's normal, toward the body (need not be unit length; z = 0 in 2-D).
    pub normal: [f64; 3],
}

/// A force on the particles of a region.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PdLoad {
    /// The particles inside this shape carry the load.
    pub region: Shape,
    /// Total force [Fx, Fy, Fz] (N), spread equally over them.
    pub force: [f64; 3],
    /// How the load starts: "step" (at once), "linear" (a constant rate), "sin2" or "septic" (the
    /// C³ ramp, for second-order studies) over `ramp_time`, then held. Also read under its older
    /// name, `history`.
    #[serde(default, alias = "history")]
    pub ramp: mechanics::time::Ramp,
    /// Ramp duration T (s), with every `ramp` but "step".
    #[serde(default)]
    pub ramp_time: Option<f64>,
}

fn default_select() -> String {
    "surface".into()
}

/// Default of `max_bonds`: the most bonds (both copies counted) a body may hold, estimated
/// before it is built. 5·10⁷ bonds are about 4·10⁵ particles in 3-D or 1.8·10⁶ in 2-D at
/// δ = 3.015 Δx. Set-up takes about 57 bytes of host memory a bond for pd-bond and
/// pd-correspondence and 216 for pd-rk-ba (peak resident set of `solid-node --describe` on
/// 20³ and 40³ blocks): 3 to 11 GB at the default, which a 16 GB host holds, built
/// in seconds. The examples hold under 10⁶ bonds.
pub const DEFAULT_MAX_BONDS: u64 = 50_000_000;

fn default_max_bonds() -> u64 {
    DEFAULT_MAX_BONDS
}
