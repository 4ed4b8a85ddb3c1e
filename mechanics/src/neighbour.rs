//! Fixed-radius neighbour search with a uniform cell list, returning families in compressed
//! rows (offsets + indices). Used by every particle solver (peridynamic families, SPG kernel
//! supports). Rows are sorted, so the result is the same for any thread count.

use rayon::prelude::*;

/// Neighbour lists in compressed-row form: the neighbours of point `i` are
/// `indices[offsets[i]..offsets[i + 1]]`, sorted ascending, never `i` itself.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Families {
    pub offsets: Vec<usize>,
    pub indices: Vec<u32>,
}

impl Families {
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    pub fn of(&self, i: usize) -> &[u32] {
        &self.indices[self.offsets[i]..self.offsets[i + 1]]
    }
    /// Total number of (point, neighbour) pairs.
    pub fn bonds(&self) -> usize {
        self.indices.len()
    }
}

/// A uniform cell list that can be rebuilt over new points without allocating once its
/// buffers have grown (for searches repeated during a run, e.g. contact candidates).
/// Points are counting-sorted into cubic cells of the edge given to [`CellGrid::rebuild`];
/// [`CellGrid::for_each_within`] visits the points in the 27 cells around a position.
#[derive(Debug, Clone, Default)]
pub struct CellGrid {
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// Points of cell c: `sorted[start[c]..start[c + 1]]`, ascending.
    start: Vec<usize>,
    sorted: Vec<u32>,
    /// Scratch of the rebuild: each point's cell, then the fill cursor per cell.
    cell_of_point: Vec<usize>,
    fill: Vec<usize>,
}

impl CellGrid {
    /// Sort `x` into cells of edge `cell` (> 0) over its bounding box.
    pub fn rebuild(&mut self, x: &[[f64; 3]], cell: f64) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in x {
            for d in 0..3 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        if x.is_empty() {
            (lo, hi) = ([0.0; 3], [0.0; 3]);
        }
        self.lo = lo;
        self.cell = cell;
        self.dims = std::array::from_fn(|d| (((hi[d] - lo[d]) / cell).floor() as usize + 1).max(1));
        let ncell = self.dims[0] * self.dims[1] * self.dims[2];
        self.start.clear();
        self.start.resize(ncell + 1, 0);
        self.cell_of_point.clear();
        for p in x {
            let c = self.flat(self.cell_of(p));
            self.cell_of_point.push(c);
            self.start[c + 1] += 1;
        }
        for c in 0..ncell {
            self.start[c + 1] += self.start[c];
        }
        self.fill.clear();
        self.fill.extend_from_slice(&self.start[..ncell]);
        self.sorted.clear();
        self.sorted.resize(x.len(), 0);
        for (i, &c) in self.cell_of_point.iter().enumerate() {
            self.sorted[self.fill[c]] = i as u32;
            self.fill[c] += 1;
        }
    }

    fn cell_of(&self, p: &[f64; 3]) -> [usize; 3] {
        std::array::from_fn(|d| {
            (((p[d] - self.lo[d]) / self.cell).floor().max(0.0) as usize).min(self.dims[d] - 1)
        })
    }

    fn flat(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// Call `f(j)` for every point j of the last rebuild over `x` with `|x_j − p|² ≤ r2`, where
    /// √r2 must not exceed the cell edge; cell by cell (z, y, x outermost to innermost), each
    /// cell's points ascending. `p` itself is visited if it is one of the points.
    pub fn for_each_within(&self, x: &[[f64; 3]], p: &[f64; 3], r2: f64, mut f: impl FnMut(u32)) {
        if self.sorted.is_empty() {
            return;
        }
        let c = self.cell_of(p);
        let range = |d: usize| c[d].saturating_sub(1)..=(c[d] + 1).min(self.dims[d] - 1);
        for cz in range(2) {
            for cy in range(1) {
                for cx in range(0) {
                    let k = self.flat([cx, cy, cz]);
                    for &j in &self.sorted[self.start[k]..self.start[k + 1]] {
                        let q = &x[j as usize];
                        let d2 =
                            (q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2);
                        if d2 <= r2 {
                            f(j);
                        }
                    }
                }
            }
        }
    }
}

/// A spatial hash of points into cubic cells: like [`CellGrid`], but its memory is set by the
/// number of points, not by their extent, so one point thrown far away (a diverging node, a
/// flying fragment) costs nothing. Rebuilt without allocating once it has grown;
/// [`HashGrid::for_each_near`] visits every point in the 27 cells around a position once
/// (cells that share a bucket are told apart by each point's own cell).
#[derive(Debug, Clone, Default)]
pub struct HashGrid {
    cell: f64,
    /// Points of bucket b: `items[start[b]..start[b + 1]]`, ascending; the bucket count is a
    /// power of two.
    start: Vec<u32>,
    items: Vec<u32>,
    /// Each point's cell.
    cell_of_item: Vec<[i64; 3]>,
}

impl HashGrid {
    /// Sort `x` into cells of edge `cell` (> 0).
    pub fn rebuild(&mut self, x: &[[f64; 3]], cell: f64) {
        self.cell = cell;
        let buckets = (2 * x.len()).next_power_of_two().max(2);
        self.start.clear();
        self.start.resize(buckets + 1, 0);
        self.cell_of_item.clear();
        for p in x {
            let c = self.cell_of(p);
            self.cell_of_item.push(c);
            let b = self.bucket(c);
            self.start[b + 1] += 1;
        }
        for b in 0..buckets {
            self.start[b + 1] += self.start[b];
        }
        self.items.clear();
        self.items.resize(x.len(), 0);
        // `start[b]` serves as bucket b's fill cursor, then is shifted back.
        for (i, &c) in self.cell_of_item.iter().enumerate() {
            let b = self.bucket(c);
            self.items[self.start[b] as usize] = i as u32;
            self.start[b] += 1;
        }
        for b in (1..=buckets).rev() {
            self.start[b] = self.start[b - 1];
        }
        self.start[0] = 0;
    }

    fn cell_of(&self, p: &[f64; 3]) -> [i64; 3] {
        // A non-finite coordinate saturates (NaN to 0): such a point lands in some cell,
        // never a panic.
        p.map(|x| (x / self.cell).floor() as i64)
    }

    fn bucket(&self, c: [i64; 3]) -> usize {
        let h = (c[0].wrapping_mul(73_856_093)
            ^ c[1].wrapping_mul(19_349_663)
            ^ c[2].wrapping_mul(83_492_791)) as u64;
        (h as usize) & (self.start.len() - 2)
    }

    /// Call `f(j)` once for every point j of the last rebuild whose cell is one of the 27
    /// around `p`'s (all points within one cell edge of `p` among them), bucket by bucket.
    pub fn for_each_near(&self, p: &[f64; 3], mut f: impl FnMut(u32)) {
        if self.items.is_empty() {
            return;
        }
        let home = self.cell_of(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let c = [
                        home[0].saturating_add(dx),
                        home[1].saturating_add(dy),
                        home[2].saturating_add(dz),
                    ];
                    let b = self.bucket(c);
                    for &j in &self.items[self.start[b] as usize..self.start[b + 1] as usize] {
                        if self.cell_of_item[j as usize] == c {
                            f(j);
                        }
                    }
                }
            }
        }
    }
}

/// The squared search radius with the relative tolerance of [`find_neighbours`].
pub fn radius_squared(radius: f64) -> f64 {
    radius * radius * (1.0 + 1e-12)
}

/// All points `j != i` with `|x_j - x_i| <= radius` (with a relative tolerance of 1e-12 on the
/// radius, so lattice points exactly on the horizon are included deterministically).
/// Works for 2-D data too (leave z = 0).
pub fn find_neighbours(x: &[[f64; 3]], radius: f64) -> Families {
    let n = x.len();
    if n == 0 || radius.is_nan() || radius <= 0.0 {
        return Families {
            offsets: vec![0; n + 1],
            indices: Vec::new(),
        };
    }
    let mut grid = CellGrid::default();
    grid.rebuild(x, radius);
    let r2 = radius_squared(radius);
    let rows: Vec<Vec<u32>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let mut row = Vec::new();
            grid.for_each_within(x, &x[i], r2, |j| {
                if j as usize != i {
                    row.push(j);
                }
            });
            row.sort_unstable();
            row
        })
        .collect();
    let mut offsets = Vec::with_capacity(n + 1);
    offsets.push(0);
    let mut total = 0;
    for r in &rows {
        total += r.len();
        offsets.push(total);
    }
    let mut indices = Vec::with_capacity(total);
    for r in rows {
        indices.extend_from_slice(&r);
    }
    Families { offsets, indices }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(n: usize, h: f64) -> Vec<[f64; 3]> {
        let mut x = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    x.push([i as f64 * h, j as f64 * h, k as f64 * h]);
                }
            }
        }
        x
    }

    #[test]
    fn matches_brute_force_and_counts_interior_family() {
        let h = 0.1;
        let x = lattice(9, h);
        let delta = 3.015 * h;
        let fam = find_neighbours(&x, delta);
        for i in 0..x.len() {
            let brute: Vec<u32> = (0..x.len())
                .filter(|&j| {
                    j != i && {
                        let d2: f64 = (0..3).map(|d| (x[j][d] - x[i][d]).powi(2)).sum();
                        d2 <= delta * delta * (1.0 + 1e-12)
                    }
                })
                .map(|j| j as u32)
                .collect();
            assert_eq!(fam.of(i), brute.as_slice(), "row {i}");
        }
        // Centre of the 9^3 lattice: the 122-member family of delta = 3.015 h.
        assert_eq!(fam.of(4 * 81 + 4 * 9 + 4).len(), 122);
    }

    #[test]
    fn rebuilt_grid_finds_the_same_rows_without_growing() {
        let h = 0.1;
        let mut x = lattice(7, h);
        let r = 2.0 * h;
        let mut grid = CellGrid::default();
        let mut row = Vec::new();
        let mut capacity = None;
        // Rebuild over moved points (a shear), as a contact search does every few steps.
        for step in 0..3 {
            for p in x.iter_mut() {
                p[0] += 0.01 * h * step as f64 * p[2];
            }
            grid.rebuild(&x, r);
            let fam = find_neighbours(&x, r);
            for i in 0..x.len() {
                row.clear();
                grid.for_each_within(&x, &x[i], radius_squared(r), |j| {
                    if j as usize != i {
                        row.push(j)
                    }
                });
                row.sort_unstable();
                assert_eq!(fam.of(i), row.as_slice(), "step {step}, row {i}");
            }
            let c = (grid.start.capacity(), grid.sorted.capacity());
            if step > 0 {
                assert_eq!(Some(c), capacity, "the rebuild must reuse its buffers");
            }
            capacity = Some(c);
        }
    }

    #[test]
    fn empty_input_gives_empty_rows() {
        let fam = find_neighbours(&[], 1.0);
        assert!(fam.is_empty());
        assert_eq!(fam.bonds(), 0);
    }

    #[test]
    fn the_hash_grid_finds_what_a_scan_finds_and_ignores_a_point_far_away() {
        let mut x = lattice(6, 0.1);
        x.push([1e300, -1e300, f64::NAN]);
        let mut g = HashGrid::default();
        g.rebuild(&x, 0.15);
        for (i, p) in x.iter().enumerate().take(x.len() - 1) {
            let mut near = Vec::new();
            g.for_each_near(p, |j| near.push(j));
            let mut seen = near.clone();
            seen.sort_unstable();
            seen.dedup();
            assert_eq!(
                seen.len(),
                near.len(),
                "point {i}: a neighbour visited twice"
            );
            for (j, q) in x.iter().enumerate() {
                let d2: f64 = (0..3).map(|d| (q[d] - p[d]).powi(2)).sum();
                if d2 <= 0.15 * 0.15 {
                    assert!(near.contains(&(j as u32)), "point {i} misses {j}");
                }
            }
        }
    }
}
