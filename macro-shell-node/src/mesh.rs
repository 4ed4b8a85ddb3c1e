//! Shell meshes from simple geometry: rectangular plates and strips, two overlapping plates (a
//! lap joint), and a square tube whose wall sheet overlaps itself along a seam (seed 004 §4.3
//! crash tube), with named node sets and element sets. Quads are numbered counter-clockwise
//! seen from the side the normal points to.

use std::collections::BTreeMap;

/// A quad shell mesh with named sets.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub nodes: Vec<[f64; 3]>,
    pub elements: Vec<[u32; 4]>,
    pub node_sets: BTreeMap<String, Vec<u32>>,
    pub element_sets: BTreeMap<String, Vec<u32>>,
}

impl Mesh {
    /// Appends a structured grid of `n1 × n2` elements spanned by `origin + s·a + t·b`,
    /// s, t ∈ [0, 1]; returns the node index of grid point (i, j) as `base + j (n1+1) + i`.
    fn grid(&mut self, origin: [f64; 3], a: [f64; 3], b: [f64; 3], n1: usize, n2: usize) -> u32 {
        let base = self.nodes.len() as u32;
        for j in 0..=n2 {
            for i in 0..=n1 {
                let s = i as f64 / n1 as f64;
                let t = j as f64 / n2 as f64;
                self.nodes.push([
                    origin[0] + s * a[0] + t * b[0],
                    origin[1] + s * a[1] + t * b[1],
                    origin[2] + s * a[2] + t * b[2],
                ]);
            }
        }
        let row = (n1 + 1) as u32;
        for j in 0..n2 as u32 {
            for i in 0..n1 as u32 {
                let n0 = base + j * row + i;
                self.elements.push([n0, n0 + 1, n0 + 1 + row, n0 + row]);
            }
        }
        base
    }

    /// Nodes whose position lies in the box [lo, hi] (inclusive, with tolerance `tol`).
    pub fn nodes_in_box(&self, lo: [f64; 3], hi: [f64; 3], tol: f64) -> Vec<u32> {
        (0..self.nodes.len() as u32)
            .filter(|&i| {
                let p = self.nodes[i as usize];
                (0..3).all(|k| p[k] >= lo[k] - tol && p[k] <= hi[k] + tol)
            })
            .collect()
    }

    /// Elements whose centroid lies in the box [lo, hi].
    pub fn elements_in_box(&self, lo: [f64; 3], hi: [f64; 3], tol: f64) -> Vec<u32> {
        (0..self.elements.len() as u32)
            .filter(|&e| {
                let c = self.centroid(e as usize);
                (0..3).all(|k| c[k] >= lo[k] - tol && c[k] <= hi[k] + tol)
            })
            .collect()
    }

    pub fn centroid(&self, e: usize) -> [f64; 3] {
        let mut c = [0.0; 3];
        for &n in &self.elements[e] {
            for k in 0..3 {
                c[k] += 0.25 * self.nodes[n as usize][k];
            }
        }
        c
    }

    /// Bounding-box diagonal, for geometric tolerances.
    pub fn size(&self) -> f64 {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in &self.nodes {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt()
    }

    /// Sorted unique nodes of a set of elements.
    pub fn nodes_of_elements(&self, elems: &[u32]) -> Vec<u32> {
        let mut v: Vec<u32> = elems
            .iter()
            .flat_map(|&e| self.elements[e as usize])
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    fn all_sets(&mut self) {
        self.node_sets
            .insert("all".into(), (0..self.nodes.len() as u32).collect());
        self.element_sets
            .insert("all".into(), (0..self.elements.len() as u32).collect());
    }
}

/// A flat rectangular plate (or strip) `length × width` in the x–y plane from `origin`,
/// `nx × ny` elements. Sets: `all`, edges `x0`, `x1`, `y0`, `y1`.
pub fn plate(length: f64, width: f64, nx: usize, ny: usize, origin: [f64; 3]) -> Mesh {
    let mut m = Mesh::default();
    m.grid(origin, [length, 0.0, 0.0], [0.0, width, 0.0], nx, ny);
    let tol = 1e-9 * length.max(width);
    let (o, l, w) = (origin, length, width);
    let big = f64::INFINITY;
    m.node_sets.insert(
        "x0".into(),
        m.nodes_in_box([o[0], -big, -big], [o[0], big, big], tol),
    );
    m.node_sets.insert(
        "x1".into(),
        m.nodes_in_box([o[0] + l, -big, -big], [o[0] + l, big, big], tol),
    );
    m.node_sets.insert(
        "y0".into(),
        m.nodes_in_box([-big, o[1], -big], [big, o[1], big], tol),
    );
    m.node_sets.insert(
        "y1".into(),
        m.nodes_in_box([-big, o[1] + w, -big], [big, o[1] + w, big], tol),
    );
    m.all_sets();
    m
}

/// Several separate flat plates (no shared nodes), each `(origin, length, width, nx, ny)` in
/// the x–y plane at its origin's z: e.g. the two shell ends of seed 004 §4.1's two-scale
/// coupon, or a lap joint with the plates at chosen heights. Sets: `plate<k>` (elements and
/// nodes of plate k) and `all`.
pub fn plates(list: &[([f64; 3], f64, f64, usize, usize)]) -> Mesh {
    let mut m = Mesh::default();
    for (k, &(origin, length, width, nx, ny)) in list.iter().enumerate() {
        let (n0, e0) = (m.nodes.len() as u32, m.elements.len() as u32);
        m.grid(origin, [length, 0.0, 0.0], [0.0, width, 0.0], nx, ny);
        m.node_sets
            .insert(format!("plate{k}"), (n0..m.nodes.len() as u32).collect());
        m.element_sets
            .insert(format!("plate{k}"), (e0..m.elements.len() as u32).collect());
    }
    m.all_sets();
    m
}

/// A single-lap joint: plate A on [0, L] × [0, W] at z = 0 and plate B on
/// [L − overlap, 2L − overlap] × [0, W] at z = gap (separate nodes; joints connect them).
/// Sets: `a`, `b` (elements), `a_overlap`, `b_overlap` (elements in the overlap),
/// `a_end` (x = 0 nodes), `b_end` (x = 2L − overlap nodes).
#[allow(clippy::too_many_arguments)]
pub fn lap_joint(length: f64, width: f64, overlap: f64, gap: f64, nx: usize, ny: usize) -> Mesh {
    let mut m = Mesh::default();
    m.grid([0.0; 3], [length, 0.0, 0.0], [0.0, width, 0.0], nx, ny);
    let ea = m.elements.len() as u32;
    let x0b = length - overlap;
    m.grid(
        [x0b, 0.0, gap],
        [length, 0.0, 0.0],
        [0.0, width, 0.0],
        nx,
        ny,
    );
    let ne = m.elements.len() as u32;
    let tol = 1e-9 * length;
    let a: Vec<u32> = (0..ea).collect();
    let b: Vec<u32> = (ea..ne).collect();
    let in_overlap = |m: &Mesh, e: u32| {
        let c = m.centroid(e as usize);
        c[0] >= x0b - tol && c[0] <= length + tol
    };
    let ao: Vec<u32> = a.iter().copied().filter(|&e| in_overlap(&m, e)).collect();
    let bo: Vec<u32> = b.iter().copied().filter(|&e| in_overlap(&m, e)).collect();
    let big = f64::INFINITY;
    let a_end = m.nodes_in_box([0.0, -big, -big], [0.0, big, big], tol);
    let xe = x0b + length;
    let b_end = m.nodes_in_box([xe, -big, -big], [xe, big, big], tol);
    m.element_sets.insert("a".into(), a);
    m.element_sets.insert("b".into(), b);
    m.element_sets.insert("a_overlap".into(), ao);
    m.element_sets.insert("b_overlap".into(), bo);
    m.node_sets.insert("a_end".into(), a_end);
    m.node_sets.insert("b_end".into(), b_end);
    m.all_sets();
    m
}

/// A square tube along z, cross-section `side × side` centred on the z axis, length `length`.
/// The wall is one sheet wound once around (4 faces, `n_side` elements each) and continued
/// for `overlap` over the first face at the offset `gap` outward: the seam where joints
/// fasten the two layers (seed 004 §4.3). Sets: `bottom` (z = 0 nodes), `top` (z = length
/// nodes), `seam_inner`, `seam_outer` (elements of the two layers in the overlap), `wall`.
pub fn square_tube(
    side: f64,
    length: f64,
    n_side: usize,
    n_length: usize,
    overlap: f64,
    gap: f64,
) -> Mesh {
    square_tube_seams(side, length, n_side, n_length, overlap, gap, 1)
}

/// [`square_tube`] with one or two seams: the second (`seams = 2`, sets `seam2_outer`,
/// `seam2_inner`) over face 2 (y = +h) from x = h − overlap to h, at y = h + gap — the two
/// flanges of seed 004 §4.3's tube, fastened by the joint pairs k, k'.
pub fn square_tube_seams(
    side: f64,
    length: f64,
    n_side: usize,
    n_length: usize,
    overlap: f64,
    gap: f64,
    seams: usize,
) -> Mesh {
    let mut m = Mesh::default();
    let h = 0.5 * side;
    let nz = n_length;
    // The perimeter as a polyline of 4 n_side segments (closed), counter-clockwise seen from
    // +z, starting at the middle... start at corner (−h, −h): face 0 is y = −h.
    let corners = [[-h, -h], [h, -h], [h, h], [-h, h]];
    let mut ring: Vec<[f64; 2]> = Vec::new();
    for f in 0..4 {
        let p = corners[f];
        let q = corners[(f + 1) % 4];
        for i in 0..n_side {
            let s = i as f64 / n_side as f64;
            ring.push([p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])]);
        }
    }
    let nr = ring.len();
    let base = m.nodes.len() as u32;
    for j in 0..=nz {
        let z = length * j as f64 / nz as f64;
        for p in &ring {
            m.nodes.push([p[0], p[1], z]);
        }
    }
    // Outward normals: elements ordered (i, i+1 along the ring, then +z) face outward.
    for j in 0..nz as u32 {
        for i in 0..nr as u32 {
            let i1 = (i + 1) % nr as u32;
            let r = nr as u32;
            m.elements.push([
                base + j * r + i,
                base + j * r + i1,
                base + (j + 1) * r + i1,
                base + (j + 1) * r + i,
            ]);
        }
    }
    let wall: Vec<u32> = (0..m.elements.len() as u32).collect();
    // Seam layer: over face 0 (y = −h) from x = −h to −h + overlap, at y = −h − gap.
    let n_ov = ((overlap / side) * n_side as f64).round().max(1.0) as usize;
    let ov = side * n_ov as f64 / n_side as f64;
    let e0 = m.elements.len() as u32;
    m.grid(
        [-h, -h - gap, 0.0],
        [ov, 0.0, 0.0],
        [0.0, 0.0, length],
        n_ov,
        nz,
    );
    let seam_outer: Vec<u32> = (e0..m.elements.len() as u32).collect();
    let tol = 1e-9 * side.max(length);
    let seam_inner: Vec<u32> = wall
        .iter()
        .copied()
        .filter(|&e| {
            let c = m.centroid(e as usize);
            (c[1] + h).abs() < tol && c[0] <= -h + ov + tol
        })
        .collect();
    if seams >= 2 {
        let e2 = m.elements.len() as u32;
        m.grid(
            [h, h + gap, 0.0],
            [-ov, 0.0, 0.0],
            [0.0, 0.0, length],
            n_ov,
            nz,
        );
        let outer2: Vec<u32> = (e2..m.elements.len() as u32).collect();
        let inner2: Vec<u32> = wall
            .iter()
            .copied()
            .filter(|&e| {
                let c = m.centroid(e as usize);
                (c[1] - h).abs() < tol && c[0] >= h - ov - tol
            })
            .collect();
        m.element_sets.insert("seam2_outer".into(), outer2);
        m.element_sets.insert("seam2_inner".into(), inner2);
    }
    let big = f64::INFINITY;
    let bottom = m.nodes_in_box([-big, -big, 0.0], [big, big, 0.0], tol);
    let top = m.nodes_in_box([-big, -big, length], [big, big, length], tol);
    m.node_sets.insert("bottom".into(), bottom);
    m.node_sets.insert("top".into(), top);
    m.element_sets.insert("wall".into(), wall);
    m.element_sets.insert("seam_inner".into(), seam_inner);
    m.element_sets.insert("seam_outer".into(), seam_outer);
    m.all_sets();
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::element::geometry;

    fn area(m: &Mesh, elems: &[u32]) -> f64 {
        elems
            .iter()
            .map(|&e| {
                let c = m.elements[e as usize].map(|n| m.nodes[n as usize]);
                geometry(&c).map_or(0.0, |g| g.area)
            })
            .sum()
    }

    #[test]
    fn plate_counts_sets_and_area() {
        let m = plate(1.0, 0.1, 10, 2, [0.0; 3]);
        assert_eq!(m.nodes.len(), 33);
        assert_eq!(m.elements.len(), 20);
        assert_eq!(m.node_sets["x0"].len(), 3);
        assert_eq!(m.node_sets["y1"].len(), 11);
        assert!((area(&m, &m.element_sets["all"]) - 0.1).abs() < 1e-14);
    }

    #[test]
    fn lap_joint_overlap_and_layers() {
        let m = lap_joint(0.1, 0.02, 0.02, 0.001, 10, 2);
        assert_eq!(m.elements.len(), 40);
        // Overlap 0.02 of 0.1 → 2 of 10 columns in each plate.
        assert_eq!(m.element_sets["a_overlap"].len(), 4);
        assert_eq!(m.element_sets["b_overlap"].len(), 4);
        assert!((area(&m, &m.element_sets["a_overlap"]) - 0.02 * 0.02).abs() < 1e-15);
        let zb: Vec<f64> = m.element_sets["b_overlap"]
            .iter()
            .map(|&e| m.centroid(e as usize)[2])
            .collect();
        assert!(zb.iter().all(|z| (z - 0.001).abs() < 1e-15));
        assert_eq!(m.node_sets["a_end"].len(), 3);
        assert_eq!(m.node_sets["b_end"].len(), 3);
    }

    #[test]
    fn tube_is_closed_outward_and_has_seam() {
        let (side, len) = (0.05, 0.2);
        let m = square_tube(side, len, 5, 20, 0.02, 0.001);
        let wall = &m.element_sets["wall"];
        assert_eq!(wall.len(), 4 * 5 * 20);
        assert!((area(&m, wall) - 4.0 * side * len).abs() < 1e-14);
        // Every wall normal points away from the axis.
        for &e in wall {
            let c = m.elements[e as usize].map(|n| m.nodes[n as usize]);
            let g = geometry(&c).unwrap_or_else(|| panic!("degenerate"));
            let cen = m.centroid(e as usize);
            assert!(g.e[2][0] * cen[0] + g.e[2][1] * cen[1] > 0.0);
        }
        assert_eq!(m.element_sets["seam_inner"].len(), 2 * 20);
        assert_eq!(m.element_sets["seam_outer"].len(), 2 * 20);
        assert_eq!(m.node_sets["bottom"].len(), 20 + 3);
        assert_eq!(m.node_sets["top"].len(), 20 + 3);
        // Counts: the wall ring has 4·5 nodes per level (closed, no duplicate at the start),
        // the seam strip (2 + 1) per level, over 21 levels.
        assert_eq!(m.nodes.len(), (20 + 3) * 21);
        assert_eq!(m.elements.len(), 4 * 5 * 20 + 2 * 20);
        // The wall is closed around: every wall edge is shared by two wall elements except
        // the 20 bottom and 20 top edges (no free edge along the length).
        let mut edges = std::collections::BTreeMap::new();
        for &e in wall {
            let c = m.elements[e as usize];
            for a in 0..4 {
                let (p, q) = (c[a], c[(a + 1) % 4]);
                *edges.entry((p.min(q), p.max(q))).or_insert(0) += 1;
            }
        }
        let free = edges.values().filter(|&&k| k == 1).count();
        assert!(edges.values().all(|&k| k <= 2));
        assert_eq!(free, 2 * 20);
        // The seam: the outer layer shares no node with the wall (the joints connect the
        // layers), and each outer element lies at the gap straight outside an inner one.
        let wall_nodes = m.nodes_of_elements(wall);
        let outer_nodes = m.nodes_of_elements(&m.element_sets["seam_outer"]);
        assert!(
            outer_nodes
                .iter()
                .all(|n| wall_nodes.binary_search(n).is_err())
        );
        for &eo in &m.element_sets["seam_outer"] {
            let co = m.centroid(eo as usize);
            let hits = m.element_sets["seam_inner"]
                .iter()
                .filter(|&&ei| {
                    let ci = m.centroid(ei as usize);
                    (ci[0] - co[0]).abs() < 1e-12
                        && (ci[1] - 0.001 - co[1]).abs() < 1e-12
                        && (ci[2] - co[2]).abs() < 1e-12
                })
                .count();
            assert_eq!(hits, 1, "outer seam element {eo}");
        }
    }
}
