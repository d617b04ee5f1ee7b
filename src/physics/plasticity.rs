//! Plasticity by return mapping after each converged step (SPEC eq. 3–5, O'Brien et al. 2002).
//!
//! With the elastic strain ε_e = ε − ε_p − ε_exp of an element and its deviatoric part
//! ε' = ε_e − tr(ε_e)/3 I, an element whose ‖ε'‖ (Frobenius) exceeds the elastic limit γ moves
//! the excess into its plastic strain: Δε_p = (‖ε'‖ − γ)/‖ε'‖ ε'. Afterwards ‖ε'‖ = γ: the
//! element stays on the yield surface. An optional cap bounds ‖ε_p‖ (O'Brien's plastic limit).
//! Only the deviatoric part yields, so the volumetric freezing expansion never becomes
//! plastic; water and partly frozen elements do not yield.
//!
//! The step itself is solved with ε_p fixed (so it is a minimisation with an exact Jacobian);
//! the mapping then updates ε_p from the converged displacement.

use super::elasticity::Elasticity;
use super::history::ElementHistory;
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
        if norm <= self.elastic_limit {
            return *plastic;
        }
        // Symmetrise against round-off so ε_p stays a symmetric tensor.
        let delta = (norm - self.elastic_limit) / norm * deviator;
        let mut updated = plastic + 0.5 * (delta + delta.transpose());
        if let Some(cap) = self.cap {
            let n = updated.norm();
            if n > cap {
                updated *= cap / n;
            }
        }
        updated
    }

    /// Updates every fully frozen element's plastic strain in `history` for the converged
    /// displacements `u` (m); returns the largest ‖ε_p‖ afterwards.
    pub fn update(
        &self,
        elasticity: &Elasticity,
        history: &mut ElementHistory,
        tets: &[[usize; 4]],
        u: &[f64],
    ) -> f64 {
        use rayon::prelude::*;
        let n = tets.len();
        if history.plastic_strain.len() != n {
            history.plastic_strain = vec![Matrix3::zeros(); n];
        }
        let h = &*history;
        let updated: Vec<Matrix3<f64>> = (0..n)
            .into_par_iter()
            .map(|e| {
                if h.is_frozen(e) {
                    let elastic = elasticity.elastic_strain(tets, h, u, e);
                    self.return_map(&elastic, &h.plastic_strain[e])
                } else {
                    h.plastic_strain[e]
                }
            })
            .collect();
        let largest = updated.iter().map(|p| p.norm()).fold(0.0, f64::max);
        history.plastic_strain = updated;
        largest
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
        assert!((dev.norm() - 1e-3).abs() < 1e-18);
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
