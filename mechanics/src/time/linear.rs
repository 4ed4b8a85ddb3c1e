//! A linear structural system M ü + C u̇ + K u = f over its free degrees of freedom (lumped
//! M and C as diagonals, K in compressed rows) and the GS4-II step over it (seed 003 eq.
//! 67–70): the effective matrix Λ₆W₁ M + Λ₅W₂ Δt C + Λ₃W₃ Δt² K is factorised once (faer's
//! sparse Cholesky; a diagonal for the explicit member) and each step is one solve, with no
//! allocation.

use super::gs4::{Gs4, Gs4Error};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, MatMut, Par, Side};

/// A square sparse matrix in compressed rows (row offsets, column indices, values).
#[derive(Debug, Clone, Default)]
pub struct Csr {
    pub n: usize,
    pub offsets: Vec<usize>,
    pub cols: Vec<usize>,
    pub vals: Vec<f64>,
}

impl Csr {
    /// Assembles from (row, col, value) triplets; duplicates are summed.
    pub fn from_triplets(n: usize, mut t: Vec<(usize, usize, f64)>) -> Self {
        t.sort_by_key(|&(i, j, _)| (i, j));
        let mut offsets = vec![0; n + 1];
        let mut cols = Vec::with_capacity(t.len());
        let mut vals: Vec<f64> = Vec::with_capacity(t.len());
        let mut last = None;
        for (i, j, v) in t {
            if last == Some((i, j)) {
                if let Some(x) = vals.last_mut() {
                    *x += v;
                }
            } else {
                cols.push(j);
                vals.push(v);
                offsets[i + 1] += 1;
                last = Some((i, j));
            }
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        Csr {
            n,
            offsets,
            cols,
            vals,
        }
    }

    /// `y = self · x`.
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        for (i, yi) in y.iter_mut().enumerate().take(self.n) {
            let mut s = 0.0;
            for k in self.offsets[i]..self.offsets[i + 1] {
                s += self.vals[k] * x[self.cols[k]];
            }
            *yi = s;
        }
    }
}

/// M ü + C u̇ + K u = f over the free degrees of freedom.
#[derive(Debug, Clone)]
pub struct LinearSystem {
    /// Lumped mass (kg), one per degree of freedom.
    pub mass: Vec<f64>,
    /// Diagonal damping (N s/m); zeros when undamped.
    pub damping: Vec<f64>,
    pub stiffness: Csr,
}

impl LinearSystem {
    pub fn len(&self) -> usize {
        self.mass.len()
    }
    pub fn is_empty(&self) -> bool {
        self.mass.is_empty()
    }

    /// `a = M⁻¹ (f − C v − K u)`: the acceleration that satisfies the equation of motion.
    pub fn acceleration(&self, u: &[f64], v: &[f64], f: &[f64], a: &mut [f64]) {
        self.stiffness.mul(u, a);
        for i in 0..a.len() {
            a[i] = (f[i] - self.damping[i] * v[i] - a[i]) / self.mass[i];
        }
    }

    /// The static solution of K u = f (K must be positive definite: the system needs enough
    /// supports to hold it), factorised for this one solve.
    pub fn solve_static(&self, f: &[f64]) -> Result<Vec<f64>, Gs4Error> {
        let k = &self.stiffness;
        let mut t = Vec::with_capacity(k.vals.len());
        for i in 0..k.n {
            for p in k.offsets[i]..k.offsets[i + 1] {
                t.push(Triplet::new(i, k.cols[p], k.vals[p]));
            }
        }
        let mut u = f.to_vec();
        SparseLlt::new(k.n, &t)?.solve_in_place(&mut u);
        Ok(u)
    }

    /// A step at or below the undamped central-difference limit 2/ω_max: ω_max² is bounded
    /// by the largest Gershgorin row sum of M⁻¹K, maxᵢ Σⱼ |Kᵢⱼ| / mᵢ (infinite without
    /// stiffness).
    pub fn critical_step_bound(&self) -> f64 {
        let k = &self.stiffness;
        let mut w2: f64 = 0.0;
        for i in 0..k.n {
            let row: f64 = k.vals[k.offsets[i]..k.offsets[i + 1]]
                .iter()
                .map(|v| v.abs())
                .sum();
            w2 = w2.max(row / self.mass[i]);
        }
        if w2 > 0.0 {
            2.0 / w2.sqrt()
        } else {
            f64::INFINITY
        }
    }

    /// Kinetic plus strain energy ½ vᵀMv + ½ uᵀKu; `scratch` has the system's length.
    pub fn energy(&self, u: &[f64], v: &[f64], scratch: &mut [f64]) -> f64 {
        self.stiffness.mul(u, scratch);
        let mut e = 0.0;
        for i in 0..u.len() {
            e += 0.5 * (self.mass[i] * v[i] * v[i] + u[i] * scratch[i]);
        }
        e
    }
}

/// Displacement, velocity and acceleration of every free degree of freedom.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    pub u: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
}

impl State {
    pub fn zeros(n: usize) -> Self {
        State {
            u: vec![0.0; n],
            v: vec![0.0; n],
            a: vec![0.0; n],
        }
    }
}

/// A sparse LLᵀ factorisation of a symmetric positive definite matrix (faer, AMD ordering),
/// with its solve scratch: factorised once, then each solve allocates nothing.
pub struct SparseLlt {
    symbolic: Box<SymbolicCholesky<usize>>,
    values: Vec<f64>,
    scratch: MemBuffer,
}

impl SparseLlt {
    /// Factorises the n × n matrix given as (row, col, value) triplets (duplicates summed;
    /// both triangles present).
    pub fn new(n: usize, t: &[Triplet<usize, usize, f64>]) -> Result<Self, Gs4Error> {
        let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, t)
            .map_err(|e| solver_error(format!("{e:?}")))?;
        let symbolic = factorize_symbolic_cholesky(
            a.symbolic(),
            Side::Lower,
            SymmetricOrdering::Amd,
            Default::default(),
        )
        .map_err(|e| solver_error(format!("{e:?}")))?;
        let mut values = vec![0.0; symbolic.len_val()];
        let mut fac_mem = MemBuffer::new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        );
        symbolic
            .factorize_numeric_llt(
                &mut values,
                a.as_ref(),
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut fac_mem),
                Default::default(),
            )
            .map_err(|e| solver_error(format!("not positive definite ({e:?})")))?;
        let scratch = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        Ok(SparseLlt {
            symbolic: Box::new(symbolic),
            values,
            scratch,
        })
    }

    /// Overwrites `x` (the right-hand side) with the solution.
    pub fn solve_in_place(&mut self, x: &mut [f64]) {
        let n = x.len();
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(x, n, 1),
            Par::Seq,
            MemStack::new(&mut self.scratch),
        );
    }
}

/// The factorised effective matrix.
enum Effective {
    /// Explicit member: the inverse of the diagonal Λ₆W₁ M + Λ₅W₂ Δt C.
    Diagonal(Vec<f64>),
    /// Implicit member: sparse LLᵀ of the symmetric positive definite effective matrix.
    Cholesky(SparseLlt),
}

/// One GS4-II member at one step size over one linear system.
pub struct Stepper {
    pub coef: Gs4,
    pub dt: f64,
    effective: Effective,
    rhs: Vec<f64>,
    tmp: Vec<f64>,
}

impl std::fmt::Debug for Stepper {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Stepper")
            .field("coef", &self.coef)
            .field("dt", &self.dt)
            .finish()
    }
}

fn solver_error(reason: impl std::fmt::Display) -> Gs4Error {
    Gs4Error::Config {
        key: "integrator".into(),
        reason: format!("effective matrix: {reason}"),
    }
}

impl Stepper {
    /// Factorises the effective matrix of `coef` at step `dt` (once, for a linear system).
    pub fn new(coef: Gs4, dt: f64, sys: &LinearSystem) -> Result<Self, Gs4Error> {
        let n = sys.len();
        if !(dt.is_finite() && dt > 0.0) {
            return Err(solver_error(format!("step must be > 0, got {dt}")));
        }
        let effective = if coef.explicit {
            Effective::Diagonal(
                (0..n)
                    .map(|i| 1.0 / (coef.l6w1 * sys.mass[i] + coef.l5w2 * dt * sys.damping[i]))
                    .collect(),
            )
        } else {
            let k = &sys.stiffness;
            let mut t = Vec::with_capacity(k.vals.len() + n);
            for i in 0..n {
                t.push(Triplet::new(
                    i,
                    i,
                    coef.l6w1 * sys.mass[i] + coef.l5w2 * dt * sys.damping[i],
                ));
                for p in k.offsets[i]..k.offsets[i + 1] {
                    t.push(Triplet::new(i, k.cols[p], coef.l3w3 * dt * dt * k.vals[p]));
                }
            }
            Effective::Cholesky(SparseLlt::new(n, &t)?)
        };
        Ok(Stepper {
            coef,
            dt,
            effective,
            rhs: vec![0.0; n],
            tmp: vec![0.0; n],
        })
    }

    /// One step from `s` (at t_n) with the weighted load `f_tilde` = (1 − W₁) f_n + W₁ f_{n+1}
    /// (seed 003 eq. 67), in place.
    pub fn step(&mut self, sys: &LinearSystem, s: &mut State, f_tilde: &[f64]) {
        let (c, dt) = (self.coef, self.dt);
        let n = sys.len();
        // ũ and ṽ without their Δa parts.
        for i in 0..n {
            self.tmp[i] = s.u[i] + c.l1w1 * dt * s.v[i] + c.l2w2 * dt * dt * s.a[i];
        }
        sys.stiffness.mul(&self.tmp, &mut self.rhs);
        for (i, (r, f)) in self.rhs.iter_mut().zip(f_tilde).enumerate() {
            let v0 = s.v[i] + c.l4w1 * dt * s.a[i];
            *r = f - sys.mass[i] * s.a[i] - sys.damping[i] * v0 - *r;
        }
        match &mut self.effective {
            Effective::Diagonal(inv) => {
                for (r, d) in self.rhs.iter_mut().zip(inv.iter()) {
                    *r *= d;
                }
            }
            Effective::Cholesky(llt) => llt.solve_in_place(&mut self.rhs),
        }
        for i in 0..n {
            let da = self.rhs[i];
            s.u[i] += c.lam1 * dt * s.v[i] + c.lam2 * dt * dt * s.a[i] + c.lam3 * dt * dt * da;
            s.v[i] += c.lam4 * dt * s.a[i] + c.lam5 * dt * da;
            s.a[i] += da;
        }
    }
}
