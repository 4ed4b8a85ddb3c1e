//! Whole-field sums and single-cell states for reports, probes and tests. Sums run per row
//! then in row order, so they are identical for any thread count.

use crate::immersed::body::SOLID;
use crate::mixture::{self, Phase};
use crate::model::Fluid;
use protocol::SolverResult;

#[derive(Debug, Clone, Copy)]
pub struct Totals {
    pub mass: f64,
    pub momentum: [f64; 3],
    /// Σ |ρu| V: the scale of momentum sums that cancel.
    pub momentum_gross: f64,
    pub kinetic: f64,
    pub internal: f64,
    pub max_pressure: f64,
    /// The least pressure and density of any gas cell (+∞ with no gas cell).
    pub min_pressure: f64,
    pub min_density: f64,
}

impl Default for Totals {
    fn default() -> Self {
        Totals {
            mass: 0.0,
            momentum: [0.0; 3],
            momentum_gross: 0.0,
            kinetic: 0.0,
            internal: 0.0,
            max_pressure: 0.0,
            min_pressure: f64::INFINITY,
            min_density: f64::INFINITY,
        }
    }
}

/// Primitive state of one cell from its conserved variables: (ρ, velocity, p, α).
pub fn cell_prim(f: &Fluid, row: usize, i: usize) -> (f64, [f64; 3], f64, Vec<f64>) {
    match f.nmat() {
        1 => cell_prim_nm::<1>(f, row, i),
        2 => cell_prim_nm::<2>(f, row, i),
        3 => cell_prim_nm::<3>(f, row, i),
        _ => cell_prim_nm::<4>(f, row, i),
    }
}

fn cell_prim_nm<const NM: usize>(
    f: &Fluid,
    row: usize,
    i: usize,
) -> (f64, [f64; 3], f64, Vec<f64>) {
    let mx = f.grid.mx();
    let nv = f.nv;
    prim_of::<NM>(&f.phases, |v| f.cons[(row * nv + v) * mx + i])
}

/// Primitive state (ρ, velocity, p, α) of the conserved values `c(v)` of one cell, as
/// [`cell_prim`] gives it: also for a cell read back from the device.
pub fn cell_prim_of(phases: &[Phase], c: &[f64]) -> (f64, [f64; 3], f64, Vec<f64>) {
    match phases.len() {
        1 => prim_of::<1>(phases, |v| c[v]),
        2 => prim_of::<2>(phases, |v| c[v]),
        3 => prim_of::<3>(phases, |v| c[v]),
        _ => prim_of::<4>(phases, |v| c[v]),
    }
}

fn prim_of<const NM: usize>(
    phases: &[Phase],
    c: impl Fn(usize) -> f64,
) -> (f64, [f64; 3], f64, Vec<f64>) {
    let ph: [Phase; NM] = std::array::from_fn(|k| phases[k].clone());
    let mut ar = [0.0; NM];
    let mut al = [0.0; NM];
    let mut rho = 0.0;
    for k in 0..NM {
        ar[k] = c(k).max(0.0);
        rho += ar[k];
    }
    let mut s = 0.0;
    for k in 0..NM - 1 {
        al[k] = c(NM + 4 + k);
        s += al[k];
    }
    al[NM - 1] = 1.0 - s;
    let vel = [c(NM) / rho, c(NM + 1) / rho, c(NM + 2) / rho];
    let rhoe = c(NM + 3) - 0.5 * rho * (vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]);
    let p = mixture::pressure(&ph, &ar, &al, rhoe);
    (rho, vel, p, al.to_vec())
}

/// The acoustic impedance ρc of a cell (the mixture's frozen sound speed).
pub fn cell_impedance(f: &Fluid, row: usize, i: usize) -> f64 {
    match f.nmat() {
        1 => cell_impedance_nm::<1>(f, row, i),
        2 => cell_impedance_nm::<2>(f, row, i),
        3 => cell_impedance_nm::<3>(f, row, i),
        _ => cell_impedance_nm::<4>(f, row, i),
    }
}

fn cell_impedance_nm<const NM: usize>(f: &Fluid, row: usize, i: usize) -> f64 {
    let ph: [Phase; NM] = std::array::from_fn(|k| f.phases[k].clone());
    let (rho, _, p, al) = cell_prim_nm::<NM>(f, row, i);
    let mx = f.grid.mx();
    let ar: [f64; NM] = std::array::from_fn(|k| f.cons[(row * f.nv + k) * mx + i].max(0.0));
    let al: [f64; NM] = std::array::from_fn(|k| al[k]);
    rho * mixture::sound_speed2::<NM>(&ph, &ar, &al, rho, p).sqrt()
}

/// [ρ, p, u, v, w] of a cell.
pub fn cell_state(f: &Fluid, row: usize, i: usize) -> [f64; 5] {
    let (rho, v, p, _) = cell_prim(f, row, i);
    [rho, p, v[0], v[1], v[2]]
}

/// Mass, momentum, energies of the gas (solid cells of the immersed body excluded). On a
/// radial grid every sum is over the rings' or shells' volumes, and the momentum is the
/// gas's momentum as a whole: zero across the axis or centre by symmetry, the axial
/// component alone in axisymmetric geometry (`momentum_gross` still sums |ρu| V).
pub fn totals(f: &mut Fluid) -> SolverResult<Totals> {
    let g = &f.grid;
    let radial = !g.columns.is_empty();
    let nm = f.nmat();
    let mx = g.mx();
    let nv = f.nv;
    let mut t = Totals::default();
    for r in 0..g.rows() {
        if !g.interior_row(r) {
            continue;
        }
        let mut row = Totals::default();
        for i in g.irange() {
            if let Some(im) = &f.immersed
                && im.kind[r * mx + i] == SOLID
            {
                continue;
            }
            let vol = g.volume_at(i);
            let (rho, v, p, _) = cell_prim(f, r, i);
            let e = f.cons[(r * nv + nm + 3) * mx + i];
            let ke = 0.5 * rho * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            row.mass += rho * vol;
            let mut m2 = 0.0;
            for d in 0..3 {
                let m = f.cons[(r * nv + nm + d) * mx + i];
                if !radial || (d == 1 && g.nd > 1) {
                    row.momentum[d] += m * vol;
                }
                m2 += m * m;
            }
            row.momentum_gross += m2.sqrt() * vol;
            row.kinetic += ke * vol;
            row.internal += (e - ke) * vol;
            row.max_pressure = row.max_pressure.max(p);
            row.min_pressure = row.min_pressure.min(p);
            row.min_density = row.min_density.min(rho);
        }
        t.mass += row.mass;
        for d in 0..3 {
            t.momentum[d] += row.momentum[d];
        }
        t.momentum_gross += row.momentum_gross;
        t.kinetic += row.kinetic;
        t.internal += row.internal;
        t.max_pressure = t.max_pressure.max(row.max_pressure);
        t.min_pressure = t.min_pressure.min(row.min_pressure);
        t.min_density = t.min_density.min(row.min_density);
    }
    Ok(t)
}

/// Values of one primitive quantity along the x-line through (j, k) (interior indices):
/// (x, ρ, u, p) per cell. For tests and examples.
pub fn x_line(f: &Fluid, j: usize, k: usize) -> Vec<(f64, f64, f64, f64)> {
    let g = &f.grid;
    let r = g.row(j + g.g[1], k + g.g[2]);
    g.irange()
        .map(|i| {
            let (rho, v, p, _) = cell_prim(f, r, i);
            (g.centre(i, j + g.g[1], k + g.g[2])[0], rho, v[0], p)
        })
        .collect()
}
