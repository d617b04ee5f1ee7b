//! The small-strain law (`model = "linear"`): ε = sym(H) − ε*, σ = C:ε.
#![allow(non_snake_case)]

use super::law::ElasticLaw;
use super::material::Material;
use super::offset::StrainOffset;
use super::response::{solid_response, Flow};
use super::tensor::Tangent;
use super::volume::VolumeChange;
use nalgebra::{Matrix3, SMatrix};

/// Small strain ε = sym(H) − ε* with H = F − I: linear, exact for small displacements, but a
/// rigid rotation produces spurious strain and forces. The strain offset ε* is subtracted,
/// σ = C:(sym H − ε*), and the element's frame is the world's (R = I).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Linear;

impl ElasticLaw for Linear {
    /// He = H − ε*, A = I.
    #[inline]
    fn elastic_gradient(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
    ) -> (Matrix3<f64>, Option<Matrix3<f64>>) {
        // σ = C:(sym H − ε*); the tangent does not depend on ε*.
        (H - offset.strain, None)
    }

    /// Ψ and σ of [`solid_response`] for ε = sym(He) (P = σ); the tangent is C acting on
    /// sym(dF), less flow_drop n⊗n while yielding.
    #[inline]
    fn solid(
        &self,
        mat: &Material,
        flow: Option<Flow>,
        He: &Matrix3<f64>,
        tangent: Option<&mut Tangent>,
        _project: bool,
    ) -> (f64, Matrix3<f64>) {
        let eps = 0.5 * (He + He.transpose());
        let response = solid_response(mat, flow, &eps);
        if let Some(t) = tangent {
            *t = linear_tangent(response.mu, response.lambda);
            if response.flow_drop != 0.0 {
                // − flow_drop n⊗n with n = ε'/‖ε'‖ (symmetric, so n : dF = n : sym(dF)).
                let dev = response.sigma - Matrix3::identity() * (response.sigma.trace() / 3.0);
                // A zero deviator (creep at rest) has no flow direction: nothing to drop.
                let dev = dev.try_normalize(0.0).unwrap_or_else(Matrix3::zeros);
                let n = SMatrix::<f64, 9, 1>::from_column_slice(dev.as_slice());
                *t -= response.flow_drop * n * n.transpose();
            }
        }
        (response.psi, response.sigma)
    }

    /// Ψ = K/2 tr(He)², P = K tr(He) I; the tangent K 1⊗1 is constant.
    #[inline]
    fn water(
        &self,
        bulk: f64,
        He: &Matrix3<f64>,
        tangent: Option<&mut Tangent>,
        _project: bool,
    ) -> (f64, Matrix3<f64>) {
        let tr = He.trace();
        if let Some(t) = tangent {
            for a in 0..3 {
                for b in 0..3 {
                    t[(a + 3 * a, b + 3 * b)] += bulk;
                }
            }
        }
        (0.5 * bulk * tr * tr, Matrix3::identity() * (bulk * tr))
    }

    /// θ = tr(H) − tr(ε*), linear in the displacements (no second derivative).
    #[inline]
    fn volume_change(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
        _with_hessian: bool,
    ) -> VolumeChange {
        VolumeChange {
            theta: H.trace() - offset.strain.trace(),
            gradient: Matrix3::identity(),
            deformation: None,
            offset_factor: Matrix3::identity(),
        }
    }

    /// ε = sym(H) − ε* in the world frame (R = I).
    #[inline]
    fn elastic_strain(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
    ) -> (Matrix3<f64>, Matrix3<f64>) {
        (
            0.5 * (H + H.transpose()) - offset.strain,
            Matrix3::identity(),
        )
    }

    /// tr(ε).
    #[inline]
    fn water_volume_change(
        &self,
        _H: &Matrix3<f64>,
        _offset: &StrainOffset,
        strain: &Matrix3<f64>,
    ) -> f64 {
        strain.trace()
    }

    /// G = I: fᵢ = −V σ ∇Nᵢ.
    #[inline]
    fn force_frame(&self, _rotation: &Matrix3<f64>, _offset: &StrainOffset) -> Matrix3<f64> {
        Matrix3::identity()
    }

    /// p I (∂θ/∂H = I).
    #[inline]
    fn pressure_stress(&self, _strain: &Matrix3<f64>, p: f64) -> Matrix3<f64> {
        Matrix3::identity() * p
    }

    /// C and K 1⊗1 do not depend on the deformation.
    #[inline]
    fn constant_tangent(&self) -> bool {
        true
    }
}

/// dP/dF of the small-strain law with Lamé constants `lambda`, `mu` (Pa): C acting on sym(dF).
#[inline]
fn linear_tangent(mu: f64, lambda: f64) -> Tangent {
    let mut t = Tangent::zeros();
    for a in 0..3 {
        for k in 0..3 {
            let row = a + 3 * k;
            // 2μ sym(dF): μ (dF_ak + dF_ka)
            t[(row, a + 3 * k)] += mu;
            t[(row, k + 3 * a)] += mu;
            if a == k {
                for b in 0..3 {
                    t[(row, b + 3 * b)] += lambda;
                }
            }
        }
    }
    t
}
