//! Fracture measurements on a particle body: the direction of a
//! crack grown from a notch tip (least-squares line through the tip fitted to the damaged
//! particles), fragments (connected components over unbroken bonds), and the critical stretch
//! that makes the lattice's energy per unit crack area equal a given fracture energy G0
//! (Silling & Askari 2005: G0 is the work to break every bond crossing a unit crack area).
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use super::family::Bonds;

/// Result of a crack-direction fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrackFit {
    /// Angle of the fitted line to the +x axis, degrees, in [0, 180).
    pub angle_deg: f64,
    /// Damaged particles used.
    pub count: usize,
    /// RMS distance of those particles from the fitted line (m).
    pub rms_offset: f64,
    /// Farthest of them from the tip (m): the crack length reached.
    pub reach: f64,
}

/// Direction of the crack that leaves `tip` into the half plane `side·(y − tip_y) > 0`
/// (side = ±1): the particles with damage index ≥ `phi_min` whose reference distance from the
/// tip lies in [r_min, r_max] and with x ≥ tip_x are fitted by the line through the tip that
/// minimises the summed squared perpendicular distances (the principal axis of Σ o oᵀ about
/// the tip, o = X − tip). The angle is returned mirrored into the upper half plane for
/// side = −1, so both cracks of a symmetric set-up report the same number.
pub fn crack_angle(
    x0: &[[f64; 3]],
    damage: &[f64],
    tip: [f64; 2],
    side: f64,
    phi_min: f64,
    r_min: f64,
    r_max: f64,
) -> Option<CrackFit> {
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    let mut pts = Vec::new();
    for i in 0..x0.len() {
        let ox = x0[i][0] - tip[0];
        let oy = side * (x0[i][1] - tip[1]);
        let r = (ox * ox + oy * oy).sqrt();
        if damage[i] >= phi_min && r >= r_min && r <= r_max && ox >= 0.0 && oy > 0.0 {
            sxx += ox * ox;
            sxy += ox * oy;
            syy += oy * oy;
            pts.push((ox, oy, r));
        }
    }
    if pts.len() < 3 {
        return None;
    }
    // Principal direction of the 2×2 second moment about the tip.
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (c, s) = (theta.cos(), theta.sin());
    let mut off = 0.0;
    let mut reach: f64 = 0.0;
    for &(ox, oy, r) in &pts {
        let d = -s * ox + c * oy;
        off += d * d;
        reach = reach.max(r);
    }
    let mut deg = theta.to_degrees();
    if deg < 0.0 {
        deg += 180.0;
    }
    Some(CrackFit {
        angle_deg: deg,
        count: pts.len(),
        rms_offset: (off / pts.len() as f64).sqrt(),
        reach,
    })
}

/// Connected components of the particle graph over bonds with intact fraction > 0 (both
/// copies of a bond evolve identically, so the row of either end decides). Returns the
/// component label of every particle and the component sizes, labelled in order of their
/// lowest particle index (deterministic).
pub fn components(bonds: &Bonds, intact: &[f64]) -> (Vec<u32>, Vec<usize>) {
    let n = bonds.particles();
    let mut label = vec![u32::MAX; n];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for s in 0..n {
        if label[s] != u32::MAX {
            continue;
        }
        let c = sizes.len() as u32;
        label[s] = c;
        stack.push(s);
        let mut size = 0;
        while let Some(i) = stack.pop() {
            size += 1;
            for b in bonds.offsets[i]..bonds.offsets[i + 1] {
                let j = bonds.nbr[b] as usize;
                if intact[b] > 0.0 && label[j] == u32::MAX {
                    label[j] = c;
                    stack.push(j);
                }
            }
        }
        sizes.push(size);
    }
    (label, sizes)
}

/// Number of fragments: components with at least `min_size` particles.
pub fn fragment_count(bonds: &Bonds, intact: &[f64], min_size: usize) -> usize {
    components(bonds, intact)
        .1
        .iter()
        .filter(|&&s| s >= min_size)
        .count()
}

/// Critical stretch s0 for which breaking every bond that crosses the line y = `y_cut` over
/// x ∈ [x_lo, x_hi] costs G0 per unit crack area: G0 (x_hi − x_lo) h = Σ ½ c_b V_i |ξ| s0²,
/// where `coef[b]` is the bond's force coefficient (force density on i = coef_b · s · ŷ) and
/// each crossing pair is counted once (from its lower particle). `h` is the thickness in 2-D
/// (the extent along z in 3-D is taken as `h` as well: pass the body's z extent).
pub fn critical_stretch_for_energy(
    g0: f64,
    x0: &[[f64; 3]],
    vol: &[f64],
    bonds: &Bonds,
    coef: &[f64],
    y_cut: f64,
    x_lo: f64,
    x_hi: f64,
    h: f64,
) -> f64 {
    let mut sum = 0.0;
    for i in 0..x0.len() {
        if x0[i][1] >= y_cut || x0[i][0] < x_lo || x0[i][0] >= x_hi {
            continue;
        }
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            if x0[j][1] > y_cut {
                sum += 0.5 * coef[b] * vol[i] / bonds.inv_len[b];
            }
        }
    }
    (g0 * (x_hi - x_lo) * h / sum).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_fit_recovers_a_known_direction() {
        // Particles on a lattice; damage on a band along 68° from the tip.
        let dx = 1e-3;
        let mut x0 = Vec::new();
        let mut d = Vec::new();
        let t = 68f64.to_radians();
        for j in 0..80 {
            for i in 0..80 {
                let p = [i as f64 * dx, j as f64 * dx, 0.0];
                let dist = (-t.sin() * p[0] + t.cos() * p[1]).abs();
                x0.push(p);
                d.push(if dist < 0.8 * dx { 0.5 } else { 0.0 });
            }
        }
        let f = crack_angle(&x0, &d, [0.0, 0.0], 1.0, 0.3, 5e-3, 60e-3).unwrap();
        assert!((f.angle_deg - 68.0).abs() < 0.5, "{f:?}");
        // Mirrored: the same band below the tip reports the same angle.
        let xm: Vec<[f64; 3]> = x0.iter().map(|p| [p[0], -p[1], 0.0]).collect();
        let g = crack_angle(&xm, &d, [0.0, 0.0], -1.0, 0.3, 5e-3, 60e-3).unwrap();
        assert!((g.angle_deg - f.angle_deg).abs() < 1e-9);
    }

    #[test]
    fn components_of_two_separated_blocks() {
        let mut x0 = Vec::new();
        for i in 0..10 {
            x0.push([i as f64, 0.0, 0.0]);
        }
        let bonds = Bonds::build(&x0, 1.5);
        let mut intact = vec![1.0; bonds.len()];
        // Break the bond 4–5 in both rows.
        for i in [4usize, 5] {
            for b in bonds.offsets[i]..bonds.offsets[i + 1] {
                let j = bonds.nbr[b] as usize;
                if i + j == 9 {
                    intact[b] = 0.0;
                }
            }
        }
        let (lab, sizes) = components(&bonds, &intact);
        assert_eq!(sizes, vec![5, 5]);
        assert_eq!(lab[0], 0);
        assert_eq!(lab[9], 1);
        assert_eq!(fragment_count(&bonds, &intact, 6), 0);
    }
}
