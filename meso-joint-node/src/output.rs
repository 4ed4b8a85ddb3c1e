//! VTK output for ParaView (ARCHITECTURE §10): particles as an unstructured grid of vertices
//! with displacement, velocity, effective plastic strain and broken-bond fraction.

use crate::model::Model;
use std::io::Write;
use std::path::Path;

/// Write one ASCII `.vtu` file of the particles at time `t`.
pub fn write_vtu(m: &Model, path: &Path, t: f64) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    let n = m.len();
    writeln!(f, "<?xml version=\"1.0\"?>")?;
    writeln!(
        f,
        "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">"
    )?;
    writeln!(
        f,
        "<UnstructuredGrid><FieldData><DataArray type=\"Float64\" Name=\"TIME\" NumberOfTuples=\"1\" format=\"ascii\">{t:e}</DataArray></FieldData>"
    )?;
    writeln!(f, "<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{n}\">")?;
    writeln!(
        f,
        "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">"
    )?;
    for x in &m.x {
        writeln!(f, "{:e} {:e} {:e}", x[0], x[1], x[2])?;
    }
    writeln!(f, "</DataArray></Points><Cells>")?;
    writeln!(
        f,
        "<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">"
    )?;
    for i in 0..n {
        writeln!(f, "{i}")?;
    }
    writeln!(
        f,
        "</DataArray><DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">"
    )?;
    for i in 0..n {
        writeln!(f, "{}", i + 1)?;
    }
    writeln!(
        f,
        "</DataArray><DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">"
    )?;
    for _ in 0..n {
        writeln!(f, "1")?;
    }
    writeln!(f, "</DataArray></Cells><PointData>")?;
    writeln!(
        f,
        "<DataArray type=\"Float64\" Name=\"displacement\" NumberOfComponents=\"3\" format=\"ascii\">"
    )?;
    for i in 0..n {
        writeln!(
            f,
            "{:e} {:e} {:e}",
            m.x[i][0] - m.x0[i][0],
            m.x[i][1] - m.x0[i][1],
            m.x[i][2] - m.x0[i][2]
        )?;
    }
    writeln!(
        f,
        "</DataArray><DataArray type=\"Float64\" Name=\"velocity\" NumberOfComponents=\"3\" format=\"ascii\">"
    )?;
    for v in &m.v {
        writeln!(f, "{:e} {:e} {:e}", v[0], v[1], v[2])?;
    }
    writeln!(
        f,
        "</DataArray><DataArray type=\"Float64\" Name=\"eq_plastic_strain\" format=\"ascii\">"
    )?;
    for s in &m.mat {
        writeln!(f, "{:e}", s.eq_plastic_strain)?;
    }
    writeln!(
        f,
        "</DataArray><DataArray type=\"Float64\" Name=\"broken_bond_fraction\" format=\"ascii\">"
    )?;
    for b in m.broken_fraction() {
        writeln!(f, "{b:e}")?;
    }
    writeln!(
        f,
        "</DataArray></PointData></Piece></UnstructuredGrid></VTKFile>"
    )?;
    Ok(())
}
