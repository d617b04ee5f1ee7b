//! Conjugate gradients preconditioned by the inverse of the matrix's diagonal (Jacobi).

use super::error::{LinearError, LinearStats};
use super::settings::IterativeSettings;
use crate::assembly::Assembly;
use crate::solver::pcg::{pcg, MatrixOperators, PcgFailure, PcgWork, Preconditioner};
use std::time::Instant;

/// Jacobi-preconditioned CG.
pub struct JacobiCg {
    tolerance: f64,
    max_iterations: usize,
    /// Inverse of the current matrix's diagonal (zero where it is not positive).
    inv_diag: Vec<f64>,
    work: PcgWork,
}

impl JacobiCg {
    /// A solver for `n` free dofs with CG's tolerance and cap from `settings`.
    pub fn new(n: usize, settings: &IterativeSettings) -> Self {
        JacobiCg {
            tolerance: settings.tolerance,
            max_iterations: settings.max_iterations,
            inv_diag: vec![0.0; n],
            work: PcgWork::new(n),
        }
    }

    /// Prepares solves with the matrix of these values: the inverse of its diagonal.
    pub fn factorize(&mut self, assembly: &Assembly, values: &[f64]) {
        jacobi_inverse(assembly, values, &mut self.inv_diag);
    }

    /// Solves `A x = b` from x = 0 with the matrix `values` (the one last passed to
    /// [`JacobiCg::factorize`]). `x` is overwritten.
    pub fn solve(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
        b: &[f64],
        x: &mut [f64],
    ) -> Result<LinearStats, LinearError> {
        let start = Instant::now();
        let mut ops = MatrixOperators {
            assembly,
            values,
            preconditioner: Jacobi(&self.inv_diag),
        };
        match pcg(
            &mut ops,
            b,
            x,
            self.tolerance,
            self.max_iterations,
            None,
            &mut self.work,
        ) {
            Ok(iterations) => Ok(LinearStats {
                t_solve: start.elapsed().as_secs_f64(),
                iterations,
                ..Default::default()
            }),
            Err(PcgFailure::NoConvergence { residual, .. }) => Err(LinearError::CgNotConverged {
                iterations: self.max_iterations,
                residual,
            }),
            // Jacobi is positive definite exactly when the diagonal is positive: a breakdown,
            // like negative curvature, says the matrix is not.
            Err(
                PcgFailure::NegativeCurvature { iteration } | PcgFailure::Breakdown { iteration },
            ) => Err(LinearError::NegativeCurvature {
                iteration,
                n: b.len(),
            }),
        }
    }
}

/// The inverse of the matrix's diagonal as a preconditioner.
struct Jacobi<'a>(&'a [f64]);

impl Preconditioner for Jacobi<'_> {
    fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        for ((z, r), d) in z.iter_mut().zip(r).zip(self.0) {
            *z = r * d;
        }
    }
}

/// Inverse of the diagonal of the matrix (zero where the diagonal is not positive).
fn jacobi_inverse(assembly: &Assembly, values: &[f64], inv_diag: &mut [f64]) {
    let s = assembly.symbolic();
    for (c, d) in inv_diag.iter_mut().enumerate() {
        let range = s.col_range(c);
        let rows = s.row_idx_of_col_raw(c);
        let diag = rows
            .binary_search(&c)
            .map(|k| values[range.start + k])
            .unwrap_or(0.0);
        *d = if diag > 0.0 { 1.0 / diag } else { 0.0 };
    }
}
