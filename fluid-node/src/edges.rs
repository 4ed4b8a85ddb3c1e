//! Edges of a material along a line (docs/physics.md §3.6): where, going from a line's start
//! to its end through the cells it crosses, the material's volume fraction first rises
//! through 0.5 and where it last falls through it, every window; and each edge's speed, the
//! least-squares slope of its positions since it moved a cell from where it started. A shock
//! that runs over a bubble moves both of the bubble's edges on its axis; their speeds are what
//! experiments on shock–bubble interaction measure.

use crate::diagnostics::cell_prim;
use crate::model::Fluid;

pub use crate::model::EdgeLine;

/// Reported for an edge the line does not cross.
pub const ABSENT: f64 = -1.0;

impl EdgeLine {
    /// The line from `from` to `to` through the grid's cells (None: fewer than two cells).
    pub fn new(
        f: &Fluid,
        name: &str,
        material: usize,
        from: [f64; 3],
        to: [f64; 3],
    ) -> Option<Self> {
        let g = &f.grid;
        let d: Vec<f64> = (0..3).map(|k| to[k] - from[k]).collect();
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let h = (0..g.nd).map(|k| g.dx[k]).fold(f64::INFINITY, f64::min);
        let samples = (len / (0.25 * h)).ceil() as usize;
        let mut cells: Vec<(usize, usize, f64)> = Vec::new();
        for s in 0..=samples {
            let u = s as f64 / samples.max(1) as f64;
            let x = [from[0] + u * d[0], from[1] + u * d[1], from[2] + u * d[2]];
            let Some([i, j, k]) = g.locate(x) else {
                continue;
            };
            let row = g.row(j, k);
            if cells.iter().any(|c| c.0 == row && c.1 == i) {
                continue;
            }
            let c = g.centre(i, j, k);
            let along = (0..3).map(|q| (c[q] - from[q]) * d[q]).sum::<f64>() / len;
            cells.push((row, i, along));
        }
        (cells.len() >= 2).then(|| EdgeLine {
            name: name.to_string(),
            material,
            cells,
            moved: h,
        })
    }

    /// (first, last): the distances along the line where the material's volume fraction first
    /// rises through 0.5 and last falls through it, linear between cell centres; a line that
    /// starts or ends inside the material has its edge there; [`ABSENT`] when the material is
    /// nowhere at 0.5 or more on the line.
    pub fn positions(&self, f: &Fluid) -> [f64; 2] {
        let alpha: Vec<f64> = self
            .cells
            .iter()
            .map(|&(r, i, _)| cell_prim(f, r, i).3[self.material])
            .collect();
        self.positions_of(&alpha)
    }

    /// [`EdgeLine::positions`] from the material's volume fraction in each of the line's
    /// cells (`alpha`, in the order of `cells`): the device path reads them back per window.
    pub fn positions_of(&self, alpha: &[f64]) -> [f64; 2] {
        let s = |k: usize| self.cells[k].2;
        let cross = |k: usize| {
            let (a0, a1) = (alpha[k - 1], alpha[k]);
            s(k - 1) + (0.5 - a0) / (a1 - a0) * (s(k) - s(k - 1))
        };
        let n = alpha.len();
        let first = if alpha[0] >= 0.5 {
            Some(s(0))
        } else {
            (1..n)
                .find(|&k| alpha[k - 1] < 0.5 && alpha[k] >= 0.5)
                .map(cross)
        };
        let last = if alpha[n - 1] >= 0.5 {
            Some(s(n - 1))
        } else {
            (1..n)
                .rev()
                .find(|&k| alpha[k - 1] >= 0.5 && alpha[k] < 0.5)
                .map(cross)
        };
        [first.unwrap_or(ABSENT), last.unwrap_or(ABSENT)]
    }
}

/// The speed of edge `side` (0 first, 1 last) of line `e` from its history `(time,
/// positions)`, the first entry where it started: the least-squares slope over the samples
/// since it moved a cell from there (m/s, positive away from the line's start); 0 before it
/// has two such samples.
pub fn speed(hist: &[(f64, Vec<[f64; 2]>)], e: usize, side: usize, moved: f64) -> f64 {
    let Some(x0) = hist.first().map(|h| h.1[e][side]) else {
        return 0.0;
    };
    if x0 == ABSENT {
        return 0.0;
    }
    let pts: Vec<(f64, f64)> = hist
        .iter()
        .map(|h| (h.0, h.1[e][side]))
        .filter(|&(_, x)| x != ABSENT && (x - x0).abs() > moved)
        .collect();
    if pts.len() < 2 {
        return 0.0;
    }
    let n = pts.len() as f64;
    let (mt, mx) = pts
        .iter()
        .fold((0.0, 0.0), |a, p| (a.0 + p.0 / n, a.1 + p.1 / n));
    let num: f64 = pts.iter().map(|p| (p.0 - mt) * (p.1 - mx)).sum();
    let den: f64 = pts.iter().map(|p| (p.0 - mt) * (p.0 - mt)).sum();
    if den > 0.0 { num / den } else { 0.0 }
}
