//! The shell model's state as structures of arrays: nodes (6 DOF, lumped mass and rotational
//! inertia, constraints, loads), elements (connectivity, integration-point stresses, resultants,
//! energies), the node → element adjacency in compressed rows for gathering, and the named
//! sets. Seed 004 eq. 21: M Ü = F_ext + F_c − F_int, with M lumped (eq. 23).

use crate::element::{Material, PL, RES, Section};
use mechanics::tensor::vec3;
use std::collections::BTreeMap;

/// Constraint bits per node: translations x, y, z then rotations x, y, z.
pub const DOF_ALL: u8 = 0b11_1111;

/// One velocity boundary condition's nodes share a time ramp.
#[derive(Debug, Clone, PartialEq)]
pub struct ReactionSet {
    pub name: String,
    pub nodes: Vec<u32>,
}

/// The model: everything the time loop reads and writes.
#[derive(Debug, Clone)]
pub struct Model {
    // ---- nodes ----
    /// Reference positions.
    pub x0: Vec<[f64; 3]>,
    /// Positions x_n.
    pub x: Vec<[f64; 3]>,
    /// Velocities v_{n−½} (after a step: v_{n+½}).
    pub v: Vec<[f64; 3]>,
    /// Angular velocities (global frame).
    pub w: Vec<[f64; 3]>,
    /// Nodal orientation quaternions [w, x, y, z] (rotation from the reference).
    pub q: Vec<[f64; 4]>,
    /// Reference nodal normals (average of the adjacent element normals).
    pub n0: Vec<[f64; 3]>,
    /// Lumped translational mass (elements + coupling + mass scaling).
    pub mass: Vec<f64>,
    /// Lumped rotational inertia.
    pub inertia: Vec<f64>,
    /// Mass from the elements alone (before coupling mass and mass scaling).
    pub mass_elem: Vec<f64>,
    pub inertia_elem: Vec<f64>,
    /// Constant point loads (N).
    pub f_ext: Vec<[f64; 3]>,
    /// Coupling force and moment of the current window (N, N m).
    pub f_c: Vec<[f64; 3]>,
    pub m_c: Vec<[f64; 3]>,
    /// Coupling stiffness bound per node (N/m), from the responders at set-up.
    pub k_c: Vec<f64>,
    /// Constrained DOF bits and the prescribed translational velocity of those DOFs.
    pub fix: Vec<u8>,
    pub v_pres: Vec<[f64; 3]>,
    /// Support reaction of the last step (force, moment) — nonzero only where constrained.
    pub reaction: Vec<[f64; 6]>,
    /// Node → (element·4 + local node) in compressed rows.
    pub adj_offsets: Vec<u32>,
    pub adj: Vec<u32>,
    // ---- elements ----
    pub conn: Vec<[u32; 4]>,
    /// ne·nip·3 in-plane stresses (local frame).
    pub stress: Vec<f64>,
    /// ne·nip·PL plastic state (back stress, eqps).
    pub plastic: Vec<f64>,
    /// Per-element scalars (see `element::RES`).
    pub res: Vec<[f64; RES]>,
    /// Element nodal internal forces minus pressure (global), gathered by the nodes.
    pub fe: Vec<[[f64; 6]; 4]>,
    /// Element pressure (Pa, along +normal), 0 for none.
    pub pressure: Vec<f64>,
    /// Initial thickness.
    pub h0: Vec<f64>,
    // ---- constants ----
    pub section: Section,
    pub material: Material,
    pub density: f64,
    /// Safety factor on the stable step.
    pub dt_scale: f64,
    /// Prescribed velocities ramp linearly from 0 over this time (0: applied at once).
    pub velocity_ramp: f64,
    /// Target step of mass scaling (None: no scaling).
    pub mass_scaling_dt: Option<f64>,
    pub node_sets: BTreeMap<String, Vec<u32>>,
    pub element_sets: BTreeMap<String, Vec<u32>>,
    pub reaction_sets: Vec<ReactionSet>,
    // ---- clock and bookkeeping ----
    pub time: f64,
    /// Step used last (0 before the first step: the first step is a half step in velocity).
    pub dt_prev: f64,
    pub steps: u64,
    pub external_work: f64,
    pub support_work: f64,
    pub interface_work: f64,
    pub external_impulse: [f64; 3],
    pub interface_impulse: [f64; 3],
    /// Impulse of the point loads alone (N s).
    pub load_impulse: [f64; 3],
    /// Angular impulse about the origin received through the interfaces, Σ Δt (x × F + M).
    pub interface_angular_impulse: [f64; 3],
    /// Added translational mass of mass scaling (kg) and rotational inertia added.
    pub added_mass: f64,
    pub added_inertia: f64,
    /// Nodes with point loads, constraints or coupling (for the small sequential sums).
    pub loaded_nodes: Vec<u32>,
    pub constrained_nodes: Vec<u32>,
    pub coupled_nodes: Vec<u32>,
    /// Single-surface contact between the shells, if on.
    pub contact: Option<crate::contact::Contact>,
}

impl Model {
    pub fn num_nodes(&self) -> usize {
        self.x.len()
    }
    pub fn num_elements(&self) -> usize {
        self.conn.len()
    }

    /// Kinetic energy of the half-step velocities, translational + rotational (fixed-order sum).
    pub fn kinetic_energy(&self) -> f64 {
        let mut e = 0.0;
        for i in 0..self.x.len() {
            let (v, w) = (self.v[i], self.w[i]);
            e += 0.5 * self.mass[i] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
                + 0.5 * self.inertia[i] * (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        }
        e
    }

    /// Internal energy (stress work + hourglass energy, and the contact's penalty energy),
    /// fixed-order sum.
    pub fn internal_energy(&self) -> f64 {
        let contact = self.contact.as_ref().map_or(0.0, |c| c.energy);
        self.res
            .iter()
            .map(|r| r[crate::element::R_EINT])
            .sum::<f64>()
            + contact
    }

    /// The contact forces at the current positions (nothing without contact).
    pub fn update_contact(&mut self) {
        if let Some(mut c) = self.contact.take() {
            c.update(self);
            self.contact = Some(c);
        }
    }

    /// Hourglass energy estimate ½ Q²/k is not stored separately; this is the pressure work.
    pub fn pressure_work(&self) -> f64 {
        self.res.iter().map(|r| r[crate::element::R_WPRES]).sum()
    }

    /// Linear momentum Σ m v (half-step velocities).
    pub fn momentum(&self) -> [f64; 3] {
        let mut p = [0.0; 3];
        for i in 0..self.x.len() {
            for k in 0..3 {
                p[k] += self.mass[i] * self.v[i][k];
            }
        }
        p
    }

    /// Gross momentum Σ m|v| (translation only), the scale of momentum sums that cancel.
    pub fn momentum_gross(&self) -> f64 {
        (0..self.x.len())
            .map(|i| {
                let v = self.v[i];
                self.mass[i] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
            })
            .sum()
    }

    /// Angular momentum about the origin, Σ x_n × m v_{n+½} + I ω_{n+½}; evaluated after a
    /// step, x_{n+1} × v_{n+½} = x_n × v_{n+½} since x_{n+1} − x_n ∥ v_{n+½}. With
    /// self-equilibrated element forces it changes exactly by Σ Δt (x_n × F + M).
    pub fn angular_momentum(&self) -> [f64; 3] {
        let mut l = [0.0; 3];
        for i in 0..self.x.len() {
            let c = vec3(&self.x[i]).cross(&vec3(&self.v[i]));
            for k in 0..3 {
                l[k] += self.mass[i] * c[k] + self.inertia[i] * self.w[i][k];
            }
        }
        l
    }

    /// Stress (local frame) at integration point `k` of element `e`.
    pub fn stress_at(&self, e: usize, k: usize) -> [f64; 3] {
        let o = (e * self.section.nip + k) * 3;
        [self.stress[o], self.stress[o + 1], self.stress[o + 2]]
    }

    /// Largest equivalent plastic strain over the integration points of element `e`.
    pub fn eqps(&self, e: usize) -> f64 {
        let nip = self.section.nip;
        (0..nip)
            .map(|k| self.plastic[(e * nip + k) * PL + 3])
            .fold(0.0, f64::max)
    }

    /// Total nodal mass.
    pub fn total_mass(&self) -> f64 {
        self.mass.iter().sum()
    }
}
