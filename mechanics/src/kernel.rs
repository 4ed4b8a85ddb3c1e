//! Meshfree kernels shared by the particle solvers: the cubic-spline window and first-order
//! reproducing-kernel (RK / MLS) shape functions with their implicit (synchronised) gradients
//! (seed 004 §2.1 eq. 1, the first-order approximation of Wu et al. 2011; Liu et al. 1995).
//!
//! A *row* is one evaluation point `x_I` and its support (neighbours `J`, the point itself
//! included when it carries a node). For a first-order basis `H(d) = [1, d_x, d_y, d_z]` and
//! `d_J = X_J − x_I`, the moment matrix is `M = Σ_J H(d_J) H(d_J)ᵀ w_J V_J` and
//!
//! * `φ_J(x_I)  = e₀ᵀ M⁻¹ H(d_J) w_J V_J`                      (RK value),
//! * `∂φ_J/∂x_k = e_kᵀ M⁻¹ H(d_J) w_J V_J, k = 1..3`          (implicit gradient).
//!
//! Both reproduce every linear field exactly: `Σ φ_J = 1`, `Σ φ_J d_J = 0`,
//! `Σ ∇φ_J = 0`, `Σ d_J ⊗ ∇φ_J = I`, to round-off, also at boundaries (patch test).

/// Cubic-spline window with support radius 1: `w(q)` for `q = r / a ≥ 0`
/// (`2/3 − 4q² + 4q³` on `[0, ½]`, `4/3 (1 − q)³` on `[½, 1]`, 0 beyond), the RKPM form.
#[inline]
pub fn cubic_spline(q: f64) -> f64 {
    let q = q.abs();
    if q <= 0.5 {
        2.0 / 3.0 - 4.0 * q * q + 4.0 * q * q * q
    } else if q < 1.0 {
        let s = 1.0 - q;
        4.0 / 3.0 * s * s * s
    } else {
        0.0
    }
}

/// Derivative `dw/dq` of [`cubic_spline`] for `q ≥ 0`.
#[inline]
pub fn cubic_spline_dq(q: f64) -> f64 {
    let q = q.abs();
    if q <= 0.5 {
        -8.0 * q + 12.0 * q * q
    } else if q < 1.0 {
        let s = 1.0 - q;
        -4.0 * s * s
    } else {
        0.0
    }
}

/// Why a row's shape functions cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KernelError {
    /// The moment matrix is singular: fewer than four non-coplanar neighbours carry weight
    /// (support too small for the spacing, or too many broken bonds).
    #[error("singular moment matrix (pivot {pivot:e}): support holds too few non-coplanar points")]
    Singular { pivot: f64 },
    #[error("row slices have different lengths")]
    Length,
}

/// First-order RK shape functions and implicit gradients of one row.
///
/// * `d[J] = X_J − x_I` (anchor-configuration offsets of the row's support points),
/// * `w[J]` kernel values (already multiplied by any bond characteristic function, eq. 16),
/// * `vol[J]` quadrature weights (particle volumes; use 1 for plain MLS),
/// * outputs `phi[J]` and `grad[J]`.
///
/// The moment matrix is scaled by the support length `scale` (any positive length of the
/// order of the support radius) so the pivot test is dimensionless.
#[allow(clippy::needless_range_loop)] // index loops mirror the matrix formulas
pub fn rk_row(
    d: &[[f64; 3]],
    w: &[f64],
    vol: &[f64],
    scale: f64,
    phi: &mut [f64],
    grad: &mut [[f64; 3]],
) -> Result<(), KernelError> {
    let n = d.len();
    if w.len() != n || vol.len() != n || phi.len() != n || grad.len() != n {
        return Err(KernelError::Length);
    }
    let inv_s = 1.0 / scale;
    // Moment matrix in scaled coordinates h = [1, d/s].
    let mut m = [[0.0f64; 4]; 4];
    let mut wsum = 0.0;
    for j in 0..n {
        let h = [1.0, d[j][0] * inv_s, d[j][1] * inv_s, d[j][2] * inv_s];
        let c = w[j] * vol[j];
        wsum += c;
        for a in 0..4 {
            for b in a..4 {
                m[a][b] += h[a] * h[b] * c;
            }
        }
    }
    for a in 0..4 {
        for b in 0..a {
            m[a][b] = m[b][a];
        }
    }
    let minv = invert_spd4(&m, wsum)?;
    for j in 0..n {
        let h = [1.0, d[j][0] * inv_s, d[j][1] * inv_s, d[j][2] * inv_s];
        let c = w[j] * vol[j];
        let mut r = [0.0; 4];
        for a in 0..4 {
            r[a] =
                (minv[a][0] * h[0] + minv[a][1] * h[1] + minv[a][2] * h[2] + minv[a][3] * h[3]) * c;
        }
        phi[j] = r[0];
        grad[j] = [r[1] * inv_s, r[2] * inv_s, r[3] * inv_s];
    }
    Ok(())
}

/// First-order RK values only (no gradients) of one row: `phi[J] = e₀ᵀ M⁻¹ H(d_J) w_J c_J`
/// with `M = Σ_J H(d_J) H(d_J)ᵀ w_J c_J`, for quadrature weights `c` (e.g. particle masses).
/// `Σ_J phi_J = 1` and `Σ_J phi_J d_J = 0` to round-off. Only the first row of `M⁻¹` is
/// needed, so this is cheaper than [`rk_row`]. Used for the *gather* smoothing weights of
/// MC-SPG (seed 004 eq. 2–3, see `meso-joint-node` `shape.rs`).
#[allow(clippy::needless_range_loop)]
pub fn rk_values(
    d: &[[f64; 3]],
    w: &[f64],
    c: &[f64],
    scale: f64,
    phi: &mut [f64],
) -> Result<(), KernelError> {
    let n = d.len();
    if w.len() != n || c.len() != n || phi.len() != n {
        return Err(KernelError::Length);
    }
    let inv_s = 1.0 / scale;
    let mut m = [[0.0f64; 4]; 4];
    let mut wsum = 0.0;
    for j in 0..n {
        let h = [1.0, d[j][0] * inv_s, d[j][1] * inv_s, d[j][2] * inv_s];
        let cw = w[j] * c[j];
        wsum += cw;
        for a in 0..4 {
            for b in a..4 {
                m[a][b] += h[a] * h[b] * cw;
            }
        }
    }
    for a in 0..4 {
        for b in 0..a {
            m[a][b] = m[b][a];
        }
    }
    let minv = invert_spd4(&m, wsum)?;
    let r0 = minv[0];
    for j in 0..n {
        let h1 = d[j][0] * inv_s;
        let h2 = d[j][1] * inv_s;
        let h3 = d[j][2] * inv_s;
        phi[j] = (r0[0] + r0[1] * h1 + r0[2] * h2 + r0[3] * h3) * w[j] * c[j];
    }
    Ok(())
}

/// Inverse of a symmetric positive (semi)definite 4×4 matrix by Cholesky; refuses a pivot
/// below `1e-10 · ref` (relative singularity test).
#[allow(clippy::needless_range_loop)]
fn invert_spd4(m: &[[f64; 4]; 4], reference: f64) -> Result<[[f64; 4]; 4], KernelError> {
    let mut l = [[0.0f64; 4]; 4];
    let tol = 1e-10 * reference.abs().max(f64::MIN_POSITIVE);
    for i in 0..4 {
        for j in 0..=i {
            let mut s = m[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if s.is_nan() || s <= tol {
                    return Err(KernelError::Singular {
                        pivot: s / reference,
                    });
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    // inv(L), lower triangular.
    let mut li = [[0.0f64; 4]; 4];
    for i in 0..4 {
        li[i][i] = 1.0 / l[i][i];
        for j in 0..i {
            let mut s = 0.0;
            for k in j..i {
                s -= l[i][k] * li[k][j];
            }
            li[i][j] = s / l[i][i];
        }
    }
    // M⁻¹ = L⁻ᵀ L⁻¹.
    let mut inv = [[0.0f64; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            let mut s = 0.0;
            for k in i.max(j)..4 {
                s += li[k][i] * li[k][j];
            }
            inv[i][j] = s;
        }
    }
    Ok(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A jittered lattice point set with deterministic pseudo-random offsets.
    fn cloud(n: usize, h: f64, jitter: f64) -> Vec<[f64; 3]> {
        let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut x = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    x.push([
                        (i as f64 + jitter * rnd()) * h,
                        (j as f64 + jitter * rnd()) * h,
                        (k as f64 + jitter * rnd()) * h,
                    ]);
                }
            }
        }
        x
    }

    #[test]
    fn spline_is_continuous_and_vanishes_at_the_support() {
        for q in [0.5 - 1e-12, 0.5 + 1e-12] {
            assert!((cubic_spline(q) - 1.0 / 6.0).abs() < 1e-10);
        }
        assert_eq!(cubic_spline(1.0), 0.0);
        assert_eq!(cubic_spline(1.3), 0.0);
        // derivative by central differences
        for q in [0.1, 0.3, 0.7, 0.9] {
            let e = 1e-6;
            let fd = (cubic_spline(q + e) - cubic_spline(q - e)) / (2.0 * e);
            assert!((fd - cubic_spline_dq(q)).abs() < 1e-8, "q {q}");
        }
    }

    #[test]
    fn rows_reproduce_linear_fields_at_interior_and_corner_points() {
        let h = 1e-3;
        let x = cloud(6, h, 0.3);
        let a = 1.8 * h;
        let g = [[0.3, -1.2, 0.5], [2.0, 0.1, -0.7], [-0.4, 0.9, 1.1]];
        let u = |p: &[f64; 3]| -> [f64; 3] {
            std::array::from_fn(|r| 0.25 + g[r][0] * p[0] + g[r][1] * p[1] + g[r][2] * p[2])
        };
        for &i in &[0usize, 3 * 36 + 3 * 6 + 3, 215] {
            let xi = x[i];
            let mut d = Vec::new();
            let mut w = Vec::new();
            let mut uj = Vec::new();
            for p in &x {
                let dj = [p[0] - xi[0], p[1] - xi[1], p[2] - xi[2]];
                let r = (dj[0] * dj[0] + dj[1] * dj[1] + dj[2] * dj[2]).sqrt();
                if r < a {
                    d.push(dj);
                    w.push(cubic_spline(r / a));
                    uj.push(u(p));
                }
            }
            let vol = vec![h * h * h; d.len()];
            let mut phi = vec![0.0; d.len()];
            let mut grad = vec![[0.0; 3]; d.len()];
            rk_row(&d, &w, &vol, a, &mut phi, &mut grad).unwrap();
            let ue = u(&xi);
            for r in 0..3 {
                let val: f64 = (0..d.len()).map(|j| phi[j] * uj[j][r]).sum();
                assert!(
                    (val - ue[r]).abs() < 1e-13,
                    "value row {i} comp {r}: {val} vs {}",
                    ue[r]
                );
                for c in 0..3 {
                    let gv: f64 = (0..d.len()).map(|j| grad[j][c] * uj[j][r]).sum();
                    assert!(
                        (gv - g[r][c]).abs() < 1e-10,
                        "grad row {i}: {gv} vs {}",
                        g[r][c]
                    );
                }
            }
        }
    }

    #[test]
    #[allow(clippy::needless_range_loop)]
    fn value_rows_match_full_rows_and_reproduce_linear_fields() {
        let h = 1e-3;
        let x = cloud(5, h, 0.3);
        let a = 1.8 * h;
        let i = 2 * 25 + 2 * 5 + 2;
        let xi = x[i];
        let mut d = Vec::new();
        let mut w = Vec::new();
        let mut c = Vec::new();
        for (k, p) in x.iter().enumerate() {
            let dj = [p[0] - xi[0], p[1] - xi[1], p[2] - xi[2]];
            let r = (dj[0] * dj[0] + dj[1] * dj[1] + dj[2] * dj[2]).sqrt();
            if r < a {
                d.push(dj);
                w.push(cubic_spline(r / a));
                // Non-uniform weights (like scaled masses).
                c.push(1.0 + 0.5 * ((k * 7919) % 13) as f64);
            }
        }
        let n = d.len();
        let mut phi = vec![0.0; n];
        let mut phi_full = vec![0.0; n];
        let mut grad = vec![[0.0; 3]; n];
        rk_values(&d, &w, &c, a, &mut phi).unwrap();
        rk_row(&d, &w, &c, a, &mut phi_full, &mut grad).unwrap();
        let sum: f64 = phi.iter().sum();
        assert!((sum - 1.0).abs() < 1e-14, "partition of unity {sum}");
        for r in 0..3 {
            let m1: f64 = (0..n).map(|j| phi[j] * d[j][r]).sum();
            assert!(m1.abs() < 1e-14 * h, "first moment {m1:e}");
        }
        for j in 0..n {
            assert!((phi[j] - phi_full[j]).abs() < 1e-13, "entry {j}");
        }
    }

    #[test]
    fn coplanar_support_is_refused() {
        let d = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
        ];
        let w = [1.0; 5];
        let mut phi = [0.0; 5];
        let mut grad = [[0.0; 3]; 5];
        assert!(matches!(
            rk_row(&d, &w, &w, 1.0, &mut phi, &mut grad),
            Err(KernelError::Singular { .. })
        ));
    }
}
