//! Tensor helpers: the 9 × 9 tangent type, Voigt notation, von Mises and principal values.

use nalgebra::{Matrix3, SMatrix};

/// 9 × 9 matrix: derivative of `vec(P)` with respect to `vec(F)` (Pa), `vec` column major.
pub type Tangent = SMatrix<f64, 9, 9>;

/// Symmetric tensor to Voigt order xx yy zz yz xz xy.
pub fn to_voigt(s: &Matrix3<f64>) -> [f64; 6] {
    [
        s[(0, 0)],
        s[(1, 1)],
        s[(2, 2)],
        s[(1, 2)],
        s[(0, 2)],
        s[(0, 1)],
    ]
}

/// Symmetric tensor from Voigt order xx yy zz yz xz xy (the inverse of [`to_voigt`]; the
/// off-diagonal entries are tensor components). `v` has 6 values.
pub fn from_voigt(v: &[f64]) -> Matrix3<f64> {
    Matrix3::new(v[0], v[5], v[4], v[5], v[1], v[3], v[4], v[3], v[2])
}

/// Von Mises equivalent of a symmetric tensor: √(3/2 s:s), s its deviator.
pub fn von_mises(s: &Matrix3<f64>) -> f64 {
    let d = s - Matrix3::identity() * (s.trace() / 3.0);
    (1.5 * d.norm_squared()).sqrt()
}

/// Largest eigenvalue of a symmetric tensor (for stress: the largest principal stress,
/// positive in tension).
pub fn max_principal(s: &Matrix3<f64>) -> f64 {
    s.symmetric_eigenvalues().max()
}
