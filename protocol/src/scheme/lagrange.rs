//! The Lagrange-multiplier multi-time-step coupling (seed 003 §4–§5; docs/architecture.md.3):
//! N ≥ 2 subdomains, each with its own integrator and step, tied by velocity continuity
//! Σᵢ Bᵢ vᵢ = 0 on matching interface nodes. This module solves the interface problem — in
//! one place, with no solver crate — and fixes what each subdomain's side must do
//! ([`LagrangeSide`]): condense its interface response once at set-up, take a free step,
//! correct with the multipliers it is sent.
//!
//! Per system step (the coarsest subdomain's step ΔT) and method:
//! * `gs4` / `ph`: every side takes its free step over ΔT (its mᵢ substeps, the multipliers
//!   ramped linearly from λ_n with the unknown increment set to zero) and reports Bᵢ v_free;
//!   `(Σᵢ Pᵢᵀ Bᵢ Hᵢ Pᵢ) Δλ = −Σᵢ Pᵢᵀ Bᵢ v_free,ᵢ` gives λ_{n+1} = λ_n + Δλ (the multiplier
//!   at the system time level, seed 003 §4.1), sent back to correct each side.
//! * `gc` (Gravouil–Combescure): at each step j of the finest subdomain, a side whose own
//!   step spans rᵢ fine steps contributes its interface velocity interpolated at θ = (j mod
//!   rᵢ + 1)/rᵢ between its start and its (linked) end,
//!   `(Σᵢ θᵢ Pᵢᵀ Bᵢ Hᵢ Pᵢ) λ_j = −Σᵢ Pᵢᵀ ((1 − θᵢ) Bᵢ v_start,ᵢ + θᵢ Bᵢ v_free,ᵢ)`,
//!   and the sides whose step ends at j correct with λ_j.
//!
//! The interface matrices depend on the steps only, so they are factorised once (dense LU
//! with partial pivoting: interfaces are small).

use std::str::FromStr;
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum LagrangeError {
    #[error("lagrange coupling: {0}")]
    Setup(String),
    #[error("lagrange coupling: the interface matrix is singular (pivot {pivot:e} at row {row})")]
    Singular { row: usize, pivot: f64 },
}

/// Fields every side's interface must provide: its velocity and its condensed operator
/// (the handshake checks them against the node's description).
pub const PROVIDES: &[&str] = &["velocity", "lagrange_operator"];
/// Fields every side's interface must accept: the multipliers are forces on it.
pub const ACCEPTS: &[&str] = &["force"];

/// The scheme's contract (docs/architecture.md.3): every side exchanges with the coordinator,
/// which solves the interface problem; nothing is lagged and no side waits for another.
pub struct Lagrange;

impl super::Scheme for Lagrange {
    fn default_fields(&self) -> (&'static [&'static str], &'static [&'static str]) {
        (PROVIDES, ACCEPTS)
    }

    fn input_lag(&self, _role: crate::message::Role, _serial: bool) -> u64 {
        0
    }

    fn responder_after_driver(&self, _serial: bool) -> bool {
        false
    }

    fn coordinator_solved(&self) -> bool {
        true
    }

    /// Set-up waits for the coordinator's request; in a window the multipliers are
    /// exchanged inside it (the runtime's `lagrange_*` steps), not taken as an input.
    fn input_window(
        &self,
        _role: crate::message::Role,
        _input_lag: u64,
        _until: Option<u64>,
        window: u64,
    ) -> Option<u64> {
        (window == 0).then_some(0)
    }

    /// Only the set-up fields go at a window's end; in a window a side sends step by step.
    fn sends_at_window_end(&self, window: u64) -> bool {
        window == 0
    }
}

/// `method = "gs4" | "gc" | "ph"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    Gs4,
    Gc,
    Ph,
}

impl FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "gs4" => Ok(Method::Gs4),
            "gc" => Ok(Method::Gc),
            "ph" => Ok(Method::Ph),
            other => Err(format!(
                "must be \"gs4\", \"gc\" or \"ph\", got \"{other}\""
            )),
        }
    }
}

/// What a subdomain's node does for the scheme, in the side's local multiplier order. In
/// process ([`LagrangeScheme::new`]) the vectors are signed (Bᵢ x); through `cosim run` a
/// side keeps every sign +1 and the coordinator applies the signs (see [`wire`]).
pub trait LagrangeSide {
    /// Global multiplier index of each local multiplier.
    fn multiplier_ids(&self) -> &[usize];
    /// Coupling steps per system step (1 for gs4/ph; the ratio mᵢ for gc).
    fn coupling_steps(&self) -> usize;
    /// Bᵢ Hᵢ, row-major: interface velocity at a coupling step's end per unit multiplier.
    fn operator(&self) -> &[f64];
    /// At t = 0: free interface acceleration and Bᵢ M⁻¹ Bᵢᵀ (row-major).
    fn initial(&mut self, free: &mut [f64], op: &mut [f64]);
    fn set_initial(&mut self, lambda0: &[f64]);
    /// Free coupling step: interface velocity at its start and at its end.
    fn free_step(&mut self, v_start: &mut [f64], v_free: &mut [f64]);
    /// Correct with the multipliers at the coupling step's end.
    fn correct(&mut self, lambda: &[f64]);
    /// Work done on the side by the interface forces since t = 0 (J).
    fn interface_work(&self) -> f64;
    /// Its coupling state at a window end, as bytes in its own versioned format, for a
    /// checkpoint (PROTOCOL.md §4.5): what `free_step` and `correct` carry from one system
    /// step to the next (the operators are built again at set-up). The runtime calls it
    /// after the solver's own `save_state`. The default: this side cannot checkpoint, and
    /// a checkpointed run stops at its first checkpoint with this reason.
    fn save_state(&self) -> Result<Vec<u8>, String> {
        Err("this lagrange side cannot save its coupling state".into())
    }
    /// Restore what [`Self::save_state`] wrote, after set-up (and after the solver's own
    /// `load_state`).
    fn load_state(&mut self, _bytes: &[u8]) -> Result<(), String> {
        Err("this lagrange side cannot load a coupling state".into())
    }
}

/// Dense LU with partial pivoting, factorised once.
#[derive(Debug, Clone)]
pub struct DenseLu {
    n: usize,
    lu: Vec<f64>,
    piv: Vec<usize>,
}

impl DenseLu {
    /// Factorises the row-major n × n matrix `a`.
    pub fn new(n: usize, mut a: Vec<f64>) -> Result<Self, LagrangeError> {
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let mut piv: Vec<usize> = (0..n).collect();
        for k in 0..n {
            let p = (k..n)
                .max_by(|&i, &j| a[i * n + k].abs().total_cmp(&a[j * n + k].abs()))
                .unwrap_or(k);
            let pivot = a[p * n + k];
            if pivot.abs().partial_cmp(&(1e-14 * scale)) != Some(std::cmp::Ordering::Greater) {
                return Err(LagrangeError::Singular { row: k, pivot });
            }
            if p != k {
                for c in 0..n {
                    a.swap(p * n + c, k * n + c);
                }
                piv.swap(p, k);
            }
            for i in k + 1..n {
                let l = a[i * n + k] / pivot;
                a[i * n + k] = l;
                for c in k + 1..n {
                    a[i * n + c] -= l * a[k * n + c];
                }
            }
        }
        Ok(DenseLu { n, lu: a, piv })
    }

    /// Solves A x = b into `x`.
    pub fn solve(&self, b: &[f64], x: &mut [f64]) {
        let n = self.n;
        for i in 0..n {
            let row = &self.lu[i * n..i * n + i];
            let s: f64 = row.iter().zip(&x[..i]).map(|(l, xc)| l * xc).sum();
            x[i] = b[self.piv[i]] - s;
        }
        for i in (0..n).rev() {
            let row = &self.lu[i * n + i + 1..(i + 1) * n];
            let s: f64 = row.iter().zip(&x[i + 1..n]).map(|(u, xc)| u * xc).sum();
            x[i] = (x[i] - s) / self.lu[i * n + i];
        }
    }
}

/// What one side gives the interface problem at set-up, in its local interface order: the
/// global multiplier of each local one and its sign (the side's Boolean Bᵢ, ±1), its coupling
/// steps per system step, its condensed operator Hᵢ (local, unsigned: the velocity response
/// of its interface to a unit force on it) and, at t = 0, its free interface acceleration and
/// M⁻¹ restricted to the interface (both local, unsigned).
#[derive(Debug, Clone, PartialEq)]
pub struct SideSetup {
    pub ids: Vec<usize>,
    pub signs: Vec<f64>,
    pub steps: usize,
    pub operator: Vec<f64>,
    pub free0: Vec<f64>,
    pub mass0: Vec<f64>,
}

/// Local interface buffers of one side.
#[derive(Debug, Clone)]
struct SideBuffers {
    ids: Vec<usize>,
    signs: Vec<f64>,
    steps: usize,
    v_start: Vec<f64>,
    v_free: Vec<f64>,
    /// The side's multipliers (signed, Bᵢᵀ λ in its local order) last solved for it.
    local: Vec<f64>,
    /// Data of its current coupling step received (message-driven use).
    offered: bool,
}

/// The coordinator's side: the interface problem and its schedule. Driven either in-process
/// ([`LagrangeScheme::new`] and [`LagrangeScheme::step`] over [`LagrangeSide`]s) or by
/// messages ([`LagrangeScheme::from_setups`], then [`LagrangeScheme::offer`] and
/// [`LagrangeScheme::try_solve`]): both run the same arithmetic in the same order.
#[derive(Debug)]
pub struct LagrangeScheme {
    method: Method,
    /// Fine steps per system step (gc), else 1.
    fine: usize,
    /// One factorised interface matrix per fine step of the system step (gs4/ph: one).
    problems: Vec<DenseLu>,
    sides: Vec<SideBuffers>,
    lambda: Vec<f64>,
    rhs: Vec<f64>,
    x: Vec<f64>,
    /// Next fine step to solve (message-driven use), within the current system step.
    next: usize,
}

impl LagrangeScheme {
    /// Set-up in-process: collects each side's condensed operator (already signed, with
    /// global multiplier ids), factorises the interface matrices, solves the initial
    /// multipliers from the acceleration-level constraint and hands them to the sides.
    pub fn new(
        method: Method,
        multipliers: usize,
        sides: &mut [&mut dyn LagrangeSide],
    ) -> Result<Self, LagrangeError> {
        let mut setups = Vec::with_capacity(sides.len());
        for s in sides.iter_mut() {
            let nl = s.multiplier_ids().len();
            let (mut free0, mut mass0) = (vec![0.0; nl], vec![0.0; nl * nl]);
            s.initial(&mut free0, &mut mass0);
            setups.push(SideSetup {
                ids: s.multiplier_ids().to_vec(),
                signs: vec![1.0; nl],
                steps: s.coupling_steps(),
                operator: s.operator().to_vec(),
                free0,
                mass0,
            });
        }
        let scheme = Self::from_setups(method, multipliers, setups)?;
        for (i, s) in sides.iter_mut().enumerate() {
            s.set_initial(scheme.side_lambda(i));
        }
        Ok(scheme)
    }

    /// Set-up from what each side sent: validates, factorises the interface matrices and
    /// solves the initial multipliers ([`Self::side_lambda`] gives each side its own).
    pub fn from_setups(
        method: Method,
        multipliers: usize,
        setups: Vec<SideSetup>,
    ) -> Result<Self, LagrangeError> {
        if setups.len() < 2 {
            return Err(LagrangeError::Setup(format!(
                "needs at least two subdomains, got {}",
                setups.len()
            )));
        }
        let n = multipliers;
        let mut touched = vec![0usize; n];
        for (i, s) in setups.iter().enumerate() {
            let nl = s.ids.len();
            if let Some(&bad) = s.ids.iter().find(|&&k| k >= n) {
                return Err(LagrangeError::Setup(format!(
                    "subdomain {i} names multiplier {bad}, but there are {n}"
                )));
            }
            for &k in &s.ids {
                touched[k] += 1;
            }
            for (what, len, want) in [
                ("signs", s.signs.len(), nl),
                ("operator", s.operator.len(), nl * nl),
                ("initial free acceleration", s.free0.len(), nl),
                ("initial inverse mass", s.mass0.len(), nl * nl),
            ] {
                if len != want {
                    return Err(LagrangeError::Setup(format!(
                        "subdomain {i}: {what} has {len} entries for {nl} multipliers"
                    )));
                }
            }
            if s.signs.iter().any(|x| x.abs() != 1.0) {
                return Err(LagrangeError::Setup(format!(
                    "subdomain {i}: signs must be ±1"
                )));
            }
            let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
            if !(finite(&s.operator) && finite(&s.free0) && finite(&s.mass0)) {
                return Err(LagrangeError::Setup(format!(
                    "subdomain {i}: non-finite set-up values"
                )));
            }
            if s.steps == 0 {
                return Err(LagrangeError::Setup(format!(
                    "subdomain {i}: zero coupling steps per system step"
                )));
            }
        }
        if let Some(k) = touched.iter().position(|&c| c < 2) {
            return Err(LagrangeError::Setup(format!(
                "multiplier {k} ties fewer than two subdomains"
            )));
        }
        let fine = match method {
            Method::Gc => setups.iter().map(|b| b.steps).max().unwrap_or(1),
            _ => 1,
        };
        if let Some((i, b)) = setups.iter().enumerate().find(|(_, b)| fine % b.steps != 0) {
            return Err(LagrangeError::Setup(format!(
                "subdomain {i} takes {} steps per system step, which does not divide the \
                 finest subdomain's {fine}",
                b.steps
            )));
        }
        if method != Method::Gc
            && let Some((i, b)) = setups.iter().enumerate().find(|(_, b)| b.steps != 1)
        {
            return Err(LagrangeError::Setup(format!(
                "subdomain {i} takes {} coupling steps per system step; {method:?} takes one",
                b.steps
            )));
        }
        let mut problems = Vec::with_capacity(fine);
        for j in 0..fine {
            let mut a = vec![0.0; n * n];
            for s in &setups {
                let theta = theta(fine, s.steps, j);
                add_signed(&mut a, n, s, &s.operator, theta);
            }
            problems.push(DenseLu::new(n, a)?);
        }
        // t = 0: the acceleration-level constraint Σᵢ Bᵢ (a_free,ᵢ + M⁻¹ Bᵢᵀ λ₀) = 0.
        let mut a = vec![0.0; n * n];
        let mut rhs = vec![0.0; n];
        for s in &setups {
            add_signed(&mut a, n, s, &s.mass0, 1.0);
            for (r, &id) in s.ids.iter().enumerate() {
                rhs[id] -= s.signs[r] * s.free0[r];
            }
        }
        let mut lambda = vec![0.0; n];
        DenseLu::new(n, a)?.solve(&rhs, &mut lambda);
        let sides = setups
            .into_iter()
            .map(|s| {
                let nl = s.ids.len();
                SideBuffers {
                    ids: s.ids,
                    signs: s.signs,
                    steps: s.steps,
                    v_start: vec![0.0; nl],
                    v_free: vec![0.0; nl],
                    local: vec![0.0; nl],
                    offered: false,
                }
            })
            .collect();
        let mut scheme = LagrangeScheme {
            method,
            fine,
            problems,
            sides,
            lambda,
            rhs,
            x: vec![0.0; n],
            next: 0,
        };
        for b in &mut scheme.sides {
            gather(&b.ids, &b.signs, &scheme.lambda, &mut b.local);
        }
        Ok(scheme)
    }

    pub fn method(&self) -> Method {
        self.method
    }
    /// Continue, at a system step's start, from `lambda` (λ at the end of the last one) and
    /// each side's multipliers as [`Self::side_lambda`] gave them then: a restart's
    /// interface problem, set up again, takes them from the checkpoint.
    pub fn restore(&mut self, lambda: &[f64], sides: &[Vec<f64>]) -> Result<(), LagrangeError> {
        let bad = |what: String| Err(LagrangeError::Setup(format!("restored state: {what}")));
        if self.next != 0 {
            return bad(format!(
                "fine step {} of a system step is under way",
                self.next
            ));
        }
        if lambda.len() != self.lambda.len() || sides.len() != self.sides.len() {
            return bad(format!(
                "{} multipliers of {} sides, the interface problem has {} of {}",
                lambda.len(),
                sides.len(),
                self.lambda.len(),
                self.sides.len()
            ));
        }
        if let Some((i, _)) = self
            .sides
            .iter()
            .zip(sides)
            .enumerate()
            .find(|(_, (b, l))| b.local.len() != l.len())
        {
            return bad(format!("side {i} has another number of multipliers"));
        }
        if !lambda
            .iter()
            .chain(sides.iter().flatten())
            .all(|x| x.is_finite())
        {
            return bad("non-finite multipliers".into());
        }
        self.lambda.copy_from_slice(lambda);
        for (b, l) in self.sides.iter_mut().zip(sides) {
            b.local.copy_from_slice(l);
            b.offered = false;
        }
        Ok(())
    }
    /// Fine steps per system step: the finest side's coupling steps for gc, else 1.
    pub fn fine_steps(&self) -> usize {
        self.fine
    }
    /// λ at the end of the last step solved (the interface force on the + side, N).
    pub fn lambda(&self) -> &[f64] {
        &self.lambda
    }
    /// Side `i`'s multipliers from the last solve that ended one of its coupling steps
    /// (signed, local order): what it corrects with.
    pub fn side_lambda(&self, i: usize) -> &[f64] {
        &self.sides[i].local
    }
    /// Whether side `i` starts one of its coupling steps at fine step `j` (it then sends
    /// its free step's interface velocities before `j` can be solved).
    pub fn starts(&self, i: usize, j: usize) -> bool {
        j.is_multiple_of(self.fine / self.sides[i].steps)
    }
    /// Whether side `i` ends one of its coupling steps at fine step `j` (it then corrects
    /// with the multipliers of `j`).
    pub fn ends(&self, i: usize, j: usize) -> bool {
        (j + 1).is_multiple_of(self.fine / self.sides[i].steps)
    }
    /// Fine step at which coupling step `c` of side `i` ends.
    pub fn end_of(&self, i: usize, c: usize) -> usize {
        (c + 1) * (self.fine / self.sides[i].steps) - 1
    }

    /// Net interface work Σᵢ Wᵢ since t = 0: zero for an exact coupling, negative when the
    /// interface dissipates (ΔE_Γ = −Σᵢ Wᵢ).
    pub fn interface_work(sides: &[&mut dyn LagrangeSide]) -> f64 {
        sides.iter().map(|s| s.interface_work()).sum()
    }

    /// One system step of every side, in the order the method prescribes (in-process).
    pub fn step(&mut self, sides: &mut [&mut dyn LagrangeSide]) -> Result<(), LagrangeError> {
        if sides.len() != self.sides.len() {
            return Err(LagrangeError::Setup(format!(
                "set up with {} subdomains, stepped with {}",
                self.sides.len(),
                sides.len()
            )));
        }
        for j in 0..self.fine {
            for (i, s) in sides.iter_mut().enumerate() {
                if self.starts(i, j) {
                    let b = &mut self.sides[i];
                    s.free_step(&mut b.v_start, &mut b.v_free);
                }
            }
            self.solve_fine(j);
            for (i, s) in sides.iter_mut().enumerate() {
                if self.ends(i, j) {
                    s.correct(&self.sides[i].local);
                }
            }
        }
        Ok(())
    }

    /// Message-driven: side `i` sends the interface velocities of its coupling step `c`
    /// (within the current system step) at its start and after its free step (local,
    /// unsigned). Out of turn or of the wrong size is an error.
    pub fn offer(
        &mut self,
        i: usize,
        c: usize,
        v_start: &[f64],
        v_free: &[f64],
    ) -> Result<(), LagrangeError> {
        let (fine, next) = (self.fine, self.next);
        let Some(b) = self.sides.get_mut(i) else {
            return Err(LagrangeError::Setup(format!("no subdomain {i}")));
        };
        let r = fine / b.steps;
        if c * r != next || b.offered {
            return Err(LagrangeError::Setup(format!(
                "subdomain {i} sent its coupling step {c} while fine step {next} is being solved"
            )));
        }
        let nl = b.ids.len();
        if v_start.len() != nl || v_free.len() != nl {
            return Err(LagrangeError::Setup(format!(
                "subdomain {i} sent {} and {} interface velocities for {nl} multipliers",
                v_start.len(),
                v_free.len()
            )));
        }
        if !v_start.iter().chain(v_free).all(|x| x.is_finite()) {
            return Err(LagrangeError::Setup(format!(
                "subdomain {i} sent non-finite interface velocities"
            )));
        }
        for r in 0..nl {
            b.v_start[r] = b.signs[r] * v_start[r];
            b.v_free[r] = b.signs[r] * v_free[r];
        }
        b.offered = true;
        Ok(())
    }

    /// Message-driven: when every side that starts a coupling step at the next fine step has
    /// sent its data, solves it and returns its index j (the sides that [`Self::ends`] at j
    /// then correct with [`Self::side_lambda`]); None while data is missing.
    pub fn try_solve(&mut self) -> Option<usize> {
        let j = self.next;
        if (0..self.sides.len()).any(|i| self.starts(i, j) && !self.sides[i].offered) {
            return None;
        }
        self.solve_fine(j);
        for i in 0..self.sides.len() {
            if self.ends(i, j) {
                self.sides[i].offered = false;
            }
        }
        self.next = (j + 1) % self.fine;
        Some(j)
    }

    /// The interface problem of fine step `j` from the sides' latest velocities; updates λ
    /// and the multipliers of the sides whose coupling step ends at `j`.
    fn solve_fine(&mut self, j: usize) {
        self.rhs.fill(0.0);
        for b in &self.sides {
            let theta = theta(self.fine, b.steps, j);
            for (k, &id) in b.ids.iter().enumerate() {
                self.rhs[id] -= (1.0 - theta) * b.v_start[k] + theta * b.v_free[k];
            }
        }
        self.problems[j].solve(&self.rhs, &mut self.x);
        match self.method {
            Method::Gc => self.lambda.copy_from_slice(&self.x),
            Method::Gs4 | Method::Ph => {
                for (l, x) in self.lambda.iter_mut().zip(&self.x) {
                    *l += x;
                }
            }
        }
        let fine = self.fine;
        for b in &mut self.sides {
            if theta(fine, b.steps, j) == 1.0 {
                gather(&b.ids, &b.signs, &self.lambda, &mut b.local);
            }
        }
    }
}

/// a[idᵣ, id_c] += θ sᵣ s_c op[r, c]: one side's signed contribution to an interface matrix.
fn add_signed(a: &mut [f64], n: usize, s: &SideSetup, op: &[f64], theta: f64) {
    let nl = s.ids.len();
    for r in 0..nl {
        for c in 0..nl {
            a[s.ids[r] * n + s.ids[c]] += theta * (s.signs[r] * s.signs[c] * op[r * nl + c]);
        }
    }
}

/// Where fine step j (0-based) ends inside the own step of a side that takes `steps` steps
/// per system step of `fine` fine steps: (j mod r + 1)/r, r = fine/steps.
fn theta(fine: usize, steps: usize, j: usize) -> f64 {
    let r = fine / steps;
    ((j % r) + 1) as f64 / r as f64
}

fn gather(ids: &[usize], signs: &[f64], global: &[f64], local: &mut [f64]) {
    for ((l, &id), s) in local.iter_mut().zip(ids).zip(signs) {
        *l = s * global[id];
    }
}

/// The scheme on the wire (no message type of its own: `Fields` on the coupling's data
/// topics, PROTOCOL.md §4.6). A side's node publishes on `cosim/<run>/<coupling>/<node>`,
/// the coordinator on `cosim/<run>/<coupling>/coordinator`:
///
/// 1. coordinator, window 0: [`WINDOW`] (the system step, s) and [`METHOD`] (0 gs4, 1 gc,
///    2 ph) — the node builds its side (its condensed operator depends on both);
/// 2. node, window 0: [`DOFS`], [`STEPS`], [`OPERATOR`], [`FREE0`], [`MASS0`] (local,
///    unsigned: see [`SideSetup`]); the coordinator matches the sides' interface points by
///    position into multipliers with signs;
/// 3. coordinator, window 0: [`STEP`] = 0 and one field per side node, named after it,
///    with its initial multipliers; the node applies them;
/// 4. every coupling step c of window k: node → [`STEP`] = c, [`V_START`], [`V_FREE`];
///    coordinator → [`STEP`] = j (the fine step solved), [`LAMBDA`] (global λ, N) and the
///    multipliers of each side node whose step ends at j, under its name.
///
/// gs4 and ph take one exchange per window (each side one coupling step); gc one per step
/// of the finest side.
pub mod wire {
    use crate::message::{Field, Fields};
    use crate::solver::{FieldSet, SolverError, SolverResult};

    use super::{LagrangeSide, Method};

    pub const WINDOW: &str = "lagrange_window";
    pub const METHOD: &str = "lagrange_method";
    pub const DOFS: &str = "lagrange_dofs";
    pub const STEPS: &str = "lagrange_steps";
    pub const OPERATOR: &str = "lagrange_operator";
    pub const FREE0: &str = "lagrange_free0";
    pub const MASS0: &str = "lagrange_mass0";
    pub const STEP: &str = "step";
    pub const V_START: &str = "v_start";
    pub const V_FREE: &str = "v_free";
    pub const LAMBDA: &str = "lambda";
    /// The peer name of every side's binding: the coordinator solves the interface problem.
    pub const PEER: &str = "coordinator";

    pub fn method_code(m: Method) -> f64 {
        match m {
            Method::Gs4 => 0.0,
            Method::Gc => 1.0,
            Method::Ph => 2.0,
        }
    }

    /// What the coordinator asks of a side at set-up (message 1): the system step and the
    /// method, from the set-up inbox of `interface`.
    pub fn request(inbox: &FieldSet, interface: &str) -> SolverResult<(Method, f64)> {
        let w = inbox.require(interface, WINDOW, 1)?[0];
        let m = inbox.require(interface, METHOD, 1)?[0];
        if !(w.is_finite() && w > 0.0) {
            return Err(SolverError::interface(
                interface,
                format!("lagrange system step must be > 0, got {w}"),
            ));
        }
        let method = match m {
            0.0 => Method::Gs4,
            1.0 => Method::Gc,
            2.0 => Method::Ph,
            other => {
                return Err(SolverError::interface(
                    interface,
                    format!("unknown lagrange method code {other}"),
                ));
            }
        };
        Ok((method, w))
    }

    /// Message 1 (coordinator, window 0).
    pub fn request_fields(coupling: &str, method: Method, window: f64) -> Fields {
        Fields {
            coupling: coupling.to_string(),
            window: 0,
            time: 0.0,
            fields: vec![scalar(WINDOW, window), scalar(METHOD, method_code(method))],
        }
    }

    pub fn scalar(name: &str, v: f64) -> Field {
        Field {
            name: name.to_string(),
            components: 1,
            values: vec![v],
        }
    }

    /// Message 2 (node, window 0): the side's set-up, into the outbox of `interface`.
    pub fn setup_fields(side: &mut dyn LagrangeSide, interface: &str, out: &mut FieldSet) {
        let nl = side.multiplier_ids().len();
        out.put(interface, DOFS, 1, 1)[0] = nl as f64;
        out.put(interface, STEPS, 1, 1)[0] = side.coupling_steps() as f64;
        out.put(interface, OPERATOR, 1, nl * nl)
            .copy_from_slice(side.operator());
        let mut free0 = vec![0.0; nl];
        let mut mass0 = vec![0.0; nl * nl];
        side.initial(&mut free0, &mut mass0);
        out.put(interface, FREE0, 1, nl).copy_from_slice(&free0);
        out.put(interface, MASS0, 1, nl * nl)
            .copy_from_slice(&mass0);
    }

    /// The coupling step index of a node's message, or the fine step of a coordinator's.
    pub fn step_of(f: &Fields) -> Option<usize> {
        let v = f.get(STEP)?.values.first().copied()?;
        (v >= 0.0 && v.fract() == 0.0 && v < u32::MAX as f64).then_some(v as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_lu_solves_a_pivoting_system() {
        // [[0, 2, 1], [1, 1, 0], [3, 0, 1]] x = b with x = (1, −2, 3): pivoting needed.
        let a = vec![0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0];
        let b = [-1.0, -1.0, 6.0];
        let lu = DenseLu::new(3, a).unwrap();
        let mut x = [0.0; 3];
        lu.solve(&b, &mut x);
        for (xi, e) in x.iter().zip([1.0, -2.0, 3.0]) {
            assert!((xi - e).abs() < 1e-14, "{x:?}");
        }
        let e = DenseLu::new(2, vec![1.0, 2.0, 2.0, 4.0]).unwrap_err();
        assert!(matches!(e, LagrangeError::Singular { row: 1, .. }), "{e}");
    }

    #[test]
    fn methods_parse_and_bad_ones_are_named() {
        assert_eq!("gs4".parse::<Method>(), Ok(Method::Gs4));
        assert_eq!("gc".parse::<Method>(), Ok(Method::Gc));
        assert_eq!("ph".parse::<Method>(), Ok(Method::Ph));
        assert!(
            "newmark"
                .parse::<Method>()
                .unwrap_err()
                .contains("\"newmark\"")
        );
    }

    #[test]
    fn fine_step_fractions() {
        assert_eq!(theta(4, 4, 2), 1.0);
        assert_eq!(theta(4, 1, 0), 0.25);
        assert_eq!(theta(4, 2, 1), 1.0);
        assert_eq!(theta(4, 2, 2), 0.5);
    }
}
