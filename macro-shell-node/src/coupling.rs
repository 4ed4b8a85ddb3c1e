//! The driver side of the kinematic shell–joint coupling (seed 004 §3.2, Fig. 4; eq. 29–33;
//! docs/architecture.md, kinematic): per interface, the shell nodes under a joint's coupling
//! surface and the shell quads there (the joint projects its particles onto them, eq. 29–32).
//!
//! * set-up: the responder's coupling mass (1 per node) is added to the interface nodes, its
//!   stiffness bound (1 per node) enters the stable step, and its constraint force and
//!   moment at t0 (3 + 3 per node) are held for the first window;
//! * every window: the constraint force and moment at t_n (eq. 33) are applied on every
//!   sub-step of t_n → t_{n+1} (including the whole velocity update at t_n: blending in the
//!   previous window's force there would lag a stiffness force, which is unstable); the driver then sends `position` (x at t_{n+1}), `velocity`
//!   (the window's mean velocity (x_{n+1} − x_n)/(t_{n+1} − t_n), which is v_{n+½} when the
//!   window is one step), `rotation` (rotation vector from the reference) and `normal` (the
//!   rotated nodal director). Several interfaces may share shell nodes; their masses,
//!   stiffnesses and forces add, in interface order.

use crate::model::Model;
use crate::step::{quat_apply, quat_log};
use protocol::{CellKind, Cells, Inbox, InterfaceMesh, Outbox, SolverError, SolverResult};

/// Fields the shell sends on a driver interface every window.
pub const SENDS: [&str; 4] = ["position", "velocity", "rotation", "normal"];
/// Fields it takes (set-up: all four; windows: force and moment).
pub const ACCEPTS: [&str; 4] = ["force", "moment", "mass", "stiffness"];
/// What it needs from its peer at set-up besides the loads.
pub const SETUP: [&str; 2] = ["mass", "stiffness"];

/// One coupling interface of the shell.
#[derive(Debug, Clone, PartialEq)]
pub struct Interface {
    pub name: String,
    /// Shell nodes (sorted) and quads over them in local numbering.
    pub nodes: Vec<u32>,
    pub cells: Vec<[u32; 4]>,
    /// Whether a kinematic coupling drives through it (set by `setup`).
    pub active: bool,
    /// Force and moment received for the current window, 3 per node.
    pub force: Vec<f64>,
    pub moment: Vec<f64>,
    /// Positions at the start of the window (for the mean window velocity).
    pub x_start: Vec<[f64; 3]>,
}

impl Interface {
    /// The interface over the elements `elems` of `mesh`.
    pub fn new(name: &str, mesh_conn: &[[u32; 4]], elems: &[u32]) -> Self {
        let mut nodes: Vec<u32> = elems.iter().flat_map(|&e| mesh_conn[e as usize]).collect();
        nodes.sort_unstable();
        nodes.dedup();
        let local = |n: u32| nodes.binary_search(&n).unwrap_or(0) as u32;
        let cells = elems
            .iter()
            .map(|&e| mesh_conn[e as usize].map(local))
            .collect();
        let n = nodes.len();
        Interface {
            name: name.to_string(),
            nodes,
            cells,
            active: false,
            force: vec![0.0; 3 * n],
            moment: vec![0.0; 3 * n],
            x_start: vec![[0.0; 3]; n],
        }
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// The interface mesh: global node ids, reference positions, quads, reference normals,
    /// and nodal areas (¼ of each adjacent quad) as weights.
    pub fn mesh(&self, m: &Model) -> InterfaceMesh {
        let positions: Vec<[f64; 3]> = self.nodes.iter().map(|&n| m.x0[n as usize]).collect();
        let mut weights = vec![0.0; self.nodes.len()];
        for c in &self.cells {
            let x = c.map(|l| positions[l as usize]);
            if let Some(g) = crate::element::geometry(&x) {
                for &l in c {
                    weights[l as usize] += 0.25 * g.area;
                }
            }
        }
        InterfaceMesh {
            ids: self.nodes.iter().map(|&n| n as u64).collect(),
            positions,
            cells: Some(Cells {
                kind: CellKind::Quad,
                connectivity: self.cells.iter().flat_map(|c| c.iter().copied()).collect(),
            }),
            normals: self.nodes.iter().map(|&n| m.n0[n as usize]).collect(),
            weights,
        }
    }

    /// Take the responder's set-up fields: mass and stiffness into the model, force and
    /// moment at t0 held for the first window.
    pub fn take_setup(&mut self, m: &mut Model, inbox: &Inbox) -> SolverResult<()> {
        let n = self.len();
        let mass = inbox.require(&self.name, "mass", n)?.to_vec();
        let stiff = inbox.require(&self.name, "stiffness", n)?.to_vec();
        for (l, &node) in self.nodes.iter().enumerate() {
            let (dm, k) = (mass[l], stiff[l]);
            if !(dm.is_finite() && dm >= 0.0) {
                return Err(SolverError::interface(
                    &self.name,
                    format!("'mass' at point {l} is {dm}"),
                ));
            }
            if !(k.is_finite() && k >= 0.0) {
                return Err(SolverError::interface(
                    &self.name,
                    format!("'stiffness' at point {l} is {k}"),
                ));
            }
            let i = node as usize;
            // The joint's coupling particles move with the node: their translational mass
            // adds here; their rotational inertia about the node is neglected (not sent).
            m.mass[i] += dm;
            m.k_c[i] += k;
        }
        self.take_loads(inbox, true)?;
        self.active = true;
        Ok(())
    }

    /// Read `force` and `moment` (3 per node). Missing fields are an error unless `optional`.
    pub fn take_loads(&mut self, inbox: &Inbox, optional: bool) -> SolverResult<()> {
        let n = self.len();
        for (name, dst) in [("force", &mut self.force), ("moment", &mut self.moment)] {
            match inbox.get(&self.name, name) {
                None if optional => {}
                _ => {
                    let vals = inbox.require(&self.name, name, 3 * n)?;
                    if let Some(p) = vals.iter().position(|v| !v.is_finite()) {
                        return Err(SolverError::interface(
                            &self.name,
                            format!("'{name}' value {p} is not finite"),
                        ));
                    }
                    dst.copy_from_slice(vals);
                }
            }
        }
        Ok(())
    }

    /// Add this interface's held force and moment to the model's coupling loads.
    pub fn apply(&self, m: &mut Model) {
        for (l, &node) in self.nodes.iter().enumerate() {
            for d in 0..3 {
                m.f_c[node as usize][d] += self.force[3 * l + d];
                m.m_c[node as usize][d] += self.moment[3 * l + d];
            }
        }
    }

    pub fn mark_start(&mut self, m: &Model) {
        for (l, &node) in self.nodes.iter().enumerate() {
            self.x_start[l] = m.x[node as usize];
        }
    }

    /// Write the interface motion at the end of a window of length `span` into `out`.
    pub fn send(&self, m: &Model, span: f64, out: &mut Outbox) {
        let n = self.len();
        {
            let p = out.put(&self.name, "position", 3, n);
            for (l, &node) in self.nodes.iter().enumerate() {
                p[3 * l..3 * l + 3].copy_from_slice(&m.x[node as usize]);
            }
        }
        {
            let v = out.put(&self.name, "velocity", 3, n);
            for (l, &node) in self.nodes.iter().enumerate() {
                for d in 0..3 {
                    v[3 * l + d] = if span > 0.0 {
                        (m.x[node as usize][d] - self.x_start[l][d]) / span
                    } else {
                        m.v[node as usize][d]
                    };
                }
            }
        }
        {
            let r = out.put(&self.name, "rotation", 3, n);
            for (l, &node) in self.nodes.iter().enumerate() {
                r[3 * l..3 * l + 3].copy_from_slice(&quat_log(m.q[node as usize]));
            }
        }
        {
            let nn = out.put(&self.name, "normal", 3, n);
            for (l, &node) in self.nodes.iter().enumerate() {
                let i = node as usize;
                nn[3 * l..3 * l + 3].copy_from_slice(&quat_apply(m.q[i], m.n0[i]));
            }
        }
    }
}

/// Interfaces named in the config, over the mesh's element sets.
pub fn interfaces_of(cfg: &[crate::setup::InterfaceConfig], m: &Model) -> Vec<Interface> {
    cfg.iter()
        .filter_map(|c| {
            m.element_sets
                .get(&c.element_set)
                .map(|elems| Interface::new(&c.name, &m.conn, elems))
        })
        .collect()
}
