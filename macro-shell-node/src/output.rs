//! Output for ParaView and plots (docs/architecture.md): one `.vtu` per written window with
//! displacement, velocity and rotation per node, and per element the mid-surface stress, the
//! von Mises stress at the top/bottom points, membrane forces, equivalent plastic strain and
//! thickness (written with vtkio), plus a `.pvd` series; and the reaction-force histories of
//! the named node sets as CSV.

use crate::element::{self, R_H};
use crate::model::Model;
use crate::step::quat_log;
use node_kit::vtk::{self, Frame};
use protocol::SolverResult;
use std::path::Path;
use vtkio::model::CellType;

/// von Mises of a plane-stress state.
fn mises(s: [f64; 3]) -> f64 {
    (s[0] * s[0] - s[0] * s[1] + s[1] * s[1] + 3.0 * s[2] * s[2]).sqrt()
}

/// Element stress in the global frame (3×3, symmetric) from the local in-plane stress.
pub fn global_stress(m: &Model, e: usize, s: [f64; 3]) -> [[f64; 3]; 3] {
    let c = m.conn[e].map(|n| m.x[n as usize]);
    let mut out = [[0.0; 3]; 3];
    if let Some(g) = element::geometry(&c) {
        let sl = [[s[0], s[2]], [s[2], s[1]]];
        for i in 0..3 {
            for j in 0..3 {
                let mut v = 0.0;
                for a in 0..2 {
                    for b in 0..2 {
                        v += g.e[a][i] * sl[a][b] * g.e[b][j];
                    }
                }
                out[i][j] = v;
            }
        }
    }
    out
}

/// Mid-surface stress of element `e` (local frame): the membrane force over the thickness.
pub fn membrane_stress(m: &Model, e: usize) -> [f64; 3] {
    let nip = m.section.nip;
    let mut s = [0.0; 3];
    for k in 0..nip {
        let sk = m.stress_at(e, k);
        for c in 0..3 {
            s[c] += 0.5 * m.section.weight[k] * sk[c];
        }
    }
    s
}

/// Write `<dir>/<name>_<window>.vtu` and list it in `<dir>/<name>.pvd` (the node kit's
/// series).
pub fn write_vtu(m: &Model, dir: &Path, name: &str, window: u64, t: f64) -> SolverResult<()> {
    let nn = m.num_nodes();
    let ne = m.num_elements();
    let disp: Vec<f64> = (0..nn)
        .flat_map(|i| (0..3).map(move |d| (i, d)))
        .map(|(i, d)| m.x[i][d] - m.x0[i][d])
        .collect();
    let vel: Vec<f64> = m.v.iter().flat_map(|p| p.iter().copied()).collect();
    let rot: Vec<f64> = m.q.iter().flat_map(|q| quat_log(*q)).collect();
    let nip = m.section.nip;
    let mut stress = Vec::with_capacity(ne * 9);
    let mut vm_top = Vec::with_capacity(ne);
    let mut vm_bot = Vec::with_capacity(ne);
    let mut eqps = Vec::with_capacity(ne);
    let mut thick = Vec::with_capacity(ne);
    for e in 0..ne {
        let s = global_stress(m, e, membrane_stress(m, e));
        stress.extend(s.iter().flat_map(|r| r.iter().copied()));
        vm_bot.push(mises(m.stress_at(e, 0)));
        vm_top.push(mises(m.stress_at(e, nip - 1)));
        eqps.push(match m.material {
            element::Material::J2(_) => m.eqps(e),
            _ => 0.0,
        });
        thick.push(m.res[e][R_H]);
    }
    let connectivity = m
        .conn
        .iter()
        .flat_map(|c| c.iter().map(|&n| n as u64))
        .collect();
    let piece = vtk::grid(
        &m.x,
        CellType::Quad,
        4,
        connectivity,
        vec![
            ("displacement", 3, disp),
            ("velocity", 3, vel),
            ("rotation", 3, rot),
        ],
        vec![
            ("stress_mid", 9, stress),
            ("mises_top", 1, vm_top),
            ("mises_bottom", 1, vm_bot),
            ("plastic_strain", 1, eqps),
            ("thickness", 1, thick),
        ],
    );
    let frame = Frame {
        dir,
        stem: name,
        window,
        time: t,
    };
    vtk::write_vtu(&frame, piece)?;
    Ok(())
}

/// Sum of the support reactions (force, moment) over a node set.
pub fn reaction_sum(m: &Model, nodes: &[u32]) -> [f64; 6] {
    let mut r = [0.0; 6];
    for &n in nodes {
        for d in 0..6 {
            r[d] += m.reaction[n as usize][d];
        }
    }
    r
}

/// Reaction history rows: time then, per reaction set, Fx Fy Fz Mx My Mz.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct History {
    pub header: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl History {
    pub fn new(m: &Model) -> Self {
        let mut header = vec!["time".to_string()];
        for s in &m.reaction_sets {
            for c in ["fx", "fy", "fz", "mx", "my", "mz"] {
                header.push(format!("{}_{c}", s.name));
            }
        }
        History {
            header,
            rows: Vec::new(),
        }
    }

    pub fn record(&mut self, m: &Model) {
        if m.reaction_sets.is_empty() {
            return;
        }
        let mut row = vec![m.time];
        for s in &m.reaction_sets {
            row.extend_from_slice(&reaction_sum(m, &s.nodes));
        }
        self.rows.push(row);
    }

    pub fn write_csv(&self, path: &Path) -> SolverResult<()> {
        let rows = self.rows.iter().map(|r| r.iter().copied());
        node_kit::table::write_csv(path, &self.header, rows)?;
        Ok(())
    }
}
