//! VTK output for ParaView (docs/architecture.md): the particles as vertex cells with
//! displacement, velocity, effective plastic strain and broken-bond fraction, written with
//! the node kit (binary `.vtu` frames, exact f64, and the `joint.pvd` series).

use crate::model::Model;
use node_kit::vtk::{self, Frame};
use std::path::Path;

/// Write `<dir>/joint_<window>.vtu` of the particles at time `t` and list it in `joint.pvd`.
pub fn write_vtu(m: &Model, dir: &Path, window: u64, t: f64) -> std::io::Result<()> {
    let disp: Vec<f64> =
        m.x.iter()
            .zip(&m.x0)
            .flat_map(|(x, x0)| [x[0] - x0[0], x[1] - x0[1], x[2] - x0[2]])
            .collect();
    let vel: Vec<f64> = m.v.iter().flat_map(|v| v.iter().copied()).collect();
    let eqps: Vec<f64> = m.mat.iter().map(|s| s.eq_plastic_strain).collect();
    let data = vec![
        ("displacement", 3, disp),
        ("velocity", 3, vel),
        ("eq_plastic_strain", 1, eqps),
        ("broken_bond_fraction", 1, m.broken_fraction()),
    ];
    let frame = Frame {
        dir,
        stem: "joint",
        window,
        time: t,
    };
    vtk::write_vtu(&frame, vtk::point_cloud(&m.x, data))?;
    Ok(())
}
