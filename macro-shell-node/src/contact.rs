//! Automatic single-surface contact between the shells: every node against every segment
//! (element) it does not belong to, with the shells' thickness offsets — the kind crash
//! analysts know as automatic single-surface contact. A node whose distance d to a segment
//! (its closest point on the segment's two triangles) is below the mean of the two
//! half-thicknesses, g = d − ½(t_node + t_segment) < 0, is pushed off it by the penalty force
//! k (−g) along the line joining them, and the segment's nodes take the opposite force shared
//! by the closest point's barycentric weights. That force is −∇(½ k g²), so the contact stores
//! ½ k g² (reported with the internal energy) and gives it back; it is equal and opposite
//! about the line of the pair, so momentum and angular momentum are untouched (to round-off).
//!
//! Candidates come from the segments' centroids in a spatial hash (`mechanics::neighbour::
//! HashGrid`) of cells one reach wide, rebuilt in place every step (no allocation per step).
//! Each node takes its deepest penetration; segments sharing a node with the node's own
//! elements are not its candidates (a fold one element wide is not a contact).

use crate::model::Model;
use mechanics::neighbour::HashGrid;
use rayon::prelude::*;

/// Node chunk per rayon task.
const CHUNK: usize = 256;

/// The contact's set-up constants and its per-step work arrays.
#[derive(Debug, Clone)]
pub struct Contact {
    /// Penalty stiffness of each segment (N/m): `scale` × its membrane stiffness estimate.
    pub k: Vec<f64>,
    /// The largest of them (the stable step adds it to every node's stiffness).
    pub k_max: f64,
    /// Contact thickness of each node: the largest thickness of its elements (m).
    t_node: Vec<f64>,
    /// Cell size of the hash: the reach at which a segment's centroid can hold a contact.
    cell: f64,
    /// The segments' centroids and their spatial hash, rebuilt every step in place.
    centroids: Vec<[f64; 3]>,
    grid: HashGrid,
    /// Contact force on each node (N) at the current positions.
    pub force: Vec<[f64; 3]>,
    /// Each node's contact: (segment, magnitude k(−g), unit normal, weights of the segment's
    /// nodes); segment u32::MAX for none.
    pairs: Vec<(u32, f64, [f64; 3], [f64; 4])>,
    /// ½ Σ k g² at the current positions (J).
    pub energy: f64,
    /// Nodes in contact at the current positions.
    pub active: usize,
}

impl Contact {
    /// The contact of model `m` with penalty `scale` (a fraction of each segment's membrane
    /// stiffness estimate, `membrane[e]`).
    pub fn new(m: &Model, scale: f64, membrane: &[f64]) -> Self {
        let (nn, ne) = (m.num_nodes(), m.num_elements());
        let k: Vec<f64> = membrane.iter().map(|s| scale * s).collect();
        let k_max = k.iter().cloned().fold(0.0, f64::max);
        let mut t_node = vec![0.0f64; nn];
        let mut half_diag: f64 = 0.0;
        for (e, c) in m.conn.iter().enumerate() {
            for &n in c {
                t_node[n as usize] = t_node[n as usize].max(m.h0[e]);
            }
            let x = c.map(|n| m.x0[n as usize]);
            let cen = centroid(&x);
            for p in x {
                half_diag = half_diag.max(dist(p, cen));
            }
        }
        let t_max = m.h0.iter().cloned().fold(0.0, f64::max);
        Contact {
            k,
            k_max,
            t_node,
            // A contact needs d < t_max, so the node is within t_max + the half-diagonal
            // of the segment's centroid; twice the reference half-diagonal leaves room for
            // elements that stretch.
            cell: t_max + 2.0 * half_diag,
            centroids: vec![[0.0; 3]; ne],
            grid: HashGrid::default(),
            force: vec![[0.0; 3]; nn],
            pairs: vec![(u32::MAX, 0.0, [0.0; 3], [0.0; 4]); nn],
            energy: 0.0,
            active: 0,
        }
    }

    /// Contact forces and energy at the positions `m.x` (into `force`, `energy`).
    pub fn update(&mut self, m: &Model) {
        for (c, q) in self.centroids.iter_mut().zip(&m.conn) {
            *c = centroid(&q.map(|n| m.x[n as usize]));
        }
        self.grid.rebuild(&self.centroids, self.cell);
        // Each node's deepest penetration (parallel: every node writes its own entries).
        let mut pairs = std::mem::take(&mut self.pairs);
        let this = &*self;
        pairs
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(c, chunk)| {
                for (j, slot) in chunk.iter_mut().enumerate() {
                    *slot = this.deepest(m, c * CHUNK + j);
                }
            });
        self.pairs = pairs;
        // Forces, in node order (deterministic): the node's own, then its segment's share.
        self.force.fill([0.0; 3]);
        let (mut energy, mut active) = (0.0, 0);
        for (i, &(e, f, n, w)) in self.pairs.iter().enumerate() {
            if e == u32::MAX {
                continue;
            }
            let seg = m.conn[e as usize];
            for d in 0..3 {
                self.force[i][d] += f * n[d];
                for a in 0..4 {
                    self.force[seg[a] as usize][d] -= w[a] * f * n[d];
                }
            }
            energy += 0.5 * f * f / self.k[e as usize];
            active += 1;
        }
        self.energy = energy;
        self.active = active;
    }

    /// Node `i`'s deepest penetration into a segment: (segment, k(−g), normal, weights).
    fn deepest(&self, m: &Model, i: usize) -> (u32, f64, [f64; 3], [f64; 4]) {
        let none = (u32::MAX, 0.0, [0.0; 3], [0.0; 4]);
        let mut best = none;
        let mut best_gap = 0.0;
        let xi = m.x[i];
        let own = &m.adj[m.adj_offsets[i] as usize..m.adj_offsets[i + 1] as usize];
        self.grid.for_each_near(&xi, |e| {
            let e = e as usize;
            let seg = m.conn[e];
            // Not a segment of the node's own elements, nor one touching them.
            if own.iter().any(|&k| {
                let c = m.conn[(k >> 2) as usize];
                c.iter().any(|n| seg.contains(n))
            }) {
                return;
            }
            let x = seg.map(|n| m.x[n as usize]);
            let (p, w) = closest_on_quad(xi, &x);
            let d = dist(xi, p);
            let gap = d - 0.5 * (self.t_node[i] + m.h0[e]);
            if gap < best_gap && d > 0.0 {
                best_gap = gap;
                let n = [0, 1, 2].map(|c| (xi[c] - p[c]) / d);
                best = (e as u32, -self.k[e] * gap, n, w);
            }
        });
        best
    }
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn centroid(x: &[[f64; 3]; 4]) -> [f64; 3] {
    [0, 1, 2].map(|c| 0.25 * (x[0][c] + x[1][c] + x[2][c] + x[3][c]))
}

/// The point of the quad's two triangles (0, 1, 2) and (0, 2, 3) closest to `p`, and its
/// weights on the quad's four nodes.
fn closest_on_quad(p: [f64; 3], x: &[[f64; 3]; 4]) -> ([f64; 3], [f64; 4]) {
    let (q1, b1) = closest_on_triangle(p, x[0], x[1], x[2]);
    let (q2, b2) = closest_on_triangle(p, x[0], x[2], x[3]);
    if dist(p, q1) <= dist(p, q2) {
        (q1, [b1[0], b1[1], b1[2], 0.0])
    } else {
        (q2, [b2[0], 0.0, b2[1], b2[2]])
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The point of triangle (a, b, c) closest to `p` and its barycentric weights (Ericson,
/// Real-Time Collision Detection, §5.1.5: the Voronoi regions of the vertices and edges).
pub fn closest_on_triangle(
    p: [f64; 3],
    a: [f64; 3],
    b: [f64; 3],
    c: [f64; 3],
) -> ([f64; 3], [f64; 3]) {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, [1.0, 0.0, 0.0]);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (add_scaled(a, ab, v), [1.0 - v, v, 0.0]);
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (add_scaled(a, ac, w), [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (add_scaled(b, sub(c, b), w), [0.0, 1.0 - w, w]);
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    let q = [0, 1, 2].map(|k| a[k] + ab[k] * v + ac[k] * w);
    (q, [1.0 - v - w, v, w])
}

fn add_scaled(a: [f64; 3], d: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] + s * d[0], a[1] + s * d[1], a[2] + s * d[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_closest_point_of_a_triangle_in_each_region() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        // Above the face: straight down, weights reproduce the point.
        let (q, w) = closest_on_triangle([0.2, 0.3, 0.7], a, b, c);
        assert!(dist(q, [0.2, 0.3, 0.0]) < 1e-15);
        assert!((w[0] - 0.5).abs() < 1e-15 && (w[1] - 0.2).abs() < 1e-15);
        // Beyond vertex b, and beyond the hypotenuse.
        assert_eq!(closest_on_triangle([2.0, -1.0, 0.5], a, b, c).0, b);
        let (q, w) = closest_on_triangle([1.0, 1.0, 0.0], a, b, c);
        assert!(dist(q, [0.5, 0.5, 0.0]) < 1e-15 && (w[1] - 0.5).abs() < 1e-15);
    }
}
