//! The stress update of one material point behind one trait, so that a solver written once
//! (e.g. the correspondence peridynamic model) runs every material: [`StressLaw`] and its
//! members, J2 plasticity with linear hardening ([`J2Material`]) and the blast solid of
//! [`crate::blast_solid`] (Johnson–Cook strength, Mie–Grüneisen pressure, Johnson–Cook
//! failure).
//!
//! The update is the rate form of the solvers (docs/physics.md, "Correspondence"): the
//! stress of the last step is rotated with the spin W (Jaumann), then the law integrates the
//! strain increment Δε = sym(L) Δt over the step; J = det F at the step's end lets a law
//! take its pressure from the density ρ₀/J (an equation of state).

use crate::j2::{J2Material, J2State, Sym, jaumann_rotate};

/// The stress update of a material point in rate form.
pub trait StressLaw: Copy + Send + Sync + std::fmt::Debug + 'static {
    /// What a point carries from step to step (its history), checkpointed as it is.
    type State: Copy
        + Default
        + Send
        + Sync
        + std::fmt::Debug
        + serde::Serialize
        + serde::de::DeserializeOwned;

    /// The state of a virgin point at rest.
    fn initial_state(&self) -> Self::State;

    /// One step of length `dt` (> 0): rotate the stress with the spin `spin` (Jaumann),
    /// integrate the strain increment `de` (Voigt, tensor shear), with `jac` = J = det F at
    /// the step's end; `plane_stress`: Δε_zz is solved for σ_zz = 0 (only for a law whose
    /// [`StressLaw::plane_stress`] is true). Returns the plastic work density of the step
    /// (J/m³, ≥ 0).
    fn step(
        &self,
        st: &mut Self::State,
        de: &Sym,
        spin: &[[f64; 3]; 3],
        dt: f64,
        jac: f64,
        plane_stress: bool,
    ) -> f64;

    /// Cauchy stress (Pa), Voigt order, tensor shear.
    fn stress(st: &Self::State) -> &Sym;

    /// Accumulated equivalent plastic strain.
    fn eq_plastic_strain(st: &Self::State) -> f64;

    /// The point's cumulative failure indicator (≥ 1: failed), for a law that has one;
    /// 0 otherwise.
    fn failure(st: &Self::State) -> f64 {
        let _ = st;
        0.0
    }

    /// Energy density the elastic part of the deformation stores (J/m³), what the point
    /// gives back on unloading.
    fn stored_energy(&self, st: &Self::State) -> f64;

    /// Young's modulus E (Pa) and Poisson's ratio ν of the elastic part.
    fn elastic_constants(&self) -> (f64, f64);

    /// The P-wave modulus K + 4G/3 of the reference state (Pa), for the stable step and the
    /// stiffness a driver sees.
    fn wave_modulus(&self) -> f64;

    /// Whether the law integrates plane stress (`step` with `plane_stress`).
    fn plane_stress(&self) -> bool;

    /// Scales the point's failure strain by `factor` (a statistical scatter); a law without
    /// failure ignores it.
    fn set_failure_factor(st: &mut Self::State, factor: f64) {
        let _ = (st, factor);
    }

    /// Names of the point scalars the law reports beyond stress and plastic strain (e.g.
    /// temperature), and their values at a point, in that order.
    fn scalar_names(&self) -> &'static [&'static str] {
        &[]
    }
    fn scalar(st: &Self::State, k: usize) -> f64 {
        let _ = (st, k);
        f64::NAN
    }
}

impl StressLaw for J2Material {
    type State = J2State;

    fn initial_state(&self) -> J2State {
        J2State::default()
    }

    /// Jaumann rotation of the stress and back stress, then the radial return
    /// ([`J2Material::update`], or [`J2Material::update_plane_stress`]); J is not used.
    #[inline]
    fn step(
        &self,
        st: &mut J2State,
        de: &Sym,
        spin: &[[f64; 3]; 3],
        dt: f64,
        _jac: f64,
        plane_stress: bool,
    ) -> f64 {
        jaumann_rotate(&mut st.stress, spin, dt);
        jaumann_rotate(&mut st.back_stress, spin, dt);
        let deqp = if plane_stress {
            self.update_plane_stress(st, de).0
        } else {
            self.update(st, de)
        };
        crate::j2::plastic_work(st, deqp)
    }

    #[inline]
    fn stress(st: &J2State) -> &Sym {
        &st.stress
    }

    #[inline]
    fn eq_plastic_strain(st: &J2State) -> f64 {
        st.eq_plastic_strain
    }

    #[inline]
    fn stored_energy(&self, st: &J2State) -> f64 {
        self.elastic_energy(&st.stress)
    }

    fn elastic_constants(&self) -> (f64, f64) {
        (self.young, self.poisson)
    }

    fn wave_modulus(&self) -> f64 {
        self.bulk_modulus() + 4.0 / 3.0 * self.shear_modulus()
    }

    fn plane_stress(&self) -> bool {
        true
    }
}
