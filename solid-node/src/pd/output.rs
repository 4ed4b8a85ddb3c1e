//! VTK output per particle for ParaView (ARCHITECTURE §10): an XML UnstructuredGrid (.vtu)
//! of vertex cells with displacement, velocity, Cauchy stress, plastic strain and damage,
//! plus a .pvd time series listing every file written so far.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use std::fmt::Write as _;
use std::path::Path;

/// Named per-particle arrays to write: (name, components, values).
pub type PointData<'a> = Vec<(&'a str, usize, Vec<f64>)>;

/// Writes `<dir>/<stem>_<window>.vtu` and refreshes `<dir>/<stem>.pvd`.
pub fn write_vtu(
    dir: &Path,
    stem: &str,
    window: u64,
    time: f64,
    points: &[[f64; 3]],
    data: &PointData,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let n = points.len();
    let mut s = String::with_capacity(64 * n * (2 + data.len()));
    s.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n");
    let _ = writeln!(s, "<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n}\">");
    s.push_str(
        "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n",
    );
    for p in points {
        let _ = writeln!(s, "{:e} {:e} {:e}", p[0], p[1], p[2]);
    }
    s.push_str("</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for i in 0..n {
        let _ = write!(s, "{i} ");
    }
    s.push_str("\n</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    for i in 0..n {
        let _ = write!(s, "{} ", i + 1);
    }
    s.push_str("\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
    for _ in 0..n {
        s.push_str("1 ");
    }
    s.push_str("\n</DataArray>\n</Cells>\n<PointData>\n");
    for (name, comps, vals) in data {
        let _ = writeln!(
            s,
            "<DataArray type=\"Float64\" Name=\"{name}\" NumberOfComponents=\"{comps}\" format=\"ascii\">"
        );
        for row in vals.chunks(*comps) {
            for v in row {
                let _ = write!(s, "{v:e} ");
            }
            s.push('\n');
        }
        s.push_str("</DataArray>\n");
    }
    s.push_str("</PointData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
    let file = format!("{stem}_{window:06}.vtu");
    std::fs::write(dir.join(&file), s)?;
    // Time series: keep a small index file of (time, file) lines next to the .pvd.
    let index = dir.join(format!("{stem}.pvd.index"));
    let mut idx = std::fs::read_to_string(&index).unwrap_or_default();
    let _ = writeln!(idx, "{time:e} {file}");
    std::fs::write(&index, &idx)?;
    let mut pvd = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n",
    );
    for line in idx.lines() {
        if let Some((t, f)) = line.split_once(' ') {
            let _ = writeln!(pvd, "<DataSet timestep=\"{t}\" file=\"{f}\"/>");
        }
    }
    pvd.push_str("</Collection>\n</VTKFile>\n");
    std::fs::write(dir.join(format!("{stem}.pvd")), pvd)
}
