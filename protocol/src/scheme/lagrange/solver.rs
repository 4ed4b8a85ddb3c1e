//! The interface problem the coordinator solves (module doc of `lagrange`): the sides'
//! condensed operators assembled with signs into the interface matrices, factorised once, and
//! the multipliers of each system (or fine) step.

use super::{LagrangeError, LagrangeSide, Method};

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
/// ([`InterfaceSolver::new`] and [`InterfaceSolver::step`] over [`LagrangeSide`]s) or by
/// messages ([`InterfaceSolver::from_setups`], then [`InterfaceSolver::offer`] and
/// [`InterfaceSolver::try_solve`]): both run the same arithmetic in the same order.
#[derive(Debug)]
pub struct InterfaceSolver {
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

impl InterfaceSolver {
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
        let mut scheme = InterfaceSolver {
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
    fn fine_step_fractions() {
        assert_eq!(theta(4, 4, 2), 1.0);
        assert_eq!(theta(4, 1, 0), 0.25);
        assert_eq!(theta(4, 2, 1), 1.0);
        assert_eq!(theta(4, 2, 2), 0.5);
    }
}
