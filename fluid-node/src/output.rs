//! Output for ParaView and plots: one VTK rectilinear grid (legacy binary `.vtk`, written with
//! `vtkio`; ParaView, VisIt and meshio all read it, where meshio cannot read XML `.vtr`) per
//! output window with cell fields density, pressure, velocity (3 components), temperature
//! (when every material has a gas constant) and the volume fraction of each material, a
//! `.pvd` collection indexing them by time, and probe time histories as CSV.
//!
//! A rectilinear grid (not image data) because vtkio stores an image's origin and spacing as
//! f32; the rectilinear node coordinates are written in f64, so SI geometry keeps full
//! precision. A 2-D grid is written as one layer of cells of the grid's z thickness.

use crate::diagnostics::cell_prim;
use crate::eos::Eos;
use crate::model::Fluid;
use node_kit::vtk::{self, Frame};
use protocol::{SolverError, SolverResult};
use std::path::Path;
use vtkio::model::{
    Attribute, Attributes, Coordinates, DataArray, DataSet, ElementType, Extent,
    RectilinearGridPiece,
};

/// File name of the VTK file of output window `window`.
pub fn vtk_file_name(window: u64) -> String {
    format!("fluid_{window:06}.vtk")
}

/// Thermal constants of a phase for the mixture temperature: (R_k, p_∞,k) from the EOS's
/// temperature relation T = (p + p_∞)/(ρ R) (ideal gas: p_∞ = 0); `None` without one.
fn thermal(eos: &impl Eos) -> Option<(f64, f64)> {
    let t1 = eos.temperature(1.0, 1.0)?;
    let t0 = eos.temperature(1.0, 0.0)?;
    let r = 1.0 / (t1 - t0);
    (r.is_finite() && r > 0.0).then_some((r, t0 * r))
}

/// The cell fields written to VTK, in x-fastest order over the interior cells:
/// (name, components, values). Temperature in thermal equilibrium of the phases,
/// T = (p + Σ α_k p_∞,k) / Σ α_kρ_k R_k (exact for a single-material cell).
pub fn cell_fields(f: &Fluid) -> Vec<(String, usize, Vec<f64>)> {
    let g = &f.grid;
    let n = g.cells();
    let nm = f.nmat();
    let mut rho = Vec::with_capacity(n);
    let mut p = Vec::with_capacity(n);
    let mut vel = Vec::with_capacity(3 * n);
    let mut temp = Vec::with_capacity(n);
    let mut alpha: Vec<Vec<f64>> = vec![Vec::with_capacity(n); nm];
    let consts: Option<Vec<(f64, f64)>> = f.phases.iter().map(|ph| thermal(&ph.eos)).collect();
    for k in g.g[2]..g.g[2] + g.n[2] {
        for j in g.g[1]..g.g[1] + g.n[1] {
            let r = g.row(j, k);
            for i in g.irange() {
                let (rh, v, pr, al) = cell_prim(f, r, i);
                rho.push(rh);
                p.push(pr);
                vel.extend_from_slice(&v);
                for (m, a) in al.iter().enumerate() {
                    alpha[m].push(*a);
                }
                if let Some(c) = &consts {
                    let (mut num, mut den) = (pr, 0.0);
                    for (m, (rk, pinf)) in c.iter().enumerate() {
                        let ark = f.cons[(r * f.nv + m) * g.mx() + i].max(0.0);
                        den += ark * rk;
                        num += al[m] * pinf;
                    }
                    temp.push(if den > 0.0 { num / den } else { 0.0 });
                }
            }
        }
    }
    let mut out = vec![
        ("density".to_string(), 1, rho),
        ("pressure".to_string(), 1, p),
        ("velocity".to_string(), 3, vel),
    ];
    if consts.is_some() {
        out.push(("temperature".to_string(), 1, temp));
    }
    for (m, a) in alpha.into_iter().enumerate() {
        out.push((format!("alpha_{}", f.material_names[m]), 1, a));
    }
    out
}

/// Write `fluid_<window>.vtk` under `dir` and list it in `fluid.pvd` (the node kit's series).
pub fn write_vtk(f: &Fluid, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
    let g = &f.grid;
    let coords = |d: usize| -> Vec<f64> {
        (0..=g.n[d])
            .map(|i| g.lower[d] + i as f64 * g.dx[d])
            .collect()
    };
    let cell = cell_fields(f)
        .into_iter()
        .map(|(name, comps, values)| {
            let elem = if comps == 3 {
                ElementType::Vectors
            } else {
                ElementType::Scalars {
                    num_comp: comps as u32,
                    lookup_table: None,
                }
            };
            Attribute::DataArray(DataArray {
                name,
                elem,
                data: values.into(),
            })
        })
        .collect();
    let [nx, ny, nz] = [g.n[0] as i32, g.n[1] as i32, g.n[2] as i32];
    let extent = Extent::Ranges([0..=nx, 0..=ny, 0..=nz]);
    let data = DataSet::inline(RectilinearGridPiece {
        extent,
        coords: Coordinates {
            x: coords(0).into(),
            y: coords(1).into(),
            z: coords(2).into(),
        },
        data: Attributes {
            point: Vec::new(),
            cell,
        },
    });
    let frame = Frame {
        dir,
        stem: "fluid",
        window,
        time: t,
    };
    vtk::write_legacy(&frame, data)?;
    Ok(())
}

/// Probe histories as CSV: time, then ρ, p, u, v, w for each probe.
/// `edges.csv`: per window the time and each edge line's first and last edge (m along it).
pub fn write_edges(f: &Fluid, hist: &[(f64, Vec<[f64; 2]>)], dir: &Path) -> SolverResult<()> {
    if f.edges.is_empty() {
        return Ok(());
    }
    let mut header = vec!["time".to_string()];
    for e in &f.edges {
        header.push(format!("{}.first", e.name));
        header.push(format!("{}.last", e.name));
    }
    let rows = hist
        .iter()
        .map(|(t, vals)| std::iter::once(*t).chain(vals.iter().flatten().copied()));
    node_kit::table::write_csv(&dir.join("edges.csv"), &header, rows).map_err(SolverError::from)
}

pub fn write_probes(f: &Fluid, hist: &[(f64, Vec<[f64; 5]>)], dir: &Path) -> SolverResult<()> {
    if f.probes.is_empty() {
        return Ok(());
    }
    let mut header = vec!["time".to_string()];
    for p in &f.probes {
        for q in ["density", "pressure", "u", "v", "w"] {
            header.push(format!("{}.{q}", p.name));
        }
    }
    let rows = hist
        .iter()
        .map(|(t, vals)| std::iter::once(*t).chain(vals.iter().flatten().copied()));
    node_kit::table::write_csv(&dir.join("probes.csv"), &header, rows).map_err(SolverError::from)
}
