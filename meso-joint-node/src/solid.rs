//! Hexahedra for the base material around the SPG core (seed 004 §4.2: the joint's
//! surroundings as solid elements, SPG only where the material fails).
//!
//! The elements live on the lattice cells' corners, and so do the core's particles
//! (`geometry::split_solid`): a node on the boundary between the two *is* a particle. Its
//! state (position, velocity) is the particle's; the elements add their force to the
//! particle's force and their lumped mass to its mass, before the particle's velocity update
//! and smoothing, so it moves as one body. Nodes of elements only are stepped here by
//! central differences. Every element force sums to zero and every particle force does, so
//! momentum is kept to round-off across the boundary, with no coupling condition and no
//! overlap: each piece of material is either a cell of particles or an element.

use mechanics::hex8::{HexParams, HexPart};
use rayon::prelude::*;

/// Marks a node that is no particle (`Solid::node_particle`).
pub const NONE: u32 = u32::MAX;

/// The share of the elements' stable-step bound a step takes.
const STEP_FACTOR: f64 = 0.9;

/// The hexahedra and the nodes they own.
#[derive(Debug, Clone)]
pub struct Solid {
    pub part: HexPart,
    /// Reference and current positions, half-step velocities and element forces of every
    /// element node (a shared node's position and velocity are copied from its particle
    /// before each force evaluation).
    pub x0: Vec<[f64; 3]>,
    pub x: Vec<[f64; 3]>,
    pub v: Vec<[f64; 3]>,
    pub f: Vec<[f64; 3]>,
    /// Lumped element mass of each node (kg); a shared node's is also in its particle's.
    pub mass: Vec<f64>,
    /// The particle each node is, or [`NONE`].
    pub node_particle: Vec<u32>,
    /// Each element's part (the lattice part its cell came from).
    pub element_part: Vec<u32>,
    /// Nodes held by a velocity condition (their update is the condition's).
    pub held: Vec<bool>,
}

impl Solid {
    /// The elements on `nodes` (their reference positions); refuses a folded element.
    pub fn new(
        nodes: Vec<[f64; 3]>,
        node_particle: Vec<u32>,
        elements: Vec<[u32; 8]>,
        element_part: Vec<u32>,
        p: HexParams,
    ) -> Result<Solid, String> {
        let part = HexPart::new(elements, &nodes, p)?;
        let n = nodes.len();
        Ok(Solid {
            mass: part.lumped_mass(),
            part,
            x0: nodes.clone(),
            x: nodes,
            v: vec![[0.0; 3]; n],
            f: vec![[0.0; 3]; n],
            node_particle,
            element_part,
            held: vec![false; n],
        })
    }

    pub fn len(&self) -> usize {
        self.x.len()
    }

    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Whether node `k` belongs to the elements alone (stepped here).
    #[inline]
    pub fn own(&self, k: usize) -> bool {
        self.node_particle[k] == NONE
    }

    /// The nodes stepped here (no particle's), in order.
    pub fn own_nodes(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).filter(|&k| self.own(k))
    }

    /// Central-difference velocity update of the free nodes stepped here.
    pub fn velocity_update(&mut self, dt: f64) {
        self.v
            .par_iter_mut()
            .zip(&self.f)
            .zip(&self.mass)
            .zip(&self.node_particle)
            .zip(&self.held)
            .for_each(|((((v, f), m), &i), &held)| {
                if i == NONE && !held {
                    for d in 0..3 {
                        v[d] += dt * f[d] / m;
                    }
                }
            });
    }

    /// Position update of the nodes stepped here.
    pub fn position_update(&mut self, dt: f64) {
        self.x
            .par_iter_mut()
            .zip(&self.v)
            .zip(&self.node_particle)
            .for_each(|((x, v), &i)| {
                if i == NONE {
                    for d in 0..3 {
                        x[d] += dt * v[d];
                    }
                }
            });
    }

    /// The element forces at the current positions, the stresses advanced over `dt`: the
    /// shared nodes take their particle's position and velocity first, and give the force
    /// back to it (added to `pf`).
    pub fn forces(
        &mut self,
        dt: f64,
        px: &[[f64; 3]],
        pv: &[[f64; 3]],
        pf: &mut [[f64; 3]],
    ) -> Result<(), String> {
        self.x
            .par_iter_mut()
            .zip(self.v.par_iter_mut())
            .zip(self.f.par_iter_mut())
            .zip(&self.node_particle)
            .for_each(|(((x, v), f), &i)| {
                if i != NONE {
                    *x = px[i as usize];
                    *v = pv[i as usize];
                }
                *f = [0.0; 3];
            });
        self.part.add_forces(&self.x, &self.v, dt, &mut self.f)?;
        for k in 0..self.len() {
            let i = self.node_particle[k];
            if i != NONE {
                for d in 0..3 {
                    pf[i as usize][d] += self.f[k][d];
                }
            }
        }
        Ok(())
    }

    /// Stress work plus hourglass energy of the elements (J).
    pub fn internal_energy(&self) -> f64 {
        let (work, hg, _) = self.part.energies();
        work + hg
    }

    /// Kinetic energy, momentum and angular momentum (about the origin) of the nodes
    /// stepped here (the shared ones are counted with their particles).
    pub fn motion(&self) -> (f64, [f64; 3], [f64; 3]) {
        let (mut e, mut p, mut l) = (0.0, [0.0; 3], [0.0; 3]);
        for k in self.own_nodes() {
            let (m, v, x) = (self.mass[k], self.v[k], self.x[k]);
            e += 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            for d in 0..3 {
                p[d] += m * v[d];
            }
            l[0] += m * (x[1] * v[2] - x[2] * v[1]);
            l[1] += m * (x[2] * v[0] - x[0] * v[2]);
            l[2] += m * (x[0] * v[1] - x[1] * v[0]);
        }
        (e, p, l)
    }

    /// Mass scaling of the elements: their density grows where their step (0.9 of the
    /// bound) is below `target`. The nodes stepped here take the added mass; returns each
    /// node's addition (a shared node's is for its particle to take).
    pub fn mass_scale(&mut self, target: f64) -> Vec<f64> {
        let add = self.part.mass_scale(&self.x, target, STEP_FACTOR);
        for (m, a) in self.mass.iter_mut().zip(&add) {
            *m += a;
        }
        add
    }

    /// The elements' stable step: 0.9 of the bound (the bound is a bound, not an estimate).
    pub fn stable_dt(&self) -> f64 {
        STEP_FACTOR * self.part.stable_dt(&self.x)
    }

    /// The largest equivalent plastic strain of the elements.
    pub fn max_plastic_strain(&self) -> f64 {
        self.part
            .state
            .iter()
            .map(|s| s.mat.eq_plastic_strain)
            .fold(0.0, f64::max)
    }
}

/// What a checkpoint holds of the elements.
#[derive(serde::Serialize, serde::Deserialize)]
pub struct SolidState {
    pub x: Vec<[f64; 3]>,
    pub v: Vec<[f64; 3]>,
    pub f: Vec<[f64; 3]>,
    pub elements: Vec<mechanics::hex8::HexState>,
}

impl Solid {
    pub fn save(&self) -> SolidState {
        SolidState {
            x: self.x.clone(),
            v: self.v.clone(),
            f: self.f.clone(),
            elements: self.part.state.to_vec(),
        }
    }

    pub fn load(&mut self, s: SolidState) -> Result<(), String> {
        let (n, ne) = (self.len(), self.part.state.len());
        if s.x.len() != n || s.v.len() != n || s.f.len() != n || s.elements.len() != ne {
            return Err(format!(
                "load_state: a solid of {} nodes / {} elements, this one has {n} / {ne}",
                s.x.len(),
                s.elements.len()
            ));
        }
        self.x = s.x;
        self.v = s.v;
        self.f = s.f;
        self.part.state = mechanics::hex8::HexStates::from_slice(&s.elements);
        Ok(())
    }
}
