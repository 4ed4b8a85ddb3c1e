//! Boundary conditions as ghost-cell fills on the primitive variables (seed 002 §5: walls,
//! non-reflecting outflow, inflow): wall and symmetry mirror the normal velocity (identical for
//! the inviscid equations), outflow copies the last interior cell (zero gradient), periodic
//! wraps, inflow imposes a fixed state, and a non-reflecting face lets the outgoing acoustic
//! wave leave and lets in only the far field's (docs/physics.md §3.4).

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
    /// Characteristic far field (docs/physics.md §3.4): the ghost carries the interior's
    /// outgoing acoustic invariant p + Z u·n (n the outward normal) and an incoming one
    /// p − Z u·n relaxed from the interior's toward the far field's by the fraction `relax`,
    /// the rest of the interior state unchanged. With `relax` 0 it is the transmissive
    /// outflow; the small relaxation holds the far field's pressure without reflecting the
    /// waves that leave.
    NonReflecting(FarField),
}

/// The far field of a non-reflecting face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FarField {
    /// Pressure far outside (Pa).
    pub pressure: f64,
    /// Velocity far outside (m/s).
    pub velocity: [f64; 3],
    /// Acoustic impedance ρc of the gas along the face (Pa s/m).
    pub impedance: f64,
    /// Fraction of the difference between the far field's incoming invariant and the
    /// interior's that each ghost fill lets in: K Δt of the relaxation rate K = σ c / L
    /// (Poinsot & Lele) over a step Δt = cfl Δx / c, so σ · cfl · Δx / L, with σ = 0.25 and L
    /// the domain's extent across the face.
    pub relax: f64,
}

impl FarField {
    /// The ghost's (pressure, velocity along the face's axis) from the interior cell's, for a
    /// face whose outward normal is `sign` × that axis (`u` the interior's velocity along the
    /// axis, `u_far` the far field's).
    #[inline(always)]
    pub fn ghost(&self, p: f64, u: f64, u_far: f64, sign: f64) -> (f64, f64) {
        let z = self.impedance;
        let out = p + z * sign * u;
        let inc = p - z * sign * u;
        let inc = inc + self.relax * ((self.pressure - z * sign * u_far) - inc);
        (0.5 * (out + inc), sign * (out - inc) / (2.0 * z))
    }
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
                    Boundary::Outflow | Boundary::NonReflecting(_) => row[inner],
                    Boundary::Periodic => row[wrap],
                    Boundary::Inflow(s) => s[v],
                };
            }
            if let Boundary::NonReflecting(far) = &bc[side] {
                let sign = if side == 0 { -1.0 } else { 1.0 };
                let (ip, iu) = ((vel0 + 3) * mx, vel0 * mx);
                let (p, u) = far.ghost(block[ip + inner], block[iu + inner], far.velocity[0], sign);
                block[ip + gi] = p;
                block[iu + gi] = u;
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
                        Boundary::Outflow | Boundary::NonReflecting(_) => Some(inner),
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
                            if let Boundary::NonReflecting(far) = &bc[d][side] {
                                let sign = if side == 0 { -1.0 } else { 1.0 };
                                let (op, ou) = (dst + (vel0 + 3) * mx, dst + (vel0 + d) * mx);
                                for i in 0..mx {
                                    let (p, u) = far.ghost(
                                        prim[op + i],
                                        prim[ou + i],
                                        far.velocity[d],
                                        sign,
                                    );
                                    prim[op + i] = p;
                                    prim[ou + i] = u;
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
