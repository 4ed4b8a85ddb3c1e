//! Output for ParaView and plots: VTK image data (cell fields ρ, p, u, T, volume fractions)
//! per window with a `.pvd` time series, and probe time histories as CSV.

use crate::diagnostics::cell_prim;
use crate::eos::Eos;
use crate::model::Fluid;
use protocol::{SolverError, SolverResult};
use std::fmt::Write as _;
use std::path::Path;

/// Write `fluid_<window>.vti` under `dir` and refresh `fluid.pvd`.
pub fn write_vtk(f: &Fluid, t: f64, window: u64, dir: &Path) -> SolverResult<()> {
    std::fs::create_dir_all(dir)?;
    let g = &f.grid;
    let n = g.cells();
    let nm = f.nmat();
    let mut rho = Vec::with_capacity(n);
    let mut p = Vec::with_capacity(n);
    let mut vel = Vec::with_capacity(3 * n);
    let mut temp = Vec::with_capacity(n);
    let mut alpha: Vec<Vec<f64>> = vec![Vec::with_capacity(n); nm];
    let all_thermal = f
        .phases
        .iter()
        .all(|ph| ph.eos.temperature(1.0, 1.0).is_some());
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
                if all_thermal {
                    // mixture temperature: p / Σ α_kρ_k R_k with R_k = p/(ρ_k T_k) per phase
                    let mut rr = 0.0;
                    for (m, ph) in f.phases.iter().enumerate() {
                        let ark = f.cons[(r * f.nv + m) * g.mx() + i].max(0.0);
                        if let Some(tk) = ph.eos.temperature(1.0, 1.0) {
                            // T(ρ=1, p=1) = 1/R for ideal gases
                            rr += ark / tk;
                        }
                    }
                    temp.push(if rr > 0.0 { pr / rr } else { 0.0 });
                }
            }
        }
    }
    let name = format!("fluid_{window:06}.vti");
    let mut s = String::new();
    let ext = format!("0 {} 0 {} 0 {}", g.n[0], g.n[1], g.n[2]);
    let _ = writeln!(s, "<?xml version=\"1.0\"?>");
    let _ = writeln!(
        s,
        "<VTKFile type=\"ImageData\" version=\"0.1\" byte_order=\"LittleEndian\">"
    );
    let _ = writeln!(
        s,
        "<ImageData WholeExtent=\"{ext}\" Origin=\"{} {} {}\" Spacing=\"{} {} {}\">",
        g.lower[0], g.lower[1], g.lower[2], g.dx[0], g.dx[1], g.dx[2]
    );
    let _ = writeln!(
        s,
        "<Piece Extent=\"{ext}\">\n<CellData Scalars=\"density\" Vectors=\"velocity\">"
    );
    let arr = |s: &mut String, name: &str, comps: usize, v: &[f64]| {
        let _ = write!(
            s,
            "<DataArray type=\"Float64\" Name=\"{name}\" NumberOfComponents=\"{comps}\" format=\"ascii\">"
        );
        for x in v {
            let _ = write!(s, "{x:e} ");
        }
        let _ = writeln!(s, "</DataArray>");
    };
    arr(&mut s, "density", 1, &rho);
    arr(&mut s, "pressure", 1, &p);
    arr(&mut s, "velocity", 3, &vel);
    if all_thermal {
        arr(&mut s, "temperature", 1, &temp);
    }
    for (m, a) in alpha.iter().enumerate() {
        arr(&mut s, &format!("alpha_{}", f.material_names[m]), 1, a);
    }
    let _ = writeln!(s, "</CellData>\n</Piece>\n</ImageData>\n</VTKFile>");
    std::fs::write(dir.join(&name), s)?;
    // time series: append to the list of written files
    let pvd = dir.join("fluid.pvd");
    let mut entries = match std::fs::read_to_string(&pvd) {
        Ok(old) => old
            .lines()
            .filter(|l| l.contains("<DataSet"))
            .filter(|l| !l.contains(&name))
            .map(|l| l.to_string())
            .collect::<Vec<_>>(),
        Err(_) => Vec::new(),
    };
    entries.push(format!("<DataSet timestep=\"{t:e}\" file=\"{name}\"/>"));
    let mut out = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n",
    );
    for e in entries {
        out.push_str(&e);
        out.push('\n');
    }
    out.push_str("</Collection>\n</VTKFile>\n");
    std::fs::write(pvd, out).map_err(SolverError::from)
}

/// Probe histories as CSV: time, then ρ, p, u, v, w for each probe.
pub fn write_probes(f: &Fluid, hist: &[(f64, Vec<[f64; 5]>)], dir: &Path) -> SolverResult<()> {
    if f.probes.is_empty() {
        return Ok(());
    }
    std::fs::create_dir_all(dir)?;
    let mut s = String::from("time");
    for p in &f.probes {
        for q in ["density", "pressure", "u", "v", "w"] {
            let _ = write!(s, ",{}.{q}", p.name);
        }
    }
    s.push('\n');
    for (t, vals) in hist {
        let _ = write!(s, "{t:e}");
        for v in vals {
            for x in v {
                let _ = write!(s, ",{x:e}");
            }
        }
        s.push('\n');
    }
    std::fs::write(dir.join("probes.csv"), s).map_err(SolverError::from)
}
