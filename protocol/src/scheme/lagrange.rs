//! The Lagrange-multiplier multi-time-step coupling (seed 003 §4–§5; ARCHITECTURE §5.3):
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

/// What a subdomain's node does for the scheme (all interface vectors signed, Bᵢ x, in the
/// side's local multiplier order).
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

/// Local interface buffers of one side.
#[derive(Debug, Clone)]
struct SideBuffers {
    ids: Vec<usize>,
    steps: usize,
    v_start: Vec<f64>,
    v_free: Vec<f64>,
    local: Vec<f64>,
}

/// The coordinator's side: the interface problem and its schedule.
#[derive(Debug)]
pub struct LagrangeScheme {
    method: Method,
    n: usize,
    /// Fine steps per system step (gc), else 1.
    fine: usize,
    /// One factorised interface matrix per fine step of the system step (gs4/ph: one).
    problems: Vec<DenseLu>,
    sides: Vec<SideBuffers>,
    lambda: Vec<f64>,
    rhs: Vec<f64>,
    x: Vec<f64>,
}

impl LagrangeScheme {
    /// Set-up: collects each side's condensed operator, factorises the interface matrices
    /// and solves the initial multipliers from the acceleration-level constraint.
    pub fn new(
        method: Method,
        multipliers: usize,
        sides: &mut [&mut dyn LagrangeSide],
    ) -> Result<Self, LagrangeError> {
        if sides.len() < 2 {
            return Err(LagrangeError::Setup(format!(
                "needs at least two subdomains, got {}",
                sides.len()
            )));
        }
        let n = multipliers;
        let mut buf = Vec::with_capacity(sides.len());
        let mut touched = vec![0usize; n];
        for (i, s) in sides.iter().enumerate() {
            let ids = s.multiplier_ids().to_vec();
            if let Some(&bad) = ids.iter().find(|&&k| k >= n) {
                return Err(LagrangeError::Setup(format!(
                    "subdomain {i} names multiplier {bad}, but there are {n}"
                )));
            }
            for &k in &ids {
                touched[k] += 1;
            }
            let nl = ids.len();
            if s.operator().len() != nl * nl {
                return Err(LagrangeError::Setup(format!(
                    "subdomain {i}: operator has {} entries for {nl} multipliers",
                    s.operator().len()
                )));
            }
            buf.push(SideBuffers {
                ids,
                steps: s.coupling_steps().max(1),
                v_start: vec![0.0; nl],
                v_free: vec![0.0; nl],
                local: vec![0.0; nl],
            });
        }
        if let Some(k) = touched.iter().position(|&c| c < 2) {
            return Err(LagrangeError::Setup(format!(
                "multiplier {k} ties fewer than two subdomains"
            )));
        }
        let fine = match method {
            Method::Gc => buf.iter().map(|b| b.steps).max().unwrap_or(1),
            _ => 1,
        };
        if let Some((i, b)) = buf.iter().enumerate().find(|(_, b)| fine % b.steps != 0) {
            return Err(LagrangeError::Setup(format!(
                "subdomain {i} takes {} steps per system step, which does not divide the \
                 finest subdomain's {fine}",
                b.steps
            )));
        }
        let mut problems = Vec::with_capacity(fine);
        for j in 0..fine {
            let mut a = vec![0.0; n * n];
            for (s, b) in sides.iter().zip(&buf) {
                let theta = theta(fine, b.steps, j);
                let op = s.operator();
                let nl = b.ids.len();
                for r in 0..nl {
                    for c in 0..nl {
                        a[b.ids[r] * n + b.ids[c]] += theta * op[r * nl + c];
                    }
                }
            }
            problems.push(DenseLu::new(n, a)?);
        }
        let mut scheme = LagrangeScheme {
            method,
            n,
            fine,
            problems,
            sides: buf,
            lambda: vec![0.0; n],
            rhs: vec![0.0; n],
            x: vec![0.0; n],
        };
        scheme.initial(sides)?;
        Ok(scheme)
    }

    fn initial(&mut self, sides: &mut [&mut dyn LagrangeSide]) -> Result<(), LagrangeError> {
        let n = self.n;
        let mut a = vec![0.0; n * n];
        self.rhs.fill(0.0);
        for (s, b) in sides.iter_mut().zip(&mut self.sides) {
            let nl = b.ids.len();
            let mut op = vec![0.0; nl * nl];
            s.initial(&mut b.v_free, &mut op);
            for r in 0..nl {
                self.rhs[b.ids[r]] -= b.v_free[r];
                for c in 0..nl {
                    a[b.ids[r] * n + b.ids[c]] += op[r * nl + c];
                }
            }
        }
        DenseLu::new(n, a)?.solve(&self.rhs, &mut self.lambda);
        for (s, b) in sides.iter_mut().zip(&mut self.sides) {
            gather(&b.ids, &self.lambda, &mut b.local);
            s.set_initial(&b.local);
        }
        Ok(())
    }

    pub fn method(&self) -> Method {
        self.method
    }
    /// λ at the end of the last step solved (the interface force on the + side, N).
    pub fn lambda(&self) -> &[f64] {
        &self.lambda
    }

    /// Net interface work Σᵢ Wᵢ since t = 0: zero for an exact coupling, negative when the
    /// interface dissipates (ΔE_Γ = −Σᵢ Wᵢ).
    pub fn interface_work(sides: &[&mut dyn LagrangeSide]) -> f64 {
        sides.iter().map(|s| s.interface_work()).sum()
    }

    /// One system step of every side, in the order the method prescribes.
    pub fn step(&mut self, sides: &mut [&mut dyn LagrangeSide]) -> Result<(), LagrangeError> {
        if sides.len() != self.sides.len() {
            return Err(LagrangeError::Setup(format!(
                "set up with {} subdomains, stepped with {}",
                self.sides.len(),
                sides.len()
            )));
        }
        for j in 0..self.fine {
            self.rhs.fill(0.0);
            for (s, b) in sides.iter_mut().zip(&mut self.sides) {
                let r = self.fine / b.steps;
                if j % r == 0 {
                    s.free_step(&mut b.v_start, &mut b.v_free);
                }
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
            for (s, b) in sides.iter_mut().zip(&mut self.sides) {
                if theta(self.fine, b.steps, j) == 1.0 {
                    gather(&b.ids, &self.lambda, &mut b.local);
                    s.correct(&b.local);
                }
            }
        }
        Ok(())
    }
}

/// Where fine step j (0-based) ends inside the own step of a side that takes `steps` steps
/// per system step of `fine` fine steps: (j mod r + 1)/r, r = fine/steps.
fn theta(fine: usize, steps: usize, j: usize) -> f64 {
    let r = fine / steps;
    ((j % r) + 1) as f64 / r as f64
}

fn gather(ids: &[usize], global: &[f64], local: &mut [f64]) {
    for (l, &id) in local.iter_mut().zip(ids) {
        *l = global[id];
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
