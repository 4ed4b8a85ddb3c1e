//! Output files ("VTK output (`vtkio`) of ρ, p, u, T, material
//! fraction; probe time histories to CSV").
//!
//! 1. A 2-D air/water grid (regions aligned with cell faces, so every cell holds one
//!    material, given by temperature and pressure) written at t = 0 and read back with vtkio:
//!    the file is a rectilinear grid with the grid's extent and node coordinates; the cell
//!    arrays are density, pressure, velocity (3 components), temperature, alpha_air,
//!    alpha_water with one value (three for velocity) per cell; in each material the
//!    density equals p/(R T) (air, ideal) or (p + p∞)/(R T) (water, stiffened), the
//!    temperature the prescribed one, pressure and velocity the prescribed ones, the
//!    fractions 1 and 0. After a window of flow, every array read back equals the solver's
//!    own cell states (`diagnostics::cell_prim`) exactly (f64 round trip).
//! 2. Probe histories: three windows of a Sod tube with two probes; `probes.csv` has the
//!    columns time, <probe>.density, .pressure, .u, .v, .w per probe, one row per window at
//!    the window end times, and the last row equals the state of the cell containing each
//!    probe (located here from its position and the grid spacing).

use fluid_node::EulerSolver;
use fluid_node::diagnostics::cell_prim;
use fluid_node::setup;
use protocol::{Inbox, Outbox, Solver, Window};
use std::path::PathBuf;
use vtkio::model::{Attribute, DataSet, IOBuffer, Piece};

fn solver(text: &str) -> EulerSolver {
    match setup::from_toml_str(text) {
        Ok(f) => EulerSolver::from_fluid(f),
        Err(e) => panic!("set-up failed: {e}"),
    }
}

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("fluid_node_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// Cell arrays read back: (name, components, values).
type Arrays = Vec<(String, usize, Vec<f64>)>;

/// (coords x, y, z; cell arrays) of a fluid VTK file.
fn read_vtr(path: &std::path::Path) -> ([Vec<f64>; 3], Arrays) {
    let vtk = vtkio::Vtk::import(path).expect("vtkio reads the file back");
    let DataSet::RectilinearGrid { pieces, .. } = vtk.data else {
        panic!("not a rectilinear grid")
    };
    assert_eq!(pieces.len(), 1);
    let Piece::Inline(piece) = pieces.into_iter().next().expect("one piece") else {
        panic!("piece not inline")
    };
    let f64s = |b: IOBuffer| b.cast_into::<f64>().expect("numeric buffer");
    let coords = [
        f64s(piece.coords.x),
        f64s(piece.coords.y),
        f64s(piece.coords.z),
    ];
    let mut arrays = Vec::new();
    for a in piece.data.cell {
        match a {
            Attribute::DataArray(d) => {
                let comps = d.num_comp();
                arrays.push((d.name.clone(), comps, f64s(d.data)));
            }
            Attribute::Field { name, .. } => panic!("unexpected field attribute {name}"),
        }
    }
    (coords, arrays)
}

#[test]
fn vtk_output_reads_back_with_vtkio() {
    let (nx, ny) = (12, 6);
    let (r_air, r_w, pinf) = (287.0, 1500.0, 6.0e8);
    let (t_air, t_w, p0) = (300.0, 290.0, 2.0e5);
    let mut s = solver(&format!(
        r#"
        cfl = 0.4
        [grid]
        cells = [{nx}, {ny}, 1]
        lower = [-0.3, 0.1, 0.0]
        upper = [0.9, 0.7, 0.05]
        [materials.air]
        eos = "ideal"
        gamma = 1.4
        gas_constant = {r_air}
        [materials.water]
        eos = "stiffened"
        gamma = 4.4
        p_inf = {pinf}
        gas_constant = {r_w}
        [[regions]]
        shape = "all"
        material = "air"
        temperature = {t_air}
        pressure = {p0}
        velocity = [20.0, -5.0, 0.0]
        [[regions]]
        shape = "box"
        lower = [0.3, 0.1, 0.0]
        upper = [0.9, 0.7, 0.05]
        material = "water"
        temperature = {t_w}
        pressure = {p0}
        velocity = [20.0, -5.0, 0.0]
        [boundaries]
        x_lower = "outflow"
        x_upper = "outflow"
        y_lower = "outflow"
        y_upper = "outflow"
    "#
    ));
    let dir = out_dir("vtk");
    s.write_output(0.0, 0, &dir).expect("write at t = 0");
    let path = dir.join(fluid_node::output::vtk_file_name(0));
    let (coords, arrays) = read_vtr(&path);
    // geometry: node coordinates of the grid
    assert_eq!(coords[0].len(), nx + 1);
    assert_eq!(coords[1].len(), ny + 1);
    assert_eq!(coords[2].len(), 2);
    assert!((coords[0][0] + 0.3).abs() < 1e-15 && (coords[0][nx] - 0.9).abs() < 1e-15);
    assert!((coords[1][0] - 0.1).abs() < 1e-15 && (coords[1][ny] - 0.7).abs() < 1e-15);
    assert!((coords[2][1] - 0.05).abs() < 1e-15);
    let names: Vec<&str> = arrays.iter().map(|a| a.0.as_str()).collect();
    assert_eq!(
        names,
        [
            "density",
            "pressure",
            "velocity",
            "temperature",
            "alpha_air",
            "alpha_water"
        ]
    );
    let n = nx * ny;
    for (name, comps, v) in &arrays {
        let want = if name == "velocity" { 3 } else { 1 };
        assert_eq!(*comps, want, "{name} components");
        assert_eq!(v.len(), want * n, "{name} length");
    }
    let get = |name: &str| &arrays.iter().find(|a| a.0 == name).expect(name).2;
    let (rho, p, vel, temp) = (
        get("density"),
        get("pressure"),
        get("velocity"),
        get("temperature"),
    );
    let (a_air, a_w) = (get("alpha_air"), get("alpha_water"));
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    let mut worst = 0.0_f64;
    for j in 0..ny {
        for i in 0..nx {
            let c = i + nx * j;
            let water = i >= nx / 2;
            let (rho_ex, t_ex) = if water {
                ((p0 + pinf) / (r_w * t_w), t_w)
            } else {
                (p0 / (r_air * t_air), t_air)
            };
            worst = worst
                .max(rel(rho[c], rho_ex))
                .max(rel(temp[c], t_ex))
                .max(rel(p[c], p0))
                .max(rel(vel[3 * c], 20.0))
                .max(rel(vel[3 * c + 1], -5.0));
            assert_eq!(vel[3 * c + 2], 0.0);
            let (aa, aw) = if water { (0.0, 1.0) } else { (1.0, 0.0) };
            assert!((a_air[c] - aa).abs() < 1e-15 && (a_w[c] - aw).abs() < 1e-15);
        }
    }
    println!("VTK at t = 0: largest relative deviation from the prescribed state {worst:.2e}");
    assert!(worst < 1e-9, "initial state in the file: {worst}");

    // one window of flow, then every array equals the solver's cell states
    let (inbox, mut outbox) = (Inbox::new(), Outbox::new());
    let w = Window {
        index: 1,
        t0: 0.0,
        t1: 2.0e-5,
        write_output: true,
    };
    s.advance(&w, &inbox, &mut outbox).expect("window");
    s.write_output(w.t1, 1, &dir).expect("write");
    let (_, arrays) = read_vtr(&dir.join(fluid_node::output::vtk_file_name(1)));
    let get = |name: &str| &arrays.iter().find(|a| a.0 == name).expect(name).2;
    let f = &s.fluid;
    let g = &f.grid;
    let mut moved = false;
    for j in 0..ny {
        for i in 0..nx {
            let c = i + nx * j;
            let (r, v, pr, al) = cell_prim(f, g.row(j + g.g[1], 0), i + g.g[0]);
            assert_eq!(get("density")[c], r);
            assert_eq!(get("pressure")[c], pr);
            for (d, vd) in v.iter().enumerate() {
                assert_eq!(get("velocity")[3 * c + d], *vd);
            }
            assert_eq!(get("alpha_air")[c], al[0]);
            assert_eq!(get("alpha_water")[c], al[1]);
            moved |= al[0] > 0.0 && al[0] < 1.0;
        }
    }
    assert!(moved, "the interface should have smeared into mixed cells");
    let pvd = std::fs::read_to_string(dir.join("fluid.pvd")).expect("pvd");
    assert_eq!(pvd.matches("<DataSet").count(), 2);
    assert!(pvd.contains(&fluid_node::output::vtk_file_name(1)));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn probe_history_csv() {
    // Sod's tube (50 cells) with two probes.
    let mut s = solver(&format!(
        r#"{}
        [[probes]]
        name = "left"
        position = [0.43, 0.5, 0.5]
        [[probes]]
        name = "right"
        position = [0.71, 0.5, 0.5]
    "#,
        setup::sod_case(50, "van_leer")
    ));
    let (inbox, mut outbox) = (Inbox::new(), Outbox::new());
    let win = 0.05;
    for k in 1..=3u64 {
        let w = Window {
            index: k,
            t0: (k - 1) as f64 * win,
            t1: k as f64 * win,
            write_output: false,
        };
        s.advance(&w, &inbox, &mut outbox).expect("window");
    }
    let dir = out_dir("probes");
    s.write_output(3.0 * win, 3, &dir).expect("write");
    let text = std::fs::read_to_string(dir.join("probes.csv")).expect("probes.csv");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let mut want = vec!["time".to_string()];
    for p in ["left", "right"] {
        for q in ["density", "pressure", "u", "v", "w"] {
            want.push(format!("{p}.{q}"));
        }
    }
    assert_eq!(header, want);
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|x| x.parse::<f64>().expect("number"))
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), 3);
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row.len(), 11);
        assert!(
            (row[0] - (k + 1) as f64 * win).abs() < 1e-15,
            "time {}",
            row[0]
        );
    }
    // the probed cells: x = 0.43 → cell 21, x = 0.71 → cell 35 (dx = 0.02)
    let f = &s.fluid;
    let g = &f.grid;
    let last = &rows[2];
    for (pi, x) in [0.43_f64, 0.71].iter().enumerate() {
        let i = (x / g.dx[0]).floor() as usize;
        let (rho, v, p, _) = cell_prim(f, g.row(0, 0), i + g.g[0]);
        let col = 1 + 5 * pi;
        assert_eq!(last[col], rho, "probe {pi} density");
        assert_eq!(last[col + 1], p, "probe {pi} pressure");
        assert_eq!(last[col + 2], v[0], "probe {pi} u");
        assert_eq!(last[col + 3], 0.0);
        assert_eq!(last[col + 4], 0.0);
    }
    // physics at t = 0.15: the left probe (its cell centre x = 0.43) sits in the rarefaction
    // fan, ρ = (c/c_L)^(2/(γ-1)) with c = 2/(γ+1) (c_L - (γ-1)/2 ξ), ξ = (x - 0.5)/t; the
    // right one between contact (x 0.639) and shock (x 0.763): the star state ρ*R = 0.26557
    let (gm, cl) = (1.4_f64, 1.4_f64.sqrt());
    let xi = (0.43 - 0.5) / 0.15;
    let c = 2.0 / (gm + 1.0) * (cl - 0.5 * (gm - 1.0) * xi);
    let rho_fan = (c / cl).powf(2.0 / (gm - 1.0));
    println!(
        "probes at t = 0.15: left ρ {:.4} (exact {rho_fan:.4}), right ρ {:.4} (exact 0.26557)",
        last[1], last[6]
    );
    assert!(
        (last[1] / rho_fan - 1.0).abs() < 0.05,
        "left probe density {}",
        last[1]
    );
    assert!(
        (last[6] / 0.26557 - 1.0).abs() < 0.1,
        "right probe density {}",
        last[6]
    );
    let _ = std::fs::remove_dir_all(&dir);
}
