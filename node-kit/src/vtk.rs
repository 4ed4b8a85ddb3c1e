//! One VTK writer for every node (docs/architecture.md): a frame per output window written with
//! vtkio in binary, exact f64 — `<stem>_<window>.vtu` (XML unstructured grid), or legacy
//! `.vtk` for a rectilinear grid (meshio cannot read XML `.vtr`) — and the `<stem>.pvd` series
//! listing every frame once, by window. Frames come in window order within a run, so a frame
//! of window `w` drops the entries of windows ≥ `w`: a run restarted from a checkpoint (or a
//! fresh run's t = 0 frame) never lists a frame twice, nor one a killed run left beyond it.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
/// The cell kinds of [`grid`] (vtkio's), for nodes that do not depend on vtkio themselves.
pub use vtkio::model::CellType;
use vtkio::model::{
    Attribute, Attributes, ByteOrder, Cells, DataSet, UnstructuredGridPiece, Version,
    VertexNumbers, Vtk,
};

/// Named arrays to write, one tuple per point (or cell): (name, components, values).
pub type Arrays<'a> = Vec<(&'a str, usize, Vec<f64>)>;

/// Where a frame goes and what it is: `<dir>/<stem>_<window:06>.<ext>` at time `time`.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    pub dir: &'a Path,
    pub stem: &'a str,
    pub window: u64,
    pub time: f64,
}

impl Frame<'_> {
    fn file(&self, ext: &str) -> String {
        format!("{}_{:06}.{ext}", self.stem, self.window)
    }

    fn export(&self, ext: &str, order: ByteOrder, data: DataSet) -> std::io::Result<PathBuf> {
        std::fs::create_dir_all(self.dir).map_err(|e| {
            std::io::Error::new(
                e.kind(),
                format!("cannot create {}: {e}", self.dir.display()),
            )
        })?;
        let file = self.file(ext);
        let vtk = Vtk {
            version: Version::new(if ext == "vtk" { (4, 2) } else { (1, 0) }),
            title: format!("{} t = {:e} s (cosim, SI units)", self.stem, self.time),
            byte_order: order,
            file_path: None,
            data,
        };
        let path = self.dir.join(&file);
        // Serialised in memory first: vtkio's own export writes through a `BufWriter` whose
        // last flush error is lost on drop, which leaves a truncated frame on a full disk.
        let mut bytes = Vec::new();
        if ext == "vtk" {
            vtk.write_legacy(&mut bytes)
        } else {
            vtk.write_xml(&mut bytes)
        }
        .map_err(|e| std::io::Error::other(format!("encoding {}: {e}", path.display())))?;
        crate::whole::write(&path, &bytes)?;
        add_to_series(self, &file)?;
        Ok(path)
    }
}

/// vtkio attributes of named arrays.
pub fn attributes(arrays: Arrays) -> Vec<Attribute> {
    arrays
        .into_iter()
        .map(|(name, comps, values)| Attribute::generic(name, comps as u32).with_data(values))
        .collect()
}

/// An unstructured grid of `points` with cells of one `kind`, `nodes` vertices each
/// (`connectivity` in that stride), and point and cell arrays.
pub fn grid(
    points: &[[f64; 3]],
    kind: CellType,
    nodes: usize,
    connectivity: Vec<u64>,
    point: Arrays,
    cell: Arrays,
) -> UnstructuredGridPiece {
    let cells = connectivity.len() / nodes.max(1);
    UnstructuredGridPiece {
        points: points.as_flattened().to_vec().into(),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity,
                offsets: (1..=cells as u64).map(|k| k * nodes as u64).collect(),
            },
            types: vec![kind; cells],
        },
        data: Attributes {
            point: attributes(point),
            cell: attributes(cell),
        },
    }
}

/// An unstructured grid of `points` with cells of several kinds and sizes: `cells` holds
/// each cell's kind and vertices (e.g. quads beside the polygons of cut elements).
pub fn mixed_grid(
    points: &[[f64; 3]],
    cells: Vec<(CellType, Vec<u64>)>,
    point: Arrays,
    cell: Arrays,
) -> UnstructuredGridPiece {
    let mut offsets = Vec::with_capacity(cells.len());
    let mut connectivity = Vec::new();
    let mut types = Vec::with_capacity(cells.len());
    for (kind, verts) in cells {
        connectivity.extend(verts);
        offsets.push(connectivity.len() as u64);
        types.push(kind);
    }
    UnstructuredGridPiece {
        points: points.as_flattened().to_vec().into(),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity,
                offsets,
            },
            types,
        },
        data: Attributes {
            point: attributes(point),
            cell: attributes(cell),
        },
    }
}

/// Particles: one vertex cell per point, with point arrays.
pub fn point_cloud(points: &[[f64; 3]], point: Arrays) -> UnstructuredGridPiece {
    let n = points.len() as u64;
    grid(
        points,
        CellType::Vertex,
        1,
        (0..n).collect(),
        point,
        Vec::new(),
    )
}

/// Write `frame` as an XML `.vtu` and list it in the series; returns the file's path.
pub fn write_vtu(frame: &Frame, piece: UnstructuredGridPiece) -> std::io::Result<PathBuf> {
    frame.export("vtu", ByteOrder::LittleEndian, DataSet::inline(piece))
}

/// Write `frame` as a legacy binary `.vtk` (big-endian, as the format requires) and list it
/// in the series; returns the file's path.
pub fn write_legacy(frame: &Frame, data: DataSet) -> std::io::Result<PathBuf> {
    frame.export("vtk", ByteOrder::BigEndian, data)
}

/// One entry of a `.pvd` series.
#[derive(Debug, Clone, PartialEq)]
pub struct Entry {
    pub window: u64,
    pub time: f64,
    pub file: String,
}

/// The value of attribute `key` in one XML element line.
fn attr<'a>(line: &'a str, key: &str) -> Option<&'a str> {
    let start = line.find(&format!(" {key}=\""))? + key.len() + 3;
    line[start..].split('"').next()
}

/// The entries of `<dir>/<stem>.pvd` (none when it does not exist) whose file is one of this
/// series' frames (`<stem>_<window>.<ext>`).
pub fn series(dir: &Path, stem: &str) -> std::io::Result<Vec<Entry>> {
    let text = match std::fs::read_to_string(dir.join(format!("{stem}.pvd"))) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(e),
    };
    Ok(text
        .lines()
        .filter(|l| l.contains("<DataSet"))
        .filter_map(|l| {
            let file = attr(l, "file")?;
            let window = file
                .strip_prefix(stem)?
                .strip_prefix('_')?
                .split('.')
                .next()?
                .parse()
                .ok()?;
            Some(Entry {
                window,
                time: attr(l, "timestep")?.parse().ok()?,
                file: file.to_string(),
            })
        })
        .collect())
}

/// List `file`, the frame of `frame.window`, in `<stem>.pvd`: entries of earlier windows are
/// kept, later ones dropped (written again by a restarted run, or left by a killed one).
fn add_to_series(frame: &Frame, file: &str) -> std::io::Result<()> {
    let mut entries = series(frame.dir, frame.stem)?;
    entries.retain(|e| e.window < frame.window);
    entries.push(Entry {
        window: frame.window,
        time: frame.time,
        file: file.to_string(),
    });
    let mut text = String::from(
        "<?xml version=\"1.0\"?>\n<!-- cosim output; units SI (m, kg, s, N, Pa, J) -->\n<VTKFile type=\"Collection\" version=\"0.1\">\n  <Collection>\n",
    );
    for e in &entries {
        let _ = writeln!(
            text,
            "    <DataSet timestep=\"{:e}\" group=\"\" part=\"0\" file=\"{}\"/>",
            e.time, e.file
        );
    }
    text.push_str("  </Collection>\n</VTKFile>\n");
    // Whole or not at all: a reader never sees half a series.
    crate::whole::write(
        &frame.dir.join(format!("{}.pvd", frame.stem)),
        text.as_bytes(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("node-kit-{}-{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    fn frame(dir: &Path, window: u64, time: f64) -> std::io::Result<PathBuf> {
        let points = [[0.0, 0.0, 0.0], [1.0, 0.5, 0.25]];
        let f = Frame {
            dir,
            stem: "p",
            window,
            time,
        };
        write_vtu(&f, point_cloud(&points, vec![("v", 1, vec![1.0, 2.0])]))
    }

    fn windows(dir: &Path) -> Vec<u64> {
        series(dir, "p").unwrap().iter().map(|e| e.window).collect()
    }

    /// A run killed after window 30 of frames every 10, restarted from its checkpoint of
    /// window 15: every frame once, in order, the times of the restarted run.
    #[test]
    fn a_restarted_series_lists_every_frame_once() {
        let dir = scratch("restart");
        for w in [0, 10, 20, 30] {
            frame(&dir, w, w as f64 * 1e-3).unwrap();
        }
        assert_eq!(windows(&dir), [0, 10, 20, 30]);
        for w in [20, 30, 40] {
            frame(&dir, w, w as f64 * 1e-3 + 1e-9).unwrap();
        }
        let s = series(&dir, "p").unwrap();
        assert_eq!(windows(&dir), [0, 10, 20, 30, 40]);
        assert_eq!(s[2].time, 20e-3 + 1e-9);
        assert_eq!(s[0].time, 0.0);
        assert_eq!(s[4].file, "p_000040.vtu");
        // A fresh run's t = 0 frame starts a new series.
        frame(&dir, 0, 0.0).unwrap();
        assert_eq!(windows(&dir), [0]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The times survive the .pvd round trip exactly (Rust's shortest round-trip `{:e}`).
    #[test]
    fn series_times_are_exact() {
        let dir = scratch("times");
        let t = 0.1f64 + 0.2;
        frame(&dir, 7, t).unwrap();
        assert_eq!(series(&dir, "p").unwrap()[0].time.to_bits(), t.to_bits());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_series_is_empty() {
        assert!(series(&scratch("none"), "p").unwrap().is_empty());
    }
}
