//! Bad input is refused with the key path, and a state that goes negative
//! during a run stops the node with the cell, the time and the variable.

use fluid_node::factory;
use protocol::{Inbox, Outbox, Solver, SolverError, Window};

const BASE: &str = r#"
cfl = 0.5
[grid]
cells = [20, 1, 1]
lower = [0.0, 0.0, 0.0]
upper = [1.0, 1.0, 1.0]
[materials.air]
eos = "ideal"
gamma = 1.4
[[regions]]
shape = "all"
material = "air"
density = 1.0
pressure = 1.0
"#;

fn build(text: &str) -> Result<Box<dyn Solver>, SolverError> {
    let t: toml::Table = text.parse().expect("test TOML parses");
    factory("euler", &t)
}

fn refused(text: &str) -> (String, String) {
    match build(text) {
        Err(SolverError::Config { key, reason }) => (key, reason),
        Err(e) => panic!("wrong error kind: {e}"),
        Ok(_) => panic!("accepted bad input:\n{text}"),
    }
}

#[test]
fn good_input_is_accepted() {
    assert!(build(BASE).is_ok());
}

#[test]
fn negative_density_is_refused() {
    let (k, r) = refused(&BASE.replace("density = 1.0", "density = -1.0"));
    assert_eq!(k, "regions[0].density");
    assert!(r.contains("-1"), "{r}");
}

#[test]
fn negative_pressure_is_refused() {
    let (k, r) = refused(&BASE.replace("pressure = 1.0", "pressure = -2.0"));
    assert_eq!(k, "regions[0].pressure");
    assert!(r.contains("-2"), "{r}");
}

#[test]
fn unknown_material_is_refused() {
    let (k, r) = refused(&BASE.replace("material = \"air\"", "material = \"argon\""));
    assert_eq!(k, "regions[0].material");
    assert!(r.contains("argon"), "{r}");
}

#[test]
fn cfl_above_one_is_refused() {
    let (k, r) = refused(&BASE.replace("cfl = 0.5", "cfl = 1.5"));
    assert_eq!(k, "cfl");
    assert!(r.contains("1.5"), "{r}");
}

#[test]
fn an_unknown_immersed_refill_is_refused() {
    let ok = format!("{BASE}[immersed]\ninterface = \"particles\"\nrefill = \"conservative\"\n");
    assert!(build(&ok).is_ok());
    let (k, r) = refused(&ok.replace("\"conservative\"", "\"mean\""));
    assert_eq!(k, "immersed.refill");
    assert!(r.contains("\"average\" or \"conservative\""), "{r}");
}

#[test]
fn zero_cells_are_refused() {
    let (k, _) = refused(&BASE.replace("cells = [20, 1, 1]", "cells = [0, 1, 1]"));
    assert_eq!(k, "grid.cells");
}

#[test]
fn unknown_key_is_refused() {
    let (k, r) = refused(&BASE.replace("cfl = 0.5", "cfl = 0.5\nvicosity = 1.0"));
    assert_eq!(k, "vicosity");
    assert!(r.starts_with("unknown key"), "{r}");
}

#[test]
fn unknown_model_is_refused() {
    let t: toml::Table = BASE.parse().expect("parses");
    match factory("navier", &t) {
        Err(SolverError::Config { key, .. }) => assert_eq!(key, "model"),
        _ => panic!("unknown model accepted"),
    }
}

/// A cell whose energy is corrupted below its kinetic energy (negative pressure) during a
/// run: the next window fails with Diverged naming cell, time and variable, not NaNs.
#[test]
fn negative_state_during_run_stops_with_cell_time_variable() {
    let mut s = fluid_node::setup::from_toml_str(BASE)
        .map(fluid_node::EulerSolver::from_fluid)
        .expect("builds");
    let (inbox, mut out) = (Inbox::new(), Outbox::new());
    let w1 = Window {
        index: 1,
        t0: 0.0,
        t1: 0.01,
        write_output: false,
    };
    s.advance(&w1, &inbox, &mut out).expect("first window");
    let f = &mut s.fluid;
    let (mx, nv) = (f.grid.mx(), f.nv);
    let r = f.grid.row(0, 0);
    let i = f.grid.g[0] + 7;
    f.cons[(r * nv + 4) * mx + i] = -1.0; // E < 0 ⇒ p < 0
    f.prim_valid = false;
    let w2 = Window {
        index: 2,
        t0: 0.01,
        t1: 0.02,
        write_output: false,
    };
    match s.advance(&w2, &inbox, &mut out) {
        Err(SolverError::Diverged { time, reason }) => {
            println!("{reason}");
            assert!((time - 0.01).abs() < 1e-12);
            assert!(reason.contains("cell (7, 0, 0)"), "{reason}");
            assert!(reason.contains("pressure"), "{reason}");
        }
        other => panic!("expected Diverged, got {other:?}"),
    }
}

/// A radial set-up that cannot run is refused by the key that makes it so.
#[test]
fn radial_set_ups_are_refused_by_key() {
    let sph = |s: &str| format!("geometry = \"spherical\"\n{BASE}\n{s}");
    let extra_region = |s: &str| {
        format!(
            "[[regions]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = 0.2\nmaterial = \"air\"\ndensity = 1.0\n{s}"
        )
    };
    let cases: Vec<(String, &str, &str)> = vec![
        (
            format!("geometry = \"conical\"\n{BASE}"),
            "geometry",
            "unknown geometry",
        ),
        (
            format!(
                "geometry = \"spherical\"\n{}",
                BASE.replace("[20, 1, 1]", "[20, 20, 1]")
            ),
            "grid.cells",
            "1-D grid",
        ),
        (
            format!("geometry = \"axisymmetric\"\n{BASE}"),
            "grid.cells",
            "2-D grid",
        ),
        (
            sph("").replace("lower = [0.0, 0.0, 0.0]", "lower = [-0.5, 0.0, 0.0]"),
            "grid.lower[0]",
            "starts at 0",
        ),
        (
            sph("[boundaries]\nx_lower = \"outflow\""),
            "boundaries.x_lower",
            "symmetry",
        ),
        (
            sph(
                "[boundaries]\nx_upper = { kind = \"inflow\", material = \"air\", density = 1.0, pressure = 1.0, velocity = [0.0, 2.0, 0.0] }",
            ),
            "boundaries.x_upper.velocity",
            "only its x component",
        ),
        (
            sph("").replace(
                "pressure = 1.0\n",
                "pressure = 1.0\nvelocity = [0.0, 1.0, 0.0]\n",
            ),
            "regions[0].velocity",
            "only its x component",
        ),
        (
            BASE.replace(
                "pressure = 1.0\n",
                "pressure = 1.0\nradial_velocity = -1.0\n",
            ),
            "regions[0].center",
            "required with radial_velocity",
        ),
        (
            format!(
                "geometry = \"axisymmetric\"\n{}",
                BASE.replace("[20, 1, 1]", "[20, 20, 1]").replace(
                    "pressure = 1.0\n",
                    "pressure = 1.0\nradial_velocity = -1.0\ncenter = [0.5, 0.0, 0.0]\n"
                )
            ),
            "regions[0].center",
            "on the axis",
        ),
        (
            sph("").replace(
                "pressure = 1.0\n",
                "pressure = 1.0\nradial_velocity = -1.0\nvelocity = [1.0, 0.0, 0.0]\n",
            ),
            "regions[0].radial_velocity",
            "not both",
        ),
        (
            sph(&extra_region("pressure = 2.0\nenergy = 1.0")),
            "regions[1].energy",
            "not both",
        ),
        (
            sph(&extra_region("")),
            "regions[1].pressure",
            "pressure or energy",
        ),
        (
            sph(&extra_region("energy = -1.0")),
            "regions[1].energy",
            "must be > 0",
        ),
        (
            sph(&extra_region("energy = 1.0").replace("density = 1.0\n", "density = -2.0\n")),
            "regions[1].density",
            "must be > 0",
        ),
        (
            sph(&extra_region("energy = 1.0").replace("density = 1.0\n", "temperature = 300.0\n")),
            "regions[1].density",
            "needs its density",
        ),
        (
            sph(&extra_region(
                "energy = 1.0\n[[regions]]\nshape = \"all\"\nmaterial = \"air\"\ndensity = 1.0\npressure = 1.0",
            )),
            "regions[1].energy",
            "covers no cell",
        ),
        (
            sph("[immersed]\ninterface = \"particles\""),
            "immersed",
            "Cartesian grid",
        ),
        (
            format!("device = \"gpu\"\n{}", sph("")),
            "device",
            "geometry 'spherical'",
        ),
    ];
    for (text, key, words) in &cases {
        let (k, r) = refused(text);
        println!("{k}: {r}");
        assert_eq!(&k, key, "{r}\n{text}");
        assert!(r.contains(words), "{key}: '{r}' lacks '{words}'");
    }
    println!("{} radial set-ups refused", cases.len());
}

/// A non-reflecting face takes the far field's pressure and velocity and nothing else, and
/// those finite.
#[test]
fn non_reflecting_faces_are_refused_by_key_where_they_cannot_run() {
    let cases = [
        (
            format!(
                "{BASE}\n[boundaries]\nx_upper = {{ kind = \"non_reflecting\", density = 1.0 }}"
            ),
            "boundaries.x_upper.density",
            "far field's pressure and velocity",
        ),
        (
            format!(
                "{BASE}\n[boundaries]\nx_upper = {{ kind = \"non_reflecting\", pressure = nan }}"
            ),
            "boundaries.x_upper.pressure",
            "finite",
        ),
    ];
    for (text, key, words) in &cases {
        let (k, r) = refused(text);
        println!("{k}: {r}");
        assert_eq!(&k, key, "{r}");
        assert!(r.contains(words), "{key}: '{r}' lacks '{words}'");
    }
    assert!(
        build(&format!(
            "{BASE}\n[boundaries]\nx_upper = {{ kind = \"non_reflecting\", pressure = 1.0 }}"
        ))
        .is_ok()
    );
}

/// An edge line names a material of two or more, and crosses the grid.
#[test]
fn edge_lines_are_refused_by_key() {
    let two = BASE.replace(
        "[materials.air]",
        "[materials.helium]\neos = \"ideal\"\ngamma = 1.67\n[materials.air]",
    );
    let line = |m: &str, to: &str| {
        format!("[[edges]]\nname = \"b\"\nmaterial = \"{m}\"\nfrom = [0.0, 0.5, 0.5]\nto = {to}\n")
    };
    let cases = [
        (
            format!("{BASE}\n{}", line("air", "[1.0, 0.5, 0.5]")),
            "edges[0].material",
            "no edge to find",
        ),
        (
            format!("{two}\n{}", line("water", "[1.0, 0.5, 0.5]")),
            "edges[0].material",
            "unknown material 'water'",
        ),
        (
            format!("{two}\n{}", line("helium", "[0.01, 0.5, 0.5]")),
            "edges[0].to",
            "fewer than two cells",
        ),
        (
            format!(
                "{two}\n{}\n{}",
                line("helium", "[1.0, 0.5, 0.5]"),
                line("air", "[1.0, 0.5, 0.5]")
            ),
            "edges[1].name",
            "given twice",
        ),
    ];
    for (text, key, words) in &cases {
        let (k, r) = refused(text);
        println!("{k}: {r}");
        assert_eq!(&k, key, "{r}");
        assert!(r.contains(words), "{key}: '{r}' lacks '{words}'");
    }
    assert!(build(&format!("{two}\n{}", line("helium", "[1.0, 0.5, 0.5]"))).is_ok());
}
