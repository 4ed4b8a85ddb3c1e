//! Riemann solvers: one signature, one file each (seed 002 §2.3 uses HLLC).

pub mod hllc;

/// Largest number of flux components: 2·NM+3 conserved (+1 face velocity) for NM ≤ 4.
pub const MAXF: usize = 12;

/// A face state in primitive form, normal direction `d` given separately.
#[derive(Debug, Clone, Copy)]
pub struct FaceState<const NM: usize> {
    /// Partial densities α_k ρ_k.
    pub ar: [f64; NM],
    /// Volume fractions (all NM, summing to 1).
    pub al: [f64; NM],
    pub vel: [f64; 3],
    pub p: f64,
    pub rho: f64,
    /// Total energy per volume.
    pub e: f64,
    pub c: f64,
}
