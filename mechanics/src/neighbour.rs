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
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in x {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let cell = radius;
    let dims: [usize; 3] =
        std::array::from_fn(|d| (((hi[d] - lo[d]) / cell).floor() as usize + 1).max(1));
    let cell_of = |p: &[f64; 3]| -> [usize; 3] {
        std::array::from_fn(|d| (((p[d] - lo[d]) / cell).floor() as usize).min(dims[d] - 1))
    };
    let flat = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
    let ncell = dims[0] * dims[1] * dims[2];
    // Counting sort of points into cells.
    let mut start = vec![0usize; ncell + 1];
    let cells: Vec<usize> = x.iter().map(|p| flat(cell_of(p))).collect();
    for &c in &cells {
        start[c + 1] += 1;
    }
    for c in 0..ncell {
        start[c + 1] += start[c];
    }
    let mut fill = start.clone();
    let mut sorted = vec![0u32; n];
    for (i, &c) in cells.iter().enumerate() {
        sorted[fill[c]] = i as u32;
        fill[c] += 1;
    }
    let r2 = radius * radius * (1.0 + 1e-12);
    let rows: Vec<Vec<u32>> = (0..n)
        .into_par_iter()
        .map(|i| {
            let p = &x[i];
            let c = cell_of(p);
            let mut row = Vec::new();
            let range = |d: usize| c[d].saturating_sub(1)..=(c[d] + 1).min(dims[d] - 1);
            for cz in range(2) {
                for cy in range(1) {
                    for cx in range(0) {
                        let k = flat([cx, cy, cz]);
                        for &j in &sorted[start[k]..start[k + 1]] {
                            if j as usize == i {
                                continue;
                            }
                            let q = &x[j as usize];
                            let d2 = (q[0] - p[0]).powi(2)
                                + (q[1] - p[1]).powi(2)
                                + (q[2] - p[2]).powi(2);
                            if d2 <= r2 {
                                row.push(j);
                            }
                        }
                    }
                }
            }
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
    fn empty_input_gives_empty_rows() {
        let fam = find_neighbours(&[], 1.0);
        assert!(fam.is_empty());
        assert_eq!(fam.bonds(), 0);
    }
}
