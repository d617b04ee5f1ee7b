//! The volume change of an element's elastic deformation, for the nodal volumetric energy.
#![allow(non_snake_case)]

use super::element::{add_stiffness, offset_grads, ElementEval, ElementRest};
use super::kinematics::add_det_hessian;
use super::tensor::Tangent;
use nalgebra::Matrix3;

/// The volume change θ of an element's elastic deformation and its derivatives, for the
/// averaged-nodal-pressure volumetric energy (`physics::volumetric`).
#[derive(Clone, Copy, Debug)]
pub struct VolumeChange {
    /// θ: tr(ε) − tr(ε*) (linear) or det Fe − 1 (corotated), dimensionless.
    pub theta: f64,
    /// ∂θ/∂F (3 × 3).
    pub gradient: Matrix3<f64>,
    /// The elastic deformation Fe = F A if the second derivative ∂²θ/∂Fe² = ∂² det Fe/∂Fe²
    /// was asked for (formed where it is used, from Fe: a 9 × 9 matrix per element would be
    /// 650 bytes to move); `None` also where θ is linear in the displacements (the linear
    /// model).
    pub deformation: Option<Matrix3<f64>>,
    /// The offset factor A of Fe = F A (identity without an offset or in the linear model).
    pub offset_factor: Matrix3<f64>,
}

impl VolumeChange {
    /// ∂θ/∂x for the 12 vertex coordinates of the element (1/m).
    pub fn nodal_gradient(&self, rest: &ElementRest) -> [f64; 12] {
        let mut g = [0.0; 12];
        for i in 0..4 {
            let gi = self.gradient * rest.grads[i];
            g[3 * i..3 * i + 3].copy_from_slice(gi.as_slice());
        }
        g
    }

    /// Adds the forces and stiffness of a pressure `p` (Pa) acting through θ on an element
    /// of rest volume V: gradient V p ∂θ/∂x and, if `hessian`, V p ∂²θ/∂x² (an indefinite
    /// matrix, left out by callers that need a positive semi-definite stiffness).
    pub fn add_pressure(&self, rest: &ElementRest, p: f64, out: &mut ElementEval, hessian: bool) {
        let v = rest.volume;
        for (o, g) in out.gradient.iter_mut().zip(self.nodal_gradient(rest)) {
            *o += v * p * g;
        }
        if let (true, Some(fe)) = (hessian, &self.deformation) {
            let mut t = Tangent::zeros();
            add_det_hessian(fe, 1.0, &mut t);
            let grads = offset_grads(&self.offset_factor, rest);
            add_stiffness(&grads, v * p, &t, &mut out.hessian);
        }
    }
}
