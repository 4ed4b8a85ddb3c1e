//! The starter: the node's parameter table (TOML, `deny_unknown_fields`) → a validated
//! `Model`. Every refusal names the key inside the params table (`section.thickness`,
//! `material.poisson_ratio`, `node_sets[0].nodes`, `mesh.elements[3]`, ...).
//! Lumped mass per seed 004 eq. 23 (row sum, ¼ of the element mass per node).

use crate::element::{self, Material, PL, R_H, RES, Section};
use crate::mesh::{self, Mesh};
use crate::model::{DOF_ALL, Model, ReactionSet};
use mechanics::j2_plane_stress::J2PlaneStress;
use mechanics::tensor::vec3;
use protocol::{SolverError, SolverResult};
use serde::Deserialize;

/// The whole parameter table of a `blt-shell` node.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ShellConfig {
    /// The shell mesh: a plate, plates, a lap joint, a tube or explicit nodes and elements.
    pub mesh: MeshConfig,
    /// The shell material (elastic or J2 plasticity).
    pub material: MaterialConfig,
    /// Through-thickness section: thickness and integration points.
    pub section: SectionConfig,
    /// Hourglass control coefficients (Belytschko–Tsay).
    #[serde(default)]
    pub hourglass: HourglassConfig,
    /// Time step control: safety factor, mass scaling, velocity ramp.
    #[serde(default)]
    pub time: TimeConfig,
    /// Named node sets (by ids or boxes) that supports, loads and outputs refer to.
    #[serde(default)]
    pub node_sets: Vec<SetConfig>,
    /// Named element sets (by ids or boxes, by centroid) for pressures and interfaces.
    #[serde(default)]
    pub element_sets: Vec<SetConfig>,
    /// Supports: constrained degrees of freedom of node sets.
    #[serde(default)]
    pub fixed: Vec<FixedConfig>,
    /// Prescribed velocities (m/s) of node sets for the whole run.
    #[serde(default)]
    pub velocity: Vec<VelocityConfig>,
    /// Initial velocities (m/s) of node sets.
    #[serde(default)]
    pub initial_velocity: Vec<VelocityConfig>,
    /// Constant forces (N per node) on node sets.
    #[serde(default)]
    pub point_loads: Vec<PointLoadConfig>,
    /// Follower pressures (Pa) on element sets.
    #[serde(default)]
    pub pressure: Vec<PressureConfig>,
    /// Coupling interfaces: element sets under the joints' coupling surfaces.
    #[serde(default)]
    pub interfaces: Vec<InterfaceConfig>,
    /// Extra outputs (support reactions).
    #[serde(default)]
    pub output: OutputConfig,
    /// Contact between the shells: `{ kind = "single_surface", penalty_scale = 0.1 }`
    /// (every node against every segment it does not belong to, with thickness offsets).
    #[serde(default)]
    pub contact: Option<ContactConfig>,
}

/// Contact between the shells.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ContactConfig {
    /// "single_surface": every node against every segment of the mesh it does not belong to.
    pub kind: String,
    /// Penalty stiffness as a fraction of each segment's membrane stiffness estimate (the
    /// stable step takes the largest penalty into account).
    #[serde(default = "default_penalty_scale")]
    pub penalty_scale: f64,
}

fn default_penalty_scale() -> f64 {
    0.1
}

/// `kind` = "plate" (length, width, nx, ny, origin), "plates" (a list `plates` of plates,
/// each with origin, length, width, nx, ny), "lap_joint" (length, width, overlap, gap, nx,
/// ny), "tube" (side, length, n_side, n_length, overlap, gap, seams) or "explicit" (nodes,
/// elements).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeshConfig {
    /// "plate", "plates", "lap_joint", "tube" or "explicit".
    pub kind: String,
    /// Plate / lap joint / tube length (m).
    pub length: Option<f64>,
    /// Plate / lap joint width (m).
    pub width: Option<f64>,
    /// Tube: side of its square section (m).
    pub side: Option<f64>,
    /// Elements along the length.
    pub nx: Option<usize>,
    /// Elements across the width.
    pub ny: Option<usize>,
    /// Tube: elements along each side.
    pub n_side: Option<usize>,
    /// Tube: elements along the length.
    pub n_length: Option<usize>,
    /// Lap joint / tube seam: overlap of the two sheets (m).
    pub overlap: Option<f64>,
    /// Lap joint / tube seam: gap between the sheets' mid-surfaces (m).
    pub gap: Option<f64>,
    /// Where the mesh starts (m).
    pub origin: Option<[f64; 3]>,
    /// Explicit mesh: node positions (m).
    pub nodes: Option<Vec<[f64; 3]>>,
    /// Explicit mesh: quadrilaterals as four node indices (from 0).
    pub elements: Option<Vec<[u32; 4]>>,
    /// Plates mesh: the plates.
    pub plates: Option<Vec<PlateConfig>>,
    /// Tube: 1 (default) or 2 seams (the second on the opposite face).
    pub seams: Option<usize>,
}

/// One plate of a `kind = "plates"` mesh.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PlateConfig {
    /// Corner of the plate (m).
    #[serde(default)]
    pub origin: [f64; 3],
    /// Length (m).
    pub length: f64,
    /// Width (m).
    pub width: f64,
    /// Elements along the length.
    pub nx: usize,
    /// Elements across the width.
    pub ny: usize,
}

/// `model` = "elastic" or "j2". Hardening either by plastic moduli (`isotropic_modulus`,
/// `kinematic_modulus`) or by `tangent_modulus` E_t with `kinematic_fraction` (0 = purely
/// isotropic, 1 = purely kinematic); see `mechanics::j2_plane_stress` for the convention.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MaterialConfig {
    /// "elastic" or "j2".
    pub model: String,
    /// Density (kg/m³).
    pub density: f64,
    /// Young's modulus (Pa).
    pub youngs_modulus: f64,
    /// Poisson's ratio (1).
    pub poisson_ratio: f64,
    /// Initial yield stress (Pa) of j2.
    pub yield_stress: Option<f64>,
    /// Isotropic plastic modulus (Pa).
    pub isotropic_modulus: Option<f64>,
    /// Kinematic plastic modulus (Pa).
    pub kinematic_modulus: Option<f64>,
    /// Tangent modulus E_t (Pa), instead of the plastic moduli.
    pub tangent_modulus: Option<f64>,
    /// Share of E_t's hardening that is kinematic (0–1).
    pub kinematic_fraction: Option<f64>,
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SectionConfig {
    /// Shell thickness (m).
    pub thickness: f64,
    /// Integration points through the thickness.
    #[serde(default = "default_nip")]
    pub integration_points: usize,
    /// Transverse shear correction factor (1).
    #[serde(default = "default_shear")]
    pub shear_factor: f64,
    /// Update the thickness with the membrane strain (plane stress).
    #[serde(default = "default_true")]
    pub update_thickness: bool,
}

fn default_nip() -> usize {
    5
}
fn default_shear() -> f64 {
    5.0 / 6.0
}
fn default_true() -> bool {
    true
}

/// Belytschko–Tsay hourglass coefficients (stiffness form).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HourglassConfig {
    /// Membrane hourglass coefficient (1).
    #[serde(default = "default_hg")]
    pub membrane: f64,
    /// Bending hourglass coefficient (1).
    #[serde(default = "default_hg")]
    pub bending: f64,
    /// Transverse hourglass coefficient (1).
    #[serde(default = "default_hg")]
    pub transverse: f64,
}

fn default_hg() -> f64 {
    0.05
}

impl Default for HourglassConfig {
    fn default() -> Self {
        HourglassConfig {
            membrane: default_hg(),
            bending: default_hg(),
            transverse: default_hg(),
        }
    }
}

#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TimeConfig {
    /// Safety factor on the element stable step.
    #[serde(default = "default_dt_scale")]
    pub dt_scale: f64,
    /// Mass scaling: add nodal mass so the stable step is at least this (s).
    pub mass_scaling_dt: Option<f64>,
    /// Prescribed velocities ramp from zero over this time (s).
    #[serde(default)]
    pub velocity_ramp: f64,
}

fn default_dt_scale() -> f64 {
    0.9
}

impl Default for TimeConfig {
    fn default() -> Self {
        TimeConfig {
            dt_scale: default_dt_scale(),
            mass_scaling_dt: None,
            velocity_ramp: 0.0,
        }
    }
}

/// A named set: by explicit ids, by a box `[xmin, ymin, zmin, xmax, ymax, zmax]` (nodes by
/// position, elements by centroid), by a list of such `boxes`, or any of them (union).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SetConfig {
    /// The set's name.
    pub name: String,
    /// Explicit ids (from 0).
    pub ids: Option<Vec<u32>>,
    /// A box [xmin, ymin, zmin, xmax, ymax, zmax] (m).
    #[serde(rename = "box")]
    pub bbox: Option<[f64; 6]>,
    /// Several boxes (union), e.g. the footprints of several joints.
    pub boxes: Option<Vec<[f64; 6]>>,
}

/// Constrained DOFs of a node set: any of "x", "y", "z", "rx", "ry", "rz", "translations",
/// "rotations", "all" (default "all").
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FixedConfig {
    /// The node set held.
    pub node_set: String,
    /// The constrained degrees of freedom.
    #[serde(default = "default_dofs")]
    pub dofs: Vec<String>,
}

fn default_dofs() -> Vec<String> {
    vec!["all".into()]
}

/// Prescribed (or initial) translational velocity components of a node set.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VelocityConfig {
    /// The node set.
    pub node_set: String,
    /// x velocity (m/s); absent: free.
    pub x: Option<f64>,
    /// y velocity (m/s); absent: free.
    pub y: Option<f64>,
    /// z velocity (m/s); absent: free.
    pub z: Option<f64>,
}

/// A constant force on every node of a set (N per node).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PointLoadConfig {
    /// The node set loaded.
    pub node_set: String,
    /// Force on each node (N).
    pub force: [f64; 3],
}

/// A follower pressure on an element set (Pa, positive along the element normal).
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PressureConfig {
    /// The element set loaded.
    pub element_set: String,
    /// Pressure (Pa), positive along the element normal.
    pub pressure: f64,
}

/// A coupling interface: the shell elements under a joint's coupling surface.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct InterfaceConfig {
    /// The interface's name (what a coupling names after the node).
    pub name: String,
    /// The element set it covers.
    pub element_set: String,
}

#[derive(Debug, Clone, Default, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    /// Node sets whose summed support reactions go to `reactions.csv` every window.
    #[serde(default)]
    pub reaction_sets: Vec<String>,
}

/// Parse and validate a parameter table.
pub fn parse(params: &toml::Table) -> SolverResult<ShellConfig> {
    protocol::params::decode(params)
}

/// Parse TOML text (a `[nodes.X.params]` table body).
pub fn parse_str(text: &str) -> SolverResult<ShellConfig> {
    let t: toml::Table = toml::from_str(text)
        .map_err(|e| SolverError::config("params", format!("not valid TOML: {}", e.message())))?;
    parse(&t)
}

fn positive(key: &str, v: f64) -> SolverResult<f64> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(SolverError::config(key, format!("must be > 0, got {v}")))
    }
}

fn need<T: Copy>(key: &str, v: Option<T>) -> SolverResult<T> {
    v.ok_or_else(|| SolverError::config(key, "required for this mesh kind"))
}

fn count(key: &str, v: Option<usize>) -> SolverResult<usize> {
    let n = need(key, v)?;
    if n == 0 || n > 100_000 {
        return Err(SolverError::config(
            key,
            format!("must be in 1..=100000, got {n}"),
        ));
    }
    Ok(n)
}

fn build_mesh(c: &MeshConfig) -> SolverResult<Mesh> {
    // a key another mesh kind takes is refused by name, not ignored
    let given = [
        ("length", c.length.is_some()),
        ("width", c.width.is_some()),
        ("side", c.side.is_some()),
        ("nx", c.nx.is_some()),
        ("ny", c.ny.is_some()),
        ("n_side", c.n_side.is_some()),
        ("n_length", c.n_length.is_some()),
        ("overlap", c.overlap.is_some()),
        ("gap", c.gap.is_some()),
        ("origin", c.origin.is_some()),
        ("nodes", c.nodes.is_some()),
        ("elements", c.elements.is_some()),
        ("plates", c.plates.is_some()),
        ("seams", c.seams.is_some()),
    ];
    let applies: &[&str] = match c.kind.as_str() {
        "plate" => &["length", "width", "nx", "ny", "origin"],
        "plates" => &["plates"],
        "lap_joint" => &["length", "width", "overlap", "gap", "nx", "ny"],
        "tube" => &[
            "side", "length", "n_side", "n_length", "overlap", "gap", "seams",
        ],
        "explicit" => &["nodes", "elements"],
        // an unknown kind is refused below, by `mesh.kind`
        _ => &[
            "length", "width", "side", "nx", "ny", "n_side", "n_length", "overlap", "gap",
            "origin", "nodes", "elements", "plates", "seams",
        ],
    };
    protocol::params::refuse_inapplicable(
        "mesh.",
        &format!("mesh kind = \"{}\"", c.kind),
        &given,
        applies,
    )?;
    let m =
        match c.kind.as_str() {
            "plate" => mesh::plate(
                positive("mesh.length", need("mesh.length", c.length)?)?,
                positive("mesh.width", need("mesh.width", c.width)?)?,
                count("mesh.nx", c.nx)?,
                count("mesh.ny", c.ny)?,
                c.origin.unwrap_or([0.0; 3]),
            ),
            "plates" => {
                let list = c.plates.as_ref().filter(|p| !p.is_empty()).ok_or_else(|| {
                    SolverError::config("mesh.plates", "required for kind 'plates'")
                })?;
                let mut specs = Vec::with_capacity(list.len());
                for (k, p) in list.iter().enumerate() {
                    if p.origin.iter().any(|v| !v.is_finite()) {
                        return Err(SolverError::config(
                            format!("mesh.plates[{k}].origin"),
                            "must be finite",
                        ));
                    }
                    specs.push((
                        p.origin,
                        positive(&format!("mesh.plates[{k}].length"), p.length)?,
                        positive(&format!("mesh.plates[{k}].width"), p.width)?,
                        count(&format!("mesh.plates[{k}].nx"), Some(p.nx))?,
                        count(&format!("mesh.plates[{k}].ny"), Some(p.ny))?,
                    ));
                }
                mesh::plates(&specs)
            }
            "lap_joint" => {
                let l = positive("mesh.length", need("mesh.length", c.length)?)?;
                let ov = positive("mesh.overlap", need("mesh.overlap", c.overlap)?)?;
                if ov > l {
                    return Err(SolverError::config(
                        "mesh.overlap",
                        format!("must be ≤ mesh.length = {l}, got {ov}"),
                    ));
                }
                mesh::lap_joint(
                    l,
                    positive("mesh.width", need("mesh.width", c.width)?)?,
                    ov,
                    positive("mesh.gap", need("mesh.gap", c.gap)?)?,
                    count("mesh.nx", c.nx)?,
                    count("mesh.ny", c.ny)?,
                )
            }
            "tube" => {
                let side = positive("mesh.side", need("mesh.side", c.side)?)?;
                let ov = positive("mesh.overlap", need("mesh.overlap", c.overlap)?)?;
                if ov > side {
                    return Err(SolverError::config(
                        "mesh.overlap",
                        format!("must be ≤ mesh.side = {side}, got {ov}"),
                    ));
                }
                let seams = c.seams.unwrap_or(1);
                if !(1..=2).contains(&seams) {
                    return Err(SolverError::config(
                        "mesh.seams",
                        format!("must be 1 or 2, got {seams}"),
                    ));
                }
                mesh::square_tube_seams(
                    side,
                    positive("mesh.length", need("mesh.length", c.length)?)?,
                    count("mesh.n_side", c.n_side)?,
                    count("mesh.n_length", c.n_length)?,
                    ov,
                    positive("mesh.gap", need("mesh.gap", c.gap)?)?,
                    seams,
                )
            }
            "explicit" => {
                let nodes = c.nodes.clone().ok_or_else(|| {
                    SolverError::config("mesh.nodes", "required for kind 'explicit'")
                })?;
                let elements = c.elements.clone().ok_or_else(|| {
                    SolverError::config("mesh.elements", "required for kind 'explicit'")
                })?;
                for (i, p) in nodes.iter().enumerate() {
                    if p.iter().any(|v| !v.is_finite()) {
                        return Err(SolverError::config(
                            format!("mesh.nodes[{i}]"),
                            "coordinates must be finite",
                        ));
                    }
                }
                for (e, c) in elements.iter().enumerate() {
                    if let Some(&n) = c.iter().find(|&&n| n as usize >= nodes.len()) {
                        return Err(SolverError::config(
                            format!("mesh.elements[{e}]"),
                            format!("node {n} does not exist ({} nodes)", nodes.len()),
                        ));
                    }
                }
                let mut m = Mesh {
                    nodes,
                    elements,
                    ..Default::default()
                };
                m.node_sets
                    .insert("all".into(), (0..m.nodes.len() as u32).collect());
                m.element_sets
                    .insert("all".into(), (0..m.elements.len() as u32).collect());
                m
            }
            other => {
                return Err(SolverError::config(
                    "mesh.kind",
                    format!("unknown '{other}' (plate, plates, lap_joint, tube, explicit)"),
                ));
            }
        };
    if m.elements.is_empty() {
        return Err(SolverError::config("mesh", "has no elements"));
    }
    // Degenerate elements: zero or negative area, or a repeated node.
    let explicit = c.kind == "explicit";
    // Hoisted: `size` walks every node (inside the loop it made set-up quadratic).
    let tiny = 1e-12 * m.size().powi(2);
    for (e, c) in m.elements.iter().enumerate() {
        let x = c.map(|n| m.nodes[n as usize]);
        let mut s = *c;
        s.sort_unstable();
        let repeated = s.windows(2).any(|w| w[0] == w[1]);
        let g = element::geometry(&x);
        if repeated || g.is_none_or(|g| g.area <= tiny) {
            let key = if explicit {
                format!("mesh.elements[{e}]")
            } else {
                format!("mesh (element {e})")
            };
            return Err(SolverError::config(
                key,
                "degenerate element (zero or negative area, or repeated nodes)",
            ));
        }
    }
    Ok(m)
}

fn material(c: &MaterialConfig) -> SolverResult<(Material, f64)> {
    let rho = positive("material.density", c.density)?;
    let e = positive("material.youngs_modulus", c.youngs_modulus)?;
    let nu = c.poisson_ratio;
    if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
        return Err(SolverError::config(
            "material.poisson_ratio",
            format!("must be in (−1, 0.5), got {nu}"),
        ));
    }
    let plastic_keys = [
        ("material.yield_stress", c.yield_stress),
        ("material.isotropic_modulus", c.isotropic_modulus),
        ("material.kinematic_modulus", c.kinematic_modulus),
        ("material.tangent_modulus", c.tangent_modulus),
        ("material.kinematic_fraction", c.kinematic_fraction),
    ];
    match c.model.as_str() {
        "elastic" => {
            if let Some((k, _)) = plastic_keys.iter().find(|(_, v)| v.is_some()) {
                return Err(SolverError::config(*k, "only for model = \"j2\""));
            }
            Ok((
                Material::Elastic {
                    youngs: e,
                    poisson: nu,
                },
                rho,
            ))
        }
        "j2" => {
            let sy = positive(
                "material.yield_stress",
                need("material.yield_stress", c.yield_stress)?,
            )?;
            let nonneg = |k: &str, v: f64| {
                if v.is_finite() && v >= 0.0 {
                    Ok(v)
                } else {
                    Err(SolverError::config(k, format!("must be ≥ 0, got {v}")))
                }
            };
            let (hi, hk) = match (c.tangent_modulus, c.isotropic_modulus, c.kinematic_modulus) {
                (Some(et), None, None) => {
                    let et = nonneg("material.tangent_modulus", et)?;
                    if et >= e {
                        return Err(SolverError::config(
                            "material.tangent_modulus",
                            format!("must be < youngs_modulus = {e}, got {et}"),
                        ));
                    }
                    let beta = c.kinematic_fraction.unwrap_or(0.0);
                    if !(0.0..=1.0).contains(&beta) {
                        return Err(SolverError::config(
                            "material.kinematic_fraction",
                            format!("must be in [0, 1], got {beta}"),
                        ));
                    }
                    let h = e * et / (e - et);
                    ((1.0 - beta) * h, beta * h)
                }
                (Some(_), _, _) => {
                    return Err(SolverError::config(
                        "material.tangent_modulus",
                        "give either tangent_modulus or isotropic/kinematic_modulus, not both",
                    ));
                }
                (None, hi, hk) => {
                    if c.kinematic_fraction.is_some() {
                        return Err(SolverError::config(
                            "material.kinematic_fraction",
                            "only with tangent_modulus",
                        ));
                    }
                    (
                        nonneg("material.isotropic_modulus", hi.unwrap_or(0.0))?,
                        nonneg("material.kinematic_modulus", hk.unwrap_or(0.0))?,
                    )
                }
            };
            Ok((
                Material::J2(J2PlaneStress {
                    youngs: e,
                    poisson: nu,
                    yield_stress: sy,
                    h_iso: hi,
                    h_kin: hk,
                }),
                rho,
            ))
        }
        other => Err(SolverError::config(
            "material.model",
            format!("unknown '{other}' (elastic, j2)"),
        )),
    }
}

fn resolve_sets(
    cfg: &[SetConfig],
    key: &str,
    existing: &mut std::collections::BTreeMap<String, Vec<u32>>,
    limit: usize,
    in_box: impl Fn([f64; 3], [f64; 3]) -> Vec<u32>,
) -> SolverResult<()> {
    for (i, s) in cfg.iter().enumerate() {
        if s.name.is_empty() {
            return Err(SolverError::config(
                format!("{key}[{i}].name"),
                "must not be empty",
            ));
        }
        if existing.contains_key(&s.name) {
            return Err(SolverError::config(
                format!("{key}[{i}].name"),
                format!("'{}' is already defined", s.name),
            ));
        }
        let mut v = Vec::new();
        if let Some(ids) = &s.ids {
            if let Some(&bad) = ids.iter().find(|&&n| n as usize >= limit) {
                return Err(SolverError::config(
                    format!("{key}[{i}].ids"),
                    format!("{bad} does not exist (there are {limit})"),
                ));
            }
            v.extend_from_slice(ids);
        }
        let boxes = s
            .bbox
            .iter()
            .map(|b| (format!("{key}[{i}].box"), *b))
            .chain(
                s.boxes
                    .iter()
                    .flatten()
                    .enumerate()
                    .map(|(k, b)| (format!("{key}[{i}].boxes[{k}]"), *b)),
            );
        for (bkey, b) in boxes {
            if (0..3).any(|k| b[k].is_nan() || b[k + 3].is_nan() || b[k] > b[k + 3]) {
                return Err(SolverError::config(
                    bkey,
                    "must be [xmin, ymin, zmin, xmax, ymax, zmax] with min ≤ max",
                ));
            }
            v.extend(in_box([b[0], b[1], b[2]], [b[3], b[4], b[5]]));
        }
        if s.ids.is_none() && s.bbox.is_none() && s.boxes.is_none() {
            return Err(SolverError::config(
                format!("{key}[{i}]"),
                "give ids, box or boxes",
            ));
        }
        v.sort_unstable();
        v.dedup();
        if v.is_empty() {
            return Err(SolverError::config(
                format!("{key}[{i}]"),
                format!("set '{}' is empty", s.name),
            ));
        }
        existing.insert(s.name.clone(), v);
    }
    Ok(())
}

fn lookup<'a>(
    sets: &'a std::collections::BTreeMap<String, Vec<u32>>,
    key: &str,
    name: &str,
) -> SolverResult<&'a [u32]> {
    sets.get(name)
        .map(|v| v.as_slice())
        .ok_or_else(|| SolverError::config(key, format!("no set named '{name}'")))
}

/// Validated configuration → model (mass, inertia, constraints, loads; no coupling yet).
pub fn build(cfg: &ShellConfig) -> SolverResult<Model> {
    let mut mesh = build_mesh(&cfg.mesh)?;
    let (mat, rho) = material(&cfg.material)?;
    let h = positive("section.thickness", cfg.section.thickness)?;
    let nip = cfg.section.integration_points;
    if !(2..=element::MAX_IP).contains(&nip) {
        return Err(SolverError::config(
            "section.integration_points",
            format!("must be in 2..={}, got {nip}", element::MAX_IP),
        ));
    }
    let ks = positive("section.shear_factor", cfg.section.shear_factor)?;
    for (k, v) in [
        ("hourglass.membrane", cfg.hourglass.membrane),
        ("hourglass.bending", cfg.hourglass.bending),
        ("hourglass.transverse", cfg.hourglass.transverse),
    ] {
        if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
            return Err(SolverError::config(
                k,
                format!("must be in [0, 1], got {v}"),
            ));
        }
    }
    let dts = cfg.time.dt_scale;
    if !(dts.is_finite() && dts > 0.0 && dts <= 1.0) {
        return Err(SolverError::config(
            "time.dt_scale",
            format!("must be in (0, 1], got {dts}"),
        ));
    }
    if let Some(t) = cfg.time.mass_scaling_dt {
        positive("time.mass_scaling_dt", t)?;
    }
    if !(cfg.time.velocity_ramp.is_finite() && cfg.time.velocity_ramp >= 0.0) {
        return Err(SolverError::config(
            "time.velocity_ramp",
            format!("must be ≥ 0, got {}", cfg.time.velocity_ramp),
        ));
    }
    let tol = 1e-9 * mesh.size();
    let nn = mesh.nodes.len();
    let ne = mesh.elements.len();
    {
        let m2 = mesh.clone();
        resolve_sets(
            &cfg.node_sets,
            "node_sets",
            &mut mesh.node_sets,
            nn,
            |lo, hi| m2.nodes_in_box(lo, hi, tol),
        )?;
        resolve_sets(
            &cfg.element_sets,
            "element_sets",
            &mut mesh.element_sets,
            ne,
            |lo, hi| m2.elements_in_box(lo, hi, tol),
        )?;
    }
    let section = Section::new(
        nip,
        ks,
        [
            cfg.hourglass.membrane,
            cfg.hourglass.bending,
            cfg.hourglass.transverse,
        ],
        cfg.section.update_thickness,
    );
    let mut model = assemble(&mesh, mat, section, rho, h);
    if let Some(c) = &cfg.contact {
        if c.kind != "single_surface" {
            return Err(SolverError::config(
                "contact.kind",
                format!("must be \"single_surface\", got \"{}\"", c.kind),
            ));
        }
        let s = c.penalty_scale;
        if !(s.is_finite() && s > 0.0 && s <= 1.0) {
            return Err(SolverError::config(
                "contact.penalty_scale",
                format!("must be in (0, 1], got {s}"),
            ));
        }
        let membrane: Vec<f64> = (0..model.num_elements())
            .map(|e| {
                let x = model.conn[e].map(|n| model.x0[n as usize]);
                element::geometry(&x).map_or(0.0, |g| {
                    element::stiffness_estimates(&section, &mat, model.h0[e], &g)[0]
                })
            })
            .collect();
        model.contact = Some(crate::contact::Contact::new(&model, s, &membrane));
    }
    model.dt_scale = dts;
    model.velocity_ramp = cfg.time.velocity_ramp;
    model.mass_scaling_dt = cfg.time.mass_scaling_dt;
    // Boundary conditions.
    for (i, f) in cfg.fixed.iter().enumerate() {
        let nodes = lookup(
            &model.node_sets,
            &format!("fixed[{i}].node_set"),
            &f.node_set,
        )?
        .to_vec();
        let mut bits = 0u8;
        for d in &f.dofs {
            bits |= match d.as_str() {
                "x" => 1,
                "y" => 2,
                "z" => 4,
                "rx" => 8,
                "ry" => 16,
                "rz" => 32,
                "translations" => 7,
                "rotations" => 56,
                "all" => DOF_ALL,
                other => {
                    return Err(SolverError::config(
                        format!("fixed[{i}].dofs"),
                        format!(
                            "unknown dof '{other}' (x y z rx ry rz translations rotations all)"
                        ),
                    ));
                }
            };
        }
        for n in nodes {
            model.fix[n as usize] |= bits;
        }
    }
    for (i, vc) in cfg.velocity.iter().enumerate() {
        let nodes = lookup(
            &model.node_sets,
            &format!("velocity[{i}].node_set"),
            &vc.node_set,
        )?
        .to_vec();
        let comps = [vc.x, vc.y, vc.z];
        if comps.iter().all(|c| c.is_none()) {
            return Err(SolverError::config(
                format!("velocity[{i}]"),
                "give x, y or z",
            ));
        }
        for n in nodes {
            for k in 0..3 {
                if let Some(val) = comps[k] {
                    if !val.is_finite() {
                        return Err(SolverError::config(
                            format!("velocity[{i}]"),
                            "must be finite",
                        ));
                    }
                    model.fix[n as usize] |= 1 << k;
                    model.v_pres[n as usize][k] = val;
                }
            }
        }
    }
    for (i, vc) in cfg.initial_velocity.iter().enumerate() {
        let nodes = lookup(
            &model.node_sets,
            &format!("initial_velocity[{i}].node_set"),
            &vc.node_set,
        )?
        .to_vec();
        for n in nodes {
            for (k, c) in [vc.x, vc.y, vc.z].into_iter().enumerate() {
                if let Some(val) = c {
                    model.v[n as usize][k] = val;
                }
            }
        }
    }
    for (i, p) in cfg.point_loads.iter().enumerate() {
        let nodes = lookup(
            &model.node_sets,
            &format!("point_loads[{i}].node_set"),
            &p.node_set,
        )?
        .to_vec();
        for n in nodes {
            for k in 0..3 {
                model.f_ext[n as usize][k] += p.force[k];
            }
        }
    }
    for (i, p) in cfg.pressure.iter().enumerate() {
        let elems = lookup(
            &model.element_sets,
            &format!("pressure[{i}].element_set"),
            &p.element_set,
        )?
        .to_vec();
        for e in elems {
            model.pressure[e as usize] += p.pressure;
        }
    }
    for (i, name) in cfg.output.reaction_sets.iter().enumerate() {
        let nodes = lookup(
            &model.node_sets,
            &format!("output.reaction_sets[{i}]"),
            name,
        )?
        .to_vec();
        model.reaction_sets.push(ReactionSet {
            name: name.clone(),
            nodes,
        });
    }
    for (i, itf) in cfg.interfaces.iter().enumerate() {
        if itf.name.is_empty() {
            return Err(SolverError::config(
                format!("interfaces[{i}].name"),
                "must not be empty",
            ));
        }
        if cfg.interfaces[..i].iter().any(|o| o.name == itf.name) {
            return Err(SolverError::config(
                format!("interfaces[{i}].name"),
                format!("'{}' is defined twice", itf.name),
            ));
        }
        lookup(
            &model.element_sets,
            &format!("interfaces[{i}].element_set"),
            &itf.element_set,
        )?;
    }
    model.refresh_lists();
    Ok(model)
}

/// Rotational inertia per unit element mass, r (nodal inertia ¼ ρ h A r per element).
///
/// The physical value is h²/12. With it, the transverse-shear stiffness κGhA/4 of the
/// rotations gives a frequency ≈ √(12κG/ρh²), far above the membrane one, and the rotations
/// would govern the step. Explicit shells therefore scale the rotary inertia up; the common
/// floor A/12 is more than needed on elongated elements, and the excess is not harmless: the
/// θ inertia of a bending beam (Rayleigh correction, Δf/f ≈ −½ r k² for wavenumber k) lowers
/// the bending frequencies at first order in the element size (−2.5 % on mode 3 of the
/// 10 × 1 steel cantilever strip). Here r is the least value at which the element's
/// rotational branch of the frequency bound (`element::stiffness_estimates`, s_w/m + s_θ/I)
/// does not exceed its membrane one, r = s_θ / (s_m − s_w), but never more than the common
/// A/12 and never less than h²/12. On square elements that is A/12 (as before); on elongated
/// ones r ∝ (short side)², so the rotary-inertia error is second order in the element size
/// (the step is always computed from the actual masses, so either choice is stable).
pub fn rotary_inertia_factor(
    section: &Section,
    material: &Material,
    h: f64,
    g: &element::Geom,
) -> f64 {
    let [s_m, s_w, s_t] = element::stiffness_estimates(section, material, h, g);
    // Guard for a shear factor so large that s_w approaches s_m: then the rotations may set
    // the step (`step::stable_dt` bounds both branches, so it stays stable).
    let r = s_t / (s_m - s_w).max(0.25 * s_m);
    r.min(g.area / 12.0).max(h * h / 12.0)
}

/// Mesh + material + section → model with lumped masses, zero state, no constraints.
pub fn assemble(mesh: &Mesh, material: Material, section: Section, density: f64, h: f64) -> Model {
    let nn = mesh.nodes.len();
    let ne = mesh.elements.len();
    let nip = section.nip;
    let mut mass = vec![0.0; nn];
    let mut inertia = vec![0.0; nn];
    let mut nsum = vec![[0.0; 3]; nn];
    let mut res = vec![[0.0; RES]; ne];
    for (e, c) in mesh.elements.iter().enumerate() {
        let x = c.map(|n| mesh.nodes[n as usize]);
        // Degenerate elements were refused by `build`; tests may assemble directly.
        let Some(g) = element::geometry(&x) else {
            continue;
        };
        let me = density * h * g.area;
        let r = rotary_inertia_factor(&section, &material, h, &g);
        for &n in c {
            mass[n as usize] += 0.25 * me;
            inertia[n as usize] += 0.25 * me * r;
            for k in 0..3 {
                nsum[n as usize][k] += g.e[2][k] * g.area;
            }
        }
        res[e][R_H] = h;
    }
    let n0 = nsum
        .iter()
        .map(|s| {
            let l = vec3(s).norm();
            if l > 0.0 {
                [s[0] / l, s[1] / l, s[2] / l]
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect();
    // Node → element adjacency (compressed rows, element order within a row).
    let mut counts = vec![0u32; nn + 1];
    for c in &mesh.elements {
        for &n in c {
            counts[n as usize + 1] += 1;
        }
    }
    for i in 0..nn {
        counts[i + 1] += counts[i];
    }
    let mut fill = counts.clone();
    let mut adj = vec![0u32; counts[nn] as usize];
    for (e, c) in mesh.elements.iter().enumerate() {
        for (a, &n) in c.iter().enumerate() {
            adj[fill[n as usize] as usize] = (e * 4 + a) as u32;
            fill[n as usize] += 1;
        }
    }
    Model {
        x0: mesh.nodes.clone(),
        x: mesh.nodes.clone(),
        v: vec![[0.0; 3]; nn],
        w: vec![[0.0; 3]; nn],
        q: vec![[1.0, 0.0, 0.0, 0.0]; nn],
        n0,
        mass_elem: mass.clone(),
        inertia_elem: inertia.clone(),
        mass,
        inertia,
        f_ext: vec![[0.0; 3]; nn],
        f_c: vec![[0.0; 3]; nn],
        m_c: vec![[0.0; 3]; nn],
        k_c: vec![0.0; nn],
        fix: vec![0; nn],
        v_pres: vec![[0.0; 3]; nn],
        reaction: vec![[0.0; 6]; nn],
        adj_offsets: counts,
        adj,
        conn: mesh.elements.clone(),
        stress: vec![0.0; ne * nip * 3],
        plastic: vec![0.0; ne * nip * PL],
        res,
        fe: vec![[[0.0; 6]; 4]; ne],
        pressure: vec![0.0; ne],
        h0: vec![h; ne],
        section,
        material,
        density,
        dt_scale: 0.9,
        velocity_ramp: 0.0,
        mass_scaling_dt: None,
        node_sets: mesh.node_sets.clone(),
        element_sets: mesh.element_sets.clone(),
        reaction_sets: Vec::new(),
        time: 0.0,
        dt_prev: 0.0,
        steps: 0,
        external_work: 0.0,
        support_work: 0.0,
        interface_work: 0.0,
        external_impulse: [0.0; 3],
        interface_impulse: [0.0; 3],
        load_impulse: [0.0; 3],
        interface_angular_impulse: [0.0; 3],
        added_mass: 0.0,
        added_inertia: 0.0,
        loaded_nodes: Vec::new(),
        constrained_nodes: Vec::new(),
        coupled_nodes: Vec::new(),
        contact: None,
    }
}

impl Model {
    /// Recompute the small node lists used by the sequential bookkeeping sums.
    pub fn refresh_lists(&mut self) {
        let n = self.x.len() as u32;
        self.loaded_nodes = (0..n)
            .filter(|&i| self.f_ext[i as usize] != [0.0; 3])
            .collect();
        self.constrained_nodes = (0..n).filter(|&i| self.fix[i as usize] != 0).collect();
    }
}

/// The benchmark plate: a 1 × 1 m, 10 mm elastic steel plate of `n × n` elements
/// with `nip` through-thickness points, clamped along x = 0 and set vibrating by a transverse
/// velocity 0.1 x². Shared by the crate's benchmark and `cosim bench`.
pub fn benchmark_plate(n: usize, nip: usize) -> SolverResult<crate::ShellSolver> {
    let toml = format!(
        r#"
[mesh]
kind = "plate"
length = 1.0
width = 1.0
nx = {n}
ny = {n}
[material]
model = "elastic"
density = 7800.0
youngs_modulus = 210.0e9
poisson_ratio = 0.3
[section]
thickness = 0.01
integration_points = {nip}
[[fixed]]
node_set = "x0"
"#
    );
    let mut s = crate::ShellSolver::from_toml_str(&toml)?;
    let m = &mut s.model;
    for i in 0..m.num_nodes() {
        let x = m.x0[i][0];
        m.v[i][2] = 0.1 * x * x;
    }
    Ok(s)
}
