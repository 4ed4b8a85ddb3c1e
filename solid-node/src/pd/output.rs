//! VTK output per particle for ParaView (ARCHITECTURE §10), written with vtkio: an XML
//! UnstructuredGrid (.vtu) of vertex cells with displacement, velocity, Cauchy stress, plastic
//! strain and damage, plus a .pvd time series listing every file written so far.
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use std::fmt::Write as _;
use std::path::Path;
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, UnstructuredGridPiece, Version,
    VertexNumbers, Vtk,
};

/// Named per-particle arrays to write: (name, components, values).
pub type PointData<'a> = Vec<(&'a str, usize, Vec<f64>)>;

/// Writes `<dir>/<stem>_<window>.vtu` (vertex cells, one per particle, written with vtkio:
/// binary, exact f64) and refreshes `<dir>/<stem>.pvd`.
pub fn write_vtu(
    dir: &Path,
    stem: &str,
    window: u64,
    time: f64,
    points: &[[f64; 3]],
    data: PointData,
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let n = points.len() as u64;
    let piece = UnstructuredGridPiece {
        points: points.as_flattened().to_vec().into(),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity: (0..n).collect(),
                offsets: (1..=n).collect(),
            },
            types: vec![CellType::Vertex; n as usize],
        },
        data: Attributes {
            point: data
                .into_iter()
                .map(|(name, comps, vals)| Attribute::generic(name, comps as u32).with_data(vals))
                .collect(),
            cell: Vec::new(),
        },
    };
    let vtk = Vtk {
        version: Version::new((1, 0)),
        title: format!("{stem} t={time:e}"),
        byte_order: ByteOrder::LittleEndian,
        file_path: None,
        data: DataSet::inline(piece),
    };
    let file = format!("{stem}_{window:06}.vtu");
    vtk.export(dir.join(&file))
        .map_err(|e| std::io::Error::other(format!("writing {file}: {e}")))?;
    // Time series: keep a small index file of (time, file) lines next to the .pvd.
    let index = dir.join(format!("{stem}.pvd.index"));
    let old = std::fs::read_to_string(&index).unwrap_or_default();
    // A restarted run writes again the frames after its checkpoint: one line per file.
    let mut idx: String = old
        .lines()
        .filter(|l| l.split_once(' ').is_none_or(|(_, f)| f != file))
        .map(|l| format!("{l}\n"))
        .collect();
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
