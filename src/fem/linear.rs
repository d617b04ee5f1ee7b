//! The small-strain (`linear`) law.
#![allow(non_snake_case)]

use super::tensor::Tangent;

/// dP/dF of the small-strain law with Lamé constants `lambda`, `mu` (Pa): C acting on sym(dF).
pub(super) fn linear_tangent(mu: f64, lambda: f64) -> Tangent {
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
