//! Riemann solvers: one signature, one file each (seed 002 §2.3 uses HLLC), and the face
//! states they take, built from primitive vectors.

pub mod hllc;

use crate::mixture::{self, Phase};

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

/// Build a face state from a primitive vector; `None` if inadmissible.
#[inline(always)]
pub fn face_state<const NM: usize>(ph: &[Phase; NM], q: &[f64; MAXF]) -> Option<FaceState<NM>> {
    let mut ar = [0.0; NM];
    let mut al = [0.0; NM];
    let mut rho = 0.0;
    let mut sa = 0.0;
    for k in 0..NM {
        ar[k] = q[k];
        rho += q[k];
        if !(q[k] >= 0.0) {
            return None;
        }
    }
    for k in 0..NM - 1 {
        let a = q[NM + 4 + k];
        if !(0.0..=1.0).contains(&a) {
            return None;
        }
        al[k] = a;
        sa += a;
    }
    // round-off may leave the last fraction a hair below zero
    al[NM - 1] = if sa > 1.0 && sa < 1.0 + 1e-12 {
        0.0
    } else {
        1.0 - sa
    };
    if !(rho > 0.0) || al[NM - 1] < 0.0 {
        return None;
    }
    let vel = [q[NM], q[NM + 1], q[NM + 2]];
    let p = q[NM + 3];
    let c2 = mixture::sound_speed2(ph, &ar, &al, rho, p);
    if !(c2 > 0.0) || !c2.is_finite() {
        return None;
    }
    let e = mixture::rhoe(ph, &ar, &al, p)
        + 0.5 * rho * (vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]);
    Some(FaceState {
        ar,
        al,
        vel,
        p,
        rho,
        e,
        c: c2.sqrt(),
    })
}
