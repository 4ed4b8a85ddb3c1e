//! Interface mapping between non-matching meshes (docs/architecture.md, "Mapping").
//!
//! The wire carries interface data in the *driver's* layout. The responder builds an
//! interpolation matrix `W` (one row per responder point, columns over driver points) and uses
//!
//! * motion: `v_r = W v_d` (a consistent interpolation of the driver's field), and
//! * loads:  `f_d = Wᵀ f_r` (the transpose, not a second interpolation).
//!
//! **Why the transpose.** With these two rules the interface power is the same on both sides,
//! `Σ_i f_d,i·v_d,i = Σ_i Σ_j W_ji f_r,j·v_d,i = Σ_j f_r,j·v_r,j`, identically in exact
//! arithmetic for *any* `W`, so the coupling neither creates nor destroys energy (the check is a
//! round-off test, `tests/mapping_power.rs`). Interpolating the loads with a second, independent
//! map would in general violate this.
//!
//! **Momentum.** The total force is preserved, `Σ_i f_d,i = Σ_j f_r,j Σ_i W_ji = Σ_j f_r,j`,
//! exactly when every row of `W` sums to one. That is the partition of unity of the driver's
//! shape functions (linear line, barycentric triangle, bilinear quad) and trivially true for the
//! nearest-neighbour and identity maps; a user map built with [`Mapping::from_rows`] keeps it only
//! if its rows do (see [`Mapping::max_row_sum_defect`]). The moment is preserved about the
//! *projected* points: `Σ x_d × f_d = Σ (W x_d)_j × f_r,j`, so it equals `Σ x_r × f_r` when the
//! responder points lie on a planar-celled driver surface (`W x_d = x_r`, linear
//! reproduction), and differs by the gap × force otherwise (curved surfaces, nearest neighbour).
//!
//! Data layout: point-major flat arrays, `src[i * components + c]`. `W` is stored in compressed
//! rows and, for the load map, also in compressed columns, so both products are gathers summed
//! in a fixed order (increasing responder index for loads): the results are bit-reproducible.
//! Applying a map allocates nothing. Constructors validate everything that came from a message
//! (empty meshes, non-finite positions, bad connectivity, degenerate or folded cells) and return
//! a [`MappingError`] instead of panicking.

use crate::message::{CellKind, InterfaceMesh};
use nalgebra::Vector3;

/// Why a mapping could not be built or applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MappingError {
    #[error("driver mesh has no points")]
    EmptyDriver,
    #[error("responder has no points")]
    EmptyResponder,
    #[error("{side} point {index} has a non-finite coordinate {position:?}")]
    NonFinitePosition {
        side: &'static str,
        index: usize,
        position: [f64; 3],
    },
    #[error("connectivity has {len} entries, not a multiple of {nodes} ({kind:?} cells)")]
    ConnectivityLength {
        kind: CellKind,
        len: usize,
        nodes: usize,
    },
    #[error("cell {cell} refers to point {index}, but the mesh has {n_points} points")]
    ConnectivityIndex {
        cell: usize,
        index: u32,
        n_points: usize,
    },
    #[error("cell {cell} ({kind:?}) is degenerate: {reason}")]
    DegenerateCell {
        cell: usize,
        kind: CellKind,
        reason: &'static str,
    },
    #[error("more than u32::MAX points or cells ({0})")]
    TooLarge(usize),
    #[error("rows: {0}")]
    BadRows(String),
    #[error("components must be > 0")]
    ZeroComponents,
    #[error("{what} has length {got}, expected {expected}")]
    Length {
        what: &'static str,
        expected: usize,
        got: usize,
    },
}

/// The interpolation matrix `W` (responder points ← driver points) in compressed rows, with its
/// transpose in compressed columns for the load map.
#[derive(Debug, Clone, PartialEq)]
pub struct Mapping {
    n_driver: usize,
    n_responder: usize,
    /// Row `j` (responder point) holds entries `row_offsets[j]..row_offsets[j + 1]`.
    row_offsets: Vec<usize>,
    /// Driver point index of each entry.
    cols: Vec<u32>,
    /// Weight of each entry.
    weights: Vec<f64>,
    /// Transpose: column `i` (driver point) holds `col_offsets[i]..col_offsets[i + 1]`.
    col_offsets: Vec<usize>,
    /// Responder point index of each transposed entry, increasing within a column.
    t_rows: Vec<u32>,
    t_weights: Vec<f64>,
}

impl Mapping {
    /// `W = I` on `n` points (matching meshes).
    pub fn identity(n: usize) -> Result<Self, MappingError> {
        if n == 0 {
            return Err(MappingError::EmptyDriver);
        }
        check_u32(n)?;
        Mapping::from_rows(n, (0..=n).collect(), (0..n as u32).collect(), vec![1.0; n])
    }

    /// `W` from compressed rows: `row_offsets` has one entry per responder point plus one,
    /// starting at 0 and ending at `cols.len() == weights.len()`; `cols` are driver indices
    /// `< n_driver`; weights finite. Repeated columns in a row are allowed (they add up).
    pub fn from_rows(
        n_driver: usize,
        row_offsets: Vec<usize>,
        cols: Vec<u32>,
        weights: Vec<f64>,
    ) -> Result<Self, MappingError> {
        let bad = |s: String| Err(MappingError::BadRows(s));
        if n_driver == 0 {
            return Err(MappingError::EmptyDriver);
        }
        check_u32(n_driver)?;
        if row_offsets.len() < 2 {
            return Err(MappingError::EmptyResponder);
        }
        let n_responder = row_offsets.len() - 1;
        check_u32(n_responder)?;
        if cols.len() != weights.len() {
            return bad(format!(
                "{} columns but {} weights",
                cols.len(),
                weights.len()
            ));
        }
        if row_offsets[0] != 0 || row_offsets[n_responder] != cols.len() {
            return bad(format!(
                "offsets must run from 0 to {}, got {}..{}",
                cols.len(),
                row_offsets[0],
                row_offsets[n_responder]
            ));
        }
        if let Some(j) = row_offsets.windows(2).position(|w| w[1] < w[0]) {
            return bad(format!("offsets decrease at row {j}"));
        }
        if let Some(k) = cols.iter().position(|&c| c as usize >= n_driver) {
            return bad(format!(
                "entry {k} has column {} >= n_driver {n_driver}",
                cols[k]
            ));
        }
        if let Some(k) = weights.iter().position(|w| !w.is_finite()) {
            return bad(format!("entry {k} has weight {}", weights[k]));
        }

        // Transpose by counting sort over columns; rows are visited in increasing order, so each
        // column lists its responder points in increasing order (the fixed summation order).
        let mut col_offsets = vec![0usize; n_driver + 1];
        for &c in &cols {
            col_offsets[c as usize + 1] += 1;
        }
        for i in 0..n_driver {
            col_offsets[i + 1] += col_offsets[i];
        }
        let mut fill = col_offsets[..n_driver].to_vec();
        let mut t_rows = vec![0u32; cols.len()];
        let mut t_weights = vec![0.0; cols.len()];
        for j in 0..n_responder {
            for k in row_offsets[j]..row_offsets[j + 1] {
                let slot = &mut fill[cols[k] as usize];
                t_rows[*slot] = j as u32;
                t_weights[*slot] = weights[k];
                *slot += 1;
            }
        }
        Ok(Mapping {
            n_driver,
            n_responder,
            row_offsets,
            cols,
            weights,
            col_offsets,
            t_rows,
            t_weights,
        })
    }

    /// Each responder point takes the value of its nearest driver point (ties: lowest index).
    /// Uses a uniform bin grid: `O((n + m) · bins visited)`, not `O(n·m)`.
    pub fn nearest(
        driver: &InterfaceMesh,
        responder_points: &[[f64; 3]],
    ) -> Result<Self, MappingError> {
        check_points(driver, responder_points)?;
        let pts = &driver.positions;
        let grid = BinGrid::new(&pts.iter().map(|&p| (p, p)).collect::<Vec<_>>());
        let m = responder_points.len();
        let mut cols = Vec::with_capacity(m);
        for q in responder_points {
            let (i, _) = grid.closest(q, |i, _| dist2(q, &pts[i as usize]));
            cols.push(i);
        }
        Mapping::from_rows(pts.len(), (0..=m).collect(), cols, vec![1.0; m])
    }

    /// Consistent interpolation with the shape functions of the driver's cells: each responder
    /// point is projected to the closest point of the closest cell (points off the surface or
    /// outside the mesh are clamped to the cell boundary) and takes the cell's shape-function
    /// weights there. Line: linear; Triangle: barycentric; Quad: bilinear, inverted by Newton in
    /// the quad's best-fit plane. A mesh without cells (or with an empty cell list) falls back
    /// to [`Mapping::nearest`]. Ties between equally close cells go to the lowest cell index.
    pub fn consistent(
        driver: &InterfaceMesh,
        responder_points: &[[f64; 3]],
    ) -> Result<Self, MappingError> {
        let cells = match &driver.cells {
            Some(c) if !c.connectivity.is_empty() => c,
            _ => return Mapping::nearest(driver, responder_points),
        };
        check_points(driver, responder_points)?;
        let pts = &driver.positions;
        let kind = cells.kind;
        let nn = kind.nodes();
        let conn = &cells.connectivity;
        if conn.len() % nn != 0 {
            return Err(MappingError::ConnectivityLength {
                kind,
                len: conn.len(),
                nodes: nn,
            });
        }
        let n_cells = conn.len() / nn;
        check_u32(n_cells)?;
        for (k, &idx) in conn.iter().enumerate() {
            if idx as usize >= pts.len() {
                return Err(MappingError::ConnectivityIndex {
                    cell: k / nn,
                    index: idx,
                    n_points: pts.len(),
                });
            }
        }
        let scale = bbox_diagonal(pts);
        let mut geo = Vec::with_capacity(n_cells);
        for c in 0..n_cells {
            let nodes = &conn[c * nn..(c + 1) * nn];
            let x = |a: usize| pts[nodes[a] as usize];
            let g = match kind {
                CellKind::Line => CellGeom::line(x(0), x(1), scale),
                CellKind::Triangle => CellGeom::triangle(x(0), x(1), x(2), scale),
                CellKind::Quad => CellGeom::quad([x(0), x(1), x(2), x(3)], scale),
            };
            geo.push(g.map_err(|reason| MappingError::DegenerateCell {
                cell: c,
                kind,
                reason,
            })?);
        }

        let grid = BinGrid::new(&geo.iter().map(|g| (g.lo, g.hi)).collect::<Vec<_>>());
        let m = responder_points.len();
        let mut row_offsets = Vec::with_capacity(m + 1);
        let mut cols = Vec::with_capacity(m * nn);
        let mut weights = Vec::with_capacity(m * nn);
        row_offsets.push(0);
        for q in responder_points {
            let c = closest_cell(&grid, &geo, q);
            let (n, _) = geo[c].project(q);
            cols.extend_from_slice(&conn[c * nn..(c + 1) * nn]);
            weights.extend_from_slice(&n[..nn]);
            row_offsets.push(cols.len());
        }
        Mapping::from_rows(pts.len(), row_offsets, cols, weights)
    }

    /// Motion: `dst = W src`, i.e. `v_r = W v_d`. `src` has `n_driver * components` entries,
    /// `dst` has `n_responder * components`, both point-major.
    pub fn map_motion(
        &self,
        src: &[f64],
        components: usize,
        dst: &mut [f64],
    ) -> Result<(), MappingError> {
        self.check_lengths(src, components, dst, self.n_driver, self.n_responder)?;
        for (j, out) in dst.chunks_exact_mut(components).enumerate() {
            out.fill(0.0);
            for k in self.row_offsets[j]..self.row_offsets[j + 1] {
                let w = self.weights[k];
                let i = self.cols[k] as usize;
                for (o, s) in out
                    .iter_mut()
                    .zip(&src[i * components..(i + 1) * components])
                {
                    *o += w * s;
                }
            }
        }
        Ok(())
    }

    /// Loads: `dst = Wᵀ src`, i.e. `f_d = Wᵀ f_r`. `src` has `n_responder * components`
    /// entries, `dst` has `n_driver * components`. Each driver entry is summed over responder
    /// points in increasing index order (deterministic).
    pub fn map_load(
        &self,
        src: &[f64],
        components: usize,
        dst: &mut [f64],
    ) -> Result<(), MappingError> {
        self.check_lengths(src, components, dst, self.n_responder, self.n_driver)?;
        for (i, out) in dst.chunks_exact_mut(components).enumerate() {
            out.fill(0.0);
            for k in self.col_offsets[i]..self.col_offsets[i + 1] {
                let w = self.t_weights[k];
                let j = self.t_rows[k] as usize;
                for (o, s) in out
                    .iter_mut()
                    .zip(&src[j * components..(j + 1) * components])
                {
                    *o += w * s;
                }
            }
        }
        Ok(())
    }

    fn check_lengths(
        &self,
        src: &[f64],
        components: usize,
        dst: &[f64],
        n_src: usize,
        n_dst: usize,
    ) -> Result<(), MappingError> {
        if components == 0 {
            return Err(MappingError::ZeroComponents);
        }
        if src.len() != n_src * components {
            return Err(MappingError::Length {
                what: "source",
                expected: n_src * components,
                got: src.len(),
            });
        }
        if dst.len() != n_dst * components {
            return Err(MappingError::Length {
                what: "destination",
                expected: n_dst * components,
                got: dst.len(),
            });
        }
        Ok(())
    }

    pub fn n_driver(&self) -> usize {
        self.n_driver
    }
    pub fn n_responder(&self) -> usize {
        self.n_responder
    }
    /// Row offsets (length `n_responder + 1`).
    pub fn row_offsets(&self) -> &[usize] {
        &self.row_offsets
    }
    /// Driver point index of each stored entry.
    pub fn cols(&self) -> &[u32] {
        &self.cols
    }
    /// Weight of each stored entry.
    pub fn weights(&self) -> &[f64] {
        &self.weights
    }
    /// Driver indices and weights of responder point `j`'s row.
    pub fn row(&self, j: usize) -> (&[u32], &[f64]) {
        let r = self.row_offsets[j]..self.row_offsets[j + 1];
        (&self.cols[r.clone()], &self.weights[r])
    }
    /// `max_j |Σ_i W_ji − 1|`: zero (to round-off) means the load map preserves total force.
    pub fn max_row_sum_defect(&self) -> f64 {
        (0..self.n_responder)
            .map(|j| (self.row(j).1.iter().sum::<f64>() - 1.0).abs())
            .fold(0.0, f64::max)
    }
}

fn check_u32(n: usize) -> Result<(), MappingError> {
    if n > u32::MAX as usize {
        Err(MappingError::TooLarge(n))
    } else {
        Ok(())
    }
}

fn check_points(driver: &InterfaceMesh, responder: &[[f64; 3]]) -> Result<(), MappingError> {
    if driver.positions.is_empty() {
        return Err(MappingError::EmptyDriver);
    }
    if responder.is_empty() {
        return Err(MappingError::EmptyResponder);
    }
    check_u32(driver.positions.len())?;
    check_u32(responder.len())?;
    for (side, pts) in [("driver", &driver.positions[..]), ("responder", responder)] {
        if let Some(index) = pts.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
            return Err(MappingError::NonFinitePosition {
                side,
                index,
                position: pts[index],
            });
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Small vector helpers.

type V3 = Vector3<f64>;

/// The point stored in `a` (positions travel as `[f64; 3]`; nalgebra does the algebra).
fn v3(a: &[f64; 3]) -> V3 {
    V3::from(*a)
}
fn dist2(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (v3(a) - v3(b)).norm_squared()
}
/// `Σ n_k x_k` over the first `n.len()` nodes.
fn combine(n: &[f64], x: &[[f64; 3]]) -> [f64; 3] {
    n.iter()
        .zip(x)
        .fold(V3::zeros(), |p, (w, xk)| p + v3(xk) * *w)
        .into()
}
fn bbox_diagonal(pts: &[[f64; 3]]) -> f64 {
    let (lo, hi) = bbox(pts.iter().map(|&p| (p, p)));
    (v3(&hi) - v3(&lo)).norm()
}
fn bbox(items: impl Iterator<Item = ([f64; 3], [f64; 3])>) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for (a, b) in items {
        for d in 0..3 {
            lo[d] = lo[d].min(a[d]);
            hi[d] = hi[d].max(b[d]);
        }
    }
    (lo, hi)
}

/// Index of the cell closest to `q` (ties: lowest index).
fn closest_cell(grid: &BinGrid, geo: &[CellGeom], q: &[f64; 3]) -> usize {
    let (c, _) = grid.closest(q, |c, best| {
        // A cell whose bounding box is already farther than the best needs no projection.
        let g = &geo[c as usize];
        if box_dist2(q, &g.lo, &g.hi) > best {
            f64::INFINITY
        } else {
            g.project(q).1
        }
    });
    c as usize
}

/// Squared distance from `q` to the box `[lo, hi]` (zero inside).
fn box_dist2(q: &[f64; 3], lo: &[f64; 3], hi: &[f64; 3]) -> f64 {
    (0..3)
        .map(|d| {
            let e = (lo[d] - q[d]).max(q[d] - hi[d]).max(0.0);
            e * e
        })
        .sum()
}

/// Closest point of segment `a b` to `q`: parameter `t ∈ [0, 1]` and squared distance.
fn segment_closest(q: &[f64; 3], a: &[f64; 3], b: &[f64; 3]) -> (f64, f64) {
    let e = v3(b) - v3(a);
    let l2 = e.norm_squared();
    let t = if l2 > 0.0 {
        ((v3(q) - v3(a)).dot(&e) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (t, dist2(q, &(v3(a) + e * t).into()))
}

// ---------------------------------------------------------------------------------------------
// Cell geometry: closest point and shape functions.

/// Relative size below which a cell counts as degenerate (length, area² and Jacobians are
/// compared with powers of `DEGENERATE · mesh diagonal`).
const DEGENERATE: f64 = 1e-12;

#[derive(Debug, Clone)]
struct CellGeom {
    kind: CellKind,
    x: [[f64; 3]; 4],
    lo: [f64; 3],
    hi: [f64; 3],
    /// Quad only: best-fit plane (centroid, in-plane axes) and the nodes in plane coordinates.
    c: V3,
    e1: V3,
    e2: V3,
    x2d: [[f64; 2]; 4],
}

impl CellGeom {
    fn new(kind: CellKind, x: [[f64; 3]; 4], n: usize) -> Self {
        let (lo, hi) = bbox(x[..n].iter().map(|&p| (p, p)));
        CellGeom {
            kind,
            x,
            lo,
            hi,
            c: V3::zeros(),
            e1: V3::zeros(),
            e2: V3::zeros(),
            x2d: [[0.0; 2]; 4],
        }
    }

    fn line(a: [f64; 3], b: [f64; 3], scale: f64) -> Result<Self, &'static str> {
        if (v3(&b) - v3(&a)).norm() <= DEGENERATE * scale {
            return Err("zero length");
        }
        Ok(CellGeom::new(CellKind::Line, [a, b, [0.0; 3], [0.0; 3]], 2))
    }

    fn triangle(a: [f64; 3], b: [f64; 3], c: [f64; 3], scale: f64) -> Result<Self, &'static str> {
        let area2 = (v3(&b) - v3(&a)).cross(&(v3(&c) - v3(&a))).norm();
        if area2 <= DEGENERATE * scale * scale {
            return Err("zero area");
        }
        Ok(CellGeom::new(CellKind::Triangle, [a, b, c, [0.0; 3]], 3))
    }

    /// Quad nodes counter-clockwise; bilinear map over `(ξ, η) ∈ [-1, 1]²` with node `k` at
    /// `(ξ_k, η_k) = (∓1, ∓1)`. The best-fit plane normal is along the cross product of the
    /// diagonals (the average normal of the quad); the bilinear map must be invertible in that
    /// plane (all four corner Jacobians positive), which rejects folded (bow-tie) and
    /// re-entrant quads.
    fn quad(x: [[f64; 3]; 4], scale: f64) -> Result<Self, &'static str> {
        let nvec = (v3(&x[2]) - v3(&x[0])).cross(&(v3(&x[3]) - v3(&x[1])));
        let nn = nvec.norm();
        if nn <= DEGENERATE * scale * scale {
            return Err("zero area");
        }
        let n = nvec / nn;
        let c = v3(&combine(&[0.25; 4], &x));
        let d = v3(&x[1]) - v3(&x[0]);
        let d = d - n * d.dot(&n);
        let dn = d.norm();
        if dn <= DEGENERATE * scale {
            return Err("first edge parallel to the normal");
        }
        let e1 = d / dn;
        let e2 = n.cross(&e1);
        let mut g = CellGeom::new(CellKind::Quad, x, 4);
        for (y, xk) in g.x2d.iter_mut().zip(&x) {
            let r = v3(xk) - c;
            *y = [r.dot(&e1), r.dot(&e2)];
        }
        for k in 0..4 {
            let p = g.x2d[(k + 3) % 4];
            let a = g.x2d[k];
            let b = g.x2d[(k + 1) % 4];
            let jac = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
            if jac <= DEGENERATE * scale * scale {
                return Err("folded or re-entrant (corner Jacobian <= 0)");
            }
        }
        g.c = c;
        g.e1 = e1;
        g.e2 = e2;
        Ok(g)
    }

    /// Shape-function weights (first `kind.nodes()` used) at the closest point of the cell to
    /// `q`, and the squared distance from `q` to that point.
    fn project(&self, q: &[f64; 3]) -> ([f64; 4], f64) {
        let x = &self.x;
        match self.kind {
            CellKind::Line => {
                let (t, d2) = segment_closest(q, &x[0], &x[1]);
                ([1.0 - t, t, 0.0, 0.0], d2)
            }
            CellKind::Triangle => {
                // Barycentric coordinates of the projection onto the plane (Gram system); if
                // it lies outside, the closest point is on an edge.
                let e1 = v3(&x[1]) - v3(&x[0]);
                let e2 = v3(&x[2]) - v3(&x[0]);
                let r = v3(q) - v3(&x[0]);
                let (a, b, c) = (e1.dot(&e1), e1.dot(&e2), e2.dot(&e2));
                let (r1, r2) = (r.dot(&e1), r.dot(&e2));
                let det = a * c - b * b;
                let s = (c * r1 - b * r2) / det;
                let t = (a * r2 - b * r1) / det;
                if s >= 0.0 && t >= 0.0 && s + t <= 1.0 {
                    let n = [1.0 - s - t, s, t, 0.0];
                    let d2 = dist2(q, &combine(&n[..3], x));
                    return (n, d2);
                }
                let mut best = ([0.0; 4], f64::INFINITY);
                for (ia, ib) in [(0, 1), (1, 2), (2, 0)] {
                    let (t, d2) = segment_closest(q, &x[ia], &x[ib]);
                    if d2 < best.1 {
                        let mut n = [0.0; 4];
                        n[ia] = 1.0 - t;
                        n[ib] = t;
                        best = (n, d2);
                    }
                }
                best
            }
            CellKind::Quad => self.project_quad(q),
        }
    }

    fn project_quad(&self, q: &[f64; 3]) -> ([f64; 4], f64) {
        const XI: [f64; 4] = [-1.0, 1.0, 1.0, -1.0];
        const ETA: [f64; 4] = [-1.0, -1.0, 1.0, 1.0];
        let shape = |xi: f64, eta: f64| {
            let mut n = [0.0; 4];
            for k in 0..4 {
                n[k] = 0.25 * (1.0 + XI[k] * xi) * (1.0 + ETA[k] * eta);
            }
            n
        };
        let r = v3(q) - self.c;
        let p = [r.dot(&self.e1), r.dot(&self.e2)];
        let xs = &self.x2d;
        // Inverse bilinear map by Newton from the centre (converges quadratically inside a
        // valid quad, so a last step of 1e-12 leaves an error near 1e-24); a solution outside
        // [-1, 1]² or no convergence means the closest point is on the boundary.
        let (mut xi, mut eta) = (0.0f64, 0.0f64);
        let mut converged = false;
        for _ in 0..30 {
            let n = shape(xi, eta);
            let mut f = [-p[0], -p[1]];
            let mut j = [[0.0; 2]; 2];
            for k in 0..4 {
                let dxi = 0.25 * XI[k] * (1.0 + ETA[k] * eta);
                let deta = 0.25 * ETA[k] * (1.0 + XI[k] * xi);
                for d in 0..2 {
                    f[d] += n[k] * xs[k][d];
                    j[d][0] += dxi * xs[k][d];
                    j[d][1] += deta * xs[k][d];
                }
            }
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if det == 0.0 || !det.is_finite() {
                break;
            }
            let dxi = (j[1][1] * f[0] - j[0][1] * f[1]) / det;
            let deta = (j[0][0] * f[1] - j[1][0] * f[0]) / det;
            xi = (xi - dxi).clamp(-4.0, 4.0);
            eta = (eta - deta).clamp(-4.0, 4.0);
            if dxi.abs() + deta.abs() <= 1e-12 {
                converged = true;
                break;
            }
        }
        const TOL: f64 = 1e-12;
        if converged && xi.abs() <= 1.0 + TOL && eta.abs() <= 1.0 + TOL {
            let n = shape(xi.clamp(-1.0, 1.0), eta.clamp(-1.0, 1.0));
            let d2 = dist2(q, &combine(&n, &self.x));
            return (n, d2);
        }
        // The edges of a bilinear quad are straight, and the bilinear parameter along an edge
        // is the linear one, so the edge closest points give the shape functions directly.
        let mut best = ([0.0; 4], f64::INFINITY);
        for (ia, ib) in [(0, 1), (1, 2), (2, 3), (3, 0)] {
            let (t, d2) = segment_closest(q, &self.x[ia], &self.x[ib]);
            if d2 < best.1 {
                let mut n = [0.0; 4];
                n[ia] = 1.0 - t;
                n[ib] = t;
                best = (n, d2);
            }
        }
        best
    }
}

// ---------------------------------------------------------------------------------------------
// Sparse uniform bin grid for closest-item queries.

/// Items (points or cell bounding boxes) binned on a uniform grid of cubes of side `h`; only
/// occupied bins are stored (sorted keys + compressed rows), so a surface in 3D costs memory in
/// proportion to its items, and `h` can follow the item spacing. A query visits shells of bins
/// of growing Chebyshev radius around the query's bin and stops once the best distance found
/// is below the distance to the nearest face of the visited block (nothing outside can be
/// closer); when a shell would hold more bins than are occupied, it scans the occupied bins.
struct BinGrid {
    lo: [f64; 3],
    h: f64,
    dims: [u64; 3],
    keys: Vec<u64>,
    offsets: Vec<usize>,
    items: Vec<u32>,
}

impl BinGrid {
    fn new(boxes: &[([f64; 3], [f64; 3])]) -> Self {
        let n = boxes.len();
        let (lo, hi) = bbox(boxes.iter().copied());
        let ext: [f64; 3] = (v3(&hi) - v3(&lo)).into();
        let max_ext = ext[0].max(ext[1]).max(ext[2]);
        let mut grid = BinGrid {
            lo,
            h: 1.0,
            dims: [1; 3],
            keys: Vec::new(),
            offsets: Vec::new(),
            items: Vec::new(),
        };
        if max_ext > 0.0 {
            // Halve h until the item centres occupy about n/2 bins (a couple of items per
            // bin), whatever the dimension of the interface; bins no finer than 2⁻²⁰ of the
            // extent (so keys fit in u64) and no smaller than an average item.
            let centres: Vec<[f64; 3]> = boxes
                .iter()
                .map(|(a, b)| [0, 1, 2].map(|d| 0.5 * (a[d] + b[d])))
                .collect();
            let mut keys = Vec::with_capacity(n);
            let mut occupied = |g: &mut BinGrid, h: f64| {
                g.set_h(h, &ext);
                keys.clear();
                keys.extend(centres.iter().map(|c| g.key(g.bin(c))));
                keys.sort_unstable();
                keys.dedup();
                keys.len()
            };
            let h_min = max_ext * 2f64.powi(-20);
            let mut h = max_ext;
            while h * 0.5 >= h_min && 2 * occupied(&mut grid, h) < n {
                h *= 0.5;
            }
            let mean_item = boxes
                .iter()
                .map(|(a, b)| {
                    let e = v3(b) - v3(a);
                    e[0].max(e[1]).max(e[2])
                })
                .sum::<f64>()
                / n as f64;
            grid.set_h(h.max(mean_item).max(h_min), &ext);
        }
        let mut pairs: Vec<(u64, u32)> = Vec::with_capacity(n);
        for (i, (a, b)) in boxes.iter().enumerate() {
            let (ia, ib) = (grid.bin(a), grid.bin(b));
            for z in ia[2]..=ib[2] {
                for y in ia[1]..=ib[1] {
                    for x in ia[0]..=ib[0] {
                        pairs.push((grid.key([x, y, z]), i as u32));
                    }
                }
            }
        }
        pairs.sort_unstable();
        grid.offsets.push(0);
        for (k, &(key, item)) in pairs.iter().enumerate() {
            if k > 0 && pairs[k - 1].0 != key {
                grid.offsets.push(k);
            }
            if k == 0 || pairs[k - 1].0 != key {
                grid.keys.push(key);
            }
            grid.items.push(item);
        }
        grid.offsets.push(pairs.len());
        grid
    }

    fn set_h(&mut self, h: f64, ext: &[f64; 3]) {
        self.h = h;
        self.dims = [0, 1, 2].map(|d| (ext[d] / h).floor() as u64 + 1);
    }

    fn bin(&self, p: &[f64; 3]) -> [u64; 3] {
        [0, 1, 2].map(|d| {
            let t = ((p[d] - self.lo[d]) / self.h).floor();
            if t <= 0.0 {
                0
            } else {
                (t as u64).min(self.dims[d] - 1)
            }
        })
    }

    fn key(&self, b: [u64; 3]) -> u64 {
        (b[2] * self.dims[1] + b[1]) * self.dims[0] + b[0]
    }

    fn unkey(&self, key: u64) -> [u64; 3] {
        let [d0, d1, _] = self.dims;
        [key % d0, (key / d0) % d1, key / (d0 * d1)]
    }

    /// Item minimising `dist2(item, best)` (squared distance to `q`), ties to the lowest index.
    /// `dist2` may return anything above `best` (e.g. infinity) for an item it can prove is
    /// farther than the best so far. The grid is never empty, so an item is always found.
    fn closest(&self, q: &[f64; 3], mut dist2: impl FnMut(u32, f64) -> f64) -> (u32, f64) {
        let c = self.bin(q);
        let mut best = (u32::MAX, f64::INFINITY);
        let mut visit_slot = |slot: usize, best: &mut (u32, f64)| {
            for &i in &self.items[self.offsets[slot]..self.offsets[slot + 1]] {
                let d = dist2(i, best.1);
                if d < best.1 || (d == best.1 && i < best.0) {
                    *best = (i, d);
                }
            }
        };
        let mut visit = |b: [u64; 3], best: &mut (u32, f64)| {
            if let Ok(slot) = self.keys.binary_search(&self.key(b)) {
                visit_slot(slot, best);
            }
        };
        let cheb = |b: [u64; 3]| (0..3).map(|d| b[d].abs_diff(c[d])).max().unwrap_or(0);
        let reach = (0..3)
            .map(|d| c[d].max(self.dims[d] - 1 - c[d]))
            .max()
            .unwrap_or(0);
        for k in 0..=reach {
            let shell = (2 * k + 1).pow(3) - if k > 0 { (2 * k - 1).pow(3) } else { 0 };
            if shell > self.keys.len() as u64 {
                // Sparse remainder: visit the occupied bins not yet visited, in key order.
                for slot in 0..self.keys.len() {
                    if cheb(self.unkey(self.keys[slot])) >= k {
                        visit_slot(slot, &mut best);
                    }
                }
                break;
            }
            let range = |d: usize| (c[d].saturating_sub(k), (c[d] + k).min(self.dims[d] - 1));
            let ((x0, x1), (y0, y1), (z0, z1)) = (range(0), range(1), range(2));
            for x in x0..=x1 {
                for y in y0..=y1 {
                    if x.abs_diff(c[0]) == k || y.abs_diff(c[1]) == k {
                        for z in z0..=z1 {
                            visit([x, y, z], &mut best);
                        }
                    } else {
                        // Only the two z-faces of the shell (one bin when k == 0).
                        if c[2] >= k {
                            visit([x, y, c[2] - k], &mut best);
                        }
                        if k > 0 && c[2] + k < self.dims[2] {
                            visit([x, y, c[2] + k], &mut best);
                        }
                    }
                }
            }
            // Distance from q to the nearest face of the visited block beyond which bins exist.
            let mut wall = f64::INFINITY;
            for d in 0..3 {
                if c[d] > k {
                    wall = wall.min(q[d] - (self.lo[d] + (c[d] - k) as f64 * self.h));
                }
                if c[d] + k + 1 < self.dims[d] {
                    wall = wall.min(self.lo[d] + (c[d] + k + 1) as f64 * self.h - q[d]);
                }
            }
            if wall == f64::INFINITY || best.1 < wall * wall {
                break;
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::Cells;

    /// splitmix64: a tiny deterministic generator for test data.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, a: f64, b: f64) -> f64 {
            a + (b - a) * self.next()
        }
        fn point(&mut self, a: f64, b: f64) -> [f64; 3] {
            [self.range(a, b), self.range(a, b), self.range(a, b)]
        }
    }

    fn mesh(positions: Vec<[f64; 3]>, kind: CellKind, connectivity: Vec<u32>) -> InterfaceMesh {
        let mut m = InterfaceMesh::points(positions);
        m.cells = Some(Cells { kind, connectivity });
        m
    }

    fn brute_nearest(pts: &[[f64; 3]], q: &[f64; 3]) -> usize {
        let mut best = (0, f64::INFINITY);
        for (i, p) in pts.iter().enumerate() {
            let d = dist2(p, q);
            if d < best.1 {
                best = (i, d);
            }
        }
        best.0
    }

    #[test]
    fn identity_maps_both_ways_unchanged() {
        let m = Mapping::identity(4).unwrap();
        let v: Vec<f64> = (0..8).map(|k| k as f64 * 0.5 - 1.0).collect();
        let mut out = vec![0.0; 8];
        m.map_motion(&v, 2, &mut out).unwrap();
        assert_eq!(out, v);
        m.map_load(&v, 2, &mut out).unwrap();
        assert_eq!(out, v);
        assert_eq!(Mapping::identity(0), Err(MappingError::EmptyDriver));
    }

    #[test]
    fn from_rows_rejects_malformed_rows() {
        let ok = Mapping::from_rows(3, vec![0, 2, 3], vec![0, 2, 1], vec![0.5, 0.5, 1.0]);
        assert!(ok.is_ok());
        for bad in [
            Mapping::from_rows(3, vec![1, 2, 3], vec![0, 2, 1], vec![0.5, 0.5, 1.0]),
            Mapping::from_rows(3, vec![0, 2, 2], vec![0, 2, 1], vec![0.5, 0.5, 1.0]),
            Mapping::from_rows(3, vec![0, 3, 2, 3], vec![0, 2, 1], vec![0.5, 0.5, 1.0]),
            Mapping::from_rows(3, vec![0, 2, 3], vec![0, 3, 1], vec![0.5, 0.5, 1.0]),
            Mapping::from_rows(3, vec![0, 2, 3], vec![0, 2, 1], vec![0.5, f64::NAN, 1.0]),
            Mapping::from_rows(3, vec![0, 2, 3], vec![0, 2, 1], vec![0.5, 0.5]),
        ] {
            assert!(matches!(bad, Err(MappingError::BadRows(_))), "{bad:?}");
        }
        assert_eq!(
            Mapping::from_rows(3, vec![0], vec![], vec![]),
            Err(MappingError::EmptyResponder)
        );
        assert_eq!(
            Mapping::from_rows(0, vec![0, 0], vec![], vec![]),
            Err(MappingError::EmptyDriver)
        );
    }

    #[test]
    fn transpose_matches_explicit_scatter() {
        // Rows with repeated and unsorted columns: Wᵀ f computed by a plain scatter over rows.
        let m = Mapping::from_rows(
            3,
            vec![0, 3, 4, 6],
            vec![2, 0, 2, 1, 1, 0],
            vec![0.25, 0.5, 0.25, 1.0, 0.75, 0.25],
        )
        .unwrap();
        let f = [1.0, -2.0, 3.0, 0.5, -4.0, 2.5];
        let mut fd = [0.0; 6];
        m.map_load(&f, 2, &mut fd).unwrap();
        let mut expected = [0.0; 6];
        for j in 0..3 {
            let (cols, w) = m.row(j);
            for (&i, &w) in cols.iter().zip(w) {
                for c in 0..2 {
                    expected[i as usize * 2 + c] += w * f[j * 2 + c];
                }
            }
        }
        assert_eq!(fd, expected);
    }

    #[test]
    fn nearest_agrees_with_brute_force_on_clouds_of_every_dimension() {
        let mut rng = Rng(7);
        let clouds: Vec<Vec<[f64; 3]>> = vec![
            (0..400).map(|_| rng.point(-1.0, 2.0)).collect(),
            (0..300)
                .map(|_| [rng.range(0.0, 5.0), rng.range(0.0, 1.0), 0.25])
                .collect(),
            (0..200)
                .map(|_| {
                    let t = rng.range(-3.0, 3.0);
                    [t, 2.0 * t, -t]
                })
                .collect(),
            vec![[1.0, 2.0, 3.0]; 5],
            vec![[0.0; 3]],
        ];
        for pts in clouds {
            let driver = InterfaceMesh::points(pts.clone());
            let queries: Vec<[f64; 3]> = (0..300)
                .map(|k| {
                    let r = if k % 5 == 0 { 1e4 } else { 8.0 };
                    rng.point(-r, r)
                })
                .collect();
            let m = Mapping::nearest(&driver, &queries).unwrap();
            for (j, q) in queries.iter().enumerate() {
                let (cols, w) = m.row(j);
                assert_eq!(w, &[1.0]);
                assert_eq!(cols[0] as usize, brute_nearest(&pts, q), "query {q:?}");
            }
        }
    }

    #[test]
    fn nearest_picks_the_obvious_point() {
        let driver = InterfaceMesh::points(vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let m = Mapping::nearest(
            &driver,
            &[[0.9, 0.2, 0.0], [0.1, 0.8, 5.0], [0.2, 0.1, -1.0]],
        )
        .unwrap();
        assert_eq!(m.cols(), &[1, 2, 0]);
    }

    /// Structured `nx × ny` quad (or split triangle) mesh of the unit square, interior nodes
    /// jittered by up to `jitter` of a cell, optionally lifted to a saddle.
    fn grid_mesh(nx: usize, ny: usize, kind: CellKind, jitter: f64, seed: u64) -> InterfaceMesh {
        let mut rng = Rng(seed);
        let mut x = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                let (mut u, mut v) = (i as f64 / nx as f64, j as f64 / ny as f64);
                if i > 0 && i < nx && j > 0 && j < ny {
                    u += jitter * rng.range(-1.0, 1.0) / nx as f64;
                    v += jitter * rng.range(-1.0, 1.0) / ny as f64;
                }
                x.push([u, v, 0.3 * (u - 0.5) * (v - 0.5)]);
            }
        }
        let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
        let mut conn = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                let q = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
                match kind {
                    CellKind::Quad => conn.extend_from_slice(&q),
                    _ => conn.extend_from_slice(&[q[0], q[1], q[2], q[0], q[2], q[3]]),
                }
            }
        }
        mesh(x, kind, conn)
    }

    #[test]
    fn grid_search_finds_the_closest_cell() {
        let mut rng = Rng(11);
        for kind in [CellKind::Quad, CellKind::Triangle] {
            let m = grid_mesh(9, 6, kind, 0.3, 3);
            let nn = kind.nodes();
            let conn = &m.cells.as_ref().unwrap().connectivity;
            let scale = bbox_diagonal(&m.positions);
            let geo: Vec<CellGeom> = conn
                .chunks(nn)
                .map(|c| {
                    let x = |a: usize| m.positions[c[a] as usize];
                    match kind {
                        CellKind::Quad => CellGeom::quad([x(0), x(1), x(2), x(3)], scale),
                        _ => CellGeom::triangle(x(0), x(1), x(2), scale),
                    }
                    .unwrap()
                })
                .collect();
            let grid = BinGrid::new(&geo.iter().map(|g| (g.lo, g.hi)).collect::<Vec<_>>());
            for k in 0..600 {
                let q = if k % 6 == 0 {
                    rng.point(-50.0, 50.0)
                } else {
                    rng.point(-0.7, 1.7)
                };
                let c = closest_cell(&grid, &geo, &q);
                let mut brute = (0, f64::INFINITY);
                for (i, g) in geo.iter().enumerate() {
                    let d2 = g.project(&q).1;
                    if d2 < brute.1 {
                        brute = (i, d2);
                    }
                }
                assert_eq!(c, brute.0, "{kind:?} query {q:?}");
            }
        }
    }

    #[test]
    fn distorted_quad_is_inverted_exactly() {
        // A general convex quad on a tilted plane; points x(ξ, η) must give back N(ξ, η).
        let e1 = [0.6, 0.0, 0.8];
        let e2 = [0.0, 1.0, 0.0];
        let lift = |u: f64, v: f64| {
            [
                1.0 + u * e1[0] + v * e2[0],
                -2.0 + u * e1[1] + v * e2[1],
                0.5 + u * e1[2] + v * e2[2],
            ]
        };
        let x = [
            lift(0.0, 0.0),
            lift(3.0, 0.4),
            lift(2.2, 2.5),
            lift(-0.4, 1.3),
        ];
        let g = CellGeom::quad(x, 5.0).unwrap();
        let mut rng = Rng(5);
        let mut worst: f64 = 0.0;
        for _ in 0..200 {
            let (xi, eta) = (rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
            let n: Vec<f64> = (0..4)
                .map(|k| {
                    let (a, b) = ([-1.0, 1.0, 1.0, -1.0][k], [-1.0, -1.0, 1.0, 1.0][k]);
                    0.25 * (1.0 + a * xi) * (1.0 + b * eta)
                })
                .collect();
            let q = combine(&n, &x);
            let (got, d2) = g.project(&q);
            assert!(d2 < 1e-28, "d2 = {d2}");
            for k in 0..4 {
                worst = worst.max((got[k] - n[k]).abs());
            }
        }
        assert!(worst < 1e-14, "worst shape-function error {worst:e}");
    }

    #[test]
    fn points_outside_clamp_to_the_cell() {
        let line = CellGeom::line([0.0; 3], [2.0, 0.0, 0.0], 2.0).unwrap();
        let (n, d2) = line.project(&[3.0, 1.0, 0.0]);
        assert_eq!((n[0], n[1], d2), (0.0, 1.0, 2.0));
        let (n, _) = line.project(&[0.5, 7.0, -3.0]);
        assert_eq!((n[0], n[1]), (0.75, 0.25));

        let tri = CellGeom::triangle([0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 1.0).unwrap();
        let (n, d2) = tri.project(&[2.0, -1.0, 0.5]);
        assert_eq!((n[0], n[1], n[2]), (0.0, 1.0, 0.0));
        assert!((d2 - 2.25).abs() < 1e-15);
        // Beyond the hypotenuse: closest point (0.5, 0.5, 0).
        let (n, d2) = tri.project(&[1.0, 1.0, 0.0]);
        assert!((n[1] - 0.5).abs() < 1e-15 && (n[2] - 0.5).abs() < 1e-15 && n[0].abs() < 1e-15);
        assert!((d2 - 0.5).abs() < 1e-15);

        let quad = CellGeom::quad(
            [[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
            1.0,
        )
        .unwrap();
        let (n, d2) = quad.project(&[1.5, 0.25, 0.0]);
        assert_eq!(n, [0.0, 0.75, 0.25, 0.0]);
        assert!((d2 - 0.25).abs() < 1e-15);
        let (n, d2) = quad.project(&[-1.0, -1.0, 2.0]);
        assert_eq!(n, [1.0, 0.0, 0.0, 0.0]);
        assert!((d2 - 6.0).abs() < 1e-15);
        // Above the interior: the weights of the foot point, distance the height.
        let (n, d2) = quad.project(&[0.25, 0.5, 3.0]);
        for (a, b) in n.iter().zip([0.375, 0.125, 0.125, 0.375]) {
            assert!((a - b).abs() < 1e-15);
        }
        assert!((d2 - 9.0).abs() < 1e-14);
    }

    #[test]
    fn malformed_meshes_are_errors() {
        let sq = vec![[0.0; 3], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let q = [[0.5, 0.5, 0.0]];
        let quad = |conn: Vec<u32>| mesh(sq.clone(), CellKind::Quad, conn);

        assert_eq!(
            Mapping::consistent(&InterfaceMesh::default(), &q),
            Err(MappingError::EmptyDriver)
        );
        assert_eq!(
            Mapping::nearest(&InterfaceMesh::default(), &q),
            Err(MappingError::EmptyDriver)
        );
        assert_eq!(
            Mapping::consistent(&quad(vec![0, 1, 2, 3]), &[]),
            Err(MappingError::EmptyResponder)
        );
        let mut nan = sq.clone();
        nan[2][1] = f64::NAN;
        assert!(matches!(
            Mapping::consistent(&mesh(nan.clone(), CellKind::Quad, vec![0, 1, 2, 3]), &q),
            Err(MappingError::NonFinitePosition {
                side: "driver",
                index: 2,
                ..
            })
        ));
        assert!(matches!(
            Mapping::nearest(&InterfaceMesh::points(nan), &q),
            Err(MappingError::NonFinitePosition {
                side: "driver",
                index: 2,
                ..
            })
        ));
        assert!(matches!(
            Mapping::consistent(&quad(vec![0, 1, 2, 3]), &[[0.0, f64::INFINITY, 0.0]]),
            Err(MappingError::NonFinitePosition {
                side: "responder",
                index: 0,
                ..
            })
        ));
        assert!(matches!(
            Mapping::consistent(&quad(vec![0, 1, 2, 3, 0]), &q),
            Err(MappingError::ConnectivityLength {
                len: 5,
                nodes: 4,
                ..
            })
        ));
        assert_eq!(
            Mapping::consistent(&quad(vec![0, 1, 2, 3, 0, 1, 2, 4]), &q),
            Err(MappingError::ConnectivityIndex {
                cell: 1,
                index: 4,
                n_points: 4
            })
        );
        // Bow-tie (nodes 2 and 3 swapped) and re-entrant (dart) quads.
        assert!(matches!(
            Mapping::consistent(&quad(vec![0, 1, 3, 2]), &q),
            Err(MappingError::DegenerateCell { cell: 0, .. })
        ));
        let dart = vec![[0.0; 3], [2.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 2.0, 0.0]];
        assert!(matches!(
            Mapping::consistent(&mesh(dart, CellKind::Quad, vec![0, 1, 2, 3]), &q),
            Err(MappingError::DegenerateCell { cell: 0, .. })
        ));
        assert!(matches!(
            Mapping::consistent(
                &mesh(sq.clone(), CellKind::Triangle, vec![0, 1, 2, 0, 2, 0]),
                &q
            ),
            Err(MappingError::DegenerateCell { cell: 1, .. })
        ));
        let line = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let collinear = vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!(matches!(
            Mapping::consistent(&mesh(collinear, CellKind::Triangle, vec![0, 1, 2]), &q),
            Err(MappingError::DegenerateCell { cell: 0, .. })
        ));
        assert!(matches!(
            Mapping::consistent(&mesh(line, CellKind::Line, vec![0, 1, 2, 2]), &q),
            Err(MappingError::DegenerateCell { cell: 1, .. })
        ));
        // No cells: falls back to nearest neighbour.
        let m = Mapping::consistent(&quad(vec![]), &[[0.9, 0.8, 0.0]]).unwrap();
        assert_eq!((m.cols(), m.weights()), (&[2u32][..], &[1.0][..]));
    }

    #[test]
    fn application_checks_lengths() {
        let m = Mapping::from_rows(
            2,
            vec![0, 1, 2, 4],
            vec![0, 1, 0, 1],
            vec![1.0, 1.0, 0.5, 0.5],
        )
        .unwrap();
        let mut out3 = [0.0; 9];
        assert_eq!(m.map_motion(&[0.0; 6], 3, &mut out3), Ok(()));
        assert_eq!(
            m.map_motion(&[0.0; 5], 3, &mut out3),
            Err(MappingError::Length {
                what: "source",
                expected: 6,
                got: 5
            })
        );
        assert_eq!(
            m.map_load(&[0.0; 9], 3, &mut out3),
            Err(MappingError::Length {
                what: "destination",
                expected: 6,
                got: 9
            })
        );
        assert_eq!(
            m.map_load(&[], 0, &mut []),
            Err(MappingError::ZeroComponents)
        );
    }
}
