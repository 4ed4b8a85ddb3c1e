//! Responder side of the immersed fluid–particle coupling (seed 002 §3, eq. 31–35;
//! docs/architecture.md "immersed"). Each window the solid sends particle positions, velocities
//! and volumes; cells are classified as fluid, interface (holds particles, has a fluid face
//! neighbour) or solid (holds particles, no fluid neighbour). Interface cells carry the mean
//! particle velocity (eq. 31); solid cells next to the gas take neighbour averages (eq. 32)
//! so the MUSCL stencils see a smooth state; faces between interface and solid cells are
//! walls moving with the particles. After every RK stage the momentum of an interface cell is
//! reset to ρ v_ib; what the reset removes, V (RHS(ρv) - v_ib RHS(ρ)) per unit time (eq. 33),
//! goes to the cell's particles in equal shares (eq. 34), weighted 1/6, 2/3, 1 over the three
//! stages (eq. 35) — exactly the weights with which the projections enter the step, so the
//! gas momentum lost equals the particle impulse to round-off. Cells a solid leaves are
//! refilled from their gas neighbours (eq. 32).

pub mod body;

use crate::mixture::Phase;
use crate::model::Fluid;
use crate::riemann::{MAXF, face_state, hllc};
pub use body::{FLUID, INTERFACE, Immersed, SOLID, WallFace};

const NONE: usize = usize::MAX;

/// The least held mass, as a fraction of the gas neighbours' mean, that a freed cell gets
/// back ([`Immersed::hand_back`]); with less it takes its gas from its neighbours.
const HAND_BACK_MIN: f64 = 0.8;

impl Immersed {
    /// Start a window with new particle data: classify cells, refill cells the solid left,
    /// zero the window impulses.
    pub fn set_particles(&mut self, f: &mut Fluid, pos: &[f64], vel: &[f64], vol: &[f64]) {
        let n = vol.len();
        self.n = n;
        self.positions.clear();
        self.velocities.clear();
        self.volumes.clear();
        self.volumes.extend_from_slice(vol);
        for p in 0..n {
            self.positions
                .push([pos[3 * p], pos[3 * p + 1], pos[3 * p + 2]]);
            self.velocities
                .push([vel[3 * p], vel[3 * p + 1], vel[3 * p + 2]]);
        }
        self.impulse.clear();
        self.impulse.resize(n, [0.0; 3]);
        self.classify(f);
    }

    fn classify(&mut self, f: &mut Fluid) {
        let grid = &f.grid;
        let mx = grid.mx();
        std::mem::swap(&mut self.kind, &mut self.prev_kind);
        self.kind.fill(FLUID);
        self.cell_of.clear();
        for p in 0..self.n {
            let c = match grid.locate(self.positions[p]) {
                Some([i, j, k]) => grid.row(j, k) * mx + i,
                None => NONE,
            };
            self.cell_of.push(c);
        }
        // counting sort of particles by cell (deterministic: particle order within a cell;
        // O(cells + particles), no allocation once the buffers have grown)
        let at = &mut self.sort_scratch;
        at.clear();
        at.resize(self.kind.len(), 0);
        for &c in &self.cell_of {
            if c != NONE {
                at[c] += 1;
            }
        }
        self.cells.clear();
        self.off.clear();
        let mut total = 0;
        for (c, k) in at.iter_mut().enumerate() {
            if *k > 0 {
                self.cells.push(c);
                self.off.push(total);
                // from here on: where the cell's next particle goes
                (*k, total) = (total, total + *k);
            }
        }
        self.off.push(total);
        self.parts.clear();
        self.parts.resize(total, 0);
        for (p, &c) in self.cell_of.iter().enumerate() {
            if c != NONE {
                self.parts[at[c]] = p;
                at[c] += 1;
            }
        }
        for &c in &self.cells {
            self.kind[c] = SOLID;
        }
        // interface: an occupied cell with a gas face neighbour inside the domain
        self.cell_kind.clear();
        self.cell_vel.clear();
        for (ci, &c) in self.cells.iter().enumerate() {
            let mut kind = SOLID;
            for (nb, _, _) in neighbours(f, c) {
                if self.kind[nb] == FLUID {
                    kind = INTERFACE;
                }
            }
            self.cell_kind.push(kind);
            // seed 002 eq. (31): mean velocity of the particles in the cell
            let ps = &self.parts[self.off[ci]..self.off[ci + 1]];
            let mut v = [0.0; 3];
            for &p in ps {
                for d in 0..3 {
                    v[d] += self.velocities[p][d];
                }
            }
            for vd in &mut v {
                *vd /= ps.len() as f64;
            }
            self.cell_vel.push(v);
        }
        for (ci, &c) in self.cells.iter().enumerate() {
            self.kind[c] = self.cell_kind[ci];
        }
        // wall faces between interface and solid cells
        self.walls.clear();
        for (ci, &c) in self.cells.iter().enumerate() {
            if self.cell_kind[ci] != SOLID {
                continue;
            }
            for (nb, d, upper) in neighbours(f, c) {
                if self.kind[nb] == INTERFACE {
                    // the interface (gas) cell nb lies on side `upper` of the solid cell
                    let (left, right, gas_left) =
                        if upper { (c, nb, false) } else { (nb, c, true) };
                    self.walls.push(WallFace {
                        d,
                        left,
                        right,
                        gas_left,
                    });
                }
            }
        }
        self.wall_order.clear();
        self.refill(f);
        // interface cells take the particle velocity now (eq. 31) keeping ρ and ρe
        for (ci, &c) in self.cells.iter().enumerate() {
            if self.cell_kind[ci] == INTERFACE {
                let (r, de) = project_cell(f, c, self.cell_vel[ci]);
                for d in 0..3 {
                    self.reclass_momentum[d] -= r[d];
                }
                self.reclass_energy += de;
            }
        }
        f.prim_valid = false;
    }

    /// Cells that were solid and now hold gas: neighbour average of the conserved state
    /// (seed 002 eq. 32 with equal weights for the face neighbours); cells that became solid
    /// leave the gas. With `conservative` (after the first classification) a cell the solid
    /// left gets back what the walls carried into it ([`Immersed::hand_back`]) or, failing
    /// that, takes its gas from its neighbours ([`Immersed::share`]).
    fn refill(&mut self, f: &mut Fluid) {
        let mx = f.grid.mx();
        let nv = f.nv;
        let nm = f.nmat();
        let vol = f.grid.cell_volume();
        let share = self.conservative && self.classified;
        self.classified = true;
        for r in 0..f.grid.rows() {
            if !f.grid.interior_row(r) {
                continue;
            }
            for i in f.grid.irange() {
                let c = r * mx + i;
                let (was, now) = (self.prev_kind[c], self.kind[c]);
                if share
                    && was == SOLID
                    && now != SOLID
                    && (self.hand_back(f, c) || self.share(f, c))
                {
                    continue;
                }
                if self.conservative && was != SOLID && now == SOLID && !self.held.is_empty() {
                    // a newly covered cell starts holding nothing
                    self.held[c * nv..(c + 1) * nv].fill(0.0);
                }
                if was == SOLID && now != SOLID {
                    let mut acc = [0.0; MAXF];
                    let mut cnt = 0.0;
                    for (nb, _, _) in neighbours(f, c) {
                        if self.prev_kind[nb] != SOLID && self.kind[nb] != SOLID {
                            let (rn, i_n) = (nb / mx, nb % mx);
                            for (v, a) in acc.iter_mut().enumerate().take(nv) {
                                *a += f.cons[(rn * nv + v) * mx + i_n];
                            }
                            cnt += 1.0;
                        }
                    }
                    if cnt > 0.0 {
                        for (v, a) in acc.iter().enumerate().take(nv) {
                            f.cons[(r * nv + v) * mx + i] = a / cnt;
                        }
                    }
                    for d in 0..3 {
                        self.reclass_momentum[d] += vol * f.cons[(r * nv + nm + d) * mx + i];
                    }
                    for k in 0..nm {
                        self.reclass_mass += vol * f.cons[(r * nv + k) * mx + i];
                    }
                    self.reclass_energy += vol * f.cons[(r * nv + nm + 3) * mx + i];
                } else if was != SOLID && now == SOLID {
                    for d in 0..3 {
                        self.reclass_momentum[d] -= vol * f.cons[(r * nv + nm + d) * mx + i];
                    }
                    for k in 0..nm {
                        self.reclass_mass -= vol * f.cons[(r * nv + k) * mx + i];
                    }
                    self.reclass_energy -= vol * f.cons[(r * nv + nm + 3) * mx + i];
                }
            }
        }
    }
}

impl Immersed {
    /// Hands back to cell `c`, which the solid has just left, what the moving walls' fluxes
    /// carried into it while it was solid (`held`: partial densities, momentum, energy, and
    /// the volume fractions weighted by the mass carried), booked as reclassification (the
    /// carrying was booked out: `held_energy`, `held_momentum`, `wall_mass`). False (nothing
    /// done, nothing booked) when less mass is held than 0.8 of the mean of its gas
    /// neighbours' (a cell a crack opened, or one the wall crossed only in part: handed
    /// back, such a thin cell beside dense gas starts a rarefaction that took the steel
    /// tube's fine variant to negative pressure), or when what is held is not a gas of
    /// positive density and pressure.
    fn hand_back(&mut self, f: &mut Fluid, c: usize) -> bool {
        if self.held.is_empty() {
            return false;
        }
        let mx = f.grid.mx();
        let nv = f.nv;
        let nm = f.nmat();
        let vol = f.grid.cell_volume();
        let at = |cell: usize, v: usize| ((cell / mx) * nv + v) * mx + cell % mx;
        let h = c * nv;
        let mass: f64 = self.held[h..h + nm].iter().sum();
        let (mut nb_mass, mut n) = (0.0, 0);
        for (nb, _, _) in neighbours(f, c) {
            if self.prev_kind[nb] != SOLID && self.kind[nb] != SOLID {
                nb_mass += (0..nm).map(|k| f.cons[at(nb, k)]).sum::<f64>() * vol;
                n += 1;
            }
        }
        if n == 0
            || !(mass > HAND_BACK_MIN * nb_mass / n as f64)
            || self.held[h..h + nm].iter().any(|&m| m < 0.0)
        {
            return false;
        }
        let mut before = [0.0; MAXF];
        for v in 0..nv {
            before[v] = f.cons[at(c, v)];
            let x = self.held[h + v];
            f.cons[at(c, v)] = if v < nm + 4 { x / vol } else { x / mass };
        }
        let (rho, u, p, _) = crate::diagnostics::cell_prim(f, c / mx, c % mx);
        if !(rho > 0.0 && p > 0.0 && p.is_finite() && u.iter().all(|x| x.is_finite())) {
            for (v, b) in before.iter().enumerate().take(nv) {
                f.cons[at(c, v)] = *b;
            }
            return false;
        }
        for v in 0..nm + 4 {
            let x = self.held[h + v];
            match v {
                v if v < nm => self.reclass_mass += x,
                v if v < nm + 3 => self.reclass_momentum[v - nm] += x,
                _ => self.reclass_energy += x,
            }
        }
        self.held[h..h + nv].fill(0.0);
        true
    }

    /// Conservative refill of cell `c`, which the solid has just left, from its gas face
    /// neighbours (cells gas before and now): it takes 1/(n+1) of its n neighbours' summed
    /// mass, momentum and energy, and each neighbour keeps n/(n+1) of its own. Every
    /// neighbour keeps its velocity and specific energy, the cell starts at their mean state
    /// diluted by n/(n+1) (the gas has expanded into the freed volume), its volume fractions
    /// their mean; nothing is created. False (nothing done) when it has no gas neighbour.
    fn share(&mut self, f: &mut Fluid, c: usize) -> bool {
        let mx = f.grid.mx();
        let nv = f.nv;
        let conserved = f.nmat() + 4;
        let mut nbs = [0usize; 6];
        let mut n = 0;
        for (nb, _, _) in neighbours(f, c) {
            if self.prev_kind[nb] != SOLID && self.kind[nb] != SOLID {
                nbs[n] = nb;
                n += 1;
            }
        }
        if n == 0 {
            return false;
        }
        let at = |cell: usize, v: usize| ((cell / mx) * nv + v) * mx + cell % mx;
        let keep = n as f64 / (n as f64 + 1.0);
        for v in 0..nv {
            let sum: f64 = nbs[..n].iter().map(|&nb| f.cons[at(nb, v)]).sum();
            if v < conserved {
                f.cons[at(c, v)] = sum / (n as f64 + 1.0);
                for &nb in &nbs[..n] {
                    f.cons[at(nb, v)] *= keep;
                }
            } else {
                f.cons[at(c, v)] = sum / n as f64;
            }
        }
        true
    }
}

/// Face neighbours of a flat cell index inside the interior: (flat, direction, is_upper).
fn neighbours(f: &Fluid, c: usize) -> impl Iterator<Item = (usize, usize, bool)> + '_ {
    let grid = &f.grid;
    let mx = grid.mx();
    let r = c / mx;
    let i = c % mx;
    let (j, k) = grid.jk(r);
    let idx = [i, j, k];
    (0..grid.nd).flat_map(move |d| {
        let step = match d {
            0 => 1,
            1 => mx,
            _ => mx * grid.m[1],
        };
        let lo = (idx[d] > grid.g[d]).then(|| (c - step, d, false));
        let hi = (idx[d] + 1 < grid.g[d] + grid.n[d]).then(|| (c + step, d, true));
        lo.into_iter().chain(hi)
    })
}

/// Reset the momentum of gas cell c to ρ v keeping ρe; returns the momentum removed
/// (V (m_before - m_after)) and the energy added (V (½ρv² − ½|m|²/ρ)).
fn project_cell(f: &mut Fluid, c: usize, v: [f64; 3]) -> ([f64; 3], f64) {
    let mx = f.grid.mx();
    let nv = f.nv;
    let nm = f.nmat();
    let vol = f.grid.cell_volume();
    let (r, i) = (c / mx, c % mx);
    let at = |var: usize| (r * nv + var) * mx + i;
    let mut rho = 0.0;
    for k in 0..nm {
        rho += f.cons[at(k)];
    }
    let m = [f.cons[at(nm)], f.cons[at(nm + 1)], f.cons[at(nm + 2)]];
    let ke_old = 0.5 * (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]) / rho;
    let ke_new = 0.5 * rho * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    let mut removed = [0.0; 3];
    for d in 0..3 {
        let mn = rho * v[d];
        removed[d] = vol * (m[d] - mn);
        f.cons[at(nm + d)] = mn;
    }
    f.cons[at(nm + 3)] += ke_new - ke_old;
    (removed, vol * (ke_new - ke_old))
}

/// Primitive state of solid cells bordering the gas: neighbour averages of the gas cells
/// (seed 002 eq. 32), with the particle velocity.
pub fn fill_solid_prims(f: &mut Fluid, im: &Immersed) {
    let mx = f.grid.mx();
    let nv = f.nv;
    let nm = f.nmat();
    for (ci, &c) in im.cells.iter().enumerate() {
        if im.cell_kind[ci] != SOLID {
            continue;
        }
        let mut acc = [0.0; MAXF];
        let mut cnt = 0.0;
        for (nb, _, _) in neighbours(f, c) {
            if im.kind[nb] != SOLID {
                let (rn, i_n) = (nb / mx, nb % mx);
                for (v, a) in acc.iter_mut().enumerate().take(nv) {
                    *a += f.prim[(rn * nv + v) * mx + i_n];
                }
                cnt += 1.0;
            }
        }
        let (r, i) = (c / mx, c % mx);
        if cnt > 0.0 {
            for (v, a) in acc.iter().enumerate().take(nv) {
                f.prim[(r * nv + v) * mx + i] = a / cnt;
            }
        }
        for d in 0..3 {
            f.prim[(r * nv + nm + d) * mx + i] = im.cell_vel[ci][d];
        }
    }
}

/// The x ghost cells of the rows in which [`fill_solid_prims`] changed a cell that those
/// ghosts copy (wall/symmetry mirror, outflow, periodic wrap: the first and last `g[0]`
/// interior cells of a row), refilled from the row's primitives; every other row keeps the x
/// ghosts `prim_all` gave it from the same primitives, so the result equals refilling every
/// row (`boundary::fill_ghosts`) bit for bit. Touches only rows where the body reaches within
/// `g[0]` cells of an x end of the domain (none when it stays clear of the x boundaries);
/// returns how many rows it refilled.
pub fn refill_x_ghosts(f: &mut Fluid, im: &Immersed) -> usize {
    let grid = &f.grid;
    let g0 = grid.g[0];
    if g0 == 0 {
        return 0;
    }
    let mx = grid.mx();
    let nv = f.nv;
    let vel0 = f.vel0();
    // interior i (ghost-inclusive) that the x ghosts read: [g0, 2 g0) and [n0, n0 + g0)
    let near = |i: usize| i < 2 * g0 || i >= grid.n[0];
    let mut last = usize::MAX;
    let mut rows = 0;
    for (ci, &c) in im.cells.iter().enumerate() {
        let r = c / mx;
        // cells are sorted by flat index: a row's cells are consecutive
        if r == last || im.cell_kind[ci] != SOLID || !near(c % mx) {
            continue;
        }
        last = r;
        let block = &mut f.prim[r * nv * mx..(r + 1) * nv * mx];
        crate::boundary::fill_row_x(grid, block, nv, vel0, &f.bc[0]);
        rows += 1;
    }
    rows
}

/// Wall fluxes on the faces between interface and solid cells: the gas cell's state against
/// its mirror image in the wall moving with the interface velocity, into `im.wall_flux`. The
/// momentum these faces carry out of the gas, weighted by the stage's flux weight `dt_w` (RK3
/// weight · dt), goes to the particles of the solid cell — together with the projections it
/// is the whole momentum the gas loses to the body. With a conservative refill, a face whose
/// gas flows into the solid cell (the wall recedes) gives the particles only the pressure's
/// push p*; the gas it carries, with its momentum and energy less the wall's work p*·v, is
/// kept in `held` for [`Immersed::hand_back`]. The stage then uses these fluxes on those
/// faces: [`write_wall_fluxes`] (unfused) or [`WallPatch`] (fused).
pub fn wall_fluxes<const NM: usize>(f: &Fluid, ph: &[Phase; NM], im: &mut Immersed, dt_w: f64) {
    let mx = f.grid.mx();
    let nv = f.nv;
    let nf = nv + 1;
    im.wall_flux.resize(im.walls.len() * nf, 0.0);
    if im.wall_order.len() != im.walls.len() {
        im.wall_order.clear();
        im.wall_order.extend(0..im.walls.len());
        let walls = &im.walls;
        im.wall_order
            .sort_unstable_by_key(|&wi| (walls[wi].d, walls[wi].left));
    }
    for wi in 0..im.walls.len() {
        let w = im.walls[wi].clone();
        let gas = if w.gas_left { w.left } else { w.right };
        let (rg, ig) = (gas / mx, gas % mx);
        let mut q = [0.0; MAXF];
        for (v, qv) in q.iter_mut().enumerate().take(nv) {
            *qv = f.prim[(rg * nv + v) * mx + ig];
        }
        // wall velocity: the interface velocity of the gas cell (eq. 31)
        let wall = match im.cells.binary_search(&gas) {
            Ok(ci) => im.cell_vel[ci][w.d],
            Err(_) => 0.0,
        };
        let mut m = q;
        m[NM + w.d] = 2.0 * wall - q[NM + w.d];
        let fl = match (face_state::<NM>(ph, &q), face_state::<NM>(ph, &m)) {
            (Some(a), Some(b)) => {
                if w.gas_left {
                    hllc::flux::<NM>(&a, &b, w.d)
                } else {
                    hllc::flux::<NM>(&b, &a, w.d)
                }
            }
            _ => [f64::NAN; MAXF],
        };
        im.wall_flux[wi * nf..(wi + 1) * nf].copy_from_slice(&fl[..nf]);
        // momentum into the solid cell: +F if the gas is on the lower side, -F otherwise
        let sign = if w.gas_left { 1.0 } else { -1.0 };
        let solid = if w.gas_left { w.right } else { w.left };
        let mflux: f64 = fl[..NM].iter().sum();
        // with a conservative refill, gas carried into the solid cell is kept with its
        // momentum (`held`): the particles take only the pressure's push p*
        let keep = im.conservative && sign * mflux > 0.0;
        let p_star = fl[NM + w.d] - mflux * wall;
        let pushed = |d: usize| match (keep, d == w.d) {
            (false, _) => fl[NM + d],
            (true, true) => p_star,
            (true, false) => 0.0,
        };
        if let Ok(ci) = im.cells.binary_search(&solid) {
            let area = f.grid.face_area(w.d);
            let j = [
                sign * pushed(0) * area * dt_w,
                sign * pushed(1) * area * dt_w,
                sign * pushed(2) * area * dt_w,
            ];
            let (a, b) = (im.off[ci], im.off[ci + 1]);
            let share = 1.0 / (b - a) as f64;
            for k in a..b {
                let p = im.parts[k];
                for d in 0..3 {
                    im.impulse[p][d] += share * j[d];
                }
            }
            for d in 0..3 {
                im.total_impulse[d] += j[d];
            }
        }
        // mass through the moving face into the gas cell (zero for a wall at rest)
        let area = f.grid.face_area(w.d);
        im.wall_mass -= sign * mflux * area * dt_w;
        if keep {
            // what the face carries into the solid cell (a wall receding from the gas; one
            // advancing into it sends gas out, which the cell it covers next gives back),
            // kept for when the solid leaves it: the partial densities and momentum as they
            // flow (the normal momentum less the pressure's push p*, from the normal flux
            // ρ*v² + p*), the energy less the wall's work p*·v, and the gas cell's volume
            // fractions weighted by the mass carried
            let held_len = f.grid.rows() * mx * nv;
            if im.held.len() != held_len {
                im.held.resize(held_len, 0.0);
            }
            let k = sign * area * dt_w;
            let at = solid * nv;
            for v in 0..NM + 3 {
                let push = if v == NM + w.d { p_star } else { 0.0 };
                im.held[at + v] += k * (fl[v] - push);
                if v >= NM {
                    im.held_momentum[v - NM] += k * (fl[v] - push);
                }
            }
            let e = k * (fl[NM + 3] - p_star * wall);
            im.held[at + NM + 3] += e;
            im.held_energy += e;
            for v in NM + 4..nv {
                im.held[at + v] += q[v] * k * mflux;
            }
        }
    }
}

/// The stage's wall fluxes ([`wall_fluxes`]) into the face-flux arrays (the unfused stage).
pub fn write_wall_fluxes(f: &mut Fluid, im: &Immersed) {
    let mx = f.grid.mx();
    let nf = f.nf();
    for (wi, w) in im.walls.iter().enumerate() {
        let (rl, il) = (w.left / mx, w.left % mx);
        for v in 0..nf {
            f.flux[w.d][(rl * nf + v) * mx + il] = im.wall_flux[wi * nf + v];
        }
    }
}

/// The stage's wall fluxes as the fused stage applies them: line by line of faces, each line
/// held in row-local scratch.
#[derive(Clone, Copy)]
pub struct WallPatch<'a> {
    walls: &'a [WallFace],
    order: &'a [usize],
    flux: &'a [f64],
    nf: usize,
    mx: usize,
}

impl<'a> WallPatch<'a> {
    /// The wall fluxes [`wall_fluxes`] left in `im` for a grid of row length `mx` and `nf`
    /// flux entries per face.
    pub fn new(im: &'a Immersed, mx: usize, nf: usize) -> Self {
        debug_assert_eq!(im.wall_order.len(), im.walls.len());
        WallPatch {
            walls: &im.walls,
            order: &im.wall_order,
            flux: &im.wall_flux,
            nf,
            mx,
        }
    }

    /// Overwrite the faces of line `line` normal to `d` (`out`: nf blocks of `mx`, indexed
    /// by the cell below the face) that are walls with their wall fluxes.
    #[inline]
    pub fn apply(&self, d: usize, line: usize, out: &mut [f64]) {
        self.apply_strided(d, line, out, self.mx, 0, self.mx);
    }

    /// [`apply`](Self::apply) for a line held in any layout: the face of cell i
    /// (`first <= i < first + width`) at `out[v * stride + i - first]`; walls outside that
    /// range are left out.
    #[inline]
    pub fn apply_strided(
        &self,
        d: usize,
        line: usize,
        out: &mut [f64],
        stride: usize,
        first: usize,
        width: usize,
    ) {
        let (mx, nf) = (self.mx, self.nf);
        let key = |wi: usize| (self.walls[wi].d, self.walls[wi].left / mx);
        let lo = self.order.partition_point(|&wi| key(wi) < (d, line));
        for &wi in &self.order[lo..] {
            if key(wi) != (d, line) {
                break;
            }
            let i = self.walls[wi].left % mx;
            if i < first || i >= first + width {
                continue;
            }
            for v in 0..nf {
                out[v * stride + i - first] = self.flux[wi * nf + v];
            }
        }
    }
}

/// After an RK stage: solid cells keep their frozen state; interface cells are projected to
/// the particle velocity and the removed momentum, weighted by `w` (eq. 35), goes to their
/// particles in equal shares (eq. 34).
pub fn project(f: &mut Fluid, im: &mut Immersed, w: f64) {
    let mx = f.grid.mx();
    let nv = f.nv;
    for ci in 0..im.cells.len() {
        let c = im.cells[ci];
        if im.cell_kind[ci] == SOLID {
            let (r, i) = (c / mx, c % mx);
            for v in 0..nv {
                let a = (r * nv + v) * mx + i;
                f.cons[a] = f.cons0[a];
            }
            continue;
        }
        let (removed, _) = project_cell(f, c, im.cell_vel[ci]);
        let ps = &im.parts[im.off[ci]..im.off[ci + 1]];
        let share = w / ps.len() as f64;
        for &p in ps {
            for d in 0..3 {
                im.impulse[p][d] += share * removed[d];
            }
        }
        for d in 0..3 {
            im.total_impulse[d] += w * removed[d];
        }
    }
}
