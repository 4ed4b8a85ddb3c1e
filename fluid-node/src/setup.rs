//! The starter: parameter table → validated `Fluid` model with its initial state (regions
//! given by ρ or T, p, velocity and material; seed 000 §3 and seed 002 eq. 36 set-ups). Every
//! refusal names the key inside `params` and the offending value.

use crate::boundary::{Boundary, FarField};
use crate::config::{BoundaryEntry, BoundarySpec, MaterialSpec, Params, RegionSpec};
use crate::eos::{Eos, IdealGas, Jwl, Material, StiffenedGas};
use crate::grid::{Geometry, Grid};
use crate::immersed::Immersed;
use crate::limiter::Limiter;
use crate::mixture::{self, Phase};
use crate::model::{Fluid, Probe};
use crate::riemann::MAXF;
use protocol::params::refuse_inapplicable;
use protocol::{SolverError, SolverResult};

fn cfg(key: impl Into<String>, reason: impl Into<String>) -> SolverError {
    SolverError::config(key, reason)
}

/// Parse a params table (errors name the full key path).
pub fn parse(params: &toml::Table) -> SolverResult<Params> {
    protocol::params::decode(params)
}

fn positive(key: &str, v: Option<f64>) -> SolverResult<f64> {
    match v {
        Some(x) if x > 0.0 && x.is_finite() => Ok(x),
        Some(x) => Err(cfg(key, format!("must be > 0, got {x}"))),
        None => Err(cfg(key, "missing")),
    }
}

fn material(name: &str, m: &MaterialSpec) -> SolverResult<Material> {
    let key = |f: &str| format!("materials.{name}.{f}");
    let given = [
        ("gamma", m.gamma.is_some()),
        ("p_inf", m.p_inf.is_some()),
        ("gas_constant", m.gas_constant.is_some()),
        ("rho0", m.rho0.is_some()),
        ("a", m.a.is_some()),
        ("b", m.b.is_some()),
        ("r1", m.r1.is_some()),
        ("r2", m.r2.is_some()),
        ("omega", m.omega.is_some()),
        ("e0", m.e0.is_some()),
    ];
    let applies: &[&str] = match m.eos.as_str() {
        "ideal" => &["gamma", "gas_constant"],
        "stiffened" => &["gamma", "p_inf", "gas_constant"],
        "jwl" => &["rho0", "a", "b", "r1", "r2", "omega", "e0"],
        _ => &[
            "gamma",
            "p_inf",
            "gas_constant",
            "rho0",
            "a",
            "b",
            "r1",
            "r2",
            "omega",
            "e0",
        ],
    };
    refuse_inapplicable(&key(""), &format!("eos = \"{}\"", m.eos), &given, applies)?;
    let gamma = |m: &MaterialSpec| -> SolverResult<f64> {
        match m.gamma {
            Some(g) if g > 1.0 && g.is_finite() => Ok(g),
            Some(g) => Err(cfg(key("gamma"), format!("must be > 1, got {g}"))),
            None => Err(cfg(key("gamma"), "missing")),
        }
    };
    let r = match m.gas_constant {
        Some(r) if r > 0.0 => r,
        Some(r) => return Err(cfg(key("gas_constant"), format!("must be > 0, got {r}"))),
        None => 0.0,
    };
    match m.eos.as_str() {
        "ideal" => Ok(Material::Ideal(IdealGas {
            gamma: gamma(m)?,
            gas_constant: r,
        })),
        "stiffened" => {
            let p_inf = match m.p_inf {
                Some(p) if p >= 0.0 => p,
                Some(p) => return Err(cfg(key("p_inf"), format!("must be ≥ 0, got {p}"))),
                None => return Err(cfg(key("p_inf"), "missing")),
            };
            Ok(Material::Stiffened(StiffenedGas {
                gamma: gamma(m)?,
                p_inf,
                gas_constant: r,
            }))
        }
        "jwl" => Ok(Material::Jwl(Jwl {
            rho0: positive(&key("rho0"), m.rho0)?,
            a: positive(&key("a"), m.a)?,
            b: positive(&key("b"), m.b)?,
            r1: positive(&key("r1"), m.r1)?,
            r2: positive(&key("r2"), m.r2)?,
            omega: positive(&key("omega"), m.omega)?,
            e0: positive(&key("e0"), m.e0)?,
        })),
        other => Err(cfg(
            key("eos"),
            format!("unknown equation of state '{other}' (ideal, stiffened, jwl)"),
        )),
    }
}

/// A region's single-material primitive state: (material index, ρ, velocity, p), and a
/// radial velocity (speed, centre) that replaces `vel` where it is given.
struct RegionState {
    mat: usize,
    rho: f64,
    vel: [f64; 3],
    p: f64,
    radial: Option<(f64, [f64; 3])>,
}

impl RegionState {
    /// The velocity at point x of a grid of `geometry` with `nd` active directions.
    fn velocity_at(&self, x: [f64; 3], geometry: Geometry, nd: usize) -> [f64; 3] {
        let Some((speed, c)) = self.radial else {
            return self.vel;
        };
        if matches!(geometry, Geometry::Cylindrical | Geometry::Spherical) {
            return [speed, 0.0, 0.0];
        }
        let mut d = [0.0; 3];
        for k in 0..nd {
            d[k] = x[k] - c[k];
        }
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if len == 0.0 {
            return [0.0; 3];
        }
        d.map(|v| speed * v / len)
    }
}

fn state_of(
    key: &str,
    names: &[String],
    mats: &[Material],
    material: &str,
    density: Option<f64>,
    temperature: Option<f64>,
    pressure: f64,
    velocity: [f64; 3],
) -> SolverResult<RegionState> {
    let mat = names.iter().position(|n| n == material).ok_or_else(|| {
        cfg(
            format!("{key}.material"),
            format!(
                "unknown material '{material}' (defined: {})",
                names.join(", ")
            ),
        )
    })?;
    let eos = &mats[mat];
    if !pressure.is_finite()
        || pressure <= eos.min_pressure()
        || (pressure <= 0.0 && matches!(eos, Material::Ideal(_)))
    {
        return Err(cfg(
            format!("{key}.pressure"),
            format!("must be > {}, got {pressure}", eos.min_pressure()),
        ));
    }
    let rho = match (density, temperature) {
        (Some(_), Some(_)) => {
            return Err(cfg(
                format!("{key}.density"),
                "give density or temperature, not both",
            ));
        }
        (Some(r), None) => {
            if !(r > 0.0) || !r.is_finite() {
                return Err(cfg(
                    format!("{key}.density"),
                    format!("must be > 0, got {r}"),
                ));
            }
            r
        }
        (None, Some(t)) => {
            if !(t > 0.0) {
                return Err(cfg(
                    format!("{key}.temperature"),
                    format!("must be > 0, got {t}"),
                ));
            }
            eos.density_from_temperature(t, pressure).ok_or_else(|| {
                cfg(
                    format!("{key}.temperature"),
                    format!("material '{material}' has no gas_constant to turn a temperature into a density"),
                )
            })?
        }
        (None, None) => return Err(cfg(format!("{key}.density"), "give density or temperature")),
    };
    if velocity.iter().any(|v| !v.is_finite()) {
        return Err(cfg(format!("{key}.velocity"), "must be finite"));
    }
    if !(eos.rho_c2(rho, pressure) > 0.0) {
        return Err(cfg(
            format!("{key}.pressure"),
            format!("state (ρ {rho}, p {pressure}) has no real sound speed"),
        ));
    }
    Ok(RegionState {
        mat,
        rho,
        vel: velocity,
        p: pressure,
        radial: None,
    })
}

enum Shape {
    All,
    Box([f64; 3], [f64; 3]),
    Sphere([f64; 3], f64),
    Half([f64; 3], [f64; 3]),
}

impl Shape {
    fn contains(&self, x: [f64; 3], nd: usize) -> bool {
        match self {
            Shape::All => true,
            Shape::Box(lo, hi) => (0..nd).all(|d| x[d] >= lo[d] && x[d] <= hi[d]),
            Shape::Sphere(c, r) => (0..nd).map(|d| (x[d] - c[d]).powi(2)).sum::<f64>() <= r * r,
            Shape::Half(p, n) => (0..3).map(|d| (x[d] - p[d]) * n[d]).sum::<f64>() >= 0.0,
        }
    }
}

fn shape(key: &str, r: &RegionSpec, radial_centre: bool) -> SolverResult<Shape> {
    let need = |v: Option<[f64; 3]>, f: &str| {
        v.ok_or_else(|| {
            cfg(
                format!("{key}.{f}"),
                format!("required for shape '{}'", r.shape),
            )
        })
    };
    let given = [
        ("lower", r.lower.is_some()),
        ("upper", r.upper.is_some()),
        ("center", r.center.is_some()),
        ("radius", r.radius.is_some()),
        ("point", r.point.is_some()),
        ("normal", r.normal.is_some()),
    ];
    let mut applies: Vec<&str> = match r.shape.as_str() {
        "all" => vec![],
        "box" => vec!["lower", "upper"],
        "sphere" | "circle" => vec!["center", "radius"],
        "half_space" => vec!["point", "normal"],
        _ => vec!["lower", "upper", "center", "radius", "point", "normal"],
    };
    let what = if radial_centre {
        applies.push("center");
        format!("shape = \"{}\" with radial_velocity", r.shape)
    } else {
        format!("shape = \"{}\"", r.shape)
    };
    refuse_inapplicable(&format!("{key}."), &what, &given, &applies)?;
    match r.shape.as_str() {
        "all" => Ok(Shape::All),
        "box" => {
            let lo = need(r.lower, "lower")?;
            let hi = need(r.upper, "upper")?;
            if (0..3).any(|d| hi[d] < lo[d]) {
                return Err(cfg(
                    format!("{key}.upper"),
                    "must be ≥ lower in every direction",
                ));
            }
            Ok(Shape::Box(lo, hi))
        }
        "sphere" | "circle" => {
            let c = need(r.center, "center")?;
            let rad = positive(&format!("{key}.radius"), r.radius)?;
            Ok(Shape::Sphere(c, rad))
        }
        "half_space" => {
            let p = need(r.point, "point")?;
            let n = need(r.normal, "normal")?;
            if n.iter().all(|x| *x == 0.0) {
                return Err(cfg(format!("{key}.normal"), "must not be zero"));
            }
            Ok(Shape::Half(p, n))
        }
        other => Err(cfg(
            format!("{key}.shape"),
            format!("unknown shape '{other}' (all, box, sphere, half_space)"),
        )),
    }
}

/// Primitive vector of a single-material state.
fn prim_vector(nm: usize, s: &RegionState) -> Vec<f64> {
    let mut q = vec![0.0; 2 * nm + 3];
    q[s.mat] = s.rho;
    q[nm..nm + 3].copy_from_slice(&s.vel);
    q[nm + 3] = s.p;
    if s.mat < nm - 1 {
        q[nm + 4 + s.mat] = 1.0;
    }
    q
}

fn boundary(
    key: &str,
    e: &Option<BoundaryEntry>,
    names: &[String],
    mats: &[Material],
) -> SolverResult<Boundary> {
    let spec = match e {
        None => return Ok(Boundary::Outflow),
        Some(BoundaryEntry::Kind(k)) => BoundarySpec {
            kind: k.clone(),
            material: None,
            density: None,
            temperature: None,
            pressure: None,
            velocity: None,
        },
        Some(BoundaryEntry::Full(s)) => s.clone(),
    };
    if spec.kind != "inflow" {
        let (what, applies): (&str, &[&str]) = if spec.kind == "non_reflecting" {
            (
                "(it takes the far field's pressure and velocity)",
                &["pressure", "velocity"],
            )
        } else {
            ("(only an inflow takes a state)", &[])
        };
        refuse_inapplicable(
            &format!("{key}."),
            &format!("kind = \"{}\" {what}", spec.kind),
            &[
                ("material", spec.material.is_some()),
                ("density", spec.density.is_some()),
                ("temperature", spec.temperature.is_some()),
                ("pressure", spec.pressure.is_some()),
                ("velocity", spec.velocity.is_some()),
            ],
            applies,
        )?;
    }
    match spec.kind.as_str() {
        "wall" | "reflective" => Ok(Boundary::Wall),
        "symmetry" => Ok(Boundary::Symmetry),
        "outflow" => Ok(Boundary::Outflow),
        "periodic" => Ok(Boundary::Periodic),
        "non_reflecting" => {
            if let Some(p) = spec.pressure
                && !p.is_finite()
            {
                return Err(cfg(
                    format!("{key}.pressure"),
                    format!("must be finite, got {p}"),
                ));
            }
            let v = spec.velocity.unwrap_or([0.0; 3]);
            if v.iter().any(|c| !c.is_finite()) {
                return Err(cfg(format!("{key}.velocity"), "must be finite"));
            }
            // the impedance (and a pressure not given) come from the face's initial state
            Ok(Boundary::NonReflecting(FarField {
                pressure: spec.pressure.unwrap_or(f64::NAN),
                velocity: v,
                impedance: f64::NAN,
                relax: f64::NAN,
            }))
        }
        "inflow" => {
            let m = spec
                .material
                .as_deref()
                .ok_or_else(|| cfg(format!("{key}.material"), "required for inflow"))?;
            let p = spec
                .pressure
                .ok_or_else(|| cfg(format!("{key}.pressure"), "required for inflow"))?;
            let s = state_of(
                key,
                names,
                mats,
                m,
                spec.density,
                spec.temperature,
                p,
                spec.velocity.unwrap_or([0.0; 3]),
            )?;
            Ok(Boundary::Inflow(prim_vector(names.len(), &s)))
        }
        other => Err(cfg(
            format!("{key}.kind"),
            format!(
                "unknown boundary '{other}' (wall, symmetry, outflow, non_reflecting, periodic, inflow)"
            ),
        )),
    }
}

/// The grid's geometry, checked against its dimension and its radial extent.
fn geometry(p: &Params) -> SolverResult<Geometry> {
    let g = match p.geometry.as_deref().unwrap_or("cartesian") {
        "cartesian" => return Ok(Geometry::Cartesian),
        "cylindrical" => Geometry::Cylindrical,
        "spherical" => Geometry::Spherical,
        "axisymmetric" => Geometry::Axisymmetric,
        other => {
            return Err(cfg(
                "geometry",
                format!(
                    "unknown geometry '{other}' (cartesian, cylindrical, spherical, axisymmetric)"
                ),
            ));
        }
    };
    let c = p.grid.cells;
    let nd = if c[2] > 1 {
        3
    } else if c[1] > 1 {
        2
    } else {
        1
    };
    let wants = if g == Geometry::Axisymmetric { 2 } else { 1 };
    if nd != wants {
        let cells = if wants == 1 {
            "[nr, 1, 1]"
        } else {
            "[nr, nz, 1] (x the radius, y the axis)"
        };
        return Err(cfg(
            "grid.cells",
            format!(
                "geometry '{}' runs on a {wants}-D grid: use cells = {cells}, got {c:?}",
                g.name()
            ),
        ));
    }
    let r0 = p.grid.lower[0];
    if !(r0 >= 0.0) {
        return Err(cfg(
            "grid.lower[0]",
            format!(
                "x is the radius in geometry '{}': it starts at 0 or above, got {r0}",
                g.name()
            ),
        ));
    }
    Ok(g)
}

/// The regions' shapes and states. A region given by its energy gets the pressure that puts
/// that internal energy into the cells it covers.
fn regions(
    p: &Params,
    grid: &Grid,
    names: &[String],
    mats: &[Material],
) -> SolverResult<Vec<(Shape, RegionState)>> {
    if p.regions.is_empty() {
        return Err(cfg("regions", "at least one region is needed"));
    }
    let geometry = grid.geometry;
    let radial_1d = matches!(geometry, Geometry::Cylindrical | Geometry::Spherical);
    let mut shapes = Vec::new();
    for (ri, r) in p.regions.iter().enumerate() {
        let key = format!("regions[{ri}]");
        // `center` is the radial velocity's centre too, except along a 1-D radius
        shapes.push(shape(&key, r, r.radial_velocity.is_some() && !radial_1d)?);
    }
    // what each region covers, sampled cell by cell: only when a region is given by energy
    let volumes = if p.regions.iter().any(|r| r.energy.is_some()) {
        region_volumes(grid, &shapes)
    } else {
        Vec::new()
    };
    let mut out = Vec::new();
    for ((ri, r), sh) in p.regions.iter().enumerate().zip(shapes) {
        let key = format!("regions[{ri}]");
        let pressure = match (r.pressure, r.energy) {
            (Some(pr), None) => pr,
            (Some(_), Some(_)) => {
                return Err(cfg(
                    format!("{key}.energy"),
                    "give pressure or energy, not both",
                ));
            }
            (None, None) => return Err(cfg(format!("{key}.pressure"), "give pressure or energy")),
            (None, Some(e)) => energy_pressure(&key, r, e, volumes[ri], names, mats)?,
        };
        let velocity = match r.radial_velocity {
            Some(_) if r.velocity != [0.0; 3] => {
                return Err(cfg(
                    format!("{key}.radial_velocity"),
                    "give velocity or radial_velocity, not both",
                ));
            }
            Some(v) if !v.is_finite() => {
                return Err(cfg(
                    format!("{key}.radial_velocity"),
                    format!("must be finite, got {v}"),
                ));
            }
            _ => r.velocity,
        };
        check_velocity(&format!("{key}.velocity"), velocity, geometry)?;
        let mut s = state_of(
            &key,
            names,
            mats,
            &r.material,
            r.density,
            r.temperature,
            pressure,
            velocity,
        )?;
        if let Some(speed) = r.radial_velocity {
            let c = if radial_1d {
                [0.0; 3]
            } else {
                r.center.ok_or_else(|| {
                    cfg(
                        format!("{key}.center"),
                        "required with radial_velocity: the point the flow leaves or meets",
                    )
                })?
            };
            if geometry == Geometry::Axisymmetric && c[0] != 0.0 {
                return Err(cfg(
                    format!("{key}.center"),
                    format!(
                        "a radial flow in axisymmetric geometry is centred on the axis (x = 0), got x = {}",
                        c[0]
                    ),
                ));
            }
            s.radial = Some((speed, c));
        }
        out.push((sh, s));
    }
    Ok(out)
}

/// The pressure at which region `r` (density given) holds internal energy `e` in its
/// covered volume `volume`.
fn energy_pressure(
    key: &str,
    r: &RegionSpec,
    e: f64,
    volume: f64,
    names: &[String],
    mats: &[Material],
) -> SolverResult<f64> {
    if !(e > 0.0) || !e.is_finite() {
        return Err(cfg(
            format!("{key}.energy"),
            format!("must be > 0, got {e}"),
        ));
    }
    let Some(rho) = r.density else {
        return Err(cfg(
            format!("{key}.density"),
            "a region given by its energy needs its density (a temperature needs a pressure)",
        ));
    };
    if !(volume > 0.0) {
        return Err(cfg(
            format!("{key}.energy"),
            "the region covers no cell (it is too small for the grid, or later regions cover it): the energy has nowhere to go",
        ));
    }
    if !(rho > 0.0) || !rho.is_finite() {
        return Err(cfg(
            format!("{key}.density"),
            format!("must be > 0, got {rho}"),
        ));
    }
    // the material's name is checked by `state_of`; an unknown one gets its error there
    let Some(m) = names.iter().position(|n| n == &r.material) else {
        return Ok(f64::NAN);
    };
    let p = mats[m].pressure(rho, e / volume / rho);
    if !(p > mats[m].min_pressure()) || !p.is_finite() {
        return Err(cfg(
            format!("{key}.energy"),
            format!(
                "{e} J in {volume:e} m³ at density {rho} gives pressure {p:e}, not above the material's least {:e}",
                mats[m].min_pressure()
            ),
        ));
    }
    Ok(p)
}

/// A region's or an inflow's velocity must lie in the directions the geometry keeps: the
/// radius alone in 1-D radial geometry, the radius and the axis in axisymmetric geometry
/// (a swirl would need its own equation).
fn check_velocity(key: &str, v: [f64; 3], geometry: Geometry) -> SolverResult<()> {
    let from = match geometry {
        Geometry::Cartesian => return Ok(()),
        Geometry::Cylindrical | Geometry::Spherical => 1,
        Geometry::Axisymmetric => 2,
    };
    if v[from..].iter().any(|&c| c != 0.0) {
        let only = if from == 1 {
            "it is radial: only its x component (along the radius) may be non-zero"
        } else {
            "it has no swirl: its z component must be 0 (x is the radius, y the axis)"
        };
        return Err(cfg(
            key,
            format!("in geometry '{}' {only}, got {v:?}", geometry.name()),
        ));
    }
    Ok(())
}

/// The radial grid's faces: at r = 0 the x_lower face is a symmetry (the default there) or a
/// wall; no direction of a radius is periodic; inflows flow along the radius.
fn radial_boundaries(p: &Params, grid: &Grid, bc: &mut [[Boundary; 2]; 3]) -> SolverResult<()> {
    let name = grid.geometry.name();
    if grid.lower[0] == 0.0 {
        match (&p.boundaries.x_lower, &bc[0][0]) {
            (None, _) => bc[0][0] = Boundary::Symmetry,
            (_, Boundary::Symmetry | Boundary::Wall) => {}
            _ => {
                return Err(cfg(
                    "boundaries.x_lower",
                    format!(
                        "the radius starts at 0 in geometry '{name}': the face there is a symmetry (the default) or a wall"
                    ),
                ));
            }
        }
    }
    if bc[0][0] == Boundary::Periodic {
        return Err(cfg(
            "boundaries.x_lower",
            format!("a radius is not periodic (geometry '{name}')"),
        ));
    }
    let b = &p.boundaries;
    for (key, e) in [
        ("boundaries.x_lower", &b.x_lower),
        ("boundaries.x_upper", &b.x_upper),
        ("boundaries.y_lower", &b.y_lower),
        ("boundaries.y_upper", &b.y_upper),
    ] {
        if let Some(BoundaryEntry::Full(s)) = e
            && let Some(v) = s.velocity
        {
            check_velocity(&format!("{key}.velocity"), v, grid.geometry)?;
        }
    }
    Ok(())
}

/// The sub-cell samples of interior cell (i, j, k), each point with its weight; returns the
/// weights' sum. A sample's weight is its share of the cell's volume: 1 on a Cartesian grid,
/// its radius to the power α in a radial geometry (so cell averages are the volume averages
/// of its ring or shell).
fn samples(grid: &Grid, i: usize, j: usize, k: usize, mut each: impl FnMut([f64; 3], f64)) -> f64 {
    let ns = match grid.nd {
        1 => 8,
        2 => 4,
        _ => 3,
    };
    let x0 = grid.centre(i, j, k);
    let alpha = grid.geometry.alpha() as i32;
    let sub = |d: usize| if d < grid.nd { ns } else { 1 };
    let mut total = 0.0;
    for a in 0..sub(0) {
        for b in 0..sub(1) {
            for c in 0..sub(2) {
                let idx = [a, b, c];
                let mut x = x0;
                for d in 0..grid.nd {
                    x[d] += ((idx[d] as f64 + 0.5) / ns as f64 - 0.5) * grid.dx[d];
                }
                let w = x[0].abs().powi(alpha);
                each(x, w);
                total += w;
            }
        }
    }
    total
}

/// The last region containing x (the first region if none does: it fills the grid).
fn region_at(shapes: &[&Shape], x: [f64; 3], nd: usize) -> usize {
    shapes
        .iter()
        .rposition(|sh| sh.contains(x, nd))
        .unwrap_or(0)
}

/// The volume each region holds once later regions have overwritten theirs.
fn region_volumes(grid: &Grid, shapes: &[Shape]) -> Vec<f64> {
    let shapes: Vec<&Shape> = shapes.iter().collect();
    let mut vol = vec![0.0; shapes.len()];
    let mut cell = vec![0.0; shapes.len()];
    for r in 0..grid.rows() {
        if !grid.interior_row(r) {
            continue;
        }
        let (j, k) = grid.jk(r);
        for i in grid.irange() {
            cell.fill(0.0);
            let total = samples(grid, i, j, k, |x, w| {
                cell[region_at(&shapes, x, grid.nd)] += w;
            });
            let v = grid.volume_at(i);
            for (a, c) in vol.iter_mut().zip(&cell) {
                *a += v * c / total;
            }
        }
    }
    vol
}

/// Build the validated model.
pub fn build(p: &Params) -> SolverResult<Fluid> {
    // grid
    let c = p.grid.cells;
    if c.iter().any(|&n| n < 1) {
        return Err(cfg(
            "grid.cells",
            format!("must be ≥ 1 in every direction, got {c:?} (a grid with zero cells)"),
        ));
    }
    if c[1] == 1 && c[2] > 1 {
        return Err(cfg(
            "grid.cells",
            "a 2-D grid is x-y: use cells = [nx, ny, 1]",
        ));
    }
    if c.iter().map(|&n| n as u128).product::<u128>() > 2_000_000_000 {
        return Err(cfg("grid.cells", format!("{c:?} is too many cells")));
    }
    for d in 0..3 {
        if !(p.grid.upper[d] > p.grid.lower[d]) {
            return Err(cfg(
                "grid.upper",
                format!(
                    "must exceed grid.lower in every direction, got {:?} vs {:?}",
                    p.grid.upper, p.grid.lower
                ),
            ));
        }
    }
    let geometry = geometry(p)?;
    let grid = Grid::radial(
        [c[0] as usize, c[1] as usize, c[2] as usize],
        p.grid.lower,
        p.grid.upper,
        geometry,
    );
    if !(p.cfl > 0.0 && p.cfl <= 1.0) {
        return Err(cfg("cfl", format!("must be in (0, 1], got {}", p.cfl)));
    }
    let limiter = Limiter::parse(&p.limiter).ok_or_else(|| {
        cfg(
            "limiter",
            format!("unknown limiter '{}' (minmod, van_leer, mc)", p.limiter),
        )
    })?;
    // materials
    if p.materials.is_empty() {
        return Err(cfg("materials", "at least one material is needed"));
    }
    if p.materials.len() > 4 {
        return Err(cfg(
            "materials",
            format!("at most 4 materials, got {}", p.materials.len()),
        ));
    }
    let names: Vec<String> = p.materials.keys().cloned().collect();
    let mut mats = Vec::new();
    for (n, m) in &p.materials {
        mats.push(material(n, m)?);
    }
    let nm = mats.len();
    let nv = 2 * nm + 3;
    // Before a byte of state is allocated or a cell sampled: the state arrays (conserved, its
    // copy, primitive, next primitive: nv values a cell; a flux of nv + 1 values a cell per
    // direction) must fit in memory, or a large grid is refused by its key instead of
    // aborting the allocator (or sampling its regions for minutes first).
    let cells = grid.rows() as u128 * grid.mx() as u128;
    let values = (4 * nv + grid.nd * (nv + 1)) as u128;
    protocol::memory::check_fits(
        "grid.cells",
        cells * values * 8,
        &format!("{cells} cells with ghosts × {values} f64 values of state"),
    )?;
    // regions
    let regions = regions(p, &grid, &names, &mats)?;
    // boundaries
    let b = &p.boundaries;
    let mut bc = [
        [
            boundary("boundaries.x_lower", &b.x_lower, &names, &mats)?,
            boundary("boundaries.x_upper", &b.x_upper, &names, &mats)?,
        ],
        [
            boundary("boundaries.y_lower", &b.y_lower, &names, &mats)?,
            boundary("boundaries.y_upper", &b.y_upper, &names, &mats)?,
        ],
        [
            boundary("boundaries.z_lower", &b.z_lower, &names, &mats)?,
            boundary("boundaries.z_upper", &b.z_upper, &names, &mats)?,
        ],
    ];
    if geometry != Geometry::Cartesian {
        radial_boundaries(p, &grid, &mut bc)?;
    }
    for (d, ax) in ["x", "y", "z"].iter().enumerate() {
        let per = [
            bc[d][0] == Boundary::Periodic,
            bc[d][1] == Boundary::Periodic,
        ];
        if per[0] != per[1] {
            return Err(cfg(
                format!("boundaries.{ax}_upper"),
                "periodic must be set on both sides",
            ));
        }
    }
    let phases: Vec<Phase> = mats.iter().cloned().map(Phase::new).collect();
    let total = grid.rows() * nv * grid.mx();
    let mut f = Fluid {
        grid: grid.clone(),
        phases,
        material_names: names.clone(),
        limiter,
        cfl: p.cfl,
        bc,
        nv,
        cons: vec![0.0; total],
        cons0: vec![0.0; total],
        prim: vec![0.0; total],
        prim_next: vec![0.0; total],
        flux: std::array::from_fn(|d| {
            if d < grid.nd {
                vec![0.0; grid.rows() * (nv + 1) * grid.mx()]
            } else {
                Vec::new()
            }
        }),
        x_bound: vec![0.0; grid.rows() * 2 * (nv + 1)],
        row_max: vec![0.0; grid.rows()],
        row_bad: vec![None; grid.rows()],
        time: 0.0,
        steps: 0,
        boundary_impulse: [0.0; 3],
        boundary_work: 0.0,
        probes: Vec::new(),
        edges: Vec::new(),
        immersed: None,
        max_steps_per_window: p.max_steps_per_window.unwrap_or(10_000_000),
        prim_valid: false,
        simd: crate::simd::Simd::detect(),
        // the radial update runs unfused (its weights differ per column)
        fused: geometry == Geometry::Cartesian,
        timing: Default::default(),
    };
    initialise(&mut f, &regions, &mats);
    far_fields(&mut f);
    for (pi, pr) in p.probes.iter().enumerate() {
        let [i, j, k] = grid.locate(pr.position).ok_or_else(|| {
            cfg(
                format!("probes[{pi}].position"),
                format!("{:?} is outside the grid", pr.position),
            )
        })?;
        f.probes.push(Probe {
            name: pr.name.clone(),
            position: pr.position,
            row: grid.row(j, k),
            i,
        });
    }
    for (ei, e) in p.edges.iter().enumerate() {
        let key = |k: &str| format!("edges[{ei}].{k}");
        if e.name.is_empty() || p.edges[..ei].iter().any(|o| o.name == e.name) {
            return Err(cfg(
                key("name"),
                format!("'{}' is empty or given twice", e.name),
            ));
        }
        let m = names.iter().position(|n| n == &e.material).ok_or_else(|| {
            cfg(
                key("material"),
                format!(
                    "unknown material '{}' (defined: {})",
                    e.material,
                    names.join(", ")
                ),
            )
        })?;
        if nm == 1 {
            return Err(cfg(
                key("material"),
                "with one material the grid is all of it: there is no edge to find",
            ));
        }
        let line = crate::edges::EdgeLine::new(&f, &e.name, m, e.from, e.to).ok_or_else(|| {
            cfg(
                key("to"),
                format!(
                    "the line from {:?} to {:?} crosses fewer than two cells of the grid",
                    e.from, e.to
                ),
            )
        })?;
        f.edges.push(line);
    }
    if let Some(im) = &p.immersed {
        if geometry != Geometry::Cartesian {
            return Err(cfg(
                "immersed",
                format!(
                    "an immersed interface needs a Cartesian grid, not geometry '{}'",
                    geometry.name()
                ),
            ));
        }
        if im.interface.is_empty() {
            return Err(cfg("immersed.interface", "must not be empty"));
        }
        let conservative = match im.refill.as_deref() {
            None | Some("average") => false,
            Some("conservative") => true,
            Some(other) => {
                return Err(cfg(
                    "immersed.refill",
                    format!("must be \"average\" or \"conservative\", got \"{other}\""),
                ));
            }
        };
        let mut body = Immersed::new(
            im.interface.clone(),
            im.particles.unwrap_or(0),
            grid.rows() * grid.mx(),
        );
        body.conservative = conservative;
        f.immersed = Some(body);
    }
    Ok(f)
}

/// Conserved state of every interior cell: the volume average over sub-cell samples of the
/// state of the last region containing each sample (smooth volume fractions at curved
/// interfaces).
fn initialise(f: &mut Fluid, regions: &[(Shape, RegionState)], mats: &[Material]) {
    let grid = f.grid.clone();
    let nm = mats.len();
    let nv = f.nv;
    let mx = grid.mx();
    let phases: Vec<Phase> = mats.iter().cloned().map(Phase::new).collect();
    let shapes: Vec<&Shape> = regions.iter().map(|(sh, _)| sh).collect();
    for r in 0..grid.rows() {
        if !grid.interior_row(r) {
            continue;
        }
        let (j, k) = grid.jk(r);
        for i in grid.irange() {
            let mut acc = [0.0; MAXF];
            let total = samples(&grid, i, j, k, |x, w| {
                let s = &regions[region_at(&shapes, x, grid.nd)].1;
                let vel = s.velocity_at(x, grid.geometry, grid.nd);
                // conserved state of the pure material (w is 1 on a Cartesian grid)
                acc[s.mat] += w * s.rho;
                for d in 0..3 {
                    acc[nm + d] += w * (s.rho * vel[d]);
                }
                let rhoe = rhoe_single(&phases[s.mat], s.rho, s.p);
                acc[nm + 3] +=
                    w * (rhoe + 0.5 * s.rho * (vel[0].powi(2) + vel[1].powi(2) + vel[2].powi(2)));
                if s.mat < nm - 1 {
                    acc[nm + 4 + s.mat] += w;
                }
            });
            for (v, a) in acc.iter().enumerate().take(nv) {
                f.cons[(r * nv + v) * mx + i] = a / total;
            }
        }
    }
}

/// σ of a non-reflecting face's relaxation toward its far field (Rudy & Strikwerda, J. Comput.
/// Phys. 36, 1980, find 0.27 the least reflecting; Poinsot & Lele, J. Comput. Phys. 101, 1992,
/// use 0.25–0.58).
const NON_REFLECTING_SIGMA: f64 = 0.25;

/// The far field of each non-reflecting face from the initial state of the cells along it:
/// the impedance ρc averaged over them, and the pressure too where the case gives none.
fn far_fields(f: &mut Fluid) {
    let g = f.grid.clone();
    for d in 0..g.nd {
        for side in 0..2 {
            let Boundary::NonReflecting(far) = f.bc[d][side] else {
                continue;
            };
            // the interior layer along the face: its cells' (row, x index)
            let layer = if side == 0 {
                g.g[d]
            } else {
                g.g[d] + g.n[d] - 1
            };
            let (mut z, mut p, mut n) = (0.0, 0.0, 0.0);
            for r in 0..g.rows() {
                if !g.interior_row(r) {
                    continue;
                }
                let (j, k) = g.jk(r);
                for i in g.irange() {
                    let on = match d {
                        0 => i == layer,
                        1 => j == layer,
                        _ => k == layer,
                    };
                    if on {
                        z += crate::diagnostics::cell_impedance(f, r, i);
                        p += crate::diagnostics::cell_state(f, r, i)[1];
                        n += 1.0;
                    }
                }
            }
            let mut far = far;
            far.impedance = z / n;
            // K Δt of the relaxation K = σ c / L over a step Δt = cfl Δx / c
            far.relax = NON_REFLECTING_SIGMA * f.cfl * g.dx[d] / (g.upper[d] - g.lower[d]);
            if far.pressure.is_nan() {
                far.pressure = p / n;
            }
            f.bc[d][side] = Boundary::NonReflecting(far);
        }
    }
}

fn rhoe_single(ph: &Phase, rho: f64, p: f64) -> f64 {
    mixture::rhoe::<1>(std::array::from_ref(ph), &[rho], &[1.0], p)
}

/// Convenience: params TOML text → model.
pub fn from_toml_str(text: &str) -> SolverResult<Fluid> {
    let t: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| cfg("params", e.to_string()))?;
    build(&parse(&t)?)
}

/// The parameter table (TOML text) of the benchmark case: the 2-D cylindrical
/// blast, p 10 in r < 0.1 and 0.1 outside, ρ 1, γ 1.4, on the unit square with `n`×`n` cells
/// and outflow boundaries. Shared by the CPU and GPU benchmarks and the checksum example.
pub fn benchmark_blast_case(n: usize) -> String {
    format!(
        r#"
        cfl = 0.5
        [grid]
        cells = [{n}, {n}, 1]
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 1.0, 1.0]
        [materials.air]
        eos = "ideal"
        gamma = 1.4
        [[regions]]
        shape = "all"
        material = "air"
        density = 1.0
        pressure = 0.1
        [[regions]]
        shape = "sphere"
        center = [0.5, 0.5, 0.0]
        radius = 0.1
        material = "air"
        density = 1.0
        pressure = 10.0
        [boundaries]
        x_lower = "outflow"
        x_upper = "outflow"
        y_lower = "outflow"
        y_upper = "outflow"
    "#
    )
}

/// [`benchmark_blast_case`] in 3-D: p 10 in a sphere of radius 0.1 at the centre of the
/// unit cube of `n`³ cells, 0.1 outside, ρ 1, γ 1.4, outflow on every side.
pub fn benchmark_blast_case_3d(n: usize) -> String {
    benchmark_blast_case(n)
        .replace(&format!("[{n}, {n}, 1]"), &format!("[{n}, {n}, {n}]"))
        .replace("center = [0.5, 0.5, 0.0]", "center = [0.5, 0.5, 0.5]")
        .replace(
            "y_upper = \"outflow\"",
            "y_upper = \"outflow\"\n        z_lower = \"outflow\"\n        z_upper = \"outflow\"",
        )
}

/// Air (ideal, γ 1.4) and TNT detonation products (JWL: the constants of
/// examples/steel_tube.toml) as a case's `[materials]` block (TOML text), for the
/// multi-material benchmarks and tests.
pub const TNT_AND_AIR: &str = r#"
        [materials.air]
        eos = "ideal"
        gamma = 1.4
        [materials.tnt]
        eos = "jwl"
        rho0 = 1630.0
        a = 3.712e11
        b = 3.21e9
        r1 = 4.15
        r2 = 0.95
        omega = 0.3
        e0 = 6.9927e9"#;

/// The multi-material blast of the benchmarks: a TNT charge (JWL products at their loading
/// density, 1630 kg/m³, and the JWL pressure of that density and 6.99 GJ/m³, 8.38 GPa) of
/// radius 0.05 m at the centre of a 1 m square of air at 1 bar (`n`² cells, outflow on every
/// side): two materials, seven variables per cell, and the JWL curve's exponentials in
/// every cell that holds products.
pub fn benchmark_tnt_case(n: usize) -> String {
    format!(
        r#"
        cfl = 0.5
        [grid]
        cells = [{n}, {n}, 1]
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 1.0, 0.01]
        {TNT_AND_AIR}
        [[regions]]
        shape = "all"
        material = "air"
        density = 1.2
        pressure = 1.0e5
        [[regions]]
        shape = "sphere"
        center = [0.5, 0.5, 0.005]
        radius = 0.05
        material = "tnt"
        density = 1630.0
        pressure = 8.3759e9
        [boundaries]
        x_lower = "outflow"
        x_upper = "outflow"
        y_lower = "outflow"
        y_upper = "outflow"
    "#
    )
}

/// The parameter table (TOML text) of Sod's shock tube (the README's case sections "Fluid node"): γ 1.4,
/// (ρ, u, p) = (1, 0, 1) left of x 0.5 and (0.125, 0, 0.1) right of it, `n` cells on [0, 1],
/// outflow ends, the given TVD limiter. Shared by the verification and GPU tests.
pub fn sod_case(n: usize, limiter: &str) -> String {
    format!(
        r#"
        cfl = 0.5
        limiter = "{limiter}"
        [grid]
        cells = [{n}, 1, 1]
        lower = [0.0, 0.0, 0.0]
        upper = [1.0, 1.0, 1.0]
        [materials.gas]
        eos = "ideal"
        gamma = 1.4
        [[regions]]
        shape = "all"
        material = "gas"
        density = 0.125
        pressure = 0.1
        [[regions]]
        shape = "box"
        lower = [0.0, 0.0, 0.0]
        upper = [0.5, 1.0, 1.0]
        material = "gas"
        density = 1.0
        pressure = 1.0
        [boundaries]
        x_lower = "outflow"
        x_upper = "outflow"
    "#
    )
}
