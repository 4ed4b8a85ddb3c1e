//! The particle body and its time loop: velocity Verlet (kick–drift–force–kick; the drift
//! advances the displacements u and sets x = X + u), prescribed
//! motion, external forces, and the CFL-type stable step (seed 001 §4.2: Δt ≤ l/c; Silling
//! & Askari 2005 for bond-based models).
// Index loops over the 3 or 6 components of small tensors read closer to the formulas;
// `!(x > 0.0)` is deliberate: it also rejects NaN.
#![allow(
    clippy::needless_range_loop,
    clippy::neg_cmp_op_on_partial_ord,
    clippy::too_many_arguments
)]

use super::family::{Bonds, par_points};
use super::model::{Dim, Kinematics, PdModel};

/// A peridynamic body: state in flat arrays, the model behind its trait.
pub struct Body {
    pub dim: Dim,
    pub spacing: f64,
    pub horizon: f64,
    pub density: f64,
    pub x0: Vec<[f64; 3]>,
    /// Current positions x = X + u (kept for output and the interface).
    pub pos: Vec<[f64; 3]>,
    /// Displacements u (u += v dt): the models form bond deformations from them.
    pub disp: Vec<[f64; 3]>,
    pub vel: Vec<[f64; 3]>,
    pub vol: Vec<f64>,
    /// Internal force density from the last evaluation (N/m³).
    pub force: Vec<[f64; 3]>,
    /// External force per particle (N), e.g. coupling loads or pressure.
    pub fext: Vec<[f64; 3]>,
    /// 1 where the velocity is prescribed (`vpres`), 0 where free; 2 where it is prescribed
    /// and the particle's mass belongs to another model (an overlap coupling's boundary
    /// layer): left out of the momentum and kinetic energy; 3 where only the components
    /// `held` marks are prescribed.
    pub prescribed: Vec<u8>,
    pub vpres: Vec<[f64; 3]>,
    /// Where `prescribed` is 3, the components held (bit d for component d).
    pub held: Vec<u8>,
    pub bonds: Bonds,
    pub model: Box<dyn PdModel>,
    pub time: f64,
    pub steps: u64,
    /// Rigid frictionless walls the free particles cannot cross (see [`Wall`]).
    pub walls: Vec<Wall>,
    /// What the walls did in the last step (zero without walls).
    pub wall_step: WallStep,
    /// Per particle, the velocity the walls gave it in the last step (scratch: empty
    /// without walls, so the sums run in particle order whatever the threads).
    wall_dv: Vec<[f64; 3]>,
}

/// A rigid, frictionless, fixed wall: the plane through `point` with unit normal `normal`,
/// which points to the side the body is on. A particle is a cube of side Δx about its
/// centre, so it touches the wall when its centre comes within Δx/2 of the plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wall {
    pub point: [f64; 3],
    pub normal: [f64; 3],
}

/// The walls' action over one step: the impulse they gave the body (N s), its magnitude
/// summed over the particles, and the work they did on it (J; the kinetic energy of the
/// normal motion they stop, negative).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WallStep {
    pub impulse: [f64; 3],
    pub impulse_magnitude: f64,
    pub work: f64,
}

impl Body {
    /// A body at rest in its reference configuration; evaluates the initial forces.
    pub fn new(
        dim: Dim,
        spacing: f64,
        horizon: f64,
        density: f64,
        x0: Vec<[f64; 3]>,
        vol: Vec<f64>,
        bonds: Bonds,
        model: Box<dyn PdModel>,
    ) -> Self {
        let n = x0.len();
        let mut b = Body {
            dim,
            spacing,
            horizon,
            density,
            pos: x0.clone(),
            disp: vec![[0.0; 3]; n],
            x0,
            vel: vec![[0.0; 3]; n],
            vol,
            force: vec![[0.0; 3]; n],
            fext: vec![[0.0; 3]; n],
            prescribed: vec![0; n],
            held: vec![0; n],
            vpres: vec![[0.0; 3]; n],
            bonds,
            model,
            time: 0.0,
            steps: 0,
            walls: Vec::new(),
            wall_step: WallStep::default(),
            wall_dv: Vec::new(),
        };
        b.eval_forces(0.0);
        b
    }

    pub fn len(&self) -> usize {
        self.x0.len()
    }

    pub fn is_empty(&self) -> bool {
        self.x0.is_empty()
    }

    pub fn kinematics(&self) -> Kinematics<'_> {
        Kinematics {
            x0: &self.x0,
            pos: &self.pos,
            disp: &self.disp,
            vel: &self.vel,
            vol: &self.vol,
        }
    }

    /// Evaluates the internal force density for the current positions/velocities.
    pub fn eval_forces(&mut self, dt: f64) {
        let k = Kinematics {
            x0: &self.x0,
            pos: &self.pos,
            disp: &self.disp,
            vel: &self.vel,
            vol: &self.vol,
        };
        self.model
            .force_density(&k, &mut self.bonds, dt, &mut self.force);
    }

    /// Stable step of the model (no safety factor).
    pub fn stable_dt(&self) -> f64 {
        self.model
            .stable_dt(&self.kinematics(), &self.bonds, self.density)
    }

    /// Half kick v += dt/2 a for free particles; prescribed particles take `vpres`.
    fn kick(&mut self, half_dt: f64) {
        let rho = self.density;
        let (f, fe, vol, pr, vp, held) = (
            &self.force,
            &self.fext,
            &self.vol,
            &self.prescribed,
            &self.vpres,
            &self.held,
        );
        par_points(&mut self.vel, &|i, v: &mut [f64; 3]| {
            let mask = match pr[i] {
                0 => 0,
                3 => held[i],
                _ => {
                    *v = vp[i];
                    return;
                }
            };
            let inv_m = 1.0 / (rho * vol[i]);
            for d in 0..3 {
                if mask & (1 << d) != 0 {
                    v[d] = vp[i][d];
                } else {
                    v[d] += half_dt * (f[i][d] / rho + fe[i][d] * inv_m);
                }
            }
        });
    }

    /// The walls between the half kick and the drift: a free particle whose drift would take
    /// it closer than Δx/2 to a wall gets the normal velocity that lands it there, −g/dt for
    /// a gap g, and keeps its tangential velocity (no friction). The walls act only through
    /// that change of velocity, so the body's momentum changes by exactly their impulse; a
    /// particle moving away is left alone, so the body leaves a wall freely.
    fn hold_off_walls(&mut self, dt: f64) {
        use rayon::prelude::*;
        let n = self.len();
        if self.wall_dv.len() != n {
            self.wall_dv = vec![[0.0; 3]; n];
        }
        let (pos, pr, walls, half) = (&self.pos, &self.prescribed, &self.walls, 0.5 * self.spacing);
        self.vel
            .par_iter_mut()
            .zip(self.wall_dv.par_iter_mut())
            .with_min_len(super::family::GRAIN)
            .enumerate()
            .for_each(|(i, (v, dv))| {
                *dv = [0.0; 3];
                if pr[i] != 0 {
                    return;
                }
                for w in walls {
                    let nrm = w.normal;
                    let gap = (0..3)
                        .map(|d| (pos[i][d] - w.point[d]) * nrm[d])
                        .sum::<f64>()
                        - half;
                    let vn = (0..3).map(|d| v[d] * nrm[d]).sum::<f64>();
                    if gap + dt * vn < 0.0 {
                        let dvn = -gap / dt - vn;
                        for d in 0..3 {
                            v[d] += dvn * nrm[d];
                            dv[d] += dvn * nrm[d];
                        }
                    }
                }
            });
        // The work that keeps the step's energy books: velocity Verlet's kinetic energy at the
        // step ends and the internal forces' trapezoidal work along dt·v' leave
        // ½m(|v'|² − |v|²) − m (dt/2) Δv·a for the wall, a the acceleration of the half kick
        // before it: m Δv·(v' + v − dt a)/2. A particle arriving at speed v loses ½m v_n²; one
        // resting on the wall, pushed into it by its neighbours, takes no work.
        let mut step = WallStep::default();
        for (i, dv) in self.wall_dv.iter().enumerate() {
            if *dv == [0.0; 3] {
                continue;
            }
            let m = self.density * self.vol[i];
            let (v, f, fe) = (self.vel[i], self.force[i], self.fext[i]);
            for d in 0..3 {
                let a = f[d] / self.density + fe[d] / m;
                step.impulse[d] += m * dv[d];
                step.work += 0.5 * m * dv[d] * (2.0 * v[d] - dv[d] - dt * a);
            }
            step.impulse_magnitude += m * (dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]).sqrt();
        }
        self.wall_step = step;
    }

    /// One velocity-Verlet step of size dt.
    pub fn step(&mut self, dt: f64) {
        self.kick(0.5 * dt);
        if !self.walls.is_empty() {
            self.hold_off_walls(dt);
        }
        {
            use rayon::prelude::*;
            let (vel, x0) = (&self.vel, &self.x0);
            self.disp
                .par_iter_mut()
                .zip(self.pos.par_iter_mut())
                .with_min_len(super::family::GRAIN)
                .enumerate()
                .for_each(|(i, (u, x))| {
                    for d in 0..3 {
                        u[d] += dt * vel[i][d];
                        x[d] = x0[i][d] + u[d];
                    }
                });
        }
        self.eval_forces(dt);
        self.kick(0.5 * dt);
        self.time += dt;
        self.steps += 1;
    }

    /// x = X + u at every particle (after the displacements changed).
    pub fn sync_positions(&mut self) {
        let (x0, u) = (&self.x0, &self.disp);
        par_points(&mut self.pos, &|i, x: &mut [f64; 3]| {
            for d in 0..3 {
                x[d] = x0[i][d] + u[i][d];
            }
        });
    }

    /// The components of particle `i`'s velocity that are prescribed (bit d for component d).
    pub fn held_components(&self, i: usize) -> u8 {
        match self.prescribed[i] {
            0 => 0,
            3 => self.held[i],
            _ => 0b111,
        }
    }

    /// Sets particle `i`'s displacement (and its position x = X + u).
    pub fn set_disp(&mut self, i: usize, u: [f64; 3]) {
        self.disp[i] = u;
        self.pos[i] = std::array::from_fn(|d| self.x0[i][d] + u[d]);
    }

    /// Total linear momentum Σ ρ V v (fixed order).
    pub fn momentum(&self) -> [f64; 3] {
        let mut p = [0.0; 3];
        for i in (0..self.len()).filter(|&i| self.prescribed[i] != 2) {
            let m = self.density * self.vol[i];
            for d in 0..3 {
                p[d] += m * self.vel[i][d];
            }
        }
        p
    }

    /// Gross momentum Σ m|v|: the scale of momentum sums that cancel.
    pub fn momentum_gross(&self) -> f64 {
        (0..self.len())
            .filter(|&i| self.prescribed[i] != 2)
            .map(|i| {
                let v = self.vel[i];
                self.density * self.vol[i] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
            })
            .sum()
    }

    pub fn kinetic_energy(&self) -> f64 {
        (0..self.len())
            .filter(|&i| self.prescribed[i] != 2)
            .map(|i| {
                let v = self.vel[i];
                0.5 * self.density * self.vol[i] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
            })
            .sum()
    }

    /// Damage index per particle (1 − intact volume fraction of the family).
    pub fn damage(&mut self) -> Vec<f64> {
        self.model.sync_bonds(&mut self.bonds);
        let mut d = vec![0.0; self.len()];
        self.bonds.damage(&self.vol, &mut d);
        d
    }
}
