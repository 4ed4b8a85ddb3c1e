//! The 2-D elastic finite-element model (`fem-2d`, seed 003 §2.1 and §5): a rectangle of
//! bilinear quads (`mechanics::fem2d`) in plane stress or strain, supported on named edges,
//! loaded by line loads on edges with a step or C³ ramp history, advanced by a GS4-II member
//! (`mechanics::time`, seed 003 §4: central differences by default, or an implicit design).
//!
//! Set-up (`from_params`) checks every key and builds the linear system; `advance` takes
//! equal substeps through the window with the load weighted at each step's algorithmic time
//! (seed 003 eq. 67); `write_output` writes the nodes with displacement, velocity and nodal
//! stress. [`Fem2d::subdomain`] presents the same model as one side of a `lagrange` coupling,
//! which `cosim run` drives through [`Solver::lagrange_side`] (the recipe of
//! `crate::lagrange`); `advance` then only reports the window from the subdomain's state.
//! An interface `{ overlap = [[x0, y0], [x1, y1]] }` hands the box's elements to a finer
//! model (an `overlap` coupling's driver): they leave the model, the ring of elements around
//! them is the interface mesh whose motion goes out, and the finer model's force on the
//! ring's nodes comes back, held over the next window.

use crate::lagrange::{SubdomainSide, resonance_limit, resonance_warning};
use mechanics::fem2d::{Edge, Fem2dError, Material, Mesh, Model, Plane};
use mechanics::time::{
    CouplingMethod, Gs4, Gs4Error, IntegratorSpec, InterfaceDof, LinearSystem, LoadRamp, Ramp,
    State, Stepper, Subdomain,
};
use mechanics::xfem::Crack;
use protocol::scheme;
use protocol::scheme::lagrange::{LagrangeSide, Method, wire as lwire};
use protocol::{Binding, Inbox, LimitApplies, LimitKind, Outbox, WindowLimit};
use protocol::{
    InterfaceInfo, InterfaceMesh, NodeDescription, Solver, SolverError, SolverResult, StepReport,
    Window,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Parameters of `fem-2d`, as in the case file's `[nodes.<name>.params]`.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Fem2dParams {
    /// Box length along x and height along y (m).
    pub length: f64,
    /// Box height along y (m).
    pub height: f64,
    /// Lower-left corner (m).
    #[serde(default)]
    pub origin: [f64; 2],
    /// Elements along x and y.
    pub nx: usize,
    /// Elements along y.
    pub ny: usize,
    /// Young's modulus (Pa).
    pub young: f64,
    /// Poisson's ratio (1).
    pub poisson: f64,
    /// Density (kg/m³).
    pub density: f64,
    /// "stress" (σzz = 0) or "strain" (εzz = 0).
    #[serde(default = "default_plane")]
    pub plane: String,
    /// Out-of-plane thickness (m).
    #[serde(default = "default_thickness")]
    pub thickness: f64,
    /// Supported edges: "left" (both components held), or "left.x" / "left.y" (one).
    #[serde(default)]
    pub fixed: Vec<String>,
    /// Uniform line loads on edges.
    #[serde(default)]
    pub loads: Vec<LoadParams>,
    /// Named points whose displacement and velocity are reported every window (`<name>_ux`,
    /// `<name>_uy`, `<name>_vx`, `<name>_vy`): the node nearest to [x, y], which must lie
    /// within one element of it.
    #[serde(default)]
    pub points: BTreeMap<String, [f64; 2]>,
    /// Interface names → edge, for a `lagrange` coupling; edges joined with "+" make one
    /// interface of several ("left+right": the middle subdomain of three in a row). Or
    /// `{ overlap = [[x0, y0], [x1, y1]] }`, for an `overlap` coupling's driver: the
    /// elements inside the box leave the model to a finer one, and the interface is the ring
    /// of elements around it, whose nodes the finer model's boundary layer follows.
    #[serde(default)]
    pub interfaces: BTreeMap<String, InterfaceSpec>,
    /// Steps per window in a lagrange coupling (the ratio m of the system step to this
    /// subdomain's step). Absent: as many as `dt` (or the explicit step bound) needs.
    #[serde(default)]
    pub substeps: Option<usize>,
    /// Time integrator (as `bar-1d`'s). Absent: central differences, the explicit member of
    /// U0(1,1,0).
    #[serde(default)]
    pub integrator: Option<IntegratorSpec>,
    /// Fraction of the explicit critical step used when `dt` is absent (≤ 1).
    #[serde(default = "default_courant")]
    pub courant: f64,
    /// Largest time step (s). An explicit integrator refuses one beyond its critical step.
    #[serde(default)]
    pub dt: Option<f64>,
    /// A crack: a polyline of points [x, y] (m). Elements it crosses from edge to edge split
    /// in two (Heaviside enrichment: each side carries its own field, the crack's faces are
    /// free); it opens only across elements it has fully crossed. An end on the boundary or
    /// outside the mesh is a mouth, an end inside is a tip. It must not pass through a node
    /// or run along an element edge.
    #[serde(default)]
    pub crack: Vec<[f64; 2]>,
}

/// An interface of `fem-2d`: edges, or a region handed to a finer model.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum InterfaceSpec {
    /// "left", or edges joined with "+": a lagrange side.
    Edges(String),
    /// A box [[x0, y0], [x1, y1]] (m) whose sides lie on element edges.
    Overlap { overlap: [[f64; 2]; 2] },
}

/// An overlap coupling's region in the mesh: which elements leave the model and the ring
/// of elements around them.
#[derive(Debug, Clone)]
struct Region {
    /// Whether each element stays in the model.
    active: Vec<bool>,
    /// The interface's nodes (mesh numbers) and its cells over them (local numbers,
    /// counter-clockwise): the active elements that share a node with a left-out one.
    nodes: Vec<usize>,
    cells: Vec<[u32; 4]>,
}

/// The elements of `mesh` inside the box `b` (its sides on element edges, checked) and
/// the ring around them. `key`: the box's key path.
fn region(mesh: &Mesh, key: &str, b: [[f64; 2]; 2]) -> SolverResult<Region> {
    let [[x0, y0], [x1, y1]] = b;
    if !(b.iter().flatten().all(|v| v.is_finite()) && x1 > x0 && y1 > y0) {
        return Err(SolverError::config(
            key,
            format!("must be [[x0, y0], [x1, y1]] with x1 > x0 and y1 > y0, got {b:?}"),
        ));
    }
    let [bx0, by0, bx1, by1] = mesh.bounds();
    let h = mesh
        .quads
        .iter()
        .map(|q| (mesh.nodes[q[0]][0] - mesh.nodes[q[1]][0]).abs())
        .fold(f64::INFINITY, f64::min);
    // a side on a mesh line, or beyond the mesh (the region reaches its boundary)
    let on_line = |v: f64, c: usize, lo: f64, hi: f64| {
        v <= lo + 1e-9 * h
            || v >= hi - 1e-9 * h
            || mesh.nodes.iter().any(|n| (n[c] - v).abs() <= 1e-9 * h)
    };
    for (v, c, lo, hi) in [
        (x0, 0, bx0, bx1),
        (x1, 0, bx0, bx1),
        (y0, 1, by0, by1),
        (y1, 1, by0, by1),
    ] {
        if !on_line(v, c, lo, hi) {
            return Err(SolverError::config(
                key,
                format!(
                    "its side at {} = {v} m lies on no element edge: put the box's sides on the \
                     mesh lines",
                    ["x", "y"][c]
                ),
            ));
        }
    }
    let centre =
        |q: &[usize; 4]| [0, 1].map(|c| 0.25 * q.iter().map(|&n| mesh.nodes[n][c]).sum::<f64>());
    let active: Vec<bool> = mesh
        .quads
        .iter()
        .map(|q| {
            let [x, y] = centre(q);
            !(x > x0 && x < x1 && y > y0 && y < y1)
        })
        .collect();
    if active.iter().all(|a| *a) {
        return Err(SolverError::config(key, "holds no element"));
    }
    if active.iter().all(|a| !*a) {
        return Err(SolverError::config(
            key,
            "holds every element: the mesh keeps nothing to couple",
        ));
    }
    let mut left_out = vec![false; mesh.nodes.len()];
    for (q, a) in mesh.quads.iter().zip(&active) {
        if !a {
            for &n in q {
                left_out[n] = true;
            }
        }
    }
    let mut local = vec![u32::MAX; mesh.nodes.len()];
    let (mut nodes, mut cells) = (Vec::new(), Vec::new());
    for (q, a) in mesh.quads.iter().zip(&active) {
        if !a || !q.iter().any(|&n| left_out[n]) {
            continue;
        }
        cells.push(q.map(|n| {
            if local[n] == u32::MAX {
                local[n] = nodes.len() as u32;
                nodes.push(n);
            }
            local[n]
        }));
    }
    Ok(Region {
        active,
        nodes,
        cells,
    })
}

/// The overlap coupling this model drives: its interface nodes' free dofs and the force the
/// finer model's layer exerts on them, held over the window.
#[derive(Debug, Clone)]
struct OverlapFem {
    interface: String,
    /// Free dof of each interface node's x and y (None where a support holds it).
    dofs: Vec<[Option<usize>; 2]>,
    /// The force on the free dofs (N), held over the window, and the one in the
    /// acceleration the next step starts from.
    force: Vec<f64>,
    before: Vec<f64>,
    /// The force [x, y] on the interface's held dofs (N), held over the window, and the one
    /// the step before took: a support holds those nodes, so it takes that force, and the
    /// reaction's impulse is the support's like any other (the force is received all the
    /// same, so the momentum handed across the interface is all accounted for).
    held: [f64; 2],
    held_before: [f64; 2],
}

/// A uniform line load on an edge.
#[derive(Debug, Clone, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LoadParams {
    /// "left" | "right" | "bottom" | "top".
    pub edge: String,
    /// Force per metre of edge [qx, qy] (N/m), whatever the thickness.
    pub traction: [f64; 2],
    /// How the load starts: "step" (at once), "linear" (a constant rate), "sin2" or "septic" (the
    /// C³ ramp, for second-order studies) over `ramp_time`, then held. Also read under its older
    /// name, `history`.
    #[serde(default, alias = "history")]
    pub ramp: Ramp,
    /// Ramp duration T (s), with every `ramp` but "step".
    #[serde(default)]
    pub ramp_time: Option<f64>,
}

fn default_plane() -> String {
    "stress".into()
}
fn default_thickness() -> f64 {
    1.0
}
fn default_courant() -> f64 {
    0.9
}

/// A load's ramp as its table gives it (`prefix`: the table's key path, "loads[0].").
pub fn load_ramp(prefix: &str, ramp: Ramp, ramp_time: Option<f64>) -> SolverResult<LoadRamp> {
    LoadRamp::new(ramp, ramp_time)
        .map_err(|(key, reason)| SolverError::config(format!("{prefix}{key}"), reason))
}

fn fem_error(prefix: &str) -> impl Fn(Fem2dError) -> SolverError + '_ {
    move |Fem2dError::Config { key, reason }| SolverError::config(format!("{prefix}{key}"), reason)
}

fn gs4_error(Gs4Error::Config { key, reason }: Gs4Error) -> SolverError {
    SolverError::config(key, reason)
}

/// What `save_state` writes: the free-dof state and the running sums.
#[derive(Debug, Clone, Serialize, Deserialize, schemars::JsonSchema)]
struct Fem2dState {
    u: Vec<f64>,
    v: Vec<f64>,
    a: Vec<f64>,
    time: f64,
    started: bool,
    /// The step the integrator was factorised for (s; 0 before the first): a restart takes
    /// the same one, so that it continues bit-identically.
    dt: f64,
    external_work: f64,
    external_impulse: [f64; 2],
    applied_impulse: f64,
    /// Impulse and work of an overlap coupling's force since the start.
    #[serde(default)]
    interface_impulse: [f64; 2],
    #[serde(default)]
    interface_work: f64,
    /// An overlap coupling's force in the acceleration the next step starts from (N per free
    /// dof; empty without one): the first step after a restart books the mean of it and the
    /// window's force, as the run before the stop did.
    #[serde(default)]
    overlap_before: Vec<f64>,
}

pub struct Fem2d {
    p: Fem2dParams,
    model: Model,
    sys: LinearSystem,
    coef: Gs4,
    /// Explicit critical step bound (s).
    critical: f64,
    /// What the user should know that does not stop the run (given at set-up).
    warnings: Vec<String>,
    /// Each load's free-dof shape (N) and history.
    loads: Vec<(Vec<f64>, LoadRamp)>,
    /// Reported points: name and node.
    points: Vec<(String, usize)>,
    /// Σ over the supported x (y) dofs of their stiffness rows, over the free dofs: the
    /// support reaction on the body is r · u.
    reaction: [Vec<f64>; 2],
    /// Direction (0 x, 1 y) of each free dof.
    component: Vec<u8>,
    state: State,
    stepper: Option<Stepper>,
    s: Fem2dState,
    f: Vec<f64>,
    f0: Vec<f64>,
    u0: Vec<f64>,
    scratch: Vec<f64>,
    /// Names of the point scalars, built once.
    scalar_names: Vec<[String; 4]>,
    lagrange: Option<LagrangeFem>,
    /// The overlap region (its interface's name), if an interface hands one to a finer model.
    region: Option<(String, Region)>,
    overlap: Option<OverlapFem>,
}

/// The model as one subdomain of a lagrange coupling: the runtime steps it.
struct LagrangeFem {
    interface: String,
    side: SubdomainSide,
    /// Σ of the load shape per component (N): the load's impulse is this × ∫ g dt.
    load_total: [f64; 2],
    /// Σ |load shape| (N).
    load_gross: f64,
}

impl std::fmt::Debug for Fem2d {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fem2d")
            .field("nodes", &self.model.mesh.nodes.len())
            .field("free_dofs", &self.sys.len())
            .field("coef", &self.coef)
            .finish()
    }
}

/// Parses an interface's edges, "left" or several joined with "+" ("left+right").
fn parse_edges(key: &str, s: &str) -> SolverResult<Vec<Edge>> {
    s.split('+')
        .map(|e| Edge::parse(key, e.trim()).map_err(fem_error("")))
        .collect()
}

/// Parses "left" or "left.x" / "left.y": the edge and the components held.
fn parse_support(key: &str, s: &str) -> SolverResult<(Edge, Vec<usize>)> {
    let (edge, comps) = match s.split_once('.') {
        None => (s, vec![0, 1]),
        Some((e, "x")) => (e, vec![0]),
        Some((e, "y")) => (e, vec![1]),
        Some(_) => {
            return Err(SolverError::config(
                key,
                format!("must be an edge, or an edge with \".x\" or \".y\", got \"{s}\""),
            ));
        }
    };
    Ok((Edge::parse(key, edge).map_err(fem_error(""))?, comps))
}

impl Fem2d {
    pub fn from_params(params: &toml::Table) -> SolverResult<Self> {
        Self::new(protocol::params::decode(params)?)
    }

    pub fn new(p: Fem2dParams) -> SolverResult<Self> {
        let plane = match p.plane.as_str() {
            "stress" => Plane::Stress,
            "strain" => Plane::Strain,
            other => {
                return Err(SolverError::config(
                    "plane",
                    format!("must be \"stress\" or \"strain\", got \"{other}\""),
                ));
            }
        };
        let material = Material {
            young: p.young,
            poisson: p.poisson,
            density: p.density,
            thickness: p.thickness,
            plane,
        };
        material.check().map_err(fem_error(""))?;
        let mesh =
            Mesh::rectangle(p.origin, p.length, p.height, p.nx, p.ny).map_err(fem_error(""))?;
        let mut fixed = Vec::new();
        for (k, s) in p.fixed.iter().enumerate() {
            let (edge, comps) = parse_support(&format!("fixed[{k}]"), s)?;
            for n in mesh.edge(edge) {
                fixed.extend(comps.iter().map(|c| 2 * n + c));
            }
        }
        if !(p.courant > 0.0 && p.courant <= 1.0) {
            return Err(SolverError::config(
                "courant",
                format!("must be in (0, 1], got {}", p.courant),
            ));
        }
        let coef = match &p.integrator {
            Some(spec) => Gs4::from_spec("integrator", spec).map_err(gs4_error)?,
            None => Gs4::central_difference(),
        };
        let crack = (!p.crack.is_empty())
            .then(|| Crack::new("crack", p.crack.clone()))
            .transpose()
            .map_err(fem_error(""))?;
        let mut region_of = None;
        for (name, spec) in &p.interfaces {
            let key = format!("interfaces.{name}");
            match spec {
                InterfaceSpec::Edges(edges) => {
                    parse_edges(&key, edges)?;
                }
                InterfaceSpec::Overlap { overlap } => {
                    if region_of.is_some() {
                        return Err(SolverError::config(
                            key,
                            "a second overlap region: the mesh hands one region to a finer model",
                        ));
                    }
                    region_of = Some((
                        name.clone(),
                        region(&mesh, &format!("{key}.overlap"), *overlap)?,
                    ));
                }
            }
        }
        let active = region_of
            .as_ref()
            .map_or_else(|| vec![true; mesh.quads.len()], |(_, r)| r.active.clone());
        let model =
            Model::with_active(mesh, material, &fixed, crack, active).map_err(fem_error(""))?;
        if let (Some((name, r)), Some(en)) = (&region_of, &model.crack) {
            // the layer follows this mesh's plain bilinear field
            let cut = r.cells.iter().position(|c| {
                let q = c.map(|n| r.nodes[n as usize]);
                q.iter().any(|&n| en.phantom[n].is_some())
            });
            if let Some(c) = cut {
                return Err(SolverError::config(
                    format!("interfaces.{name}.overlap"),
                    format!(
                        "the crack splits a node of the ring of elements around the region \
                         (interface cell {c}): let the region hold the crack near its edges"
                    ),
                ));
            }
        }
        if model.free_dofs() == 0 {
            return Err(SolverError::config(
                "fixed",
                "holds every node: nothing moves",
            ));
        }
        let sys = model.system();
        let critical = model.critical_step_bound();
        if let Some(dt) = p.dt {
            if !(dt.is_finite() && dt > 0.0) {
                return Err(SolverError::config("dt", format!("must be > 0, got {dt}")));
            }
            if coef.explicit && dt > critical {
                return Err(SolverError::config(
                    "dt",
                    format!(
                        "{dt:e} s exceeds the explicit critical step bound {critical:e} s; \
                         use a smaller step or an implicit integrator"
                    ),
                ));
            }
        }
        let mut loads = Vec::with_capacity(p.loads.len());
        for (k, l) in p.loads.iter().enumerate() {
            let key = |s: &str| format!("loads[{k}].{s}");
            let edge = Edge::parse(&key("edge"), &l.edge).map_err(fem_error(""))?;
            if !l.traction.iter().all(|q| q.is_finite()) {
                return Err(SolverError::config(key("traction"), "must be finite"));
            }
            let history = load_ramp(&key(""), l.ramp, l.ramp_time)?;
            let full = model.edge_load(&model.mesh.edge(edge), l.traction);
            let mut shape = vec![0.0; sys.len()];
            model.restrict(&full, &mut shape);
            loads.push((shape, history));
        }
        let b = model.mesh.bounds();
        let hx = p.length / p.nx as f64;
        let hy = p.height / p.ny as f64;
        let reach = (hx * hx + hy * hy).sqrt();
        let mut points = Vec::with_capacity(p.points.len());
        for (name, xy) in &p.points {
            let key = format!("points.{name}");
            let inside = xy[0] >= b[0] - hx
                && xy[0] <= b[2] + hx
                && xy[1] >= b[1] - hy
                && xy[1] <= b[3] + hy;
            match model.mesh.nearest(*xy) {
                Some((node, d)) if inside && d <= reach => points.push((name.clone(), node)),
                _ => {
                    return Err(SolverError::config(
                        key,
                        format!(
                            "{xy:?} is not on the mesh [{}, {}] × [{}, {}]",
                            b[0], b[2], b[1], b[3]
                        ),
                    ));
                }
            }
        }
        if p.substeps == Some(0) {
            return Err(SolverError::config("substeps", "must be ≥ 1, got 0"));
        }
        let mut reaction = [vec![0.0; sys.len()], vec![0.0; sys.len()]];
        let k = &model.stiffness;
        for (i, d) in model.dof.iter().enumerate() {
            if d.is_some() {
                continue;
            }
            for q in k.offsets[i]..k.offsets[i + 1] {
                if let Some(j) = model.dof[k.cols[q]] {
                    reaction[i % 2][j] += k.vals[q];
                }
            }
        }
        let mut component = vec![0u8; sys.len()];
        for (i, d) in model.dof.iter().enumerate() {
            if let Some(d) = *d {
                component[d] = (i % 2) as u8;
            }
        }
        let n = sys.len();
        let scalar_names = points
            .iter()
            .map(|(name, _)| ["ux", "uy", "vx", "vy"].map(|q| format!("{name}_{q}")))
            .collect();
        Ok(Fem2d {
            loads,
            points,
            reaction,
            component,
            state: State::zeros(n),
            stepper: None,
            s: Fem2dState {
                u: Vec::new(),
                v: Vec::new(),
                a: Vec::new(),
                time: 0.0,
                started: false,
                dt: 0.0,
                external_work: 0.0,
                external_impulse: [0.0; 2],
                applied_impulse: 0.0,
                interface_impulse: [0.0; 2],
                interface_work: 0.0,
                overlap_before: Vec::new(),
            },
            f: vec![0.0; n],
            f0: vec![0.0; n],
            u0: vec![0.0; n],
            scratch: vec![0.0; n],
            scalar_names,
            lagrange: None,
            region: region_of,
            overlap: None,
            critical,
            warnings: Vec::new(),
            coef,
            sys,
            model,
            p,
        })
    }

    /// The step the node takes at most (s): `dt` when given, else `courant` × the explicit
    /// critical step bound.
    pub fn step_limit(&self) -> f64 {
        self.p.dt.unwrap_or(self.p.courant * self.critical)
    }

    /// The explicit critical step bound of the mesh (s).
    pub fn critical_step(&self) -> f64 {
        self.critical
    }

    /// The integrator in words: "central differences", or the implicit design's name.
    fn integrator_name(&self) -> String {
        match &self.p.integrator {
            Some(spec) if !self.coef.explicit => format!("implicit {}", spec.design),
            _ => "central differences".into(),
        }
    }

    /// The mesh, material, supports and assembled operators.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The node nearest to `xy`.
    pub fn node_at(&self, xy: [f64; 2]) -> Option<usize> {
        self.model.mesh.nearest(xy).map(|(n, _)| n)
    }

    /// Displacement, velocity and acceleration of component `c` of node `n` (0 where held).
    pub fn node_motion(&self, n: usize, c: usize) -> [f64; 3] {
        match self.model.dof.get(2 * n + c).copied().flatten() {
            Some(d) => [self.state.u[d], self.state.v[d], self.state.a[d]],
            None => [0.0; 3],
        }
    }

    /// The load at time t over the free dofs, into `f`.
    fn load_at(loads: &[(Vec<f64>, LoadRamp)], t: f64, f: &mut [f64]) {
        f.fill(0.0);
        for (shape, h) in loads {
            let g = h.at(t);
            for (fi, s) in f.iter_mut().zip(shape) {
                *fi += s * g;
            }
        }
    }

    /// The support reactions on the body [Rx, Ry] for the free-dof displacement `u`.
    fn reactions(&self, u: &[f64]) -> [f64; 2] {
        std::array::from_fn(|c| self.reaction[c].iter().zip(u).map(|(r, x)| r * x).sum())
    }

    /// The stepper for steps of `dt`, refactorised only when the step changes: windows of
    /// equal length give steps equal to round-off, which keep the step already factorised
    /// (also across a restart). Returns the step to take.
    fn ensure_stepper(&mut self, dt: f64) -> SolverResult<f64> {
        let same = |a: f64| (a - dt).abs() <= 1e-12 * dt;
        if self.stepper.as_ref().is_none_or(|s| !same(s.dt)) {
            let step = if same(self.s.dt) { self.s.dt } else { dt };
            self.stepper = Some(Stepper::new(self.coef, step, &self.sys).map_err(gs4_error)?);
            self.s.dt = step;
        }
        Ok(self.s.dt)
    }

    /// `nsub` steps of `dt` from `t0`.
    fn step(&mut self, t0: f64, nsub: u64, dt: f64) -> SolverResult<()> {
        if !self.s.started {
            // The acceleration in equilibrium with the load at t = 0.
            Self::load_at(&self.loads, t0, &mut self.f);
            let st = &mut self.state;
            self.sys.acceleration(&st.u, &st.v, &self.f, &mut st.a);
            self.s.started = true;
        }
        let dt = self.ensure_stepper(dt)?;
        let w1 = self.coef.w1;
        for k in 0..nsub {
            let ta = t0 + k as f64 * dt;
            let tb = ta + dt;
            // f̃ = (1 − W₁) f(t_n) + W₁ f(t_n+1) (seed 003 eq. 67); f0 keeps f(t_n).
            Self::load_at(&self.loads, ta, &mut self.f0);
            Self::load_at(&self.loads, tb, &mut self.scratch);
            for ((f, a), b) in self.f.iter_mut().zip(&self.f0).zip(&self.scratch) {
                *f = (1.0 - w1) * a + w1 * b;
            }
            if let Some(o) = &self.overlap {
                for (f, c) in self.f.iter_mut().zip(&o.force) {
                    *f += c;
                }
            }
            self.u0.copy_from_slice(&self.state.u);
            let r0 = self.reactions(&self.state.u);
            let Some(stepper) = self.stepper.as_mut() else {
                return Err(SolverError::Other("no stepper".into()));
            };
            stepper.step(&self.sys, &mut self.state, &self.f);
            if let Some(o) = self.overlap.as_mut() {
                // The finer model's force, held over the window. The integrator gives the
                // step the mean of the force in the acceleration it starts from and the one
                // it ends with, so the step after a new force arrives takes the mean of the
                // old and the new.
                for (i, (c, b)) in o.force.iter().zip(&mut o.before).enumerate() {
                    let fm = 0.5 * (*b + c);
                    self.s.interface_impulse[self.component[i] as usize] += fm * dt;
                    self.s.interface_work += fm * (self.state.u[i] - self.u0[i]);
                    *b = *c;
                }
                // what the supports take of it (at rest: no work)
                for c in 0..2 {
                    let hm = 0.5 * (o.held_before[c] + o.held[c]);
                    self.s.interface_impulse[c] += hm * dt;
                    self.s.external_impulse[c] -= hm * dt;
                }
                o.held_before = o.held;
            }
            let r1 = self.reactions(&self.state.u);
            // Trapezoidal work and impulse of the loads over the step; supports add their
            // reaction's impulse.
            let mut work = 0.0;
            let mut impulse = [0.0; 2];
            let mut applied = 0.0;
            for i in 0..self.sys.len() {
                let fm = 0.5 * (self.f0[i] + self.scratch[i]);
                work += fm * (self.state.u[i] - self.u0[i]);
                impulse[self.component[i] as usize] += fm * dt;
                applied += fm.abs() * dt;
            }
            self.s.external_work += work;
            self.s.applied_impulse += applied;
            for c in 0..2 {
                self.s.external_impulse[c] += impulse[c] + 0.5 * (r0[c] + r1[c]) * dt;
            }
        }
        if let Some(i) = self.state.u.iter().position(|x| !x.is_finite()) {
            return Err(SolverError::Diverged {
                time: t0 + nsub as f64 * dt,
                reason: format!("displacement of free dof {i} is not finite"),
            });
        }
        Ok(())
    }

    /// The nodes of an interface: its edges' nodes in order, each node once.
    fn interface_nodes(&self, name: &str) -> SolverResult<Vec<usize>> {
        let spec = self.p.interfaces.get(name).ok_or_else(|| {
            SolverError::interface(
                name,
                "no such interface on this mesh (see params.interfaces)",
            )
        })?;
        let s = match spec {
            InterfaceSpec::Edges(s) => s,
            InterfaceSpec::Overlap { .. } => {
                return Ok(self
                    .region
                    .as_ref()
                    .map(|(_, r)| r.nodes.clone())
                    .unwrap_or_default());
            }
        };
        let mut nodes: Vec<usize> = Vec::new();
        for e in parse_edges(&format!("interfaces.{name}"), s)? {
            for n in self.model.mesh.edge(e) {
                if !nodes.contains(&n) {
                    nodes.push(n);
                }
            }
        }
        Ok(nodes)
    }

    /// This model as one subdomain of a `lagrange` coupling (seed 003 §4.1): the multipliers
    /// tie both components of every node of interface `name`'s edges (ordered along them;
    /// the node's x multiplier is `first_lambda + 2k`, its y one the next), with sign `sign`
    /// in B (+1 on one side, −1 on the other). The loads must share one history. The
    /// subdomain keeps ∫ r·u dt of the support reactions (its probes 0 and 1: x and y).
    pub fn subdomain(
        &self,
        name: &str,
        sign: f64,
        first_lambda: usize,
        dt_system: f64,
        substeps: usize,
        method: CouplingMethod,
    ) -> SolverResult<Subdomain> {
        let mut iface = Vec::new();
        let enriched = |n: usize| {
            self.model
                .crack
                .as_ref()
                .is_some_and(|en| en.phantom[n].is_some())
        };
        for (k, n) in self.interface_nodes(name)?.into_iter().enumerate() {
            if enriched(n) {
                return Err(SolverError::interface(
                    name,
                    format!(
                        "node {n} is split by the crack: keep the crack off a lagrange interface"
                    ),
                ));
            }
            for c in 0..2 {
                let dof = self.model.dof[2 * n + c].ok_or_else(|| {
                    SolverError::interface(name, format!("node {n} is held by a support"))
                })?;
                iface.push(InterfaceDof {
                    dof,
                    sign,
                    lambda: first_lambda + 2 * k + c,
                });
            }
        }
        let mut shape = vec![0.0; self.sys.len()];
        let mut history = LoadRamp::STEP;
        for (k, (s, h)) in self.loads.iter().enumerate() {
            if k > 0 && *h != history {
                return Err(SolverError::config(
                    format!("loads[{k}].ramp"),
                    "a lagrange subdomain takes loads of one ramp",
                ));
            }
            history = *h;
            for (a, b) in shape.iter_mut().zip(s) {
                *a += b;
            }
        }
        Subdomain::new(
            self.sys.clone(),
            self.coef,
            dt_system,
            substeps,
            method,
            iface,
            shape,
            Box::new(move |t| history.at(t)),
        )
        .and_then(|s| s.with_probes(self.reaction.concat()))
        .map_err(gs4_error)
    }

    /// Builds the subdomain for the lagrange coupling `b` (seed 003 §4) from the system step
    /// and method the coordinator asks for, this model's integrator and `substeps` per
    /// system step (an explicit integrator within its critical step).
    fn setup_lagrange(&mut self, b: &Binding, inbox: &Inbox) -> SolverResult<()> {
        let (method, window) = lwire::request(inbox, &b.interface)?;
        let substeps = match self.p.substeps {
            Some(m) => m,
            None => (window / self.step_limit() - 1e-9).ceil().max(1.0) as usize,
        };
        let step = window / substeps as f64;
        if self.coef.explicit && step > self.critical * (1.0 + 1e-12) {
            return Err(SolverError::config(
                "substeps",
                format!(
                    "{substeps} steps per window of {window:e} s take {step:e} s, beyond the \
                     explicit critical step bound {:e} s",
                    self.critical
                ),
            ));
        }
        if self.p.substeps.is_none() && method != Method::Gc {
            self.warnings.extend(resonance_warning(
                &self.coef,
                &self.integrator_name(),
                substeps,
                window,
                self.critical,
            ));
        }
        let method = match method {
            Method::Gs4 => CouplingMethod::Gs4,
            Method::Gc => CouplingMethod::Gc,
            Method::Ph => CouplingMethod::Ph,
        };
        let sub = self.subdomain(&b.interface, 1.0, 0, window, substeps, method)?;
        let mut load_total = [0.0; 2];
        let mut load_gross = 0.0;
        for (shape, _) in &self.loads {
            for (i, s) in shape.iter().enumerate() {
                load_total[self.component[i] as usize] += s;
                load_gross += s.abs();
            }
        }
        self.lagrange = Some(LagrangeFem {
            interface: b.interface.clone(),
            side: SubdomainSide(sub),
            load_total,
            load_gross,
        });
        Ok(())
    }

    /// Drives the overlap coupling `b` (this mesh's region): its ring's nodes are the
    /// interface; their motion goes out at set-up and after every window.
    fn setup_overlap(&mut self, b: &Binding, out: &mut Outbox) -> SolverResult<()> {
        if self.overlap.is_some() {
            return Err(SolverError::interface(
                &b.interface,
                "a second overlap coupling on the region",
            ));
        }
        let nodes = self.interface_nodes(&b.interface)?;
        let dofs = nodes
            .iter()
            .map(|&n| [0, 1].map(|c| self.model.dof[2 * n + c]))
            .collect();
        self.overlap = Some(OverlapFem {
            interface: b.interface.clone(),
            dofs,
            force: vec![0.0; self.sys.len()],
            before: vec![0.0; self.sys.len()],
            held: [0.0; 2],
            held_before: [0.0; 2],
        });
        self.send_overlap_motion(out);
        Ok(())
    }

    /// The overlap force of this window: the finer model's force on each interface node,
    /// held over the window (it must have arrived).
    fn take_overlap_force(&mut self, inbox: &Inbox) -> SolverResult<()> {
        let Some(o) = self.overlap.as_mut() else {
            return Ok(());
        };
        let f = inbox.require(&o.interface, "force", 3 * o.dofs.len())?;
        if f.iter().any(|a| !a.is_finite()) {
            return Err(SolverError::interface(
                &o.interface,
                "non-finite force received",
            ));
        }
        o.force.fill(0.0);
        o.held = [0.0; 2];
        for (k, d) in o.dofs.iter().enumerate() {
            for c in 0..2 {
                match d[c] {
                    Some(i) => o.force[i] += f[3 * k + c],
                    None => o.held[c] += f[3 * k + c],
                }
            }
        }
        Ok(())
    }

    /// The interface nodes' position and velocity now, into `out`.
    fn send_overlap_motion(&self, out: &mut Outbox) {
        let Some(o) = self.overlap.as_ref() else {
            return;
        };
        let Some((_, r)) = self.region.as_ref() else {
            return;
        };
        let n = o.dofs.len();
        let x = out.put(&o.interface, "position", 3, n);
        for (k, (d, &node)) in o.dofs.iter().zip(&r.nodes).enumerate() {
            let p = self.model.mesh.nodes[node];
            for c in 0..2 {
                x[3 * k + c] = p[c] + d[c].map_or(0.0, |i| self.state.u[i]);
            }
            x[3 * k + 2] = 0.0;
        }
        let v = out.put(&o.interface, "velocity", 3, n);
        for (k, d) in o.dofs.iter().enumerate() {
            for c in 0..2 {
                v[3 * k + c] = d[c].map_or(0.0, |i| self.state.v[i]);
            }
            v[3 * k + 2] = 0.0;
        }
    }

    /// Energies, momentum, the named points and the running sums of `self.s`: the window's
    /// report.
    fn report(&mut self, substeps: u64) -> StepReport {
        let (u, v) = (&self.state.u, &self.state.v);
        let mut ke = 0.0;
        let mut p = [0.0; 2];
        let mut gross = 0.0;
        for i in 0..u.len() {
            let m = self.sys.mass[i];
            ke += 0.5 * m * v[i] * v[i];
            p[self.component[i] as usize] += m * v[i];
            gross += m * v[i].abs();
        }
        self.sys.stiffness.mul(u, &mut self.scratch);
        let ie: f64 = 0.5 * u.iter().zip(&self.scratch).map(|(a, b)| a * b).sum::<f64>();
        let mut scalars = Vec::with_capacity(4 * self.points.len());
        for ((_, node), names) in self.points.iter().zip(&self.scalar_names) {
            for (k, name) in names.iter().enumerate() {
                // displacement x, y, then velocity x, y
                scalars.push((name.clone(), self.node_motion(*node, k % 2)[k / 2]));
            }
        }
        StepReport {
            kinetic_energy: ke,
            internal_energy: ie,
            external_work: self.s.external_work,
            momentum: [p[0], p[1], 0.0],
            momentum_gross: gross,
            external_impulse: [self.s.external_impulse[0], self.s.external_impulse[1], 0.0],
            applied_impulse: self.s.applied_impulse,
            interface_impulse: [
                self.s.interface_impulse[0],
                self.s.interface_impulse[1],
                0.0,
            ],
            interface_work: self.s.interface_work,
            substeps,
            scalars,
            ..Default::default()
        }
    }

    /// The report of a window the runtime has stepped through the lagrange side: the state
    /// from the subdomain; the work and impulses of the loads, supports and interface as the
    /// subdomain summed them over its substeps.
    fn report_lagrange(&mut self, w: &Window) -> SolverResult<StepReport> {
        let Some(l) = self.lagrange.as_ref() else {
            return Err(SolverError::Other("no lagrange side".into()));
        };
        let sub = &l.side.0;
        if let Some(i) = sub.state.u.iter().position(|x| !x.is_finite()) {
            return Err(SolverError::Diverged {
                time: w.t1,
                reason: format!("displacement of free dof {i} is not finite"),
            });
        }
        self.state.u.copy_from_slice(&sub.state.u);
        self.state.v.copy_from_slice(&sub.state.v);
        self.state.a.copy_from_slice(&sub.state.a);
        let g = sub.load_integral;
        self.s.external_work = sub.external_work;
        for c in 0..2 {
            self.s.external_impulse[c] = l.load_total[c] * g + sub.probe_integral[c];
        }
        self.s.applied_impulse = l.load_gross * g.abs();
        let mut iface = [0.0; 3];
        // Local interface dof r is component r % 2 of its node (see `subdomain`).
        for (r, j) in sub.interface_impulse.iter().enumerate() {
            iface[r % 2] += j;
        }
        let (work, substeps) = (sub.interface_work, sub.substeps() as u64);
        self.s.time = w.t1;
        let mut report = self.report(substeps);
        report.interface_work = work;
        report.interface_impulse = iface;
        Ok(report)
    }

    fn full(&self, free: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.model.dof.len()];
        self.model.expand(free, &mut out);
        out
    }
}

impl Solver for Fem2d {
    fn describe(&self) -> NodeDescription {
        NodeDescription {
            model: "fem-2d".into(),
            interfaces: self
                .p
                .interfaces
                .iter()
                .map(|(name, spec)| InterfaceInfo {
                    name: name.clone(),
                    points: self.interface_nodes(name).map_or(0, |n| n.len()),
                    provides: match spec {
                        // a lagrange side (seed 003 §4): its condensed interface operator
                        InterfaceSpec::Edges(_) => {
                            vec!["velocity".into(), "lagrange_operator".into()]
                        }
                        // an overlap driver: its ring's motion
                        InterfaceSpec::Overlap { .. } => {
                            vec!["position".into(), "velocity".into()]
                        }
                    },
                    accepts: vec!["force".into()],
                })
                .collect(),
            units: "SI".into(),
        }
    }

    fn interface(&self, name: &str) -> SolverResult<InterfaceMesh> {
        if let Some((region_name, r)) = &self.region
            && region_name == name
        {
            let mut m = InterfaceMesh::points(
                r.nodes
                    .iter()
                    .map(|&n| {
                        let [x, y] = self.model.mesh.nodes[n];
                        [x, y, 0.0]
                    })
                    .collect(),
            );
            m.cells = Some(protocol::message::Cells {
                kind: protocol::message::CellKind::Quad,
                connectivity: r.cells.iter().flatten().copied().collect(),
            });
            return Ok(m);
        }
        Ok(InterfaceMesh::points(
            self.interface_nodes(name)?
                .into_iter()
                .map(|n| {
                    let [x, y] = self.model.mesh.nodes[n];
                    [x, y, 0.0]
                })
                .collect(),
        ))
    }

    fn setup(&mut self, bindings: &[Binding], inbox: &Inbox, out: &mut Outbox) -> SolverResult<()> {
        self.lagrange = None;
        self.overlap = None;
        let mut lagrange = None;
        for b in bindings {
            let sch = scheme::of(b.kind);
            let region = self.region.as_ref().is_some_and(|(n, _)| *n == b.interface);
            if sch.boundary_layer() || region {
                if !(sch.boundary_layer() && region && !sch.follows(b.role)) {
                    return Err(SolverError::interface(
                        &b.interface,
                        "an overlap coupling takes the mesh's overlap region as its driver, and \
                         the region serves that coupling only",
                    ));
                }
                self.setup_overlap(b, out)?;
                continue;
            }
            if !sch.coordinator_solved() {
                return Err(SolverError::interface(
                    &b.interface,
                    "fem-2d takes part in lagrange and overlap couplings only (not kinematic or \
                     immersed)",
                ));
            }
            if lagrange.is_some() {
                return Err(SolverError::interface(
                    &b.interface,
                    "fem-2d is one subdomain of one lagrange coupling: join its edges in one \
                     interface (\"left+right\") and list every subdomain in that coupling's sides",
                ));
            }
            lagrange = Some(b);
        }
        if let Some(b) = lagrange {
            self.setup_lagrange(b, inbox)?;
        }
        if let (Some((name, _)), None) = (&self.region, &self.overlap) {
            // the region's elements are out of the model: alone, the mesh has a hole there
            return Err(SolverError::config(
                format!("interfaces.{name}.overlap"),
                "no overlap coupling takes the region: the mesh would run with a hole in \
                 it (add a [[couplings]] kind = \"overlap\" with this interface as its \
                 driver, or remove the region)",
            ));
        }
        Ok(())
    }

    fn lagrange_side(&mut self, interface: &str) -> Option<&mut dyn LagrangeSide> {
        match self.lagrange.as_mut() {
            Some(l) if l.interface == interface => Some(&mut l.side),
            _ => None,
        }
    }

    fn stable_dt(&self) -> f64 {
        self.step_limit()
    }

    fn window_limits(&self) -> Vec<WindowLimit> {
        let Some(n) = self.p.substeps else {
            return Vec::new();
        };
        let mut limits = Vec::new();
        if self.coef.explicit {
            limits.push(WindowLimit {
                applies: LimitApplies::LagrangeSide,
                integrator: "central differences".into(),
                substeps: n as u64,
                max_step: self.critical,
                key: Some("params.substeps".into()),
                kind: LimitKind::Stability,
            });
        }
        limits.extend(resonance_limit(
            &self.coef,
            &self.integrator_name(),
            n,
            self.critical,
        ));
        limits
    }

    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn advance(&mut self, w: &Window, inbox: &Inbox, out: &mut Outbox) -> SolverResult<StepReport> {
        let span = w.t1 - w.t0;
        if span.is_nan() || span <= 0.0 {
            return Err(SolverError::Other(format!(
                "empty window [{}, {}]",
                w.t0, w.t1
            )));
        }
        if self.lagrange.is_some() {
            return self.report_lagrange(w);
        }
        self.take_overlap_force(inbox)?;
        let nsub = (span / self.step_limit() - 1e-9).ceil().max(1.0) as u64;
        let dt = span / nsub as f64;
        self.step(w.t0, nsub, dt)?;
        self.s.time = w.t1;
        self.send_overlap_motion(out);
        Ok(self.report(nsub))
    }

    fn write_output(&self, t: f64, window: u64, dir: &std::path::Path) -> SolverResult<()> {
        // The nodes as VTK points (ParaView: `fem2d.pvd`) with displacement, velocity and the
        // nodal mean of the element stresses [σxx, σyy, σxy]. A cracked mesh draws each part
        // of a cut element as a polygon of its own, with its side's field at its vertices, so
        // that the opening shows once warped by the displacement.
        let mesh = &self.model.mesh;
        let nn = mesh.nodes.len();
        let mut points: Vec<[f64; 3]> = mesh.nodes.iter().map(|&[x, y]| [x, y, 0.0]).collect();
        let u = self.full(&self.state.u);
        let v = self.full(&self.state.v);
        let vec3 = |full: &[f64]| {
            full[..2 * nn]
                .chunks_exact(2)
                .flat_map(|c| [c[0], c[1], 0.0])
                .collect::<Vec<f64>>()
        };
        let mut elem = vec![[0.0; 3]; mesh.quads.len()];
        self.model.element_stress(&u, &mut elem);
        let mut stress = vec![0.0; 3 * nn];
        self.model.nodal_stress(&elem, &mut stress);
        let (mut disp, mut vel) = (vec3(&u), vec3(&v));
        let mut cells = Vec::with_capacity(mesh.quads.len());
        let (mut cell_stress, mut part) = (Vec::new(), Vec::new());
        for piece in self.model.pieces() {
            let q = &mesh.quads[piece.element];
            let Some(poly) = &piece.polygon else {
                cells.push((
                    node_kit::vtk::CellType::Quad,
                    q.iter().map(|&n| n as u64).collect(),
                ));
                cell_stress.extend(elem[piece.element]);
                part.push(0.0);
                continue;
            };
            let first = points.len() as u64;
            let mut mean = [0.0; 3];
            for &p in poly {
                let (du, s) = self.model.field_at(piece.element, &piece.dofs, p, &u);
                let (dv, _) = self.model.field_at(piece.element, &piece.dofs, p, &v);
                points.push([p[0], p[1], 0.0]);
                disp.extend([du[0], du[1], 0.0]);
                vel.extend([dv[0], dv[1], 0.0]);
                stress.extend(s);
                for r in 0..3 {
                    mean[r] += s[r] / poly.len() as f64;
                }
            }
            cells.push((
                node_kit::vtk::CellType::Polygon,
                (first..first + poly.len() as u64).collect(),
            ));
            cell_stress.extend(mean);
            part.push(piece.side);
        }
        let data = vec![
            ("displacement", 3, disp),
            ("velocity", 3, vel),
            ("stress", 3, stress),
        ];
        let mut cell_data = vec![("element_stress", 3, cell_stress)];
        if self.model.crack.is_some() {
            // Which side of the crack a cut element's part lies on (+1 left of the crack's
            // direction, −1 right; 0 for a whole element).
            cell_data.push(("crack_side", 1, part));
        }
        let frame = node_kit::vtk::Frame {
            dir,
            stem: "fem2d",
            window,
            time: t,
        };
        node_kit::vtk::write_vtu(
            &frame,
            node_kit::vtk::mixed_grid(&points, cells, data, cell_data),
        )?;
        Ok(())
    }

    fn save_state(&self) -> SolverResult<Vec<u8>> {
        // In a lagrange coupling the runtime saves the subdomain beside this (its
        // `LagrangeSide::save_state`).
        let mut s = self.s.clone();
        s.u = self.state.u.clone();
        s.v = self.state.v.clone();
        s.a = self.state.a.clone();
        // the free dofs' forces, then the held dofs' [x, y]
        s.overlap_before = self
            .overlap
            .as_ref()
            .map(|o| o.before.iter().chain(&o.held_before).copied().collect())
            .unwrap_or_default();
        protocol::checkpoint::encode_state(&s)
    }

    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        use protocol::checkpoint::check_len;
        let s: Fem2dState = protocol::checkpoint::decode_state(bytes)?;
        let n = self.sys.len();
        check_len("u", s.u.len(), n)?;
        check_len("v", s.v.len(), n)?;
        check_len("a", s.a.len(), n)?;
        if let Some(o) = self.overlap.as_mut() {
            let n = o.before.len();
            check_len("overlap force", s.overlap_before.len(), n + 2)?;
            o.before.copy_from_slice(&s.overlap_before[..n]);
            o.held_before = [s.overlap_before[n], s.overlap_before[n + 1]];
        }
        self.state.u.copy_from_slice(&s.u);
        self.state.v.copy_from_slice(&s.v);
        self.state.a.copy_from_slice(&s.a);
        self.s = Fem2dState {
            u: Vec::new(),
            v: Vec::new(),
            a: Vec::new(),
            overlap_before: Vec::new(),
            ..s
        };
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> LoadRamp {
        let l: LoadParams = toml::from_str(text).expect("a load table");
        load_ramp("loads[0].", l.ramp, l.ramp_time).expect("a valid ramp")
    }

    /// The older spelling `history = "ramp"` is the septic ramp, as `ramp = "septic"` is; a
    /// load without either starts at once.
    #[test]
    fn the_older_history_spelling_reads_as_the_septic_ramp() {
        let head = "edge = \"right\"\ntraction = [1.0, 0.0]\n";
        let older = load(&format!("{head}history = \"ramp\"\nramp_time = 0.5"));
        let newer = load(&format!("{head}ramp = \"septic\"\nramp_time = 0.5"));
        assert_eq!(older, newer);
        assert_eq!(older.ramp, Ramp::Septic);
        assert_eq!(older.time, 0.5);
        assert_eq!(load(&format!("{head}history = \"step\"")), LoadRamp::STEP);
        assert_eq!(load(head), LoadRamp::STEP);
    }
}
