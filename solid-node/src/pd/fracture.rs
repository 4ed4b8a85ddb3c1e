//! Fracture measurements on a particle body: the direction of a
//! crack grown from a notch tip (least-squares line through the tip fitted to the damaged
//! particles), fragments (connected components over unbroken bonds, each measured: mass,
//! speed, width and thickness — [`measure_fragments`]), and the critical stretch
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
use mechanics::neighbour::HashGrid;
use mechanics::xfem::Crack;
use std::collections::BinaryHeap;

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

/// One fragment as measured in its current configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fragment {
    /// Particles in it.
    pub particles: usize,
    /// Mass (kg; per unit thickness times the thickness in 2-D).
    pub mass: f64,
    /// Centre of mass (m).
    pub centroid: [f64; 3],
    /// Velocity of the centre of mass (m/s).
    pub velocity: [f64; 3],
    /// Extent along the tube (m): about an axis, the arc its particles span at their mean
    /// radius; without one, the extent along the longer principal axis of the x–y plane.
    /// Each particle stands for a cell one spacing wide, so a line of k particles is k
    /// spacings long.
    pub width: f64,
    /// Extent across (m): about an axis, the radial extent; without one, along the shorter
    /// principal axis (one spacing added as for the width).
    pub thickness: f64,
}

impl Fragment {
    /// Speed of the centre of mass (m/s).
    pub fn speed(&self) -> f64 {
        let v = self.velocity;
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
    }
}

/// The components of `label`/`sizes` with at least `min_size` particles, measured at the
/// current positions `pos` with velocities `vel` and particle masses `mass`, heaviest first
/// (ties by lowest label). `axis`: a point (x, y) of the tube's axis along z, for widths as
/// arcs and thicknesses as radial extents; `spacing`: the lattice spacing added to each
/// extent. Returns the fragments and, per particle, the index of its fragment in that list
/// (`u32::MAX` for a particle of a smaller piece).
pub fn measure_fragments(
    label: &[u32],
    sizes: &[usize],
    min_size: usize,
    pos: &[[f64; 3]],
    vel: &[[f64; 3]],
    mass: &[f64],
    axis: Option<[f64; 2]>,
    spacing: f64,
) -> (Vec<Fragment>, Vec<u32>) {
    // component label → rank among the kept ones (by label first, re-ranked by mass below)
    let kept: Vec<usize> = (0..sizes.len()).filter(|&c| sizes[c] >= min_size).collect();
    let mut slot = vec![u32::MAX; sizes.len()];
    for (k, &c) in kept.iter().enumerate() {
        slot[c] = k as u32;
    }
    let nk = kept.len();
    // (particle, index of its kept fragment) for every particle of a kept fragment
    let members = || {
        label
            .iter()
            .enumerate()
            .filter_map(|(i, &c)| match slot[c as usize] {
                u32::MAX => None,
                k => Some((i, k as usize)),
            })
    };
    // first pass: mass, momentum and first moment
    let mut m = vec![0.0; nk];
    let mut mx = vec![[0.0; 3]; nk];
    let mut mv = vec![[0.0; 3]; nk];
    for (i, k) in members() {
        m[k] += mass[i];
        for d in 0..3 {
            mx[k][d] += mass[i] * pos[i][d];
            mv[k][d] += mass[i] * vel[i][d];
        }
    }
    let centroid: Vec<[f64; 3]> = (0..nk)
        .map(|k| std::array::from_fn(|d| mx[k][d] / m[k]))
        .collect();
    // second pass: extents, in polar coordinates about the axis or along principal axes
    let mut lo = vec![[f64::INFINITY; 2]; nk];
    let mut hi = vec![[f64::NEG_INFINITY; 2]; nk];
    let mut mr = vec![0.0; nk];
    let frames: Vec<[f64; 4]> = match axis {
        // the centroid's angle: arcs are measured from it, so a piece across θ = ±π is whole
        Some(a) => centroid
            .iter()
            .map(|c| [(c[1] - a[1]).atan2(c[0] - a[0]), 0.0, 0.0, 0.0])
            .collect(),
        None => {
            let mut s = vec![[0.0; 3]; nk];
            for (i, k) in members() {
                let (dx, dy) = (pos[i][0] - centroid[k][0], pos[i][1] - centroid[k][1]);
                s[k][0] += mass[i] * dx * dx;
                s[k][1] += mass[i] * dx * dy;
                s[k][2] += mass[i] * dy * dy;
            }
            // the longer principal direction of the x–y second moment
            s.iter()
                .map(|s| {
                    let t = 0.5 * (2.0 * s[1]).atan2(s[0] - s[2]);
                    [t.cos(), t.sin(), 0.0, 0.0]
                })
                .collect()
        }
    };
    for (i, k) in members() {
        let q = match axis {
            Some(a) => {
                let (dx, dy) = (pos[i][0] - a[0], pos[i][1] - a[1]);
                let r = (dx * dx + dy * dy).sqrt();
                let mut dt = dy.atan2(dx) - frames[k][0];
                if dt > std::f64::consts::PI {
                    dt -= std::f64::consts::TAU;
                } else if dt < -std::f64::consts::PI {
                    dt += std::f64::consts::TAU;
                }
                mr[k] += mass[i] * r;
                [dt, r]
            }
            None => {
                let (dx, dy) = (pos[i][0] - centroid[k][0], pos[i][1] - centroid[k][1]);
                let [c, s, ..] = frames[k];
                [c * dx + s * dy, -s * dx + c * dy]
            }
        };
        for d in 0..2 {
            lo[k][d] = lo[k][d].min(q[d]);
            hi[k][d] = hi[k][d].max(q[d]);
        }
    }
    let mut out: Vec<Fragment> = (0..nk)
        .map(|k| {
            let (along, across) = match axis {
                Some(_) => ((hi[k][0] - lo[k][0]) * mr[k] / m[k], hi[k][1] - lo[k][1]),
                None => (hi[k][0] - lo[k][0], hi[k][1] - lo[k][1]),
            };
            Fragment {
                particles: sizes[kept[k]],
                mass: m[k],
                centroid: centroid[k],
                velocity: std::array::from_fn(|d| mv[k][d] / m[k]),
                width: along + spacing,
                thickness: across + spacing,
            }
        })
        .collect();
    // heaviest first; the sort is stable, so equal masses keep label order
    let mut order: Vec<usize> = (0..nk).collect();
    order.sort_by(|&a, &b| out[b].mass.total_cmp(&out[a].mass));
    let mut rank = vec![0u32; nk];
    for (r, &k) in order.iter().enumerate() {
        rank[k] = r as u32;
    }
    out = order.iter().map(|&k| out[k]).collect();
    let of_particle = label
        .iter()
        .map(|&c| match slot[c as usize] {
            u32::MAX => u32::MAX,
            k => rank[k as usize],
        })
        .collect();
    (out, of_particle)
}

/// Mean width, mean thickness and largest speed of `fragments` (zeros when there are none).
pub fn fragment_summary(fragments: &[Fragment]) -> [f64; 3] {
    if fragments.is_empty() {
        return [0.0; 3];
    }
    let n = fragments.len() as f64;
    [
        fragments.iter().map(|f| f.width).sum::<f64>() / n,
        fragments.iter().map(|f| f.thickness).sum::<f64>() / n,
        fragments.iter().map(Fragment::speed).fold(0.0, f64::max),
    ]
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

    /// A ring of particles on polar rows (radii r0 + k h, k < 4) cut into `pieces` equal
    /// arcs, the first centred on θ = π so that it straddles the ±π cut; component labels by
    /// arc.
    fn cut_ring(pieces: usize, per_piece: usize, r0: f64, h: f64) -> (Vec<[f64; 3]>, Vec<u32>) {
        let mut pos = Vec::new();
        let mut label = Vec::new();
        let dth = std::f64::consts::TAU / (pieces * per_piece) as f64;
        for p in 0..pieces {
            for j in 0..per_piece {
                let th = std::f64::consts::PI + (p * per_piece + j) as f64 * dth
                    - 0.5 * (per_piece - 1) as f64 * dth;
                for k in 0..4 {
                    let r = r0 + k as f64 * h;
                    pos.push([0.3 + r * th.cos(), -0.2 + r * th.sin(), 0.0]);
                    label.push(p as u32);
                }
            }
        }
        (pos, label)
    }

    #[test]
    fn arcs_of_a_cut_ring_measure_their_arc_and_wall() {
        let (h, r0) = (0.5e-3, 30e-3);
        let (pieces, per) = (12, 10);
        let (pos, label) = cut_ring(pieces, per, r0, h);
        let n = pos.len();
        let mut vel = vec![[0.0; 3]; n];
        // every piece moves outward at 100 m/s plus 7 m/s along z
        for i in 0..n {
            let (dx, dy) = (pos[i][0] - 0.3, pos[i][1] + 0.2);
            let r = (dx * dx + dy * dy).sqrt();
            vel[i] = [100.0 * dx / r, 100.0 * dy / r, 7.0];
        }
        let mass = vec![2.0e-3; n];
        let sizes = vec![4 * per; pieces];
        let (f, of) =
            measure_fragments(&label, &sizes, 10, &pos, &vel, &mass, Some([0.3, -0.2]), h);
        assert_eq!(f.len(), pieces);
        assert_eq!(of.len(), n);
        // the arc spanned by the particle centres at the mean radius, plus one spacing
        let dth = std::f64::consts::TAU / (pieces * per) as f64;
        let r_mean = r0 + 1.5 * h;
        let width = (per - 1) as f64 * dth * r_mean + h;
        for g in &f {
            assert_eq!(g.particles, 40);
            assert!((g.mass - 0.08).abs() < 1e-15);
            assert!(
                (g.width - width).abs() < 1e-12 * width,
                "{} {width}",
                g.width
            );
            assert!((g.thickness - 4.0 * h).abs() < 1e-12, "{}", g.thickness);
            // the centre of mass moves outward at the mean of the radial velocities'
            // projections on the piece's mid-line, and along z at 7 m/s
            let radial = 100.0
                * (0..per)
                    .map(|j| ((j as f64 - 0.5 * (per - 1) as f64) * dth).cos())
                    .sum::<f64>()
                / per as f64;
            assert!((g.speed() - (radial * radial + 49.0).sqrt()).abs() < 1e-9);
        }
        // the piece across θ = ±π is whole, not an arc of 2π
        let straddling = of[0] as usize;
        assert!(f[straddling].width < 2.0 * width);
        // pieces below the minimum size are left out and marked
        let mut small = sizes.clone();
        small[3] = 5;
        let (g, of) =
            measure_fragments(&label, &small, 10, &pos, &vel, &mass, Some([0.3, -0.2]), h);
        assert_eq!(g.len(), pieces - 1);
        let marked = of.iter().filter(|&&k| k == u32::MAX).count();
        assert_eq!(marked, 4 * per);
        let [w, t, v] = fragment_summary(&f);
        assert!((w - width).abs() < 1e-12 * width && (t - 4.0 * h).abs() < 1e-12);
        assert!(v > 99.0 && v < 101.0);
    }

    #[test]
    fn a_rotated_block_without_an_axis_measures_its_sides() {
        // 12 × 3 particles at spacing h, turned 30° and shifted; and a lighter 2 × 2 block
        let h = 1e-3;
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let mut pos = Vec::new();
        let mut label = Vec::new();
        for i in 0..12 {
            for j in 0..3 {
                let (x, y) = (i as f64 * h, j as f64 * h);
                pos.push([1.0 + c * x - s * y, 2.0 + s * x + c * y, 0.0]);
                label.push(0);
            }
        }
        for i in 0..2 {
            for j in 0..2 {
                pos.push([5.0 + i as f64 * h, j as f64 * h, 0.0]);
                label.push(1);
            }
        }
        let n = pos.len();
        let vel = vec![[3.0, 4.0, 0.0]; n];
        let mass = vec![1.0; n];
        let (f, of) = measure_fragments(&label, &[36, 4], 4, &pos, &vel, &mass, None, h);
        assert_eq!(f.len(), 2);
        // heaviest first: the 12 × 3 block is fragment 0
        assert_eq!((f[0].particles, f[1].particles), (36, 4));
        assert_eq!((of[0], of[n - 1]), (0, 1));
        assert!((f[0].width - 12.0 * h).abs() < 1e-12, "{}", f[0].width);
        assert!(
            (f[0].thickness - 3.0 * h).abs() < 1e-12,
            "{}",
            f[0].thickness
        );
        assert!((f[1].width - 2.0 * h).abs() < 1e-12 && (f[1].thickness - 2.0 * h).abs() < 1e-12);
        assert!((f[0].speed() - 5.0).abs() < 1e-12);
        let cx = 1.0 + c * 5.5 * h - s * 1.0 * h;
        assert!((f[0].centroid[0] - cx).abs() < 1e-12);
    }
}

/// Where a crack has got to: its tip and its length along its path (m), and how many broken
/// bonds carry it on from the tip it started with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrackFront {
    pub tip: [f64; 2],
    pub length: f64,
    pub bonds: usize,
}

/// The front of `crack` (its last point the tip it starts from) among the broken bonds of
/// `bonds`: each broken bond stands for a piece of crack at its reference midpoint; pieces
/// within `reach` of each other (the horizon) are joined, and so are those within `reach`
/// of the starting tip. The front is the joined piece farthest along that graph from the
/// starting tip (Dijkstra's shortest paths over `mechanics::neighbour::HashGrid`), and the
/// length the crack's own plus that path. Broken bonds not joined to the crack (another crack, a damaged edge) are not counted.
pub fn crack_front(x0: &[[f64; 3]], bonds: &Bonds, crack: &Crack, reach: f64) -> CrackFront {
    let start = crack.ends()[1];
    let mut pts: Vec<[f64; 3]> = Vec::new();
    for i in 0..x0.len() {
        for b in bonds.offsets[i]..bonds.offsets[i + 1] {
            let j = bonds.nbr[b] as usize;
            if j > i && bonds.intact[b] == 0.0 {
                pts.push([
                    0.5 * (x0[i][0] + x0[j][0]),
                    0.5 * (x0[i][1] + x0[j][1]),
                    0.0,
                ]);
            }
        }
    }
    let mut grid = HashGrid::default();
    grid.rebuild(&pts, reach);
    let dist = |a: [f64; 3], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
    /// A heap entry ordered by smallest path first.
    #[derive(PartialEq)]
    struct Next(f64, usize);
    impl Eq for Next {}
    impl PartialOrd for Next {
        fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
            Some(self.cmp(o))
        }
    }
    impl Ord for Next {
        fn cmp(&self, o: &Self) -> std::cmp::Ordering {
            o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
        }
    }
    let mut path = vec![f64::INFINITY; pts.len()];
    let mut heap = BinaryHeap::new();
    for (k, &p) in pts.iter().enumerate() {
        let d = dist(p, start);
        if d <= reach {
            path[k] = d;
            heap.push(Next(d, k));
        }
    }
    while let Some(Next(d, k)) = heap.pop() {
        if d > path[k] {
            continue;
        }
        let pk = [pts[k][0], pts[k][1]];
        grid.for_each_near(&pts[k], |m| {
            let m = m as usize;
            let step = dist(pts[m], pk);
            if step <= reach && d + step < path[m] {
                path[m] = d + step;
                heap.push(Next(d + step, m));
            }
        });
    }
    let joined = path.iter().filter(|d| d.is_finite()).count();
    let far = (0..pts.len())
        .filter(|&k| path[k].is_finite())
        .max_by(|&a, &b| path[a].total_cmp(&path[b]).then(b.cmp(&a)));
    match far {
        Some(k) => CrackFront {
            tip: [pts[k][0], pts[k][1]],
            length: crack.length() + path[k],
            bonds: joined,
        },
        None => CrackFront {
            tip: start,
            length: crack.length(),
            bonds: 0,
        },
    }
}
