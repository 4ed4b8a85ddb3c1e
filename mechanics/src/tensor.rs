//! Small tensor algebra of every solver, on nalgebra's fixed-size `Vector3` and `Matrix3`:
//! the conversions to and from the flat storage of the state arrays (`[f64; 3]`, row-major
//! `[[f64; 3]; 3]`; they compile to register moves), and the two operations nalgebra does not
//! offer in the arithmetic the kernels rely on: an inverse by the adjugate with a threshold on
//! the determinant, and Rodrigues' rotation by a rotation vector.
//!
//! nalgebra's `dot`, `cross`, `norm`, `determinant` and products of 3×3 matrices and vectors
//! sum their terms in the order the hand-written helpers they replace did (first index
//! first), so results are bit-identical. Its `try_inverse` divides each cofactor by the
//! determinant; [`inverse`] multiplies by its reciprocal, as the kernels always have.

pub use nalgebra::{Matrix3, Vector3};

/// A 3×3 matrix in the row-major flat storage of the state arrays (`m[row][column]`).
pub type Rows3 = [[f64; 3]; 3];

/// The identity in flat storage.
pub const IDENTITY: Rows3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// The matrix stored row-major in `m`.
#[inline(always)]
pub fn mat(m: &Rows3) -> Matrix3<f64> {
    // nalgebra's arrays of arrays are columns
    Matrix3::from(*m).transpose()
}

/// `m` in row-major flat storage.
#[inline(always)]
pub fn rows(m: &Matrix3<f64>) -> Rows3 {
    m.transpose().into()
}

/// The vector stored in `a`.
#[inline(always)]
pub fn vec3(a: &[f64; 3]) -> Vector3<f64> {
    Vector3::from(*a)
}

/// Inverse by the adjugate, `adj(m) · (1/det m)`; `None` when the determinant is not finite or
/// `|det m| ≤ tiny` (NaN included).
#[inline]
pub fn inverse(m: &Matrix3<f64>, tiny: f64) -> Option<Matrix3<f64>> {
    let d = m.determinant();
    if !(d.abs() > tiny && d.is_finite()) {
        return None;
    }
    let id = 1.0 / d;
    let a = |r: usize, c: usize| m[(r, c)];
    Some(Matrix3::new(
        (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) * id,
        (a(0, 2) * a(2, 1) - a(0, 1) * a(2, 2)) * id,
        (a(0, 1) * a(1, 2) - a(0, 2) * a(1, 1)) * id,
        (a(1, 2) * a(2, 0) - a(1, 0) * a(2, 2)) * id,
        (a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0)) * id,
        (a(0, 2) * a(1, 0) - a(0, 0) * a(1, 2)) * id,
        (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0)) * id,
        (a(0, 1) * a(2, 0) - a(0, 0) * a(2, 1)) * id,
        (a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0)) * id,
    ))
}

/// `v` rotated by the rotation vector `theta` (Rodrigues:
/// `v cos θ + (k × v) sin θ + k (k·v)(1 − cos θ)`, `k = theta/θ`); `v` itself below 1e-300 rad.
#[inline]
pub fn rotate(theta: &Vector3<f64>, v: &Vector3<f64>) -> Vector3<f64> {
    let a = theta.norm();
    if a < 1e-300 {
        return *v;
    }
    let k = theta.map(|c| c / a);
    let kv = k.cross(v);
    let kd = k.dot(v);
    let (s, c) = a.sin_cos();
    Vector3::from_fn(|d, _| v[d] * c + kv[d] * s + k[d] * kd * (1.0 - c))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Rows3 {
        [[2.0, -0.3, 0.7], [0.1, 1.5, -0.4], [0.25, 0.6, 3.0]]
    }

    /// Row-major storage round-trips, and `mat` reads rows as rows.
    #[test]
    fn flat_storage_round_trips_row_major() {
        let m = sample();
        let a = mat(&m);
        assert_eq!(a[(0, 1)], -0.3);
        assert_eq!(a[(2, 0)], 0.25);
        assert_eq!(rows(&a), m);
        assert_eq!(<[f64; 3]>::from(vec3(&[1.0, 2.0, 3.0])), [1.0, 2.0, 3.0]);
    }

    /// `m · inverse(m)` is the identity to round-off; a singular matrix and a NaN have none.
    #[test]
    fn inverse_by_adjugate() {
        let a = mat(&sample());
        let i = a * inverse(&a, 1e-300).expect("regular");
        let err = (i - Matrix3::identity()).abs().max();
        assert!(err < 1e-15, "{err:e}");
        let singular = Matrix3::new(1.0, 2.0, 3.0, 2.0, 4.0, 6.0, 0.0, 1.0, 1.0);
        assert!(inverse(&singular, 1e-300).is_none());
        assert!(inverse(&(a * f64::NAN), 1e-300).is_none());
        assert!(inverse(&(a * 1e-120), 1e-300).is_none());
    }

    /// A quarter turn about z takes x to y; a rotation keeps the length; a zero rotation is
    /// the identity.
    #[test]
    fn rodrigues_rotation() {
        let q = rotate(
            &Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2),
            &Vector3::x(),
        );
        assert!((q - Vector3::y()).norm() < 1e-15, "{q:?}");
        let v = Vector3::new(0.3, -1.2, 2.0);
        let r = rotate(&Vector3::new(0.4, 0.1, -0.7), &v);
        assert!((r.norm() - v.norm()).abs() < 1e-15);
        assert_eq!(rotate(&Vector3::zeros(), &v), v);
    }
}
