//! One subdomain's side of the Lagrange-multiplier multi-time-step coupling (seed 003
//! §4.1–§4.3): its own GS4-II member and step, tied to the others by multipliers λ on
//! interface degrees of freedom (signed Boolean B, Σᵢ Bᵢ vᵢ = 0). The interface problem itself
//! is solved elsewhere (`protocol::scheme::lagrange`); a subdomain only
//!
//! * condenses, once at set-up, the response of its interface velocity to the unknown
//!   multipliers over one of its coupling steps into a small matrix Bᵢ Hᵢ (and keeps the
//!   response of its whole state, Φᵢ, to correct with),
//! * takes a free coupling step (the unknown part of λ set to zero) and reports Bᵢ v_free,
//! * corrects its state with the multipliers it is sent: x ↦ state_free + Φᵢ x (exact for a
//!   linear system, by superposition).
//!
//! Methods: `Gs4` solves λ at the system (coarsest) step and ramps it linearly through each
//! subdomain's substeps, sampled at the substep's own algorithmic time t_k + W₁Δt (seed 003
//! §4.3: time-level consistency); `Ph` (Prakash and Hjelmstad 2004) ramps it the same way but
//! samples at the substep end; `Gc` (Gravouil and Combescure 2001) solves λ at every step of
//! the finest subdomain, interpolating the coarser subdomains' interface velocities linearly.
//!
//! Audit: per substep the subdomain keeps, for the corrected trajectory, the work and the
//! time integral of its load, the impulse of the interface forces and ∫ p·u dt of any probe
//! vectors p its model gives ([`Subdomain::with_probes`], e.g. support reactions). For the
//! U0(1,1,0) members (equilibrium at each step's end, trapezoidal velocity update) these
//! trapezoidal sums are exactly the momentum the forces gave.

use super::gs4::{Gs4, Gs4Error};
use super::linear::{LinearSystem, State, Stepper};

/// The coupling method (`method = "gs4" | "gc" | "ph"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CouplingMethod {
    Gs4,
    Gc,
    Ph,
}

/// Multiplier k acts on degree of freedom `dof` with the sign of Bᵢ (±1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InterfaceDof {
    pub dof: usize,
    pub sign: f64,
    /// Index of the multiplier in the coupling's global λ.
    pub lambda: usize,
}

/// An external load f(t) = shape · g(t).
pub type LoadHistory = Box<dyn Fn(f64) -> f64 + Send>;

/// One subdomain with its integrator, its interface and its coupling operators.
pub struct Subdomain {
    sys: LinearSystem,
    stepper: Stepper,
    method: CouplingMethod,
    /// Substeps per system step (the ratio mᵢ of the system step to this subdomain's step).
    substeps: usize,
    /// Substeps in one coupling step: mᵢ for gs4/ph (λ solved per system step), 1 for gc.
    inner: usize,
    iface: Vec<InterfaceDof>,
    load_shape: Vec<f64>,
    load: LoadHistory,
    /// State at the start of the current coupling step, then the free state, then the
    /// corrected state.
    pub state: State,
    /// Time at the start of the current coupling step.
    pub time: f64,
    /// λ at the start of the current coupling step (gs4/ph) and the last λ applied.
    lambda_start: Vec<f64>,
    lambda_end: Vec<f64>,
    /// Response of u, v, a to a unit unknown multiplier k: column k at [k n .. (k+1) n].
    phi_u: Vec<f64>,
    phi_v: Vec<f64>,
    phi_a: Vec<f64>,
    /// Bᵢ Hᵢ, row-major n_λ × n_λ.
    operator: Vec<f64>,
    /// Interface displacement after each inner substep: free run, and response per unit
    /// multiplier (for the interface work).
    free_iface_u: Vec<f64>,
    phi_iface_u: Vec<f64>,
    iface_u_start: Vec<f64>,
    /// Interface velocity (signed, Bᵢ v) at the start of the coupling step.
    iface_v_start: Vec<f64>,
    /// Work done on this subdomain by the interface forces since the start (J).
    pub interface_work: f64,
    /// Impulse of the interface force on each interface dof since the start (N s, along the
    /// dof).
    pub interface_impulse: Vec<f64>,
    /// Work of the external load since the start (J) and ∫ g dt of its history (s).
    pub external_work: f64,
    pub load_integral: f64,
    /// ∫ pᵩ·u dt of each probe since the start.
    pub probe_integral: Vec<f64>,
    /// The load shape, then the probes (row-major, n each).
    probes: Vec<f64>,
    /// pᵩ·u after each inner substep of the free run, and its response per unit multiplier.
    free_probe: Vec<f64>,
    phi_probe: Vec<f64>,
    /// pᵩ·u at the start of the coupling step (a scratch row while correcting).
    probe_start: Vec<f64>,
    f: Vec<f64>,
    x: Vec<f64>,
    prev_u: Vec<f64>,
    ids: Vec<usize>,
}

impl std::fmt::Debug for Subdomain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Subdomain")
            .field("dofs", &self.sys.len())
            .field("substeps", &self.substeps)
            .field("method", &self.method)
            .finish()
    }
}

impl Subdomain {
    /// Builds the subdomain and its condensed interface operator for the system step
    /// `dt_system`, taken in `substeps` equal steps of `coef`. Starts at rest at t = 0.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        sys: LinearSystem,
        coef: Gs4,
        dt_system: f64,
        substeps: usize,
        method: CouplingMethod,
        iface: Vec<InterfaceDof>,
        load_shape: Vec<f64>,
        load: LoadHistory,
    ) -> Result<Self, Gs4Error> {
        let n = sys.len();
        let bad = |reason: String| Gs4Error::Config {
            key: "subdomain".into(),
            reason,
        };
        if substeps == 0 {
            return Err(bad("substeps must be ≥ 1".into()));
        }
        if load_shape.len() != n {
            return Err(bad(format!(
                "load shape has {} entries for {n} dofs",
                load_shape.len()
            )));
        }
        if let Some(d) = iface.iter().find(|d| d.dof >= n || d.sign.abs() != 1.0) {
            return Err(bad(format!(
                "interface dof {d:?} out of range or sign not ±1"
            )));
        }
        let stepper = Stepper::new(coef, dt_system / substeps as f64, &sys)?;
        let inner = match method {
            CouplingMethod::Gc => 1,
            _ => substeps,
        };
        let nl = iface.len();
        let mut s = Subdomain {
            sys,
            stepper,
            method,
            substeps,
            inner,
            iface,
            load_shape,
            load,
            state: State::zeros(n),
            time: 0.0,
            lambda_start: vec![0.0; nl],
            lambda_end: vec![0.0; nl],
            phi_u: vec![0.0; n * nl],
            phi_v: vec![0.0; n * nl],
            phi_a: vec![0.0; n * nl],
            operator: vec![0.0; nl * nl],
            free_iface_u: vec![0.0; inner * nl],
            phi_iface_u: vec![0.0; inner * nl * nl],
            iface_u_start: vec![0.0; nl],
            iface_v_start: vec![0.0; nl],
            interface_work: 0.0,
            interface_impulse: vec![0.0; nl],
            external_work: 0.0,
            load_integral: 0.0,
            probe_integral: Vec::new(),
            probes: Vec::new(),
            free_probe: Vec::new(),
            phi_probe: Vec::new(),
            probe_start: Vec::new(),
            f: vec![0.0; n],
            x: vec![0.0; nl],
            prev_u: vec![0.0; nl],
            ids: Vec::new(),
        };
        s.ids = s.iface.iter().map(|d| d.lambda).collect();
        s.set_probes(Vec::new());
        s.condense();
        Ok(s)
    }

    /// The subdomain with probe vectors (row-major, n entries each) whose ∫ p·u dt it keeps
    /// ([`Self::probe_integral`]): condenses again.
    pub fn with_probes(mut self, probes: Vec<f64>) -> Result<Self, Gs4Error> {
        let n = self.sys.len();
        if !probes.len().is_multiple_of(n.max(1)) {
            return Err(Gs4Error::Config {
                key: "subdomain".into(),
                reason: format!("probes have {} entries for {n} dofs", probes.len()),
            });
        }
        self.set_probes(probes);
        self.condense();
        Ok(self)
    }

    fn set_probes(&mut self, probes: Vec<f64>) {
        let n = self.sys.len();
        let nq = probes.len() / n.max(1);
        let (np, nl) = (nq + 1, self.iface.len());
        let mut all = Vec::with_capacity(np * n);
        all.extend_from_slice(&self.load_shape);
        all.extend_from_slice(&probes);
        self.probes = all;
        self.probe_integral = vec![0.0; nq];
        self.free_probe = vec![0.0; self.inner * np];
        self.phi_probe = vec![0.0; self.inner * np * nl];
        self.probe_start = vec![0.0; np];
    }

    /// pᵩ·u of every probe (the load shape first) into `out`.
    fn probe_values(probes: &[f64], u: &[f64], out: &mut [f64]) {
        for (o, p) in out.iter_mut().zip(probes.chunks_exact(u.len().max(1))) {
            *o = p.iter().zip(u).map(|(a, b)| a * b).sum();
        }
    }

    pub fn multipliers(&self) -> usize {
        self.iface.len()
    }
    /// Global multiplier index of each local one.
    pub fn multiplier_ids(&self) -> &[usize] {
        &self.ids
    }
    pub fn substeps(&self) -> usize {
        self.substeps
    }
    /// Coupling steps per system step: 1 for gs4/ph, mᵢ for gc.
    pub fn coupling_steps(&self) -> usize {
        self.substeps / self.inner
    }
    pub fn system(&self) -> &LinearSystem {
        &self.sys
    }
    pub fn coef(&self) -> Gs4 {
        self.stepper.coef
    }
    /// Bᵢ Hᵢ (row-major n_λ × n_λ): the signed interface velocity at the end of a coupling
    /// step per unit unknown multiplier.
    pub fn operator(&self) -> &[f64] {
        &self.operator
    }

    /// Weight of the unknown multiplier in inner substep k: gs4 samples the ramp at the
    /// substep's algorithmic time, ph at its end, gc applies λ of the step end in full.
    fn ramp(&self, k: usize) -> f64 {
        let w = match self.method {
            CouplingMethod::Gs4 => self.stepper.coef.w1,
            CouplingMethod::Ph | CouplingMethod::Gc => 1.0,
        };
        (k as f64 + w) / self.inner as f64
    }

    /// The response of the state to each unit unknown multiplier over one coupling step,
    /// from rest (seed 003 Fig. 4: the condensed interface operators, once at set-up).
    fn condense(&mut self) {
        let n = self.sys.len();
        let nl = self.iface.len();
        let mut st = State::zeros(n);
        for k in 0..nl {
            st.u.fill(0.0);
            st.v.fill(0.0);
            st.a.fill(0.0);
            for j in 0..self.inner {
                self.f.fill(0.0);
                let d = self.iface[k];
                self.f[d.dof] += d.sign * self.ramp(j);
                self.stepper.step(&self.sys, &mut st, &self.f);
                for (r, dr) in self.iface.iter().enumerate() {
                    self.phi_iface_u[(j * nl + r) * nl + k] = dr.sign * st.u[dr.dof];
                }
                let np = self.probe_start.len();
                for (q, p) in self.probes.chunks_exact(n.max(1)).enumerate() {
                    self.phi_probe[(j * np + q) * nl + k] =
                        p.iter().zip(&st.u).map(|(a, b)| a * b).sum();
                }
            }
            self.phi_u[k * n..(k + 1) * n].copy_from_slice(&st.u);
            self.phi_v[k * n..(k + 1) * n].copy_from_slice(&st.v);
            self.phi_a[k * n..(k + 1) * n].copy_from_slice(&st.a);
            for (r, dr) in self.iface.iter().enumerate() {
                self.operator[r * nl + k] = dr.sign * st.v[dr.dof];
            }
        }
    }

    /// Signed interface values Bᵢ x of a state vector.
    pub fn interface_values(&self, x: &[f64], out: &mut [f64]) {
        for (o, d) in out.iter_mut().zip(&self.iface) {
            *o = d.sign * x[d.dof];
        }
    }

    /// Set-up at t = 0 (acceleration-level constraint): the free initial acceleration
    /// Bᵢ M⁻¹ (f(0) − C v − K u) into `free`, and Bᵢ M⁻¹ Bᵢᵀ (row-major) into `op`.
    pub fn initial(&mut self, free: &mut [f64], op: &mut [f64]) {
        let g = (self.load)(0.0);
        for (fi, s) in self.f.iter_mut().zip(&self.load_shape) {
            *fi = s * g;
        }
        let st = &mut self.state;
        self.sys.acceleration(&st.u, &st.v, &self.f, &mut st.a);
        self.interface_values(&self.state.a, free);
        let nl = self.iface.len();
        op.fill(0.0);
        for (r, dr) in self.iface.iter().enumerate() {
            for (k, dk) in self.iface.iter().enumerate() {
                if dr.dof == dk.dof {
                    op[r * nl + k] += dr.sign * dk.sign / self.sys.mass[dr.dof];
                }
            }
        }
    }

    /// Applies the initial multipliers: a += M⁻¹ Bᵢᵀ λ₀.
    pub fn set_initial(&mut self, lambda0: &[f64]) {
        for (d, l) in self.iface.iter().zip(lambda0) {
            self.state.a[d.dof] += d.sign * l / self.sys.mass[d.dof];
        }
        self.lambda_start.copy_from_slice(lambda0);
        self.lambda_end.copy_from_slice(lambda0);
    }

    /// Takes the free coupling step from `self.time` (unknown multipliers zero) and writes
    /// the signed interface velocity at its end into `v_free` and at its start into
    /// `v_start` (what the interface problem needs).
    pub fn free_step(&mut self, v_start: &mut [f64], v_free: &mut [f64]) {
        let nl = self.iface.len();
        let dt = self.stepper.dt;
        let w1 = self.stepper.coef.w1;
        self.interface_values(&self.state.v, v_start);
        self.iface_v_start.copy_from_slice(v_start);
        let mut iu = std::mem::take(&mut self.iface_u_start);
        self.interface_values(&self.state.u, &mut iu);
        self.iface_u_start = iu;
        Self::probe_values(&self.probes, &self.state.u, &mut self.probe_start);
        let np = self.probe_start.len();
        // gs4/ph keep λ_n as the known part of the ramp; gc's unknown is the whole λ.
        if self.method == CouplingMethod::Gc {
            self.lambda_start.fill(0.0);
        } else {
            self.lambda_start.copy_from_slice(&self.lambda_end);
        }
        for j in 0..self.inner {
            let t0 = self.time + j as f64 * dt;
            let g = (1.0 - w1) * (self.load)(t0) + w1 * (self.load)(t0 + dt);
            for (fi, s) in self.f.iter_mut().zip(&self.load_shape) {
                *fi = s * g;
            }
            for (d, l) in self.iface.iter().zip(&self.lambda_start) {
                self.f[d.dof] += d.sign * l;
            }
            self.stepper.step(&self.sys, &mut self.state, &self.f);
            for (r, d) in self.iface.iter().enumerate() {
                self.free_iface_u[j * nl + r] = d.sign * self.state.u[d.dof];
            }
            Self::probe_values(
                &self.probes,
                &self.state.u,
                &mut self.free_probe[j * np..(j + 1) * np],
            );
        }
        self.interface_values(&self.state.v, v_free);
    }

    /// Corrects the free state with the multipliers `lambda` at the end of the coupling step
    /// and advances the clock; adds the interface work of the step.
    pub fn correct(&mut self, lambda: &[f64]) {
        let n = self.sys.len();
        let dt = self.stepper.dt;
        let nl = self.iface.len();
        for ((x, l), l0) in self.x.iter_mut().zip(lambda).zip(&self.lambda_start) {
            *x = l - l0;
        }
        for k in 0..nl {
            let xk = self.x[k];
            if xk == 0.0 {
                continue;
            }
            let col = k * n..(k + 1) * n;
            for (s, p) in self.state.u.iter_mut().zip(&self.phi_u[col.clone()]) {
                *s += p * xk;
            }
            for (s, p) in self.state.v.iter_mut().zip(&self.phi_v[col.clone()]) {
                *s += p * xk;
            }
            for (s, p) in self.state.a.iter_mut().zip(&self.phi_a[col]) {
                *s += p * xk;
            }
        }
        // Interface work: Σ over substeps of Δ(Bu) · λ̄, λ̄ the mean of the multipliers in the
        // equations at the substep's two ends (the trapezoidal work of the constraint force).
        let lam_prev = &self.lambda_end;
        let prev_u = &mut self.prev_u;
        prev_u.copy_from_slice(&self.iface_u_start);
        let mut work = 0.0;
        for j in 0..self.inner {
            let s0 = j as f64 / self.inner as f64;
            let s1 = (j + 1) as f64 / self.inner as f64;
            for r in 0..nl {
                let mut u = self.free_iface_u[j * nl + r];
                for k in 0..nl {
                    u += self.phi_iface_u[(j * nl + r) * nl + k] * self.x[k];
                }
                let (l0, l1) = match self.method {
                    CouplingMethod::Gc => (if j == 0 { lam_prev[r] } else { lambda[r] }, lambda[r]),
                    _ => (
                        lam_prev[r] + s0 * (lambda[r] - lam_prev[r]),
                        lam_prev[r] + s1 * (lambda[r] - lam_prev[r]),
                    ),
                };
                work += (u - prev_u[r]) * 0.5 * (l0 + l1);
                self.interface_impulse[r] += self.iface[r].sign * 0.5 * (l0 + l1) * dt;
                prev_u[r] = u;
            }
        }
        self.interface_work += work;
        // The load's work and the probes' integrals along the corrected substeps (the
        // trapezoidal rule, as the interface work).
        let np = self.probe_start.len();
        for j in 0..self.inner {
            let ta = self.time + j as f64 * dt;
            let (ga, gb) = ((self.load)(ta), (self.load)(ta + dt));
            for q in 0..np {
                let row = (j * np + q) * nl;
                let mut val = self.free_probe[j * np + q];
                for (p, x) in self.phi_probe[row..row + nl].iter().zip(&self.x) {
                    val += p * x;
                }
                let prev = self.probe_start[q];
                if q == 0 {
                    self.external_work += 0.5 * (ga + gb) * (val - prev);
                } else {
                    self.probe_integral[q - 1] += 0.5 * dt * (prev + val);
                }
                self.probe_start[q] = val;
            }
            self.load_integral += 0.5 * dt * (ga + gb);
        }
        self.lambda_end.copy_from_slice(lambda);
        self.time += self.inner as f64 * self.stepper.dt;
    }

    /// Kinetic plus strain energy and the work of the external load so far is the caller's;
    /// this is ½ vᵀMv + ½ uᵀKu of the current state.
    pub fn energy(&mut self) -> f64 {
        let mut scratch = std::mem::take(&mut self.f);
        let e = self.sys.energy(&self.state.u, &self.state.v, &mut scratch);
        self.f = scratch;
        e
    }
}
