//! Boundary conditions as ghost-cell fills on the primitive variables (seed 002 §5: walls,
//! non-reflecting outflow, inflow): wall and symmetry mirror the normal velocity (identical for
//! the inviscid equations), outflow copies the last interior cell (zero gradient), periodic
//! wraps, inflow imposes a fixed state.

use crate::grid::Grid;
use rayon::prelude::*;

#[derive(Debug, Clone, PartialEq)]
pub enum Boundary {
    Wall,
    Symmetry,
    Outflow,
    Periodic,
    /// Fixed primitive state in the solver's primitive ordering.
    Inflow(Vec<f64>),
}

/// Fill the ghost cells of `prim` (nv primitive variables, normal velocity of direction d at
/// index `vel0 + d`). `bc[d][side]`, side 0 = lower. Runs x, then y, then z so edges and
/// corners take consistent values.
pub fn fill_ghosts(grid: &Grid, prim: &mut [f64], nv: usize, vel0: usize, bc: &[[Boundary; 2]; 3]) {
    let mx = grid.mx();
    // x: inside each interior row (rows are independent: rayon over rows)
    if grid.g[0] > 0 {
        prim.par_chunks_mut(nv * mx)
            .enumerate()
            .for_each(|(r, block)| {
                if grid.interior_row(r) {
                    fill_row_x(grid, block, nv, vel0, &bc[0]);
                }
            });
    }
    fill_ghosts_yz(grid, prim, nv, vel0, bc);
}

/// The x ghost cells of one interior row (`block`: its nv variables), from its interior
/// cells: what [`fill_ghosts`] does to that row before the y and z ghosts (which copy whole
/// rows, x ghosts included). The time loop calls it on each row just after the row's
/// primitives, while they are in cache.
#[inline]
pub fn fill_row_x(grid: &Grid, block: &mut [f64], nv: usize, vel0: usize, bc: &[Boundary; 2]) {
    let mx = grid.mx();
    let g = grid.g;
    let nx = grid.n[0];
    for side in 0..2 {
        for l in 0..g[0] {
            // ghost index and its source
            let (gi, mirror, inner, wrap) = if side == 0 {
                (g[0] - 1 - l, g[0] + l, g[0], g[0] + nx - 1 - l)
            } else {
                (g[0] + nx + l, g[0] + nx - 1 - l, g[0] + nx - 1, g[0] + l)
            };
            for v in 0..nv {
                let row = &mut block[v * mx..(v + 1) * mx];
                row[gi] = match &bc[side] {
                    Boundary::Wall | Boundary::Symmetry => {
                        if v == vel0 {
                            -row[mirror]
                        } else {
                            row[mirror]
                        }
                    }
                    Boundary::Outflow => row[inner],
                    Boundary::Periodic => row[wrap],
                    Boundary::Inflow(s) => s[v],
                };
            }
        }
    }
}

/// The y and z ghost cells of [`fill_ghosts`] (whole rows, x ghost cells included: the x
/// ghosts of the interior rows must be filled first).
pub fn fill_ghosts_yz(
    grid: &Grid,
    prim: &mut [f64],
    nv: usize,
    vel0: usize,
    bc: &[[Boundary; 2]; 3],
) {
    let mx = grid.mx();
    let g = grid.g;
    // y and z: whole rows (ghost x cells included)
    for d in 1..3 {
        if g[d] == 0 {
            continue;
        }
        let n = grid.n[d];
        let stride = grid.row_stride(d);
        // rows to visit: all rows whose index in the other (non-d) transverse direction is
        // interior for d = 1, or anything for d = 2 (y ghosts are filled by then)
        for r in 0..grid.rows() {
            let (j, k) = grid.jk(r);
            let (idx, other_ok) = if d == 1 {
                (j, k >= g[2] && k < g[2] + grid.n[2])
            } else {
                (k, true)
            };
            if !other_ok || idx != g[d] {
                continue;
            }
            // r is the first interior row along d of this line
            for side in 0..2 {
                for l in 0..g[d] {
                    let (gi, mirror, inner, wrap) = if side == 0 {
                        (g[d] - 1 - l, g[d] + l, g[d], g[d] + n - 1 - l)
                    } else {
                        (g[d] + n + l, g[d] + n - 1 - l, g[d] + n - 1, g[d] + l)
                    };
                    let row_of = |t: usize| r + (t - g[d]) * stride;
                    let dst = row_of(gi) * nv * mx;
                    let src_t = match &bc[d][side] {
                        Boundary::Wall | Boundary::Symmetry => Some(mirror),
                        Boundary::Outflow => Some(inner),
                        Boundary::Periodic => Some(wrap),
                        Boundary::Inflow(_) => None,
                    };
                    match src_t {
                        Some(t) => {
                            let src = row_of(t) * nv * mx;
                            prim.copy_within(src..src + nv * mx, dst);
                            if matches!(bc[d][side], Boundary::Wall | Boundary::Symmetry) {
                                let o = dst + (vel0 + d) * mx;
                                for x in &mut prim[o..o + mx] {
                                    *x = -*x;
                                }
                            }
                        }
                        None => {
                            if let Boundary::Inflow(s) = &bc[d][side] {
                                for v in 0..nv {
                                    let o = dst + v * mx;
                                    prim[o..o + mx].fill(s[v]);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}
