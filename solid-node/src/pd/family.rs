//! Peridynamic families in compressed rows (from `mechanics::neighbour`), with the reference
//! bond vectors ξ, their lengths, and the per-bond intact fraction ω_D (seed 000 eq. C.1),
//! plus the deterministic row-parallel driver every kernel uses (gather per particle).
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use mechanics::neighbour::{Families, find_neighbours};
use mechanics::tensor::vec3;

/// Bonds of all particles: the bonds of particle `i` are `offsets[i]..offsets[i + 1]`.
/// Both (i, j) and (j, i) are stored; each row owns its copy of the bond state, and the two
/// copies evolve identically because every bond quantity is symmetric in i and j.
#[derive(Debug, Clone, Default)]
pub struct Bonds {
    pub offsets: Vec<usize>,
    pub nbr: Vec<u32>,
    /// Reference bond vector ξ = X_j − X_i.
    pub xi: Vec<[f64; 3]>,
    /// 1/|ξ|.
    pub inv_len: Vec<f64>,
    /// Intact fraction ω_D ∈ [0, 1] (1 intact, 0 broken), never increasing.
    pub intact: Vec<f64>,
    /// Per particle: in a no-fail zone (a bond with either end there never breaks). Empty
    /// when the body has none, so kernels test it only on the rare path of a bond about to
    /// break ([`spared`]).
    pub no_fail: Vec<bool>,
}

/// Whether bond (i, j) is kept whatever its damage law says: either end in a no-fail zone
/// (`no_fail` as [`Bonds::no_fail`]; empty: none).
#[inline]
pub fn spared(no_fail: &[bool], i: usize, j: usize) -> bool {
    !no_fail.is_empty() && (no_fail[i] || no_fail[j])
}

/// `mask` (bit l: bond `nb[l]` of particle `i`'s row breaks) less the bonds a no-fail zone
/// keeps: the vector kernels' rare path, to be called only when some bond of the chunk breaks
/// and the body has zones. Kept out of line (and cold): a call inside the vector loop would
/// make the loop save its vector registers around it; taken only on that rare branch, it
/// costs nothing (measured: called on every chunk it slowed the kernels by a quarter).
#[cold]
#[inline(never)]
pub fn spare_mask(no_fail: &[bool], i: usize, nb: &[u32], mask: u8) -> u8 {
    if no_fail.is_empty() || mask == 0 {
        return mask;
    }
    let mut m = mask;
    for (l, &j) in nb.iter().enumerate().take(8) {
        if m & (1 << l) != 0 && spared(no_fail, i, j as usize) {
            m &= !(1 << l);
        }
    }
    m
}

impl Bonds {
    /// Families within `horizon` of the reference positions `x0`.
    pub fn build(x0: &[[f64; 3]], horizon: f64) -> Self {
        let Families { offsets, indices } = find_neighbours(x0, horizon);
        let mut xi = Vec::with_capacity(indices.len());
        let mut inv_len = Vec::with_capacity(indices.len());
        for i in 0..x0.len() {
            for &j in &indices[offsets[i]..offsets[i + 1]] {
                let d = vec3(&x0[j as usize]) - vec3(&x0[i]);
                xi.push(d.into());
                inv_len.push(1.0 / d.norm());
            }
        }
        let n = indices.len();
        Bonds {
            offsets,
            nbr: indices,
            xi,
            inv_len,
            intact: vec![1.0; n],
            no_fail: Vec::new(),
        }
    }

    pub fn len(&self) -> usize {
        self.nbr.len()
    }

    /// The same families less the bonds `cut(i, j)` refuses (a crack there from the start:
    /// the bonds are not broken, they never were). `cut` is asked with i < j only, so that
    /// the families stay symmetric even where its answer depends on the order (a crossing
    /// test at a crack's end point, decided by round-off).
    pub fn without(&self, cut: impl Fn(usize, usize) -> bool) -> Bonds {
        let n = self.offsets.len() - 1;
        let mut out = Bonds {
            offsets: Vec::with_capacity(n + 1),
            nbr: Vec::with_capacity(self.nbr.len()),
            xi: Vec::with_capacity(self.nbr.len()),
            inv_len: Vec::with_capacity(self.nbr.len()),
            intact: Vec::with_capacity(self.nbr.len()),
            no_fail: self.no_fail.clone(),
        };
        out.offsets.push(0);
        for i in 0..n {
            for b in self.offsets[i]..self.offsets[i + 1] {
                let j = self.nbr[b] as usize;
                if !cut(i.min(j), i.max(j)) {
                    out.nbr.push(self.nbr[b]);
                    out.xi.push(self.xi[b]);
                    out.inv_len.push(self.inv_len[b]);
                    out.intact.push(self.intact[b]);
                }
            }
            out.offsets.push(out.nbr.len());
        }
        out
    }

    /// The index of bond (j, i) for bond `b` = (i, j) of row `i`, `None` when the family of
    /// j does not hold i. Rows are sorted by neighbour (`find_neighbours` sorts them), so a
    /// binary search finds it: O(log family), not a scan of the row.
    pub fn twin(&self, i: usize, b: usize) -> Option<usize> {
        let j = self.nbr[b] as usize;
        let start = self.offsets[j];
        let row = &self.nbr[start..self.offsets[j + 1]];
        u32::try_from(i)
            .ok()
            .and_then(|i| row.binary_search(&i).ok())
            .map(|k| start + k)
    }

    /// [`Bonds::twin`] of every bond (0 where there is none; families are symmetric, one
    /// horizon, so every bond has one), in parallel over rows.
    pub fn twins(&self) -> Vec<u32> {
        let mut rev = vec![0u32; self.len()];
        let mut rows = vec![(); self.particles()];
        par_rows(
            &self.offsets,
            &mut rows,
            &mut rev,
            &|i, _, row: &mut [u32]| {
                for (k, r) in row.iter_mut().enumerate() {
                    *r = self.twin(i, self.offsets[i] + k).unwrap_or(0) as u32;
                }
            },
        );
        rev
    }

    pub fn is_empty(&self) -> bool {
        self.nbr.is_empty()
    }

    pub fn particles(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Damage index φ_i = 1 − Σ ω_D V_j / Σ V_j per particle.
    pub fn damage(&self, vol: &[f64], out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            let (mut a, mut b) = (0.0, 0.0);
            for k in self.offsets[i]..self.offsets[i + 1] {
                let v = vol[self.nbr[k] as usize];
                a += self.intact[k] * v;
                b += v;
            }
            *o = if b > 0.0 { 1.0 - a / b } else { 0.0 };
        }
    }
}

/// Members of a full (interior) family on a lattice of spacing `dx`: the lattice vectors
/// n ≠ 0 with |n| Δx ≤ δ (with `find_neighbours`' tolerance), counted line by line in
/// O(m²) for m = δ/Δx ≤ 1000; past that (families of over 3·10⁶ members), the volume of
/// the ball 4/3 π m³ or the disc π m², which differ from the count by less than 1 %.
pub fn full_family(horizon: f64, dx: f64, three_d: bool) -> f64 {
    let r = horizon / dx;
    if !r.is_finite() || r < 0.0 {
        return f64::INFINITY;
    }
    if r > 1000.0 {
        return if three_d {
            4.0 / 3.0 * std::f64::consts::PI * r.powi(3)
        } else {
            std::f64::consts::PI * r * r
        };
    }
    let r2 = mechanics::neighbour::radius_squared(r);
    let m = r.floor() as i64;
    // lattice points of the segment −√rem ≤ c ≤ √rem
    let line = |rem: f64| {
        if rem < 0.0 {
            0.0
        } else {
            2.0 * rem.sqrt().floor() + 1.0
        }
    };
    let mut n = 0.0;
    for a in -m..=m {
        let ra = r2 - (a * a) as f64;
        if three_d {
            for b in -m..=m {
                n += line(ra - (b * b) as f64);
            }
        } else {
            n += line(ra);
        }
    }
    n - 1.0
}

/// Particles per rayon task.
pub(crate) const GRAIN: usize = 256;

/// Runs `f(i, &mut per_particle[i], &mut per_bond[row i])` for every particle, in parallel
/// over contiguous particle ranges. Each call writes only its own particle and its own row,
/// so the result is bit-identical for any thread count. No allocation.
pub fn par_rows<P, B, F>(offsets: &[usize], per_particle: &mut [P], per_bond: &mut [B], f: &F)
where
    P: Send,
    B: Send,
    F: Fn(usize, &mut P, &mut [B]) + Sync,
{
    par_row_blocks(offsets, per_particle, per_bond, &|lo, pp, pb| {
        let mut rest = pb;
        for (k, p) in pp.iter_mut().enumerate() {
            let i = lo + k;
            let len = offsets[i + 1] - offsets[i];
            let (row, tail) = std::mem::take(&mut rest).split_at_mut(len);
            rest = tail;
            f(i, p, row);
        }
    });
}

/// Runs `f(lo, &mut per_particle[lo..hi], &mut per_bond[offsets[lo]..offsets[hi]])` on
/// contiguous blocks of at most [`GRAIN`] particles, in parallel: a kernel that keeps scratch
/// per block (set up once, not per row) sees whole blocks. The blocks depend only on the
/// particle count, so results are bit-identical for any thread count. No allocation.
pub fn par_row_blocks<P, B, F>(offsets: &[usize], per_particle: &mut [P], per_bond: &mut [B], f: &F)
where
    P: Send,
    B: Send,
    F: Fn(usize, &mut [P], &mut [B]) + Sync,
{
    fn rec<P: Send, B: Send, F: Fn(usize, &mut [P], &mut [B]) + Sync>(
        lo: usize,
        offsets: &[usize],
        pp: &mut [P],
        pb: &mut [B],
        f: &F,
    ) {
        let n = pp.len();
        if n <= GRAIN {
            f(lo, pp, pb);
            return;
        }
        let mid = n / 2;
        let (p0, p1) = pp.split_at_mut(mid);
        let (b0, b1) = pb.split_at_mut(offsets[lo + mid] - offsets[lo]);
        rayon::join(
            || rec(lo, offsets, p0, b0, f),
            || rec(lo + mid, offsets, p1, b1, f),
        );
    }
    let n = per_particle.len();
    debug_assert_eq!(per_bond.len(), offsets[n] - offsets[0]);
    rec(0, offsets, per_particle, per_bond, f);
}

/// Particle-only parallel map (no per-bond output), same determinism guarantee.
pub fn par_points<P, F>(per_particle: &mut [P], f: &F)
where
    P: Send,
    F: Fn(usize, &mut P) + Sync,
{
    use rayon::prelude::*;
    per_particle
        .par_iter_mut()
        .with_min_len(GRAIN)
        .enumerate()
        .for_each(|(i, p)| f(i, p));
}

/// Surface particles: fewer than the full set of 2·dim lattice nearest neighbours within
/// 1.01 Δx among their family members.
pub fn surface_particles(x0: &[[f64; 3]], bonds: &Bonds, dx: f64, three_d: bool) -> Vec<usize> {
    let full = if three_d { 6 } else { 4 };
    let lim = 1.01 * dx;
    (0..x0.len())
        .filter(|&i| {
            let c = (bonds.offsets[i]..bonds.offsets[i + 1])
                .filter(|&k| 1.0 / bonds.inv_len[k] <= lim)
                .count();
            c < full
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pd::geometry::cube_lattice;

    #[test]
    fn benchmark_block_has_the_stated_bond_count() {
        // ISSUE: 31³ block, δ = 3.015 Δx: 122-member interior families, 3,244,494 bonds.
        let x = cube_lattice(31, 1.0);
        let b = Bonds::build(&x, 3.015);
        assert_eq!(b.particles(), 29_791);
        assert_eq!(b.len(), 3_244_494);
        let centre = 15 + 31 * (15 + 31 * 15);
        assert_eq!(b.offsets[centre + 1] - b.offsets[centre], 122);
    }

    #[test]
    fn full_family_is_the_interior_family_find_neighbours_gives() {
        // the centre particle of a lattice wider than two horizons: its row is a full family
        for (ratio, three_d) in [
            (1.5, true),
            (2.0, true),
            (3.015, true),
            (4.5, true),
            (3.015, false),
            (6.0, false),
            (12.0, false),
        ] {
            let n = 2 * ratio as usize + 3;
            let x: Vec<[f64; 3]> = if three_d {
                cube_lattice(n, 1.0)
            } else {
                cube_lattice(n, 1.0)
                    .into_iter()
                    .filter(|p| p[2] == 0.0)
                    .collect()
            };
            let c = n / 2;
            let centre = c + n * (c + if three_d { n * c } else { 0 });
            assert_eq!(
                x[centre],
                [c as f64, c as f64, if three_d { c as f64 } else { 0.0 }]
            );
            let b = Bonds::build(&x, ratio);
            let row = (b.offsets[centre + 1] - b.offsets[centre]) as f64;
            assert_eq!(
                full_family(ratio, 1.0, three_d),
                row,
                "δ/Δx = {ratio}, 3-D {three_d}"
            );
        }
        // past the counted range: the ball's volume
        let big = full_family(2000.0, 1.0, true);
        assert!((big / (4.0 / 3.0 * std::f64::consts::PI * 8e9) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn twins_are_the_reverse_bonds() {
        let x = cube_lattice(6, 1.0);
        let b = Bonds::build(&x, 2.2);
        let rev = b.twins();
        assert_eq!(rev.len(), b.len());
        for i in 0..b.particles() {
            for k in b.offsets[i]..b.offsets[i + 1] {
                let t = rev[k] as usize;
                assert_eq!(b.nbr[t] as usize, i, "bond {k}");
                assert!(
                    (b.offsets[b.nbr[k] as usize]..b.offsets[b.nbr[k] as usize + 1]).contains(&t)
                );
            }
        }
    }

    #[test]
    fn par_rows_visits_each_row_once() {
        let x = cube_lattice(12, 1.0);
        let b = Bonds::build(&x, 2.0);
        let mut cnt = vec![0usize; b.particles()];
        let mut tag = vec![0u32; b.len()];
        par_rows(&b.offsets, &mut cnt, &mut tag, &|i, c, row: &mut [u32]| {
            *c = row.len();
            for t in row.iter_mut() {
                *t = i as u32;
            }
        });
        for i in 0..b.particles() {
            assert_eq!(cnt[i], b.offsets[i + 1] - b.offsets[i]);
            assert!(
                tag[b.offsets[i]..b.offsets[i + 1]]
                    .iter()
                    .all(|&t| t == i as u32)
            );
        }
    }
}
