//! Plasticity by return mapping (O'Brien et al. 2002, the paper's eqs. (3)–(5); see
//! docs/numerics.md#plasticity).
//!
//! With the elastic strain ε_e = ε − ε_p − ε_exp of an element and its deviatoric part
//! ε' = ε_e − tr(ε_e)/3 I, an element whose ‖ε'‖ (Frobenius) exceeds the elastic limit γ moves
//! the excess into its plastic strain: Δε_p = (‖ε'‖ − γ)/‖ε'‖ ε'. Afterwards ‖ε'‖ = γ: the
//! element stays on the yield surface. The transition is smoothed over ±δγ
//! (`fem::YIELD_SMOOTHING`): between (1 − δ)γ and (1 + δ)γ the deviatoric response softens
//! reversibly to the yield stress, and the plastic strain takes the excess beyond (1 + δ)γ. Only the deviatoric part yields, so the volumetric
//! freezing expansion never becomes plastic.
//!
//! The mapping is part of the step's solve: each element's energy is the incremental
//! potential of the mapping from the plastic strain of the step's start
//! (`fem::solid_response`), a convex energy whose Hessian is the consistent tangent, so the
//! solve converges to displacements whose stress is the returned one. After the step,
//! [`crate::physics::Elasticity::update_inelastic_strain`] stores the mapped plastic strain for the next step. Every element
//! containing ice yields, a partly frozen one at its ice's share of the yield stress (see
//! `Elasticity::law_of`); water does not.
//!
//! An optional cap bounds ‖ε_p‖ (O'Brien's plastic limit; not in the paper). An element at
//! the cap is elastic from then on, so its stress is no longer bounded by the yield stress.
//!
//! In the corotated model the plastic strain is the logarithm of the natural shape's
//! deviatoric stretch (`fem::StrainOffset`) and the mapping adds the increment
//! found in the element's frame: exact to first order in the increment, so the next step's
//! trial stress at the same displacements is the returned stress to that order.

use crate::fem::YIELD_SMOOTHING;
use nalgebra::Matrix3;

/// Plasticity parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plasticity {
    /// Elastic limit γ: largest deviatoric elastic strain norm (dimensionless).
    pub elastic_limit: f64,
    /// Largest plastic strain norm ‖ε_p‖, if capped (dimensionless).
    pub cap: Option<f64>,
}

impl Plasticity {
    /// The plastic strain after mapping an element with elastic strain `elastic` and plastic
    /// strain `plastic` back onto the yield surface.
    pub fn return_map(&self, elastic: &Matrix3<f64>, plastic: &Matrix3<f64>) -> Matrix3<f64> {
        let deviator = elastic - Matrix3::identity() * (elastic.trace() / 3.0);
        let norm = deviator.norm();
        // The elastic strain the element keeps: up to the end of the yield transition, where
        // the law's stress reaches the yield stress, so that the law at the updated state
        // gives exactly the stress the solve converged to.
        let kept = (1.0 + YIELD_SMOOTHING) * self.elastic_limit;
        if norm <= kept {
            return *plastic;
        }
        // Symmetrise against round-off so ε_p stays a symmetric tensor.
        let delta = (norm - kept) / norm * deviator;
        let mut updated = plastic + 0.5 * (delta + delta.transpose());
        if let Some(cap) = self.cap {
            let n = updated.norm();
            if n > cap {
                updated *= cap / n;
            }
        }
        updated
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn return_map_lands_on_the_yield_surface_and_ignores_volume() {
        let p = Plasticity {
            elastic_limit: 1e-3,
            cap: None,
        };
        let strain = Matrix3::new(3e-3, 1e-3, 0.0, 1e-3, -1e-3, 0.0, 0.0, 0.0, 5e-4);
        let plastic = p.return_map(&strain, &Matrix3::zeros());
        let remaining = strain - plastic;
        let dev = remaining - Matrix3::identity() * (remaining.trace() / 3.0);
        // It keeps the deviatoric strain at the end of the yield transition, (1 + δ)γ.
        assert!((dev.norm() - (1.0 + crate::fem::YIELD_SMOOTHING) * 1e-3).abs() < 1e-18);
        assert!(plastic.trace().abs() < 1e-18 && plastic == plastic.transpose());
        // Pure volume change never yields, however large.
        assert_eq!(
            p.return_map(&(Matrix3::identity() * 0.1), &plastic),
            plastic
        );
        // The cap bounds the plastic strain.
        let capped = Plasticity {
            elastic_limit: 1e-3,
            cap: Some(1e-3),
        };
        let big = capped.return_map(&(strain * 10.0), &Matrix3::zeros());
        assert!((big.norm() - 1e-3).abs() < 1e-15);
    }
}
