//! 2-D linear elastic finite elements (seed 003 §2.1): bilinear quadrilaterals integrated with
//! 2×2 Gauss points, plane stress or plane strain, on a mesh of nodes and quads (structured
//! rectangles built here); row-sum lumped mass, sparse stiffness, supports removed by a
//! free-dof numbering, consistent edge loads and node sets by name. The result is the linear
//! system M ü + K u = f that `time::Stepper` (GS4-II, seed 003 §4) advances.
//!
//! Layout: node i has degrees of freedom 2i (x) and 2i + 1 (y); quad corners run
//! counter-clockwise; nodal stresses are [σxx, σyy, σxy] per node.
// Index loops over the 8 element dofs and 3 stress components read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

use crate::time::{Csr, LinearSystem};
use crate::xfem::{self, Crack, Cut};
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum Fem2dError {
    /// A bad parameter: the key and why.
    #[error("{key}: {reason}")]
    Config { key: String, reason: String },
}

fn config(key: &str, reason: impl Into<String>) -> Fem2dError {
    Fem2dError::Config {
        key: key.into(),
        reason: reason.into(),
    }
}

/// The 2-D idealisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plane {
    /// σzz = 0 (thin plate of the given thickness).
    Stress,
    /// εzz = 0 (a slice of the given thickness of a long body).
    Strain,
}

/// An isotropic linear elastic material and the out-of-plane thickness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Young's modulus (Pa).
    pub young: f64,
    pub poisson: f64,
    /// Density (kg/m³).
    pub density: f64,
    /// Out-of-plane thickness (m).
    pub thickness: f64,
    pub plane: Plane,
}

impl Material {
    /// Refuses non-physical values, naming the key.
    pub fn check(&self) -> Result<(), Fem2dError> {
        for (key, v) in [
            ("young", self.young),
            ("density", self.density),
            ("thickness", self.thickness),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(config(key, format!("must be > 0, got {v}")));
            }
        }
        let upper = match self.plane {
            Plane::Stress => 1.0,
            Plane::Strain => 0.5,
        };
        if !(self.poisson > -1.0 && self.poisson < upper) {
            return Err(config(
                "poisson",
                format!(
                    "must be in (-1, {upper}) for this plane, got {}",
                    self.poisson
                ),
            ));
        }
        Ok(())
    }

    /// The elasticity matrix D: σ = D ε with ε = [εxx, εyy, γxy].
    pub fn elasticity(&self) -> [[f64; 3]; 3] {
        let (e, nu) = (self.young, self.poisson);
        match self.plane {
            Plane::Stress => {
                let c = e / (1.0 - nu * nu);
                [
                    [c, c * nu, 0.0],
                    [c * nu, c, 0.0],
                    [0.0, 0.0, c * (1.0 - nu) / 2.0],
                ]
            }
            Plane::Strain => {
                let c = e / ((1.0 + nu) * (1.0 - 2.0 * nu));
                [
                    [c * (1.0 - nu), c * nu, 0.0],
                    [c * nu, c * (1.0 - nu), 0.0],
                    [0.0, 0.0, c * (1.0 - 2.0 * nu) / 2.0],
                ]
            }
        }
    }

    /// The speed of long waves along a bar of this material: √(E/ρ) in plane stress,
    /// √(E/((1 − ν²)ρ)) in plane strain (m/s).
    pub fn bar_wave_speed(&self) -> f64 {
        let e = match self.plane {
            Plane::Stress => self.young,
            Plane::Strain => self.young / (1.0 - self.poisson * self.poisson),
        };
        (e / self.density).sqrt()
    }
}

/// A side of the mesh's bounding box.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Edge {
    Left,
    Right,
    Bottom,
    Top,
}

impl Edge {
    /// Parses "left" | "right" | "bottom" | "top"; `key` names the value in errors.
    pub fn parse(key: &str, s: &str) -> Result<Self, Fem2dError> {
        match s {
            "left" => Ok(Edge::Left),
            "right" => Ok(Edge::Right),
            "bottom" => Ok(Edge::Bottom),
            "top" => Ok(Edge::Top),
            other => Err(config(
                key,
                format!("must be \"left\", \"right\", \"bottom\" or \"top\", got \"{other}\""),
            )),
        }
    }
}

/// Nodes and counter-clockwise bilinear quads.
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    pub nodes: Vec<[f64; 2]>,
    pub quads: Vec<[usize; 4]>,
}

/// Most elements a mesh built here takes (its arrays must fit in memory).
pub const MAX_ELEMENTS: usize = 10_000_000;

impl Mesh {
    /// `nx` × `ny` equal quads over the box [x0, x0 + lx] × [y0, y0 + ly]; node (i, j) is
    /// number j (nx + 1) + i.
    pub fn rectangle(
        origin: [f64; 2],
        lx: f64,
        ly: f64,
        nx: usize,
        ny: usize,
    ) -> Result<Self, Fem2dError> {
        for (key, v) in [("length", lx), ("height", ly)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(config(key, format!("must be > 0, got {v}")));
            }
        }
        if !(origin[0].is_finite() && origin[1].is_finite()) {
            return Err(config("origin", "must be finite"));
        }
        for (key, n) in [("nx", nx), ("ny", ny)] {
            if n == 0 {
                return Err(config(key, "must be ≥ 1, got 0"));
            }
        }
        if nx.saturating_mul(ny) > MAX_ELEMENTS {
            return Err(config(
                "nx",
                format!("nx × ny must be at most {MAX_ELEMENTS}, got {nx} × {ny}"),
            ));
        }
        let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1));
        for j in 0..=ny {
            for i in 0..=nx {
                nodes.push([
                    origin[0] + lx * i as f64 / nx as f64,
                    origin[1] + ly * j as f64 / ny as f64,
                ]);
            }
        }
        let id = |i: usize, j: usize| j * (nx + 1) + i;
        let mut quads = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                quads.push([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        Ok(Mesh { nodes, quads })
    }

    /// Bounding box [xmin, ymin, xmax, ymax].
    pub fn bounds(&self) -> [f64; 4] {
        self.nodes.iter().fold(
            [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ],
            |b, p| {
                [
                    b[0].min(p[0]),
                    b[1].min(p[1]),
                    b[2].max(p[0]),
                    b[3].max(p[1]),
                ]
            },
        )
    }

    /// The nodes on one side of the bounding box, ordered along it (by y for left/right,
    /// by x for bottom/top).
    pub fn edge(&self, edge: Edge) -> Vec<usize> {
        let b = self.bounds();
        let tol = 1e-9 * (b[2] - b[0]).max(b[3] - b[1]);
        let (axis, value, along) = match edge {
            Edge::Left => (0, b[0], 1),
            Edge::Right => (0, b[2], 1),
            Edge::Bottom => (1, b[1], 0),
            Edge::Top => (1, b[3], 0),
        };
        let mut ids: Vec<usize> = (0..self.nodes.len())
            .filter(|&i| (self.nodes[i][axis] - value).abs() <= tol)
            .collect();
        ids.sort_by(|&a, &b| self.nodes[a][along].total_cmp(&self.nodes[b][along]));
        ids
    }

    /// The node nearest to `p` and its distance.
    pub fn nearest(&self, p: [f64; 2]) -> Option<(usize, f64)> {
        self.nodes
            .iter()
            .enumerate()
            .map(|(i, q)| (i, ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Element edges that belong to one quad only (the boundary), as node pairs.
    pub fn boundary_segments(&self) -> Vec<[usize; 2]> {
        let mut all: Vec<([usize; 2], [usize; 2])> = Vec::with_capacity(4 * self.quads.len());
        for q in &self.quads {
            for k in 0..4 {
                let (a, b) = (q[k], q[(k + 1) % 4]);
                all.push(([a.min(b), a.max(b)], [a, b]));
            }
        }
        all.sort_by_key(|e| e.0);
        let mut out = Vec::new();
        let mut i = 0;
        while i < all.len() {
            let mut j = i + 1;
            while j < all.len() && all[j].0 == all[i].0 {
                j += 1;
            }
            if j == i + 1 {
                out.push(all[i].1);
            }
            i = j;
        }
        out
    }
}

/// Gauss points of the 2×2 rule on [−1, 1]² (weights 1).
const GAUSS: f64 = 0.577_350_269_189_625_8;
const CORNERS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

/// Shape functions and their physical gradients at (ξ, η) of a quad with corners `xy`:
/// N_a = ¼(1 + ξξ_a)(1 + ηη_a); returns (N, ∂N/∂x, ∂N/∂y, det J).
fn shape(xy: &[[f64; 2]; 4], xi: f64, eta: f64) -> ([f64; 4], [f64; 4], [f64; 4], f64) {
    let mut n = [0.0; 4];
    let mut dxi = [0.0; 4];
    let mut deta = [0.0; 4];
    for a in 0..4 {
        let [ca, da] = CORNERS[a];
        n[a] = 0.25 * (1.0 + xi * ca) * (1.0 + eta * da);
        dxi[a] = 0.25 * ca * (1.0 + eta * da);
        deta[a] = 0.25 * da * (1.0 + xi * ca);
    }
    let mut j = [[0.0; 2]; 2];
    for a in 0..4 {
        j[0][0] += dxi[a] * xy[a][0];
        j[0][1] += dxi[a] * xy[a][1];
        j[1][0] += deta[a] * xy[a][0];
        j[1][1] += deta[a] * xy[a][1];
    }
    let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
    let mut dx = [0.0; 4];
    let mut dy = [0.0; 4];
    for a in 0..4 {
        dx[a] = (j[1][1] * dxi[a] - j[0][1] * deta[a]) / det;
        dy[a] = (-j[1][0] * dxi[a] + j[0][0] * deta[a]) / det;
    }
    (n, dx, dy, det)
}

fn gauss_points() -> [[f64; 2]; 4] {
    CORNERS.map(|[a, b]| [a * GAUSS, b * GAUSS])
}

/// Strain of the element displacement `ue` (8 values) at a point with gradients dx, dy.
fn strain(dx: &[f64; 4], dy: &[f64; 4], ue: &[f64; 8]) -> [f64; 3] {
    let mut e = [0.0; 3];
    for a in 0..4 {
        e[0] += dx[a] * ue[2 * a];
        e[1] += dy[a] * ue[2 * a + 1];
        e[2] += dy[a] * ue[2 * a] + dx[a] * ue[2 * a + 1];
    }
    e
}

/// Element stiffness ∫ Bᵀ D B t dA (2×2 Gauss) and lumped masses ρ t ∫ N_a dA (the row sums
/// of the consistent mass, since Σ N_b = 1). None for a degenerate or clockwise element.
pub fn element(
    xy: &[[f64; 2]; 4],
    d: &[[f64; 3]; 3],
    material: &Material,
) -> Option<([[f64; 8]; 8], [f64; 4])> {
    let t = material.thickness;
    let mut k = [[0.0; 8]; 8];
    let mut m = [0.0; 4];
    for [xi, eta] in gauss_points() {
        let (n, dx, dy, det) = shape(xy, xi, eta);
        if !(det > 0.0) {
            return None;
        }
        let b = b_matrix(&dx, &dy);
        let mut db = [[0.0; 8]; 3];
        for r in 0..3 {
            for c in 0..8 {
                db[r][c] = (0..3).map(|s| d[r][s] * b[s][c]).sum();
            }
        }
        let w = t * det;
        for i in 0..8 {
            for j in 0..8 {
                k[i][j] += w * (0..3).map(|r| b[r][i] * db[r][j]).sum::<f64>();
            }
        }
        for a in 0..4 {
            m[a] += material.density * w * n[a];
        }
    }
    Some((k, m))
}

/// ∫ Bᵀ D B t dA over the part `poly` (a counter-clockwise polygon inside the quad `xy`):
/// the stiffness of one side of a cut element (exact for parallelograms, where B is linear).
fn part_stiffness(
    xy: &[[f64; 2]; 4],
    d: &[[f64; 3]; 3],
    material: &Material,
    poly: &[[f64; 2]],
) -> [[f64; 8]; 8] {
    let mut k = [[0.0; 8]; 8];
    for (x, w) in xfem::polygon_rule(poly) {
        let [xi, eta] = xfem::parent_coordinates(xy, x);
        let (_, dx, dy, _) = shape(xy, xi, eta);
        let b = b_matrix(&dx, &dy);
        let db: [[f64; 8]; 3] = std::array::from_fn(|r| {
            std::array::from_fn(|c| (0..3).map(|s| d[r][s] * b[s][c]).sum())
        });
        let wt = material.thickness * w;
        for i in 0..8 {
            for j in 0..8 {
                k[i][j] += wt * (0..3).map(|r| b[r][i] * db[r][j]).sum::<f64>();
            }
        }
    }
    k
}

/// Where `crack` cuts `mesh`: its tips, each node's side and phantom, each element's cut.
/// Refuses a crack through (or within 10⁻⁶ of an element from) a node, along an element
/// edge, or crossing one element twice, naming `crack`.
fn enrich(mesh: &Mesh, crack: Crack) -> Result<Enrichment, Fem2dError> {
    let nodes = &mesh.nodes;
    let h = mesh
        .quads
        .iter()
        .flat_map(|q| (0..4).map(move |k| (q[k], q[(k + 1) % 4])))
        .map(|(a, b)| (nodes[a][0] - nodes[b][0]).hypot(nodes[a][1] - nodes[b][1]))
        .fold(f64::INFINITY, f64::min);
    let mut side = Vec::with_capacity(nodes.len());
    for (i, &p) in nodes.iter().enumerate() {
        let (dist, s) = crack.locate(p);
        if dist <= 1e-6 * h {
            return Err(config(
                "crack",
                format!(
                    "passes through node {i} at {p:?} (within {dist:e} m): move it off the node"
                ),
            ));
        }
        side.push(s);
    }
    let boundary = mesh.boundary_segments();
    let tips = crack.ends().map(|p| {
        let inside = mesh
            .quads
            .iter()
            .any(|q| xfem::quad_contains(&q.map(|i| nodes[i]), p));
        let on_edge = boundary
            .iter()
            .any(|&[a, b]| xfem::segment_distance(p, nodes[a], nodes[b]) <= 1e-9 * h);
        inside && !on_edge
    });
    let mut cuts = Vec::with_capacity(mesh.quads.len());
    for (e, q) in mesh.quads.iter().enumerate() {
        let cut = crack
            .cut(&q.map(|i| nodes[i]), tips)
            .map_err(|m| config("crack", format!("element {e}: {m}")))?;
        if let Cut::Through { fraction, .. } = cut
            && !(fraction > 1e-9 && fraction < 1.0 - 1e-9)
        {
            return Err(config(
                "crack",
                format!("runs along an edge of element {e}: move it into the element"),
            ));
        }
        cuts.push(cut);
    }
    if cuts.iter().all(|c| *c == Cut::None) {
        return Err(config(
            "crack",
            "does not meet the mesh (it crosses no element and ends in none)",
        ));
    }
    // A node is enriched when the crack crosses an element of its support and no element of
    // its support holds a tip (so the opening closes at the tip's element).
    let mut crossed = vec![false; nodes.len()];
    let mut at_tip = vec![false; nodes.len()];
    for (q, cut) in mesh.quads.iter().zip(&cuts) {
        for &i in q {
            match cut {
                Cut::Through { .. } => crossed[i] = true,
                Cut::Tip => at_tip[i] = true,
                Cut::None => {}
            }
        }
    }
    let mut count = 0;
    let phantom = (0..nodes.len())
        .map(|i| {
            (crossed[i] && !at_tip[i]).then(|| {
                count += 1;
                count - 1
            })
        })
        .collect();
    Ok(Enrichment {
        crack,
        tips,
        phantom,
        side,
        cuts,
    })
}

/// B columns: dof 2a → [∂x N_a, 0, ∂y N_a], dof 2a+1 → [0, ∂y N_a, ∂x N_a].
fn b_matrix(dx: &[f64; 4], dy: &[f64; 4]) -> [[f64; 8]; 3] {
    let mut b = [[0.0; 8]; 3];
    for a in 0..4 {
        b[0][2 * a] = dx[a];
        b[1][2 * a + 1] = dy[a];
        b[2][2 * a] = dy[a];
        b[2][2 * a + 1] = dx[a];
    }
    b
}

/// A mesh with its material and supports: the assembled operators over all degrees of
/// freedom and the numbering of the free ones.
#[derive(Debug, Clone)]
pub struct Model {
    pub mesh: Mesh,
    pub material: Material,
    /// Free-dof number of every dof (2 per node), None where supported.
    pub dof: Vec<Option<usize>>,
    /// Stiffness over all dofs.
    pub stiffness: Csr,
    /// Lumped mass over all dofs (kg).
    pub mass: Vec<f64>,
    /// The crack and what it enriches, if the model has one.
    pub crack: Option<Enrichment>,
    /// Whether each element takes part (an overlap coupling's patch leaves its elements out:
    /// another model carries that material). A node of inactive elements only is held.
    pub active: Vec<bool>,
    free: usize,
}

/// What [`Model::pieces`] gives: a whole element (`polygon` None, `side` 0) or one part of a
/// cut element (its polygon, `side` ±1), with the all-dof numbers of its field.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    pub element: usize,
    pub side: f64,
    pub polygon: Option<Vec<[f64; 2]>>,
    pub dofs: [usize; 8],
}

/// A crack's enrichment of a model (seed 001 eqs. 67–70, in the phantom-node basis of
/// `crate::xfem`). Dofs 2i, 2i + 1 are node i's own displacement; a node whose support the
/// crack splits also carries the other side's displacement continued to it (its phantom),
/// at dofs 2N + 2k, 2N + 2k + 1 for phantom k (N nodes).
#[derive(Debug, Clone)]
pub struct Enrichment {
    pub crack: Crack,
    /// Which of the crack's two ends are tips (inside the body); the others are mouths.
    pub tips: [bool; 2],
    /// Phantom number of each node (None where the node is not enriched).
    pub phantom: Vec<Option<usize>>,
    /// The side of the crack each node lies on (+1 left of it, −1 right).
    pub side: Vec<f64>,
    /// How the crack meets each element.
    pub cuts: Vec<Cut>,
}

impl Enrichment {
    /// The dofs of element `q`'s field on `side` of the crack: a node on the other side
    /// with a phantom gives its phantom's dofs, every other node its own.
    pub fn dofs(&self, q: &[usize; 4], side: f64, nodes: usize) -> [usize; 8] {
        std::array::from_fn(|i| {
            let (a, c) = (i / 2, i % 2);
            match self.phantom[q[a]] {
                Some(k) if self.side[q[a]] != side => 2 * nodes + 2 * k + c,
                _ => 2 * q[a] + c,
            }
        })
    }

    /// Number of enriched nodes.
    pub fn phantoms(&self) -> usize {
        self.phantom.iter().flatten().count()
    }
}

impl Model {
    /// Assembles K and M over all dofs; `fixed` lists the supported dofs (2 node + component).
    pub fn new(mesh: Mesh, material: Material, fixed: &[usize]) -> Result<Self, Fem2dError> {
        Self::cracked(mesh, material, fixed, None)
    }

    /// As [`Model::new`], with a crack: the elements it crosses split into two parts, each
    /// integrated over its own area with its own copy of the field (see [`Enrichment`]); a
    /// support holds a node's phantom with the node. Each part's lumped mass is its share of
    /// the element's area times the element's lumped masses, so each side of the crack
    /// carries exactly its own mass. Elements holding a tip stay whole and their nodes get no
    /// phantom: the crack opens only across elements it has fully crossed, closing to zero at
    /// the edge where it enters the tip's element.
    pub fn cracked(
        mesh: Mesh,
        material: Material,
        fixed: &[usize],
        crack: Option<Crack>,
    ) -> Result<Self, Fem2dError> {
        let active = vec![true; mesh.quads.len()];
        Self::with_active(mesh, material, fixed, crack, active)
    }

    /// As [`Model::cracked`], with only the elements marked in `active` assembled: the
    /// others carry neither stiffness nor mass, and a node that belongs to inactive elements
    /// only is held (it has nothing to move it).
    pub fn with_active(
        mesh: Mesh,
        material: Material,
        fixed: &[usize],
        crack: Option<Crack>,
        active: Vec<bool>,
    ) -> Result<Self, Fem2dError> {
        material.check()?;
        let nn = mesh.nodes.len();
        if active.len() != mesh.quads.len() {
            return Err(config(
                "mesh",
                format!(
                    "{} activity flags for {} elements",
                    active.len(),
                    mesh.quads.len()
                ),
            ));
        }
        if let Some(q) = mesh.quads.iter().find(|q| q.iter().any(|&i| i >= nn)) {
            return Err(config(
                "mesh",
                format!("quad {q:?} names a node that does not exist"),
            ));
        }
        let enrichment = crack.map(|c| enrich(&mesh, c)).transpose()?;
        let phantoms = enrichment.as_ref().map_or(0, Enrichment::phantoms);
        let nd = 2 * (nn + phantoms);
        let d = material.elasticity();
        let mut t = Vec::with_capacity(64 * mesh.quads.len());
        let mut mass = vec![0.0; nd];
        let mut idle = vec![true; nd];
        let mut scatter = |dofs: &[usize; 8], ke: &[[f64; 8]; 8], me: &[f64; 4], share: f64| {
            for a in 0..8 {
                idle[dofs[a]] = false;
                mass[dofs[a]] += share * me[a / 2];
                for b in 0..8 {
                    t.push((dofs[a], dofs[b], ke[a][b]));
                }
            }
        };
        // dofs of no element at all (an error), and of inactive elements only (held)
        let mut orphan = vec![true; nd];
        for (e, q) in mesh.quads.iter().enumerate() {
            let xy = q.map(|i| mesh.nodes[i]);
            let (ke, me) = element(&xy, &d, &material).ok_or_else(|| {
                config(
                    "mesh",
                    format!("element {e} is degenerate or clockwise (det J ≤ 0 at a Gauss point)"),
                )
            })?;
            let own: [usize; 8] = std::array::from_fn(|i| 2 * q[i / 2] + i % 2);
            if !active[e] {
                for i in own {
                    orphan[i] = false;
                }
                continue;
            }
            match enrichment.as_ref().map(|en| (en, &en.cuts[e])) {
                Some((en, Cut::Through { plus, fraction, .. })) => {
                    let kp = part_stiffness(&xy, &d, &material, plus);
                    let km: [[f64; 8]; 8] =
                        std::array::from_fn(|i| std::array::from_fn(|j| ke[i][j] - kp[i][j]));
                    scatter(&en.dofs(q, 1.0, nn), &kp, &me, *fraction);
                    scatter(&en.dofs(q, -1.0, nn), &km, &me, 1.0 - fraction);
                }
                _ => scatter(&own, &ke, &me, 1.0),
            }
        }
        let mut held = vec![false; nd];
        for i in 0..nd {
            if idle[i] && orphan[i] && i < 2 * nn {
                return Err(config(
                    "mesh",
                    format!("node {} belongs to no element", i / 2),
                ));
            }
            // A phantom of an inactive element only, or a node of inactive elements only.
            held[i] = idle[i];
            if !idle[i] && !(mass[i] > 0.0) {
                return Err(config(
                    "mesh",
                    format!("node {} has no mass", (i / 2).min(nn - 1)),
                ));
            }
        }
        for &i in fixed {
            if i < 2 * nn {
                held[i] = true;
                if let Some(k) = enrichment.as_ref().and_then(|en| en.phantom[i / 2]) {
                    held[2 * nn + 2 * k + i % 2] = true;
                }
            }
        }
        let mut dof = vec![None; nd];
        let mut free = 0;
        for (d, h) in dof.iter_mut().zip(&held) {
            if !h {
                *d = Some(free);
                free += 1;
            }
        }
        Ok(Model {
            stiffness: Csr::from_triplets(nd, t),
            mesh,
            material,
            dof,
            mass,
            crack: enrichment,
            active,
            free,
        })
    }

    /// A step at or below the central-difference limit 2/ω_max of the free system: the
    /// larger of two Gershgorin bounds on ω²_max, that of M⁻¹K's rows
    /// ([`LinearSystem::critical_step_bound`]) and that of the symmetric M^(−½) K M^(−½),
    /// maxᵢ Σⱼ |Kᵢⱼ| / √(mᵢ mⱼ). The second is the tighter one across a crack, where the
    /// light phantom dofs of a small part sit beside heavy ones.
    pub fn critical_step_bound(&self) -> f64 {
        let sys = self.system();
        let k = &sys.stiffness;
        let mut w2: f64 = 0.0;
        for i in 0..k.n {
            let row: f64 = (k.offsets[i]..k.offsets[i + 1])
                .map(|p| k.vals[p].abs() / (sys.mass[i] * sys.mass[k.cols[p]]).sqrt())
                .sum();
            w2 = w2.max(row);
        }
        let symmetric = if w2 > 0.0 {
            2.0 / w2.sqrt()
        } else {
            f64::INFINITY
        };
        sys.critical_step_bound().max(symmetric)
    }

    /// Number of free degrees of freedom.
    pub fn free_dofs(&self) -> usize {
        self.free
    }

    /// M ü + K u = f over the free dofs (undamped).
    pub fn system(&self) -> LinearSystem {
        let mut t = Vec::with_capacity(self.stiffness.vals.len());
        let k = &self.stiffness;
        for i in 0..k.n {
            let Some(fi) = self.dof[i] else { continue };
            for p in k.offsets[i]..k.offsets[i + 1] {
                if let Some(fj) = self.dof[k.cols[p]] {
                    t.push((fi, fj, k.vals[p]));
                }
            }
        }
        let mut mass = vec![0.0; self.free];
        for (i, d) in self.dof.iter().enumerate() {
            if let Some(d) = *d {
                mass[d] = self.mass[i];
            }
        }
        LinearSystem {
            damping: vec![0.0; self.free],
            stiffness: Csr::from_triplets(self.free, t),
            mass,
        }
    }

    /// Consistent nodal forces of a uniform line load `q` (N per metre of edge, [qx, qy])
    /// on the boundary segments whose two nodes are in `nodes`, over all dofs: each
    /// straight bilinear edge of length L takes q L / 2 at each end. Where a crack's mouth
    /// crosses a loaded segment, each side's part loads that side's field.
    pub fn edge_load(&self, nodes: &[usize], q: [f64; 2]) -> Vec<f64> {
        let nn = self.mesh.nodes.len();
        let mut on = vec![false; nn];
        for &i in nodes {
            on[i] = true;
        }
        let mut f = vec![0.0; self.dof.len()];
        let mut add = |dof: usize, share: f64| {
            f[dof] += share * q[dof % 2];
        };
        // the directed edges of inactive elements: no material there to load
        let inactive: std::collections::HashSet<[usize; 2]> = self
            .mesh
            .quads
            .iter()
            .zip(&self.active)
            .filter(|(_, a)| !**a)
            .flat_map(|(q, _)| (0..4).map(|k| [q[k], q[(k + 1) % 4]]))
            .collect();
        for [a, b] in self.mesh.boundary_segments() {
            if !(on[a] && on[b]) || inactive.contains(&[a, b]) {
                continue;
            }
            let (pa, pb) = (self.mesh.nodes[a], self.mesh.nodes[b]);
            let len = (pb[0] - pa[0]).hypot(pb[1] - pa[1]);
            // The crack's mouth on this segment, when it splits it between two fields.
            let split = self.crack.as_ref().and_then(|en| {
                let t = *en.crack.crossings(pa, pb).first()?;
                let other = |n: usize, side: f64| match en.phantom[n] {
                    Some(k) if en.side[n] != side => 2 * nn + 2 * k,
                    _ => 2 * n,
                };
                (en.phantom[a].is_some() || en.phantom[b].is_some()).then(|| {
                    let (sa, sb) = (en.side[a], en.side[b]);
                    (t, [2 * a, other(b, sa)], [other(a, sb), 2 * b])
                })
            });
            for c in 0..2 {
                match split {
                    // ∫ N_a, ∫ N_b over [0, t] (a's side) and over [t, 1] (b's side).
                    Some((t, near, far)) => {
                        add(near[0] + c, len * (t - 0.5 * t * t));
                        add(near[1] + c, len * 0.5 * t * t);
                        add(far[0] + c, len * 0.5 * (1.0 - t) * (1.0 - t));
                        add(far[1] + c, len * 0.5 * (1.0 - t * t));
                    }
                    None => {
                        add(2 * a + c, 0.5 * len);
                        add(2 * b + c, 0.5 * len);
                    }
                }
            }
        }
        f
    }

    /// The free-dof part of an all-dof vector.
    pub fn restrict(&self, full: &[f64], free: &mut [f64]) {
        for (i, d) in self.dof.iter().enumerate() {
            if let Some(d) = *d {
                free[d] = full[i];
            }
        }
    }

    /// An all-dof vector from a free-dof one (zero at the supports).
    pub fn expand(&self, free: &[f64], full: &mut [f64]) {
        for (i, d) in self.dof.iter().enumerate() {
            full[i] = d.map_or(0.0, |d| free[d]);
        }
    }

    /// The dofs of element `e`'s field at the physical point `p`: across a crack, the field
    /// of the side `p` lies on.
    fn dofs_at(&self, e: usize, p: [f64; 2]) -> [usize; 8] {
        let q = &self.mesh.quads[e];
        match self.crack.as_ref() {
            Some(en) if matches!(en.cuts[e], Cut::Through { .. }) => {
                en.dofs(q, en.crack.side(p), self.mesh.nodes.len())
            }
            _ => std::array::from_fn(|i| 2 * q[i / 2] + i % 2),
        }
    }

    /// Stress [σxx, σyy, σxy] at each of element `e`'s 2×2 Gauss points for the all-dof
    /// displacement `u` (in a cut element, each point from its own side's field).
    fn element_gauss_stress(&self, e: usize, d: &[[f64; 3]; 3], u: &[f64]) -> [[f64; 3]; 4] {
        let q = &self.mesh.quads[e];
        let xy = q.map(|i| self.mesh.nodes[i]);
        gauss_points().map(|[xi, eta]| {
            let (n, dx, dy, _) = shape(&xy, xi, eta);
            let p = [0, 1].map(|c| (0..4).map(|a| n[a] * xy[a][c]).sum::<f64>());
            let dofs = self.dofs_at(e, p);
            let ue: [f64; 8] = std::array::from_fn(|i| u[dofs[i]]);
            let eps = strain(&dx, &dy, &ue);
            std::array::from_fn(|r| (0..3).map(|c| d[r][c] * eps[c]).sum::<f64>())
        })
    }

    /// The pieces to draw: every whole active element, and each part of a cut one as its own
    /// polygon with the dofs of its side's field.
    pub fn pieces(&self) -> Vec<Piece> {
        let nn = self.mesh.nodes.len();
        let mut out = Vec::with_capacity(self.mesh.quads.len());
        for (e, q) in self.mesh.quads.iter().enumerate() {
            if !self.active[e] {
                continue;
            }
            let own = std::array::from_fn(|i| 2 * q[i / 2] + i % 2);
            match self.crack.as_ref().map(|en| (en, &en.cuts[e])) {
                Some((en, Cut::Through { plus, minus, .. })) => {
                    for (side, poly) in [(1.0, plus), (-1.0, minus)] {
                        out.push(Piece {
                            element: e,
                            side,
                            polygon: Some(poly.clone()),
                            dofs: en.dofs(q, side, nn),
                        });
                    }
                }
                _ => out.push(Piece {
                    element: e,
                    side: 0.0,
                    polygon: None,
                    dofs: own,
                }),
            }
        }
        out
    }

    /// Displacement [ux, uy] and stress [σxx, σyy, σxy] at the physical point `p` of element
    /// `e`, from the field whose dofs are `dofs` in the all-dof vector `u`.
    pub fn field_at(
        &self,
        e: usize,
        dofs: &[usize; 8],
        p: [f64; 2],
        u: &[f64],
    ) -> ([f64; 2], [f64; 3]) {
        let xy = self.mesh.quads[e].map(|i| self.mesh.nodes[i]);
        let [xi, eta] = xfem::parent_coordinates(&xy, p);
        let (n, dx, dy, _) = shape(&xy, xi, eta);
        let ue: [f64; 8] = std::array::from_fn(|i| u[dofs[i]]);
        let disp = [0, 1].map(|c| (0..4).map(|a| n[a] * ue[2 * a + c]).sum::<f64>());
        let eps = strain(&dx, &dy, &ue);
        let d = self.material.elasticity();
        (
            disp,
            std::array::from_fn(|r| (0..3).map(|c| d[r][c] * eps[c]).sum::<f64>()),
        )
    }

    /// Stress [σxx, σyy, σxy] per element, the mean over its Gauss points, for the all-dof
    /// displacement `u`.
    pub fn element_stress(&self, u: &[f64], out: &mut [[f64; 3]]) {
        let d = self.material.elasticity();
        for (e, s) in out.iter_mut().enumerate().take(self.mesh.quads.len()) {
            let g = self.element_gauss_stress(e, &d, u);
            *s = std::array::from_fn(|r| 0.25 * g.iter().map(|x| x[r]).sum::<f64>());
        }
    }

    /// Stress at every Gauss point of every element ([σxx, σyy, σxy], 4 per element).
    pub fn gauss_stress(&self, u: &[f64]) -> Vec<[f64; 3]> {
        let d = self.material.elasticity();
        (0..self.mesh.quads.len())
            .flat_map(|e| self.element_gauss_stress(e, &d, u))
            .collect()
    }

    /// Nodal stress: the mean of the active element stresses around each node, from `elem`
    /// (see [`Model::element_stress`]); `out` holds 3 values per node (zero at a node of
    /// inactive elements only).
    pub fn nodal_stress(&self, elem: &[[f64; 3]], out: &mut [f64]) {
        out.fill(0.0);
        let mut count = vec![0u32; self.mesh.nodes.len()];
        for ((q, s), _) in self
            .mesh
            .quads
            .iter()
            .zip(elem)
            .zip(&self.active)
            .filter(|(_, a)| **a)
        {
            for &i in q {
                for r in 0..3 {
                    out[3 * i + r] += s[r];
                }
                count[i] += 1;
            }
        }
        for (i, c) in count.iter().enumerate() {
            if *c > 0 {
                for r in 0..3 {
                    out[3 * i + r] /= *c as f64;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steel(plane: Plane) -> Material {
        Material {
            young: 200e9,
            poisson: 0.3,
            density: 7800.0,
            thickness: 0.02,
            plane,
        }
    }

    /// A 4 × 3 mesh over [0, 2] × [0, 1] with its interior nodes moved (no element
    /// becomes a parallelogram).
    fn distorted() -> Mesh {
        let mut m = Mesh::rectangle([0.0, 0.0], 2.0, 1.0, 4, 3).unwrap();
        let shifts = [
            [0.11, -0.07],
            [-0.09, 0.05],
            [0.06, 0.08],
            [-0.04, -0.1],
            [0.1, 0.03],
            [-0.07, 0.09],
        ];
        let mut k = 0;
        for j in 1..3 {
            for i in 1..4 {
                let n = j * 5 + i;
                m.nodes[n][0] += shifts[k][0];
                m.nodes[n][1] += shifts[k][1];
                k += 1;
            }
        }
        m
    }

    #[test]
    fn patch_test_reproduces_uniform_strain_exactly() {
        // u = a + H x: every interior node is in equilibrium with no load, and the stress
        // at every Gauss point of the distorted mesh is D ε of the field, for both planes.
        for plane in [Plane::Stress, Plane::Strain] {
            let mat = steel(plane);
            let model = Model::new(distorted(), mat, &[]).unwrap();
            let (a, h) = ([1e-4, -2e-4], [[1e-3, 4e-4], [-2e-4, 5e-4]]);
            let u: Vec<f64> = model
                .mesh
                .nodes
                .iter()
                .flat_map(|p| {
                    [
                        a[0] + h[0][0] * p[0] + h[0][1] * p[1],
                        a[1] + h[1][0] * p[0] + h[1][1] * p[1],
                    ]
                })
                .collect();
            let mut f = vec![0.0; u.len()];
            model.stiffness.mul(&u, &mut f);
            let boundary: Vec<usize> = [Edge::Left, Edge::Right, Edge::Bottom, Edge::Top]
                .iter()
                .flat_map(|&e| model.mesh.edge(e))
                .collect();
            let scale = f.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let mut interior = 0;
            for n in 0..model.mesh.nodes.len() {
                if !boundary.contains(&n) {
                    assert!(f[2 * n].abs() < 1e-12 * scale && f[2 * n + 1].abs() < 1e-12 * scale);
                    interior += 1;
                }
            }
            assert_eq!(interior, 6);
            let d = mat.elasticity();
            let eps = [h[0][0], h[1][1], h[0][1] + h[1][0]];
            let exact: [f64; 3] = std::array::from_fn(|r| (0..3).map(|c| d[r][c] * eps[c]).sum());
            let s = model.gauss_stress(&u);
            assert_eq!(s.len(), 4 * 12);
            for g in &s {
                for r in 0..3 {
                    assert!(
                        (g[r] - exact[r]).abs() < 1e-9 * exact[0].abs(),
                        "{g:?} vs {exact:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn rigid_body_modes_give_zero_force() {
        let model = Model::new(distorted(), steel(Plane::Stress), &[]).unwrap();
        let n = model.mesh.nodes.len();
        let modes: [fn([f64; 2]) -> [f64; 2]; 3] =
            [|_| [1.0, 0.0], |_| [0.0, 1.0], |p| [-p[1], p[0]]];
        let kmax = model
            .stiffness
            .vals
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        for mode in &modes {
            let u: Vec<f64> = model.mesh.nodes.iter().flat_map(|&p| mode(p)).collect();
            let mut f = vec![0.0; 2 * n];
            model.stiffness.mul(&u, &mut f);
            for fi in &f {
                assert!(fi.abs() < 1e-13 * kmax, "{fi}");
            }
        }
    }

    #[test]
    fn total_mass_is_exact() {
        // ρ t × area, on the rectangle and on the distorted mesh (same outline), per
        // direction; the lumped masses of a rectangle's corner, edge and interior nodes are
        // 1/4, 1/2 and 1 element mass.
        for mesh in [
            Mesh::rectangle([0.0, 0.0], 2.0, 1.0, 4, 3).unwrap(),
            distorted(),
        ] {
            let mat = steel(Plane::Stress);
            let model = Model::new(mesh, mat, &[]).unwrap();
            let exact = mat.density * mat.thickness * 2.0;
            let mx: f64 = model.mass.iter().step_by(2).sum();
            let my: f64 = model.mass.iter().skip(1).step_by(2).sum();
            assert!((mx - exact).abs() < 1e-12 * exact && (my - exact).abs() < 1e-12 * exact);
        }
        let mat = steel(Plane::Stress);
        let model = Model::new(
            Mesh::rectangle([0.0, 0.0], 2.0, 1.0, 4, 3).unwrap(),
            mat,
            &[],
        )
        .unwrap();
        let me = mat.density * mat.thickness * 0.5 / 3.0;
        for (node, share) in [(0, 0.25), (1, 0.5), (6, 1.0)] {
            assert!((model.mass[2 * node] - share * me).abs() < 1e-12 * me);
        }
    }

    #[test]
    fn edge_load_is_consistent_and_sums_to_the_resultant() {
        let model = Model::new(
            Mesh::rectangle([0.0, 0.0], 10.0, 1.0, 10, 4).unwrap(),
            steel(Plane::Stress),
            &[],
        )
        .unwrap();
        let right = model.mesh.edge(Edge::Right);
        assert_eq!(right.len(), 5);
        let f = model.edge_load(&right, [-1e4, 2e3]);
        let fx: f64 = f.iter().step_by(2).sum();
        let fy: f64 = f.iter().skip(1).step_by(2).sum();
        assert!((fx + 1e4).abs() < 1e-9 && (fy - 2e3).abs() < 1e-9);
        // End nodes of the edge take h/2 · q / ... = q h / 2 with h = 1/4: 1250 N; inner 2500.
        assert!((f[2 * right[0]] + 1250.0).abs() < 1e-9);
        assert!((f[2 * right[2]] + 2500.0).abs() < 1e-9);
    }

    fn cantilever(nx: usize, ny: usize) -> (Model, f64) {
        // Seed 003 §5.2 geometry: 10 m × 1 m × 1 m, E 72 GPa, ν 0.3, clamped at x = 0, end
        // shear P = 100 kN (100 000 N/m on the 1 m end edge).
        let mat = Material {
            young: 72e9,
            poisson: 0.3,
            density: 2700.0,
            thickness: 1.0,
            plane: Plane::Stress,
        };
        let mesh = Mesh::rectangle([0.0, 0.0], 10.0, 1.0, nx, ny).unwrap();
        let fixed: Vec<usize> = mesh
            .edge(Edge::Left)
            .iter()
            .flat_map(|&n| [2 * n, 2 * n + 1])
            .collect();
        let model = Model::new(mesh, mat, &fixed).unwrap();
        let right = model.mesh.edge(Edge::Right);
        let f_all = model.edge_load(&right, [0.0, -1e5]);
        let mut f = vec![0.0; model.free_dofs()];
        model.restrict(&f_all, &mut f);
        let u = model.system().solve_static(&f).unwrap();
        // Tip deflection: the mean uy over the end edge.
        let tip = right
            .iter()
            .map(|&n| u[model.dof[2 * n + 1].unwrap()])
            .sum::<f64>()
            / right.len() as f64;
        (model, tip)
    }

    #[test]
    fn cantilever_tip_converges_to_timoshenko_beam_theory() {
        // Timoshenko: δ = P L³/(3 E I) + P L/(κ G A), κ = 5/6 (5.556e-3 + 4.33e-5 m). Full
        // 2×2 integration of bilinear quads locks in bending: the error falls as h², so it
        // must shrink about four times per halving and be small on the finest mesh.
        let (p, l, e, nu): (f64, f64, f64, f64) = (1e5, 10.0, 72e9, 0.3);
        let (i, a) = (1.0 / 12.0, 1.0);
        let g = e / (2.0 * (1.0 + nu));
        let exact = p * l.powi(3) / (3.0 * e * i) + p * l / (5.0 / 6.0 * g * a);
        let errs: Vec<f64> = [(20, 2), (40, 4), (80, 8)]
            .iter()
            .map(|&(nx, ny)| {
                let (_, tip) = cantilever(nx, ny);
                (-tip - exact) / exact
            })
            .collect();
        println!("cantilever tip relative errors {errs:?}");
        for e in &errs {
            assert!(
                *e < 0.0,
                "bilinear quads are stiffer than the beam: {errs:?}"
            );
        }
        for k in 0..2 {
            let order = (errs[k] / errs[k + 1]).log2();
            assert!(order > 1.7, "order {order} ({errs:?})");
        }
        assert!(errs[2].abs() < 0.02, "{errs:?}");
    }

    #[test]
    fn lowest_axial_frequency_is_a_quarter_wave() {
        // A fixed–free bar 10 m × 1 m in plane stress: its axial modes are symmetric about
        // the centre line, so the upper half with uy = 0 on the centre line has the first
        // axial mode as its lowest, f = c/(4L), c = √(E/ρ) (Love's lateral-inertia
        // correction, ν²π²r²/(8L²) ≈ 1e-4, and the mesh's dispersion (kh)²/24 ≈ 6e-5 are far
        // below the tolerance). Inverse iteration with K⁻¹M.
        let mat = Material {
            young: 72e9,
            poisson: 0.3,
            density: 2700.0,
            thickness: 1.0,
            plane: Plane::Stress,
        };
        let mesh = Mesh::rectangle([0.0, 0.0], 10.0, 0.5, 40, 2).unwrap();
        let mut fixed: Vec<usize> = mesh
            .edge(Edge::Left)
            .iter()
            .flat_map(|&n| [2 * n, 2 * n + 1])
            .collect();
        fixed.extend(mesh.edge(Edge::Bottom).iter().map(|&n| 2 * n + 1));
        let model = Model::new(mesh, mat, &fixed).unwrap();
        let sys = model.system();
        let mut x = vec![1.0; sys.len()];
        let mut omega2 = 0.0;
        for _ in 0..60 {
            let mx: Vec<f64> = x.iter().zip(&sys.mass).map(|(a, m)| a * m).collect();
            let y = sys.solve_static(&mx).unwrap();
            let mut ky = vec![0.0; y.len()];
            sys.stiffness.mul(&y, &mut ky);
            let num: f64 = y.iter().zip(&ky).map(|(a, b)| a * b).sum();
            let den: f64 = y.iter().zip(&sys.mass).map(|(a, m)| a * a * m).sum();
            omega2 = num / den;
            let norm = den.sqrt();
            x = y.iter().map(|a| a / norm).collect();
        }
        let f = omega2.sqrt() / (2.0 * std::f64::consts::PI);
        let exact = mat.bar_wave_speed() / 40.0;
        println!("first axial frequency {f} Hz, c/4L = {exact} Hz");
        assert!((f - exact).abs() < 2e-3 * exact, "{f} vs {exact}");
    }

    /// A block of inactive elements leaves the model: its interior nodes are held, the mass
    /// is the active area's, and the stiffness is the whole mesh's less the block's (in a
    /// linear field, the nodes around the block feel the block's missing traction, the others
    /// nothing). A line load skips the block's own boundary edges.
    #[test]
    fn inactive_elements_leave_the_model() {
        let mesh = Mesh::rectangle([0.0, 0.0], 4.0, 3.0, 4, 3).unwrap();
        let mat = steel(Plane::Stress);
        // the 2 x 1 block of elements (1, 1), (2, 1) and the top-left corner element
        let off = [5, 6, 8];
        let active: Vec<bool> = (0..12).map(|e| !off.contains(&e)).collect();
        let whole = Model::new(mesh.clone(), mat, &[]).unwrap();
        let part = Model::with_active(mesh.clone(), mat, &[], None, active).unwrap();
        // node 15 (0, 3) belongs to element 8 only
        assert_eq!(part.dof[30], None);
        assert_eq!(part.dof[31], None);
        assert_eq!(part.free_dofs(), whole.free_dofs() - 2);
        let rho_t = mat.density * mat.thickness;
        let m: f64 = part.mass.iter().step_by(2).sum();
        assert!((m - 9.0 * rho_t).abs() < 1e-12 * m, "{m}");
        // linear field u = (1e-3 x + 2e-4 y, −3e-4 x + 5e-4 y)
        let u: Vec<f64> = mesh
            .nodes
            .iter()
            .flat_map(|&[x, y]| [1e-3 * x + 2e-4 * y, -3e-4 * x + 5e-4 * y])
            .collect();
        let (mut fw, mut fp) = (vec![0.0; u.len()], vec![0.0; u.len()]);
        whole.stiffness.mul(&u, &mut fw);
        part.stiffness.mul(&u, &mut fp);
        let scale = fw.iter().fold(0.0f64, |a, b| a.max(b.abs()));
        let touches = |n: usize| off.iter().any(|&e| mesh.quads[e].contains(&n));
        let boundary = |[x, y]: [f64; 2]| x == 0.0 || y == 0.0 || x == 4.0 || y == 3.0;
        let mut felt = 0;
        for (n, &p) in mesh.nodes.iter().enumerate() {
            let r = fp[2 * n].hypot(fp[2 * n + 1]);
            if !touches(n) && !boundary(p) {
                assert!(r < 1e-12 * scale, "node {n}: {r}");
            }
            // node 11 (1, 2) is the block's corner and the corner element's opposite corner:
            // in a uniform stress their pulls on it cancel
            if n == 11 {
                assert!(r < 1e-12 * scale, "node {n}: {r}");
            } else if touches(n) && part.dof[2 * n].is_some() && !boundary(p) {
                assert!(r > 1e-3 * scale, "node {n} feels no missing traction");
                felt += 1;
            }
        }
        assert_eq!(felt, 5);
        // a load on the top edge: element 8's top edge (nodes 15, 16) takes none
        let top = mesh.edge(Edge::Top);
        let f = part.edge_load(&top, [0.0, 1.0]);
        let total: f64 = f.iter().skip(1).step_by(2).sum();
        assert!((total - 3.0).abs() < 1e-12, "{total}");
        assert_eq!(f[2 * 15 + 1], 0.0);
        assert_eq!(part.pieces().len(), 9);
    }

    #[test]
    fn bad_input_names_its_key() {
        let mut m = steel(Plane::Strain);
        m.poisson = 0.5;
        assert!(m.check().unwrap_err().to_string().starts_with("poisson:"));
        m.poisson = 0.3;
        m.thickness = 0.0;
        assert!(m.check().unwrap_err().to_string().starts_with("thickness:"));
        let e = Mesh::rectangle([0.0, 0.0], 1.0, 1.0, 0, 2).unwrap_err();
        assert!(e.to_string().starts_with("nx:"));
        let mut mesh = Mesh::rectangle([0.0, 0.0], 1.0, 1.0, 1, 1).unwrap();
        mesh.quads[0].swap(1, 3);
        let e = Model::new(mesh, steel(Plane::Stress), &[]).unwrap_err();
        assert!(e.to_string().contains("clockwise"), "{e}");
    }
}
