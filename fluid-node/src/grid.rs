//! Structured grid with ghost layers — Cartesian, or with x a radius (`Geometry`: cylindrical,
//! spherical, axisymmetric; each x column then carries its cells' volume and face areas) — and
//! the row-blocked structure-of-arrays layout every kernel uses: a "row" is one x-line of cells (ghosts included); row `r` stores its
//! `nv` variables one after another, `data[(r * nv + v) * mx + i]`. A row with all its
//! variables is one contiguous chunk, so rayon splits work by rows without scatter.

/// Ghost layers in each active direction (MUSCL needs two).
pub const NG: usize = 2;

/// What the grid's coordinates measure (docs/physics.md, "Radial geometries").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Geometry {
    /// x, y, z Cartesian: every cell the same box.
    Cartesian,
    /// 1-D, x the distance from an axis: a cell is a cylindrical shell one metre long.
    Cylindrical,
    /// 1-D, x the distance from a centre: a cell is a spherical shell.
    Spherical,
    /// 2-D, x the distance from the axis and y along it: a cell is a ring of the whole
    /// revolution.
    Axisymmetric,
}

impl Geometry {
    /// The exponent α of the radial face area A ∝ r^α (0 in Cartesian geometry).
    pub fn alpha(self) -> u32 {
        match self {
            Geometry::Cartesian => 0,
            Geometry::Cylindrical | Geometry::Axisymmetric => 1,
            Geometry::Spherical => 2,
        }
    }
    /// The name a case file gives it.
    pub fn name(self) -> &'static str {
        match self {
            Geometry::Cartesian => "cartesian",
            Geometry::Cylindrical => "cylindrical",
            Geometry::Spherical => "spherical",
            Geometry::Axisymmetric => "axisymmetric",
        }
    }
}

/// The volume and x-face areas of the cells of one x column of a radial grid (the same in
/// every row): the finite-volume weights of the radial direction.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Column {
    /// Cell volume (m³; per metre of axis in cylindrical geometry).
    pub volume: f64,
    /// Area of the cell's inner (lower x) face (m²; per metre of axis in cylindrical geometry).
    pub area_lo: f64,
    /// Area of its outer (upper x) face.
    pub area_hi: f64,
    /// `area_lo / volume` and `area_hi / volume`: the update's weights, divided once here
    /// instead of in every stage for every variable.
    pub lo_per_volume: f64,
    pub hi_per_volume: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Interior cells per direction.
    pub n: [usize; 3],
    /// Ghost layers per direction (NG when the direction is active, else 0).
    pub g: [usize; 3],
    /// Cells per direction including ghosts.
    pub m: [usize; 3],
    pub lower: [f64; 3],
    pub upper: [f64; 3],
    pub dx: [f64; 3],
    /// Number of active directions (1, 2 or 3).
    pub nd: usize,
    /// What the coordinates measure.
    pub geometry: Geometry,
    /// Per x index (ghosts included) the radial weights of its cells; empty in Cartesian
    /// geometry, where [`Grid::cell_volume`] and [`Grid::face_area`] hold for every cell.
    pub columns: Vec<Column>,
}

impl Grid {
    pub fn new(n: [usize; 3], lower: [f64; 3], upper: [f64; 3]) -> Self {
        let nd = if n[2] > 1 {
            3
        } else if n[1] > 1 {
            2
        } else {
            1
        };
        let mut g = [0; 3];
        for (d, gd) in g.iter_mut().enumerate().take(nd) {
            let _ = d;
            *gd = NG;
        }
        let m = [n[0] + 2 * g[0], n[1] + 2 * g[1], n[2] + 2 * g[2]];
        let dx = [
            (upper[0] - lower[0]) / n[0] as f64,
            (upper[1] - lower[1]) / n[1] as f64,
            (upper[2] - lower[2]) / n[2] as f64,
        ];
        Grid {
            n,
            g,
            m,
            lower,
            upper,
            dx,
            nd,
            geometry: Geometry::Cartesian,
            columns: Vec::new(),
        }
    }

    /// A grid whose x coordinate is a radius (`geometry` not Cartesian: 1-D cylindrical or
    /// spherical, 2-D axisymmetric with y along the axis). The caller has checked that the
    /// dimension fits the geometry and that `lower[0] ≥ 0`.
    pub fn radial(n: [usize; 3], lower: [f64; 3], upper: [f64; 3], geometry: Geometry) -> Self {
        let mut grid = Grid::new(n, lower, upper);
        grid.geometry = geometry;
        if geometry == Geometry::Cartesian {
            return grid;
        }
        let pi = std::f64::consts::PI;
        // a ring's thickness along the axis (axisymmetric); the cylinder is one metre long
        let dz = if geometry == Geometry::Axisymmetric {
            grid.dx[1]
        } else {
            1.0
        };
        let face = |r: f64| -> f64 {
            match geometry {
                Geometry::Spherical => 4.0 * pi * r * r,
                _ => 2.0 * pi * r * dz,
            }
        };
        let below = |r: f64| -> f64 {
            // volume inside radius r
            match geometry {
                Geometry::Spherical => 4.0 / 3.0 * pi * r * r * r,
                _ => pi * r * r * dz,
            }
        };
        grid.columns = (0..grid.mx())
            .map(|i| {
                // ghost columns mirror their interior partners' radii about r = 0 if they
                // fall below it; their weights are never used in an update
                let lo = (lower[0] + (i as f64 - grid.g[0] as f64) * grid.dx[0]).abs();
                let hi = (lo + grid.dx[0]).abs();
                let volume = (below(hi) - below(lo)).abs();
                Column {
                    volume,
                    area_lo: face(lo),
                    area_hi: face(hi),
                    lo_per_volume: face(lo) / volume,
                    hi_per_volume: face(hi) / volume,
                }
            })
            .collect();
        grid
    }

    /// Volume of a cell of x index i (ghost-inclusive): [`Grid::cell_volume`] in Cartesian
    /// geometry, its ring or shell otherwise.
    #[inline(always)]
    pub fn volume_at(&self, i: usize) -> f64 {
        if self.columns.is_empty() {
            self.cell_volume()
        } else {
            self.columns[i].volume
        }
    }

    /// Row length (cells per x-line including ghosts).
    #[inline(always)]
    pub fn mx(&self) -> usize {
        self.m[0]
    }
    /// Number of rows including ghost rows.
    #[inline(always)]
    pub fn rows(&self) -> usize {
        self.m[1] * self.m[2]
    }
    /// Row index of (j, k) (ghost-inclusive indices).
    #[inline(always)]
    pub fn row(&self, j: usize, k: usize) -> usize {
        j + k * self.m[1]
    }
    /// (j, k) of a row.
    #[inline(always)]
    pub fn jk(&self, r: usize) -> (usize, usize) {
        (r % self.m[1], r / self.m[1])
    }
    /// Row stride of a unit step in direction d (d = 1: next j, d = 2: next k).
    #[inline(always)]
    pub fn row_stride(&self, d: usize) -> usize {
        if d == 1 { 1 } else { self.m[1] }
    }
    /// True for a row whose (j, k) are both interior.
    #[inline(always)]
    pub fn interior_row(&self, r: usize) -> bool {
        let (j, k) = self.jk(r);
        j >= self.g[1] && j < self.g[1] + self.n[1] && k >= self.g[2] && k < self.g[2] + self.n[2]
    }
    /// Interior x range of a row.
    #[inline(always)]
    pub fn irange(&self) -> std::ops::Range<usize> {
        self.g[0]..self.g[0] + self.n[0]
    }
    /// Cell volume (a 2-D grid is one cell of thickness upper-lower in z, SI).
    pub fn cell_volume(&self) -> f64 {
        self.dx[0] * self.dx[1] * self.dx[2]
    }
    /// Area of a face normal to d.
    pub fn face_area(&self, d: usize) -> f64 {
        self.cell_volume() / self.dx[d]
    }
    /// Interior cell count.
    pub fn cells(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }
    /// Centre of cell (i, j, k) in ghost-inclusive indices.
    #[inline(always)]
    pub fn centre(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [
            self.lower[0] + (i as f64 - self.g[0] as f64 + 0.5) * self.dx[0],
            self.lower[1] + (j as f64 - self.g[1] as f64 + 0.5) * self.dx[1],
            self.lower[2] + (k as f64 - self.g[2] as f64 + 0.5) * self.dx[2],
        ]
    }
    /// Interior cell containing point x (ghost-inclusive indices), if inside the domain.
    pub fn locate(&self, x: [f64; 3]) -> Option<[usize; 3]> {
        let mut idx = [0usize; 3];
        for d in 0..3 {
            if d >= self.nd {
                idx[d] = 0;
                continue;
            }
            let s = (x[d] - self.lower[d]) / self.dx[d];
            if !(s >= 0.0 && s < self.n[d] as f64) {
                return None;
            }
            idx[d] = (s.floor() as usize).min(self.n[d] - 1) + self.g[d];
        }
        Some(idx)
    }
    /// Flat index of variable v of cell (i, row r) in a buffer with nv variables.
    #[inline(always)]
    pub fn at(&self, nv: usize, r: usize, v: usize, i: usize) -> usize {
        (r * nv + v) * self.m[0] + i
    }
}
