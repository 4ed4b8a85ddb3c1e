//! The peridynamic model family (one trait per family, one file per member): a model
//! turns the current positions and velocities into a force density per particle (N/m³),
//! updating its bond damage and internal variables (seed 001 eq. 183, seed 000 eq. A.13).
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use super::family::Bonds;
use mechanics::j2::Sym;
use protocol::solver::SolverResult;

/// The particle kinematics a model reads.
#[derive(Debug, Clone, Copy)]
pub struct Kinematics<'a> {
    /// Reference positions X.
    pub x0: &'a [[f64; 3]],
    /// Current positions x = X + u (output, interface, and the rk-ba kernels).
    pub pos: &'a [[f64; 3]],
    /// Displacements u, carried next to x (u += v dt): bond deformations are formed from
    /// η = u_j − u_i against the reference bond ξ, so small strains keep full precision
    /// however far the body sits from the origin.
    pub disp: &'a [[f64; 3]],
    /// Velocities (at the half step in velocity Verlet, as the rate forms need).
    pub vel: &'a [[f64; 3]],
    /// Particle volumes V (m³; Δx²·h in 2-D).
    pub vol: &'a [f64],
}

/// Dimension of the particle model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dim {
    Three,
    PlaneStress,
    PlaneStrain,
}

impl Dim {
    pub fn three_d(self) -> bool {
        self == Dim::Three
    }
}

/// A peridynamic material model.
pub trait PdModel: Send + Sync {
    /// Config name.
    fn name(&self) -> &'static str;

    /// Force density on every particle for the current state; `dt` is the step just taken
    /// (rate forms integrate their stress over it). Updates bond damage in `bonds.intact`
    /// (or in the model's own bond arrays, see [`PdModel::sync_bonds`]).
    fn force_density(&mut self, k: &Kinematics, bonds: &mut Bonds, dt: f64, f: &mut [[f64; 3]]);

    /// Largest stable time step (s), before any safety factor.
    fn stable_dt(&self, k: &Kinematics, bonds: &Bonds, density: f64) -> f64;

    /// Elastic energy stored in the force state at the current deformation (J): what the
    /// internal forces give back on unloading (bond micro-potentials for pd-bond, the strain
    /// energy density of the stress for the correspondence models).
    fn strain_energy(&mut self, k: &Kinematics, bonds: &Bonds) -> f64;

    /// Work of plastic flow since the start (J, ≥ 0); 0 for an elastic model.
    fn plastic_work(&self, vol: &[f64]) -> f64 {
        let _ = vol;
        0.0
    }

    /// Energy released by bond damage since the start (J): the strain energy the damage
    /// took out of the force state (pd-bond: each broken bond's micro-potential, ≥ 0; the
    /// correspondence models: the drop of their strain energy when bonds change, see their
    /// `release`, which a single event can make negative).
    fn fracture_energy(&self) -> f64 {
        0.0
    }

    /// Copies model-held bond state into `bonds.intact` (for output); default: nothing to do.
    fn sync_bonds(&self, bonds: &mut Bonds) {
        let _ = bonds;
    }

    /// Writes into `bonds.intact` which bonds still tie their two particles together at
    /// positions `pos` (> 0: tied), for the fragments: by default every bond not broken
    /// ([`PdModel::sync_bonds`]). A model whose bonds stop carrying force past a distance
    /// says so here.
    fn fragment_links(&self, pos: &[[f64; 3]], bonds: &mut Bonds) {
        let _ = pos;
        self.sync_bonds(bonds);
    }

    /// Cauchy stress per particle, when the model has one.
    fn stress(&self) -> Option<Vec<Sym>> {
        None
    }

    /// Equivalent plastic strain per particle, when the model has one.
    fn plastic_strain(&self) -> Option<Vec<f64>> {
        None
    }

    /// Scales each particle's failure strain by `factor[i]` (Mott's scatter): a model whose
    /// stress law has a failure strain takes it, at its particles or (the mean of the two
    /// ends) at its bonds; others ignore it. Called once, at set-up.
    fn set_failure_factors(&mut self, factor: &[f64]) {
        let _ = factor;
    }

    /// Further per-particle scalars of the model's stress law (name, one value per
    /// particle), e.g. the temperature of a Johnson–Cook solid; none by default.
    fn point_scalars(&self) -> Vec<(&'static str, Vec<f64>)> {
        Vec::new()
    }

    /// The model's history (what the next step needs and cannot recompute) for a checkpoint,
    /// in the node kit's state encoding (`protocol::checkpoint::encode_state`).
    fn save_state(&self) -> SolverResult<Vec<u8>>;

    /// Restores what [`PdModel::save_state`] wrote, refusing a history of another size;
    /// caches are rebuilt on the next step.
    fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()>;

    /// Caps the instruction set of the model's bond kernels (benchmarks compare the builds;
    /// every choice gives the same bits, except pd-correspondence's explicit AVX-512 kernels,
    /// which sum in another order). Default: the model has no multiversioned kernel.
    fn set_simd(&mut self, simd: mechanics::simd::Simd) {
        let _ = simd;
    }

    /// A bound on the stiffness (N/m) a particle of volume `v` presents to a driver.
    fn stiffness_bound(&self, k: &Kinematics, bonds: &Bonds, i: usize) -> f64;

    /// The force density on particle `i` (N/m³) from its bonds to the particles `from` marks
    /// (nonzero): the pair forces of the last [`PdModel::force_density`], which sum with the
    /// same bonds' forces on those particles to zero. An overlap coupling's boundary layer
    /// sends it (the pull of the patch's own material on a layer particle). None: the model
    /// does not split its force by bond.
    fn partial_force(
        &self,
        k: &Kinematics,
        bonds: &Bonds,
        i: usize,
        from: &[u8],
    ) -> Option<[f64; 3]> {
        let _ = (k, bonds, i, from);
        None
    }

    /// Counts of the model's own that a run with damage reports each window (name, value),
    /// e.g. how many particles' gradients damage has reduced; none by default.
    fn damage_scalars(&self) -> Vec<(&'static str, f64)> {
        Vec::new()
    }

    /// Each particle's share of the last [`PdModel::strain_energy`] (J), when the model
    /// keeps them.
    fn point_energies(&self) -> Option<&[f64]> {
        None
    }
}
