//! Particle supports in compressed rows and their first-order RK shape functions in the
//! anchor (reference) configuration, with the adaptive anisotropic Lagrangian kernel
//! (seed 004 eq. 12–14) and the bond characteristic function χ (eq. 16–17).
//!
//! Row `I` holds the evaluation point `X_I`: its own entry first, then its neighbours in
//! ascending order. Entry `p` of row `I` with column `J` stores `φ_J(X_I)` and `∇_X φ_J(X_I)`;
//! `mirror[p]` is the entry of row `J` with column `I`, so the transposed quantities of the
//! gather sums (eq. 2–5, and the internal force) are read without any scatter. The
//! transposed quantities are also stored in row order (`psi_t`, `grad_t`), refreshed whenever
//! the shapes change, so the per-step loops stream through memory without indirection.
//!
//! `psi[p]` (row I, column J) is the gather smoothing weight `ψ_I(X_J)` of eq. 2–3: the kernel
//! of particle I, first-order corrected with the lumped masses `m̂_J` as quadrature weights,
//! so that `Σ_J ψ_I(X_J) = 1` and `Σ_J ψ_I(X_J) (X_J − X_I) = 0` (see `model.rs` for why
//! the linear part is what conserves angular momentum).

use mechanics::kernel::{cubic_spline, rk_row, rk_values};
use mechanics::neighbour::Families;
use mechanics::tensor::vec3;
use rayon::prelude::*;

/// A 3×3 matrix in the row-major flat storage of the state arrays.
pub type M3 = mechanics::tensor::Rows3;

/// Supports in compressed rows, with per-entry shape data.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Rows {
    pub offsets: Vec<usize>,
    pub cols: Vec<u32>,
    /// Row of each entry (for entry-parallel loops).
    pub row_of: Vec<u32>,
    pub mirror: Vec<u32>,
    /// Bond intact (χ = 1, eq. 17); irreversible once false.
    pub alive: Vec<bool>,
    /// Initial bond length ‖X_J − X_I‖ (eq. 15).
    pub len0: Vec<f64>,
    pub phi: Vec<f64>,
    pub grad: Vec<[f64; 3]>,
    /// Gather smoothing weights `ψ_I(X_J)` (eq. 2–3, mass-weighted first-order correction).
    pub psi: Vec<f64>,
    /// Transposed entries in row order: `psi_t[p] = psi[mirror[p]] = ψ_J(X_I)`,
    /// `grad_t[p] = grad[mirror[p]] = ∇φ_I(X_J)`.
    pub psi_t: Vec<f64>,
    pub grad_t: Vec<[f64; 3]>,
    /// Scratch of the shape computation (offsets, kernel values, volumes), reused; not
    /// part of a checkpoint.
    #[serde(skip)]
    d: Vec<[f64; 3]>,
    #[serde(skip)]
    w: Vec<f64>,
    #[serde(skip)]
    vw: Vec<f64>,
}

impl Rows {
    /// Take the rows, bond states and shape values of `saved` (read from a checkpoint, which
    /// holds no scratch), keeping this one's scratch buffers.
    pub fn restore(&mut self, saved: Rows) {
        let d = std::mem::take(&mut self.d);
        let w = std::mem::take(&mut self.w);
        let vw = std::mem::take(&mut self.vw);
        *self = Rows { d, w, vw, ..saved };
    }

    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    #[inline]
    pub fn range(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i]..self.offsets[i + 1]
    }

    /// Build rows (self first) from neighbour families, keeping only the pairs `allowed`
    /// accepts (e.g. no bonds between two separate plates).
    pub fn build(fam: &Families, x: &[[f64; 3]], allowed: impl Fn(usize, usize) -> bool) -> Self {
        let n = fam.len();
        let mut offsets = Vec::with_capacity(n + 1);
        let mut cols = Vec::with_capacity(fam.bonds() + n);
        offsets.push(0);
        for i in 0..n {
            cols.push(i as u32);
            for &j in fam.of(i) {
                if allowed(i, j as usize) {
                    cols.push(j);
                }
            }
            offsets.push(cols.len());
        }
        let nnz = cols.len();
        let mut row_of = vec![0u32; nnz];
        for i in 0..n {
            for p in offsets[i]..offsets[i + 1] {
                row_of[p] = i as u32;
            }
        }
        // Mirror entries by binary search in the sorted tail of row J.
        let mirror: Vec<u32> = (0..nnz)
            .into_par_iter()
            .map(|p| {
                let i = row_of[p];
                let j = cols[p] as usize;
                if j as u32 == i {
                    return p as u32;
                }
                let tail = &cols[offsets[j] + 1..offsets[j + 1]];
                match tail.binary_search(&i) {
                    Ok(k) => (offsets[j] + 1 + k) as u32,
                    // `allowed` and the search are symmetric, so this cannot happen; keep the
                    // entry self-consistent rather than panic.
                    Err(_) => p as u32,
                }
            })
            .collect();
        let len0 = (0..nnz)
            .map(|p| {
                let i = row_of[p] as usize;
                let j = cols[p] as usize;
                (vec3(&x[i]) - vec3(&x[j])).norm()
            })
            .collect();
        Rows {
            offsets,
            cols,
            row_of,
            mirror,
            alive: vec![true; nnz],
            len0,
            phi: vec![0.0; nnz],
            grad: vec![[0.0; 3]; nnz],
            psi: vec![0.0; nnz],
            psi_t: vec![0.0; nnz],
            grad_t: vec![[0.0; 3]; nnz],
            d: vec![[0.0; 3]; nnz],
            w: vec![0.0; nnz],
            vw: vec![0.0; nnz],
        }
    }

    /// (Re)compute the shape functions of the rows flagged in `which` (all rows when `None`)
    /// in the anchor configuration `xa` with the adaptive anisotropic Lagrangian kernel
    /// (eq. 12–14): the kernel domain "deforms and rotates according to the Lagrangian
    /// motion" (§2.2), i.e. the window of a pair is evaluated at its material distance,
    /// `w = χ_IJ ω(‖X⁰_I − X⁰_J‖ / a)` (`len0`). `‖F_J⁻¹ (X̂_I − X̂_J)‖` is the affine
    /// approximation of the same argument; it differs where F varies over the support (grips,
    /// surfaces), and that difference made every re-anchoring change the discrete operator
    /// non-affinely: the balanced stress field of the old anchor then drove a stress wave
    /// (4.4 % error in uniaxial tension after one re-anchor, tests/tension.rs). The
    /// moment matrix and gradients use the anchor offsets `X̂_J − X̂_I`. Returns the first
    /// singular row.
    pub fn compute(
        &mut self,
        xa: &[[f64; 3]],
        vol: &[f64],
        support: f64,
        which: Option<&[bool]>,
    ) -> Result<(), usize> {
        match self.compute_rows(xa, vol, support, which, None) {
            (_, Some(i)) => Err(i),
            _ => Ok(()),
        }
    }

    /// As [`Rows::compute`], but a row left singular (or with less than `keep` of its
    /// kernel weight) by broken bonds (eq. 16: the particle
    /// has lost its support, i.e. it has separated from the body) is *detached* instead of
    /// failing the run: `φ = δ_IJ` and `∇φ = 0`, so the particle no longer deforms or carries
    /// stress and moves on with its velocity as a free lump of mass. Returns how many rows
    /// were detached now.
    pub fn compute_detaching(
        &mut self,
        xa: &[[f64; 3]],
        vol: &[f64],
        support: f64,
        which: Option<&[bool]>,
        keep: f64,
    ) -> usize {
        self.compute_rows(xa, vol, support, which, Some(keep)).0
    }

    fn compute_rows(
        &mut self,
        xa: &[[f64; 3]],
        vol: &[f64],
        support: f64,
        which: Option<&[bool]>,
        detach: Option<f64>,
    ) -> (usize, Option<usize>) {
        let offsets = &self.offsets;
        let cols = &self.cols;
        let alive = &self.alive;
        let len0 = &self.len0;
        let phi = split_rows(&mut self.phi, offsets);
        let grad = split_rows(&mut self.grad, offsets);
        let d = split_rows(&mut self.d, offsets);
        let w = split_rows(&mut self.w, offsets);
        let vw = split_rows(&mut self.vw, offsets);
        let bad: (usize, usize) = phi
            .into_par_iter()
            .zip(grad)
            .zip(d)
            .zip(w)
            .zip(vw)
            .enumerate()
            .filter_map(|(i, ((((phi, grad), d), w), vw))| {
                if let Some(flags) = which
                    && !flags[i]
                {
                    return None;
                }
                let base = offsets[i];
                for k in 0..phi.len() {
                    let p = base + k;
                    let j = cols[p] as usize;
                    d[k] = (vec3(&xa[j]) - vec3(&xa[i])).into();
                    // Kernel of the pair at its material distance (eq. 12–14, see above).
                    let q = len0[p] / support;
                    w[k] = if alive[p] { cubic_spline(q) } else { 0.0 };
                    vw[k] = vol[j];
                }
                // A row that has lost most of its kernel weight to broken bonds is as good
                // as cut loose (its moment matrix is near-singular and its gradients would
                // be wild): detach it before it is exactly singular. So is a row whose
                // intact bonds have all but collapsed onto a plane or a line (see
                // `support_collapsed`), whatever weight they keep.
                let mut full = 0.0;
                let mut kept = 0.0;
                for k in 0..phi.len() {
                    let c = cubic_spline(len0[base + k] / support) * vw[k];
                    full += c;
                    kept += w[k] * vw[k];
                }
                let collapsed = detach.is_some()
                    && kept < full
                    && support_collapsed(d, w, vw, &len0[base..base + phi.len()], support);
                let res = if detach.is_some_and(|f| kept < f * full) || collapsed {
                    Err(())
                } else {
                    rk_row(d, w, vw, support, phi, grad).map_err(|_| ())
                };
                match res {
                    Ok(()) => None,
                    Err(_) if detach.is_some() => {
                        for k in 0..phi.len() {
                            phi[k] = if cols[base + k] as usize == i {
                                1.0
                            } else {
                                0.0
                            };
                            grad[k] = [0.0; 3];
                        }
                        Some((1usize, usize::MAX))
                    }
                    Err(_) => Some((0, i)),
                }
            })
            .reduce(|| (0, usize::MAX), |a, b| (a.0 + b.0, a.1.min(b.1)));
        let first = (bad.1 != usize::MAX).then_some(bad.1);
        (bad.0, first)
    }
}

impl Rows {
    /// (Re)compute the gather smoothing weights `ψ_I(X_J)` of the flagged rows (all when
    /// `None`) from the kernel values and offsets stored by the last [`Rows::compute`] of the
    /// row, with the lumped masses `mh` as quadrature weights (eq. 2–3). Returns the first
    /// singular row.
    pub fn compute_psi(
        &mut self,
        mh: &[f64],
        support: f64,
        which: Option<&[bool]>,
    ) -> Result<(), usize> {
        self.compute_psi_rows(mh, support, which, None)
    }

    /// As [`Rows::compute_psi`], detaching rows as [`Rows::compute_detaching`] does
    /// (`ψ = δ_IJ`).
    pub fn compute_psi_detaching(
        &mut self,
        mh: &[f64],
        support: f64,
        which: Option<&[bool]>,
        keep: f64,
    ) {
        let _ = self.compute_psi_rows(mh, support, which, Some(keep));
    }

    fn compute_psi_rows(
        &mut self,
        mh: &[f64],
        support: f64,
        which: Option<&[bool]>,
        detach: Option<f64>,
    ) -> Result<(), usize> {
        let offsets = &self.offsets;
        let cols = &self.cols;
        let psi = split_rows(&mut self.psi, offsets);
        let vw = split_rows(&mut self.vw, offsets);
        let (d, w, len0) = (&self.d, &self.w, &self.len0);
        let bad: Option<usize> = psi
            .into_par_iter()
            .zip(vw)
            .enumerate()
            .filter_map(|(i, (psi, vw))| {
                if let Some(flags) = which
                    && !flags[i]
                {
                    return None;
                }
                let r = offsets[i]..offsets[i + 1];
                for (k, p) in r.clone().enumerate() {
                    vw[k] = mh[cols[p] as usize];
                }
                let (mut full, mut kept) = (0.0, 0.0);
                for (k, p) in r.clone().enumerate() {
                    full += cubic_spline(len0[p] / support) * vw[k];
                    kept += w[p] * vw[k];
                }
                let collapsed = detach.is_some()
                    && kept < full
                    && support_collapsed(
                        &d[r.clone()],
                        &w[r.clone()],
                        vw,
                        &len0[r.clone()],
                        support,
                    );
                let res = if detach.is_some_and(|f| kept < f * full) || collapsed {
                    Err(())
                } else {
                    rk_values(&d[r.clone()], &w[r.clone()], vw, support, psi).map_err(|_| ())
                };
                match res {
                    Ok(()) => None,
                    Err(_) if detach.is_some() => {
                        for (k, p) in r.enumerate() {
                            psi[k] = if cols[p] as usize == i { 1.0 } else { 0.0 };
                        }
                        None
                    }
                    Err(_) => Some(i),
                }
            })
            .min();
        match bad {
            Some(i) => Err(i),
            None => Ok(()),
        }
    }

    /// Refresh the row-ordered transposed copies `psi_t`, `grad_t` from the mirror entries.
    pub fn refresh_transposed(&mut self) {
        let (mirror, psi, grad) = (&self.mirror, &self.psi, &self.grad);
        self.psi_t
            .par_iter_mut()
            .zip(self.grad_t.par_iter_mut())
            .enumerate()
            .for_each(|(p, (pt, gt))| {
                let q = mirror[p] as usize;
                *pt = psi[q];
                *gt = grad[q];
            });
    }
}

/// Split a per-entry buffer into one mutable slice per row.
pub fn split_rows<'a, T>(mut buf: &'a mut [T], offsets: &[usize]) -> Vec<&'a mut [T]> {
    let n = offsets.len().saturating_sub(1);
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let (a, b) = std::mem::take(&mut buf).split_at_mut(offsets[i + 1] - offsets[i]);
        out.push(a);
        buf = b;
    }
    out
}

/// Least spread of a row's intact support, as a share of its full support's, below which the
/// row is detached: [`support_collapsed`].
pub const SUPPORT_SPREAD_MIN: f64 = 0.1;

/// Whether the intact bonds of a row (weights `w`, zero for broken ones; quadrature weights
/// `vw`; anchor offsets `d`) have collapsed onto a plane or a line: the least eigenvalue of
/// their weighted covariance below [`SUPPORT_SPREAD_MIN`] of the whole row's (every bond at
/// its kernel weight, `len0`). Such a row's moment matrix is near-singular in the lost
/// direction, and its gradients along it are wild: in a necking bar, the bonds along the bar
/// break (stretched, plastic) while those across it, compressed by the contraction, hold, and
/// a particle keeping only those would see any motion along the bar as an enormous strain. A
/// one-sided support (a free surface, one face of a crack) keeps a quarter or more of the
/// spread and is not detached.
fn support_collapsed(d: &[[f64; 3]], w: &[f64], vw: &[f64], len0: &[f64], support: f64) -> bool {
    let spread = |weight: &dyn Fn(usize) -> f64| {
        let (mut s, mut m1) = (0.0, [0.0; 3]);
        let mut m2 = [[0.0; 3]; 3];
        for k in 0..d.len() {
            let c = weight(k) * vw[k];
            s += c;
            for a in 0..3 {
                m1[a] += c * d[k][a];
                for b in 0..3 {
                    m2[a][b] += c * d[k][a] * d[k][b];
                }
            }
        }
        if !(s > 0.0) {
            return 0.0;
        }
        let cov =
            mechanics::tensor::Matrix3::from_fn(|a, b| m2[a][b] / s - m1[a] * m1[b] / (s * s));
        cov.symmetric_eigenvalues().min()
    };
    let full = spread(&|k| cubic_spline(len0[k] / support));
    let kept = spread(&|k| w[k]);
    kept < SUPPORT_SPREAD_MIN * full
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The neighbours of a lattice particle (spacing 0.5, support 1) and their kernel weights:
    /// (offsets, weights, volumes, reference lengths).
    fn lattice_row() -> (Vec<[f64; 3]>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut d = Vec::new();
        for i in -2i32..=2 {
            for j in -2i32..=2 {
                for k in -2i32..=2 {
                    let x = [0.5 * i as f64, 0.5 * j as f64, 0.5 * k as f64];
                    let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
                    if r < 1.0 {
                        d.push(x);
                    }
                }
            }
        }
        let len0: Vec<f64> = d
            .iter()
            .map(|x| (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt())
            .collect();
        let w = len0.iter().map(|&r| cubic_spline(r)).collect();
        (d.clone(), w, vec![1.0; d.len()], len0)
    }

    #[test]
    fn a_row_keeping_only_bonds_across_the_bar_is_collapsed_a_one_sided_row_is_not() {
        let (d, w, vw, len0) = lattice_row();
        assert!(d.len() > 20, "{} neighbours", d.len());
        // intact
        assert!(!support_collapsed(&d, &w, &vw, &len0, 1.0));
        // a necking bar along x: every bond with a component along x broken, the bonds in
        // the particle's own cross-section kept (most of the weight of the nearest ones)
        let across: Vec<f64> = d
            .iter()
            .zip(&w)
            .map(|(x, &w)| if x[0] == 0.0 { w } else { 0.0 })
            .collect();
        let kept: f64 = across.iter().sum::<f64>() / w.iter().sum::<f64>();
        assert!(kept > 0.3, "kept {kept} of the weight");
        assert!(support_collapsed(&d, &across, &vw, &len0, 1.0));
        // ... and with a trace of one diagonal bond left: still collapsed
        let mut trace = across.clone();
        let k = d.iter().position(|x| x == &[0.5, 0.5, 0.0]).unwrap();
        trace[k] = w[k];
        assert!(support_collapsed(&d, &trace, &vw, &len0, 1.0));
        // one face of a crack: the bonds to one side broken, the rest kept
        let one_sided: Vec<f64> = d
            .iter()
            .zip(&w)
            .map(|(x, &w)| if x[0] > 0.0 { 0.0 } else { w })
            .collect();
        assert!(!support_collapsed(&d, &one_sided, &vw, &len0, 1.0));
    }
}
