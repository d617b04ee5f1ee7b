//! Strain offsets ε* (eigenstrain, expansion, plastic strain) and the corotated model's
//! offset factor A = F*⁻¹.
#![allow(non_snake_case)]

use nalgebra::Matrix3;

/// A strain offset ε* = e I + d (the expansion e and the plastic strain d, deviatoric) with
/// the corotated model's offset factor A = F*⁻¹ computed once, for F* = (1 + e) exp(d): ε* is
/// fixed during a solve, and A's matrix exponential would otherwise be the costliest part of
/// every element evaluation.
///
/// F* is the natural shape of the element: isotropic growth by 1 + e (the expansion, exact for
/// a free body) and the plastic shape change exp(d), which keeps volume exactly (det = e^tr d
/// = 1). With I + d instead, the natural volume would shrink by ½ tr(d²) at second order —
/// 1 % at ‖ε_p‖ = 0.14, a hydrostatic tension of K · 1 % ≈ 1e9 Pa that was pure artefact (and
/// read as fracture). A − I is formed from exp_m1, without cancellation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrainOffset {
    /// ε* (dimensionless): σ = C:(ε − ε*) in the linear model.
    pub strain: Matrix3<f64>,
    /// A − I.
    factor_minus_i: Matrix3<f64>,
}

impl StrainOffset {
    /// The offset ε* = `strain` (symmetric).
    pub fn new(strain: Matrix3<f64>) -> Self {
        let e = strain.trace() / 3.0;
        let d = strain - Matrix3::identity() * e;
        // A − I = (exp(−d) − I − e I) / (1 + e).
        let exp_m1 = if d.iter().all(|v| *v == 0.0) {
            Matrix3::zeros()
        } else {
            expm1_symmetric(&(-d))
        };
        StrainOffset {
            strain,
            factor_minus_i: (exp_m1 - Matrix3::identity() * e) / (1.0 + e),
        }
    }

    /// No offset.
    pub fn zero() -> Self {
        Self::new(Matrix3::zeros())
    }

    /// Whether ε* = 0.
    #[inline]
    pub fn is_zero(&self) -> bool {
        self.strain.iter().all(|v| *v == 0.0)
    }
}

/// The corotated model's offset factor A = F*⁻¹ of `offset` and the elastic displacement
/// gradient He = (I + H) A − I for the displacement gradient H, formed as H A + (A − I).
#[inline]
pub(super) fn offset_elastic_gradient(
    offset: &StrainOffset,
    H: &Matrix3<f64>,
) -> (Matrix3<f64>, Matrix3<f64>) {
    let a = Matrix3::identity() + offset.factor_minus_i;
    (a, H * a + offset.factor_minus_i)
}

/// exp(X) − I of a symmetric 3 × 3 matrix without cancellation, by scaling and squaring: X is
/// halved s times until ‖X/2ˢ‖_F ≤ 1/8, exp − I of that by its Taylor series to the degree m whose
/// truncation ‖Y‖ᵐ/(m + 1)! relative to ‖Y‖ is below 1e-17 (10 at 1/8, 4 at the 1e-4 strains of
/// ice), then squared back as E ← 2E + E² (the identity for exp(2Y) − I). A twentieth of the cost
/// of an eigendecomposition, which the corotated model's plastic offset needs for every element at
/// every solve; equal to it to round-off.
pub(super) fn expm1_symmetric(x: &Matrix3<f64>) -> Matrix3<f64> {
    let norm = x.norm();
    let halvings = if norm > 0.125 {
        (norm / 0.125).log2().ceil() as i32
    } else {
        0
    };
    let y = x * 0.5f64.powi(halvings);
    let y_norm = norm * 0.5f64.powi(halvings);
    let mut degree = 1;
    let mut truncation = y_norm / 2.0;
    while degree < 10 && truncation > 1e-17 {
        degree += 1;
        truncation *= y_norm / (degree + 1) as f64;
    }
    // Horner: Y (I + Y/2 (I + Y/3 (… (I + Y/m)))).
    let mut e = Matrix3::identity();
    for k in (2..=degree).rev() {
        e = Matrix3::identity() + y * e / k as f64;
    }
    e = y * e;
    for _ in 0..halvings {
        e = 2.0 * e + e * e;
    }
    0.5 * (e + e.transpose())
}
