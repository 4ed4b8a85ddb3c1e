//! What several solvers share (docs/architecture.md): constitutive updates (J2 plasticity with
//! isotropic and kinematic hardening, in 3-D and plane stress; Johnson–Cook visco-plasticity
//! with adiabatic heating and its failure law; the blast solid that joins them to an
//! equation of state), the Mie–Grüneisen equation of state, one trait over them all, damage
//! laws, meshfree kernels, neighbour search in compressed rows, explicit time-step helpers,
//! 2-D bilinear finite elements, the GS4-II time integrators and the small tensor algebra (on
//! nalgebra). One concern per file.

pub mod blast_solid;
pub mod damage;
pub mod fem2d;
pub mod gpu;
pub mod hex8;
pub mod j2;
pub mod j2_plane_stress;
pub mod johnson_cook;
pub mod kernel;
pub mod lanes;
pub mod mie_gruneisen;
pub mod neighbour;
pub mod simd;
pub mod stress_law;
pub mod tensor;
pub mod time;
pub mod xfem;
