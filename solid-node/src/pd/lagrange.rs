//! The particle body as one side of a `lagrange` coupling (seed 003 §4, §5.4): an explicit
//! central-difference subdomain (velocity Verlet with the forces at the step end, GS4-II's
//! explicit U0(1,1,0)) with its lumped mass, tied to the others on interface particles.
//!
//! One coupling step is one particle step. The step-end displacement does not depend on the
//! step-end multipliers and the step-end acceleration, a = M⁻¹(f(u) + f_ext + Bᵀλ), is affine
//! in them; so the condensed operator is Bᵢ Hᵢ = Δt/2 M⁻¹ on the interface (from the mass and
//! the step alone, no stiffness), the free step is one ordinary step with the known part of λ,
//! and the correction a += M⁻¹Bᵀx, v += Δt/2 M⁻¹Bᵀx is exact whatever the force law (the
//! nonlinear PD force included). gs4 and ph then need this side at one step per system step
//! (more would need the body's tangent stiffness over the substeps); gc takes any ratio.

use super::integrate::Body;
use mechanics::time::LoadRamp;
use protocol::checkpoint::{check_len, decode_state, encode_state};
use protocol::solver::{SolverError, SolverResult};
use std::borrow::Cow;

/// The coupling state of an explicit particle side; the body is stepped through it.
#[derive(Debug, Clone)]
pub struct ExplicitSide {
    /// Interface unknowns: (particle, component), in the order of the interface's points,
    /// then per point its components.
    dofs: Vec<(usize, usize)>,
    /// Multiplier index of each unknown and its sign in B (in process; ±1, +1 on the wire).
    ids: Vec<usize>,
    sign: f64,
    dt: f64,
    /// Coupling steps per system step: 1 (gs4, ph) or the ratio m (gc).
    steps: usize,
    /// gc: the whole multiplier is unknown in a step; gs4/ph: its increment over λ_n.
    gc: bool,
    operator: Vec<f64>,
    /// Acceleration of every particle at the current step end (internal, loads, multipliers).
    acc: Vec<[f64; 3]>,
    /// Load: particle and its force at full load (N), times `history`.
    load: Vec<(usize, [f64; 3])>,
    history: LoadRamp,
    lambda_start: Vec<f64>,
    lambda_end: Vec<f64>,
    u_start: Vec<f64>,
    /// Σ load·u at the start of the step (for the load's work).
    load_u: f64,
    /// Work done on the body by the interface forces since t = 0 (J; trapezoidal).
    pub interface_work: f64,
    /// Impulse of the interface forces per axis since t = 0 (N s).
    pub interface_impulse: [f64; 3],
    /// Work of the loads since t = 0 (J) and ∫ g dt of their history (s).
    pub external_work: f64,
    pub load_integral: f64,
    /// Time at the end of the last corrected step (s).
    pub time: f64,
}

impl ExplicitSide {
    /// The side for interface particles `points` (each with `comps` components tied, local
    /// multipliers `first_lambda` + comps·k + c, sign `sign`), particle step `dt`, `steps`
    /// coupling steps per system step (1 unless `gc`), loads of one history. The body must
    /// be at rest and unstressed; its initial acceleration holds the loads at t = 0.
    pub fn new(
        body: &Body,
        points: &[usize],
        comps: usize,
        (first_lambda, sign): (usize, f64),
        (dt, steps, gc): (f64, usize, bool),
        load: Vec<(usize, [f64; 3])>,
        history: LoadRamp,
    ) -> Self {
        let mut dofs = Vec::with_capacity(points.len() * comps);
        for &p in points {
            for c in 0..comps {
                dofs.push((p, c));
            }
        }
        let nl = dofs.len();
        let ids = (0..nl).map(|k| first_lambda + k).collect();
        let mut operator = vec![0.0; nl * nl];
        for (r, &(p, _)) in dofs.iter().enumerate() {
            operator[r * nl + r] = 0.5 * dt / mass(body, p);
        }
        let mut s = ExplicitSide {
            dofs,
            ids,
            sign,
            dt,
            steps,
            gc,
            operator,
            acc: vec![[0.0; 3]; body.len()],
            load,
            history,
            lambda_start: vec![0.0; nl],
            lambda_end: vec![0.0; nl],
            u_start: vec![0.0; nl],
            load_u: 0.0,
            interface_work: 0.0,
            interface_impulse: [0.0; 3],
            external_work: 0.0,
            load_integral: 0.0,
            time: 0.0,
        };
        s.accelerate(body, 0.0);
        s
    }

    pub fn multiplier_ids(&self) -> &[usize] {
        &self.ids
    }
    pub fn coupling_steps(&self) -> usize {
        self.steps
    }
    pub fn operator(&self) -> &[f64] {
        &self.operator
    }
    pub fn dt(&self) -> f64 {
        self.dt
    }
    /// Total load at full history (N per axis).
    pub fn load_total(&self) -> [f64; 3] {
        let mut t = [0.0; 3];
        for (_, f) in &self.load {
            for d in 0..3 {
                t[d] += f[d];
            }
        }
        t
    }

    /// a = f/ρ + (g(t) load + Bᵀ λ_start)/m from the body's current force density.
    fn accelerate(&mut self, body: &Body, t: f64) {
        let rho = body.density;
        for (a, f) in self.acc.iter_mut().zip(&body.force) {
            *a = [f[0] / rho, f[1] / rho, f[2] / rho];
        }
        let g = self.history.at(t);
        for &(p, f) in &self.load {
            let m = mass(body, p);
            for d in 0..3 {
                self.acc[p][d] += g * f[d] / m;
            }
        }
        for (&(p, c), l) in self.dofs.iter().zip(&self.lambda_start) {
            self.acc[p][c] += self.sign * l / mass(body, p);
        }
    }

    /// At t = 0: the free interface acceleration and Bᵢ M⁻¹ Bᵢᵀ.
    pub fn initial(&mut self, body: &Body, free: &mut [f64], op: &mut [f64]) {
        self.lambda_start.fill(0.0);
        self.accelerate(body, 0.0);
        let nl = self.dofs.len();
        op.fill(0.0);
        for (r, &(p, c)) in self.dofs.iter().enumerate() {
            free[r] = self.sign * self.acc[p][c];
            op[r * nl + r] = 1.0 / mass(body, p);
        }
        self.load_u = self.load_dot(body);
    }

    /// The initial multipliers: a += M⁻¹ Bᵀ λ₀.
    pub fn set_initial(&mut self, body: &Body, lambda0: &[f64]) {
        for (&(p, c), l) in self.dofs.iter().zip(lambda0) {
            self.acc[p][c] += self.sign * l / mass(body, p);
        }
        self.lambda_start.copy_from_slice(lambda0);
        self.lambda_end.copy_from_slice(lambda0);
    }

    fn load_dot(&self, body: &Body) -> f64 {
        self.load
            .iter()
            .map(|&(p, f)| (0..3).map(|d| f[d] * body.disp[p][d]).sum::<f64>())
            .sum()
    }

    /// One free particle step with the known part of λ: v += Δt/2 a, u += Δt v, forces,
    /// a from them, v += Δt/2 a. Writes the signed interface velocity at its start and end.
    pub fn free_step(&mut self, body: &mut Body, v_start: &mut [f64], v_free: &mut [f64]) {
        let dt = self.dt;
        for (r, &(p, c)) in self.dofs.iter().enumerate() {
            v_start[r] = self.sign * body.vel[p][c];
            self.u_start[r] = self.sign * body.disp[p][c];
        }
        if self.gc {
            self.lambda_start.fill(0.0);
        } else {
            self.lambda_start.copy_from_slice(&self.lambda_end);
        }
        for (v, a) in body.vel.iter_mut().zip(&self.acc) {
            for d in 0..3 {
                v[d] += 0.5 * dt * a[d];
            }
        }
        for i in 0..body.len() {
            for d in 0..3 {
                body.disp[i][d] += dt * body.vel[i][d];
                body.pos[i][d] = body.x0[i][d] + body.disp[i][d];
            }
        }
        body.eval_forces(dt);
        self.accelerate(body, self.time + dt);
        for (v, a) in body.vel.iter_mut().zip(&self.acc) {
            for d in 0..3 {
                v[d] += 0.5 * dt * a[d];
            }
        }
        body.time = self.time + dt;
        body.steps += 1;
        for (r, &(p, c)) in self.dofs.iter().enumerate() {
            v_free[r] = self.sign * body.vel[p][c];
        }
    }

    /// Corrects the free step with the step-end multipliers `lambda` (a += M⁻¹Bᵀx,
    /// v += Δt/2 M⁻¹Bᵀx, x = λ − λ_start) and adds the step's interface and load work and
    /// impulses (trapezoidal: exactly what central differences give the momentum).
    pub fn correct(&mut self, body: &mut Body, lambda: &[f64]) {
        let dt = self.dt;
        for (r, &(p, c)) in self.dofs.iter().enumerate() {
            let x = self.sign * (lambda[r] - self.lambda_start[r]) / mass(body, p);
            self.acc[p][c] += x;
            body.vel[p][c] += 0.5 * dt * x;
            let (l0, l1) = (self.lambda_end[r], lambda[r]);
            let du = self.sign * body.disp[p][c] - self.u_start[r];
            self.interface_work += du * 0.5 * (l0 + l1);
            self.interface_impulse[c] += self.sign * 0.5 * (l0 + l1) * dt;
        }
        let (ga, gb) = (self.history.at(self.time), self.history.at(self.time + dt));
        let lu = self.load_dot(body);
        self.external_work += 0.5 * (ga + gb) * (lu - self.load_u);
        self.load_u = lu;
        self.load_integral += 0.5 * dt * (ga + gb);
        self.lambda_end.copy_from_slice(lambda);
        self.time += dt;
    }
}

/// What a checkpoint holds of a lagrange side (`ExplicitSide::save_state`): its size, step
/// and method first, so that a state of another side is refused, then the step-end
/// accelerations, the multipliers, the step-start interface displacements, the load's Σ f·u,
/// the audit sums and the clock.
#[derive(serde::Serialize, serde::Deserialize)]
struct SideState<'a> {
    particles: usize,
    unknowns: usize,
    steps: usize,
    gc: bool,
    dt: f64,
    acc: Cow<'a, [[f64; 3]]>,
    lambda_start: Cow<'a, [f64]>,
    lambda_end: Cow<'a, [f64]>,
    u_start: Cow<'a, [f64]>,
    load_u: f64,
    interface_work: f64,
    interface_impulse: [f64; 3],
    external_work: f64,
    load_integral: f64,
    time: f64,
}

impl ExplicitSide {
    /// What the side carries from one system step to the next, for a checkpoint beside the
    /// body's (`PdSolver::save_state`).
    pub fn save_state(&self) -> SolverResult<Vec<u8>> {
        encode_state(&SideState {
            particles: self.acc.len(),
            unknowns: self.dofs.len(),
            steps: self.steps,
            gc: self.gc,
            dt: self.dt,
            acc: Cow::Borrowed(&self.acc),
            lambda_start: Cow::Borrowed(&self.lambda_start),
            lambda_end: Cow::Borrowed(&self.lambda_end),
            u_start: Cow::Borrowed(&self.u_start),
            load_u: self.load_u,
            interface_work: self.interface_work,
            interface_impulse: self.interface_impulse,
            external_work: self.external_work,
            load_integral: self.load_integral,
            time: self.time,
        })
    }

    /// The inverse of [`Self::save_state`], on the side set up again for the same body,
    /// interface, step and method; nothing changes unless the whole state reads.
    pub fn load_state(&mut self, bytes: &[u8]) -> SolverResult<()> {
        let s: SideState = decode_state(bytes)?;
        let bad = |m: String| Err(SolverError::Other(format!("load_state: {m}")));
        if s.particles != self.acc.len() || s.unknowns != self.dofs.len() {
            return bad(format!(
                "coupling state of {} particles / {} interface unknowns, this side has {} / {}",
                s.particles,
                s.unknowns,
                self.acc.len(),
                self.dofs.len()
            ));
        }
        if s.steps != self.steps || s.gc != self.gc || s.dt.to_bits() != self.dt.to_bits() {
            return bad(format!(
                "coupling state of {} steps of {:e} s (gc: {}) per system step, this side \
                 takes {} of {:e} s (gc: {})",
                s.steps, s.dt, s.gc, self.steps, self.dt, self.gc
            ));
        }
        check_len("accelerations", s.acc.len(), self.acc.len())?;
        let nl = self.dofs.len();
        check_len("step-start multipliers", s.lambda_start.len(), nl)?;
        check_len("step-end multipliers", s.lambda_end.len(), nl)?;
        check_len("step-start displacements", s.u_start.len(), nl)?;
        self.acc = s.acc.into_owned();
        self.lambda_start = s.lambda_start.into_owned();
        self.lambda_end = s.lambda_end.into_owned();
        self.u_start = s.u_start.into_owned();
        self.load_u = s.load_u;
        self.interface_work = s.interface_work;
        self.interface_impulse = s.interface_impulse;
        self.external_work = s.external_work;
        self.load_integral = s.load_integral;
        self.time = s.time;
        Ok(())
    }
}

fn mass(body: &Body, p: usize) -> f64 {
    body.density * body.vol[p]
}

#[cfg(test)]
mod tests {
    use crate::pd::solver::PdSolver;
    use protocol::scheme::lagrange::{InterfaceSolver, LagrangeSide, Method};
    use protocol::solver::Solver;

    /// A plane-stress pd-correspondence block x in [x0, x1] (lattice columns at x0 … x1,
    /// spacing 0.1, 5 rows), interface "cut" = the column at `cut`; with a load on the column
    /// at x = 1 when `loaded`.
    fn block(x0: f64, x1: f64, cut: f64, loaded: bool) -> PdSolver {
        let h = 0.05;
        let load = if loaded {
            "loads = [{ region = { shape = \"box\", min = [0.95, -1.0, 0.0], max = [1.05, 1.0, 0.0] }, force = [4.0e7, -2.0e7, 0.0] }]"
        } else {
            ""
        };
        let text = format!(
            "dimension = \"plane_stress\"\nspacing = 0.1\nhorizon = 0.3015\ndensity = 2700.0\n\
             young = 70e9\npoisson = 0.3\n\
             bodies = [{{ shape = \"box\", min = [{}, {}, 0.0], max = [{}, {}, 0.0] }}]\n\
             interfaces = [{{ name = \"cut\", select = \"all\", region = {{ shape = \"box\", min = [{}, -1.0, 0.0], max = [{}, 1.0, 0.0] }} }}]\n{load}\n",
            x0 - h,
            -h,
            x1 + h,
            0.4 + h,
            cut - 0.01,
            cut + 0.01,
        );
        let table: toml::Table = match toml::from_str(&text) {
            Ok(t) => t,
            Err(e) => panic!("test table: {e}"),
        };
        match PdSolver::from_table("pd-correspondence", &table) {
            Ok(s) => s,
            Err(e) => panic!("test block: {e}"),
        }
    }

    /// The glued monolithic run of the two blocks: central differences over both bodies
    /// where each tied pair of particles moves as one particle of their summed mass under
    /// their summed force (what exact velocity continuity means for lumped masses).
    fn glued(a: &mut PdSolver, b: &mut PdSolver, dt: f64, steps: usize) {
        let pairs: Vec<(usize, usize)> = a
            .interface_points("cut")
            .into_iter()
            .zip(b.interface_points("cut"))
            .collect();
        let acc = |a: &PdSolver, b: &PdSolver| {
            let mut out = [Vec::new(), Vec::new()];
            for (k, s) in [a, b].into_iter().enumerate() {
                let body = &s.body;
                out[k] = (0..body.len())
                    .map(|i| {
                        let m = body.density * body.vol[i];
                        std::array::from_fn(|d| {
                            body.force[i][d] / body.density + s.load_on(i)[d] / m
                        })
                    })
                    .collect::<Vec<[f64; 3]>>();
            }
            for &(i, j) in &pairs {
                let (ma, mb) = (
                    a.body.density * a.body.vol[i],
                    b.body.density * b.body.vol[j],
                );
                let f: [f64; 3] = std::array::from_fn(|d| out[0][i][d] * ma + out[1][j][d] * mb);
                for d in 0..3 {
                    out[0][i][d] = f[d] / (ma + mb);
                    out[1][j][d] = f[d] / (ma + mb);
                }
            }
            out
        };
        let mut acc_now = acc(a, b);
        for _ in 0..steps {
            for (s, ac) in [&mut *a, &mut *b].into_iter().zip(&acc_now) {
                let body = &mut s.body;
                for i in 0..body.len() {
                    for d in 0..3 {
                        body.vel[i][d] += 0.5 * dt * ac[i][d];
                        body.disp[i][d] += dt * body.vel[i][d];
                        body.pos[i][d] = body.x0[i][d] + body.disp[i][d];
                    }
                }
                body.eval_forces(dt);
            }
            acc_now = acc(a, b);
            for (s, ac) in [&mut *a, &mut *b].into_iter().zip(&acc_now) {
                let body = &mut s.body;
                for i in 0..body.len() {
                    for d in 0..3 {
                        body.vel[i][d] += 0.5 * dt * ac[i][d];
                    }
                }
            }
        }
    }

    /// Largest |u − u_ref| over both bodies, relative to the largest |u_ref|.
    fn difference(a: &[&PdSolver; 2], r: &[&PdSolver; 2]) -> f64 {
        let (mut e, mut scale) = (0.0f64, 0.0f64);
        for (s, t) in a.iter().zip(r) {
            for (u, v) in s.body.disp.iter().zip(&t.body.disp) {
                for d in 0..3 {
                    e = e.max((u[d] - v[d]).abs());
                    scale = scale.max(v[d].abs());
                }
            }
        }
        e / scale
    }

    #[test]
    fn one_step_per_system_step_reproduces_the_glued_bodies_to_round_off() {
        // Two blocks sharing the column x = 0.5, pulled at x = 1 hard enough (strains of
        // order 1e-3 … 1e-2) that the correspondence force is visibly nonlinear: the
        // coupling at m = 1 is exact whatever the force law, for gs4 and gc alike.
        for method in [Method::Gs4, Method::Gc] {
            let (mut l, mut r) = (block(0.0, 0.5, 0.5, false), block(0.5, 1.0, 0.5, true));
            let dt = 0.5 * l.dt().min(r.dt());
            let steps = 400;
            let tied = l.interface_points("cut").len();
            assert_eq!(tied, 5, "tied particle pairs");
            if let Err(e) = l.lagrange_side_for("cut", method, dt, (0, 1.0)) {
                panic!("{e}");
            }
            if let Err(e) = r.lagrange_side_for("cut", method, dt, (0, -1.0)) {
                panic!("{e}");
            }
            let mut scheme = {
                let mut sides: [&mut dyn LagrangeSide; 2] = [&mut l, &mut r];
                match InterfaceSolver::new(method, 2 * tied, &mut sides) {
                    Ok(s) => s,
                    Err(e) => panic!("{e}"),
                }
            };
            for _ in 0..steps {
                let mut sides: [&mut dyn LagrangeSide; 2] = [&mut l, &mut r];
                if let Err(e) = scheme.step(&mut sides) {
                    panic!("{e}");
                }
            }
            let (mut gl, mut gr) = (block(0.0, 0.5, 0.5, false), block(0.5, 1.0, 0.5, true));
            glued(&mut gl, &mut gr, dt, steps);
            let e = difference(&[&l, &r], &[&gl, &gr]);
            let strain = gr.body.disp.iter().map(|u| u[0].abs()).fold(0.0, f64::max);
            println!(
                "{method:?}: m = 1 against the glued bodies after {steps} steps: {e:.3e} (largest |ux| {strain:.3e} m)"
            );
            assert!(strain > 1e-4, "the load deforms the blocks: {strain:e}");
            assert!(e < 1e-11, "{method:?}: {e:e}");
            // The interface forces do no net work on the glued pair and give no net
            // impulse: both sides' sums cancel.
            let w = l.interface_work() + r.interface_work();
            let wl = l.interface_work().abs();
            println!("{method:?}: net interface work {w:.3e} J of {wl:.3e} J per side");
            assert!(w.abs() <= 1e-9 * wl, "{method:?}: ΔE_Γ {w:e}");
        }
    }

    /// Sets both blocks up as sides of `method` at system step `window` and builds the
    /// interface problem.
    fn coupled(method: Method, window: f64) -> (PdSolver, PdSolver, InterfaceSolver) {
        let (mut l, mut r) = (block(0.0, 0.5, 0.5, false), block(0.5, 1.0, 0.5, true));
        for (s, sign) in [(&mut l, 1.0), (&mut r, -1.0)] {
            if let Err(e) = s.lagrange_side_for("cut", method, window, (0, sign)) {
                panic!("{e}");
            }
        }
        let nl = LagrangeSide::multiplier_ids(&l).len();
        let scheme = {
            let mut sides: [&mut dyn LagrangeSide; 2] = [&mut l, &mut r];
            match InterfaceSolver::new(method, nl, &mut sides) {
                Ok(s) => s,
                Err(e) => panic!("{e}"),
            }
        };
        (l, r, scheme)
    }

    fn run(sc: &mut InterfaceSolver, l: &mut PdSolver, r: &mut PdSolver, steps: usize) {
        for _ in 0..steps {
            let mut sides: [&mut dyn LagrangeSide; 2] = [&mut *l, &mut *r];
            if let Err(e) = sc.step(&mut sides) {
                panic!("{e}");
            }
        }
    }

    /// Everything that must continue bit for bit: λ, both bodies' motion and forces, clocks,
    /// the sides' audit sums.
    fn bits(sc: &InterfaceSolver, l: &PdSolver, r: &PdSolver) -> Vec<u64> {
        let mut v: Vec<u64> = sc.lambda().iter().map(|x| x.to_bits()).collect();
        for s in [l, r] {
            let b = &s.body;
            for a in b.disp.iter().chain(&b.vel).chain(&b.force) {
                v.extend(a.iter().map(|x| x.to_bits()));
            }
            v.push(b.time.to_bits());
            v.push(b.steps);
            let (_, side) = s.lagrange.as_ref().expect("a lagrange side");
            for x in [
                side.interface_work,
                side.external_work,
                side.load_integral,
                side.time,
            ]
            .iter()
            .chain(&side.interface_impulse)
            {
                v.push(x.to_bits());
            }
        }
        v
    }

    #[test]
    fn a_restored_particle_side_continues_bit_identically() {
        // gs4 at one particle step per system step; gc at three (its clock, loads and
        // multipliers then cross system steps in substeps).
        let (total, at) = (300, 120);
        for (method, ratio) in [(Method::Gs4, 0.5), (Method::Gc, 3.0)] {
            let window = ratio * block(0.0, 0.5, 0.5, false).dt();
            let (mut l, mut r, mut sc) = coupled(method, window);
            assert_eq!(l.coupling_steps(), if method == Method::Gc { 3 } else { 1 });
            run(&mut sc, &mut l, &mut r, total);
            let uninterrupted = bits(&sc, &l, &r);

            let (mut l, mut r, mut sc) = coupled(method, window);
            run(&mut sc, &mut l, &mut r, at);
            let take = |s: &PdSolver| -> (Vec<u8>, Vec<u8>) {
                match (Solver::save_state(s), LagrangeSide::save_state(s)) {
                    (Ok(own), Ok(side)) => (own, side),
                    (Err(e), _) => panic!("{e}"),
                    (_, Err(e)) => panic!("{e}"),
                }
            };
            let saved = [take(&l), take(&r)];
            let lambda = (
                sc.lambda().to_vec(),
                vec![sc.side_lambda(0).to_vec(), sc.side_lambda(1).to_vec()],
            );
            assert!(
                l.body.disp.iter().any(|u| u[0] != 0.0),
                "{method:?}: at rest"
            );
            assert!(lambda.0.iter().any(|&x| x != 0.0), "{method:?}: no λ yet");

            let (mut l, mut r, mut sc) = coupled(method, window);
            for (s, (own, side)) in [&mut l, &mut r].into_iter().zip(&saved) {
                if let Err(e) = Solver::load_state(s, own) {
                    panic!("{e}");
                }
                if let Err(e) = LagrangeSide::load_state(s, side) {
                    panic!("{e}");
                }
            }
            if let Err(e) = sc.restore(&lambda.0, &lambda.1) {
                panic!("{e}");
            }
            run(&mut sc, &mut l, &mut r, total - at);
            let restored = bits(&sc, &l, &r);
            assert_eq!(uninterrupted.len(), restored.len());
            let differ = uninterrupted
                .iter()
                .zip(&restored)
                .filter(|(a, b)| a != b)
                .count();
            println!(
                "{method:?}: {differ} of {} values differ after the restart",
                restored.len()
            );
            assert_eq!(differ, 0, "{method:?}");
        }
    }

    #[test]
    fn a_coupling_state_of_another_side_is_refused() {
        let window = 0.5 * block(0.0, 0.5, 0.5, false).dt();
        let (l, mut r, _) = coupled(Method::Gs4, window);
        let state = match LagrangeSide::save_state(&l) {
            Ok(s) => s,
            Err(e) => panic!("{e}"),
        };
        // Same particle count and interface, other step.
        let (_, mut other, _) = coupled(Method::Gs4, 0.5 * window);
        let e = match LagrangeSide::load_state(&mut other, &state) {
            Ok(()) => panic!("a state of another step loaded"),
            Err(e) => e,
        };
        assert!(e.contains("steps of"), "{e}");
        // The body's own state is no coupling state.
        let body = match Solver::save_state(&l) {
            Ok(s) => s,
            Err(e) => panic!("{e}"),
        };
        if LagrangeSide::load_state(&mut r, &body).is_ok() {
            panic!("a body's state loaded as a coupling state");
        }
        let e = match LagrangeSide::load_state(&mut r, &state[..state.len() - 8]) {
            Ok(()) => panic!("a truncated state loaded"),
            Err(e) => e,
        };
        assert!(e.contains("truncated"), "{e}");
        // A body without a lagrange side has no coupling state.
        let plain = block(0.0, 0.5, 0.5, false);
        assert!(LagrangeSide::save_state(&plain).is_err());
    }

    #[test]
    fn gs4_refuses_substeps_and_gc_takes_them() {
        // gs4 and ph need one particle step per system step; gc any ratio.
        let mut l = block(0.0, 0.5, 0.5, false);
        let window = 3.0 * l.dt();
        let e = match l.lagrange_side_for("cut", Method::Gs4, window, (0, 1.0)) {
            Ok(()) => panic!("gs4 with three particle steps per window was accepted"),
            Err(e) => e.to_string(),
        };
        assert!(e.contains("substeps") && e.contains("gc"), "{e}");
        if let Err(e) = l.lagrange_side_for("cut", Method::Gc, window, (0, 1.0)) {
            panic!("{e}");
        }
        assert_eq!(l.coupling_steps(), 3);
        let e = match l.lagrange_side_for("nowhere", Method::Gc, window, (0, 1.0)) {
            Ok(()) => panic!("a second side was accepted"),
            Err(e) => e.to_string(),
        };
        assert!(e.contains("one lagrange coupling"), "{e}");
    }

    #[test]
    fn bad_points_and_loads_are_refused_by_key() {
        let base = "dimension = \"plane_stress\"\nspacing = 0.1\nhorizon = 0.3015\n\
                    density = 2700.0\nyoung = 70e9\npoisson = 0.3\n\
                    bodies = [{ shape = \"box\", min = [0.0, 0.0, 0.0], max = [0.5, 0.4, 0.0] }]\n";
        let far = "[{ shape = \"box\", min = [5.0, 5.0, 0.0], max = [6.0, 6.0, 0.0] }]";
        for (extra, key) in [
            ("points = { A = [3.0, 3.0] }", "points.A"),
            ("points = { A = [0.05, 0.05, 0.0] }", "points.A"),
            (
                &format!(
                    "loads = [{{ region = {}, force = [0.0, 1.0, 0.0] }}]",
                    &far[1..far.len() - 1]
                ),
                "loads[0].region",
            ),
            (
                "loads = [{ region = { shape = \"box\", min = [0.0, 0.0, 0.0], max = [0.5, 0.4, 0.0] }, force = [0.0, 1.0, 0.0], ramp = \"septic\" }]",
                "loads[0].ramp_time",
            ),
            ("substeps = 0", "substeps"),
        ] {
            let table: toml::Table = match toml::from_str(&format!("{base}{extra}\n")) {
                Ok(t) => t,
                Err(e) => panic!("{extra}: {e}"),
            };
            match PdSolver::from_table("pd-correspondence", &table) {
                Ok(_) => panic!("{extra}: accepted"),
                Err(e) => assert!(e.to_string().contains(key), "{extra}: {e}"),
            }
        }
    }
}
