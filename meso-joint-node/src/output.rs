//! VTK output for ParaView (docs/architecture.md): the particles as vertex cells with
//! displacement, velocity, effective plastic strain, broken-bond fraction (and, with
//! Johnson–Cook, temperature), written with
//! the node kit (binary `.vtu` frames, exact f64, and the `joint.pvd` series); solid
//! elements, where the joint has them, as hexahedra in their own series (`solid.pvd`) with
//! the nodes' displacement and velocity and each element's stress, von Mises stress and
//! effective plastic strain.

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
    let eqps: Vec<f64> = m.mat.iter().map(|s| s.eq_plastic_strain()).collect();
    let mut data = vec![
        ("displacement", 3, disp),
        ("velocity", 3, vel),
        ("eq_plastic_strain", 1, eqps),
        ("broken_bond_fraction", 1, m.broken_fraction()),
    ];
    // Johnson–Cook heats the particles by their plastic work.
    if m.p.blast.is_some() {
        let temperature = m
            .mat
            .iter()
            .map(|s| match s {
                crate::model::Point::Blast(b) => b.jc.temperature,
                crate::model::Point::J2(_) => f64::NAN,
            })
            .collect();
        data.push(("temperature", 1, temperature));
    }
    let frame = Frame {
        dir,
        stem: "joint",
        window,
        time: t,
    };
    vtk::write_vtu(&frame, vtk::point_cloud(&m.x, data))?;
    if let Some(sd) = &m.solid {
        let disp: Vec<f64> =
            sd.x.iter()
                .zip(&sd.x0)
                .flat_map(|(x, x0)| [x[0] - x0[0], x[1] - x0[1], x[2] - x0[2]])
                .collect();
        let vel: Vec<f64> = sd.v.iter().flat_map(|v| v.iter().copied()).collect();
        let states = sd.part.state.to_vec();
        // Voigt order xx, yy, zz, yz, xz, xy as ParaView's symmetric tensors take it
        // (xx, yy, zz, xy, yz, xz)
        let stress: Vec<f64> = states
            .iter()
            .flat_map(|s| {
                let t = s.mat.stress;
                [t[0], t[1], t[2], t[5], t[3], t[4]]
            })
            .collect();
        let mises: Vec<f64> = states
            .iter()
            .map(|s| mechanics::j2::von_mises(&s.mat.stress))
            .collect();
        let eqps: Vec<f64> = states.iter().map(|s| s.mat.eq_plastic_strain).collect();
        let connectivity: Vec<u64> = sd
            .part
            .elements
            .iter()
            .flatten()
            .map(|&k| k as u64)
            .collect();
        let frame = Frame {
            dir,
            stem: "solid",
            window,
            time: t,
        };
        vtk::write_vtu(
            &frame,
            vtk::grid(
                &sd.x,
                vtk::CellType::Hexahedron,
                8,
                connectivity,
                vec![("displacement", 3, disp), ("velocity", 3, vel)],
                vec![
                    ("stress", 6, stress),
                    ("von_mises_stress", 1, mises),
                    ("eq_plastic_strain", 1, eqps),
                ],
            ),
        )?;
    }
    Ok(())
}
