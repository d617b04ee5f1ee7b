//! What every linear method reports: its failures and the statistics of one solve.

use crate::solver::amg::AmgError;

/// Failures of the linear solve.
#[derive(Debug, thiserror::Error)]
pub enum LinearError {
    /// The matrix is not positive definite: a rigid-body mode is unconstrained, or a part of
    /// the mesh is detached.
    #[error(
        "the system matrix is not positive definite (pivot {pivot} of {n}): the body has an \
         unconstrained rigid-body mode (add Dirichlet conditions) or a part of the mesh is detached"
    )]
    NotPositiveDefinite { pivot: usize, n: usize },
    /// A symmetric factorisation (a distributed run's) found `count` negative or zero
    /// eigenvalues: the matrix is not positive definite.
    #[error("the system matrix is not positive definite ({count} negative or zero eigenvalues of a {n}-dof system)")]
    NonPositiveEigenvalues { count: usize, n: usize },
    /// CG met a direction of non-positive curvature: the matrix is not positive definite.
    #[error("the system matrix is not positive definite (conjugate gradients found negative curvature at iteration {iteration} of a {n}-dof system)")]
    NegativeCurvature { iteration: usize, n: usize },
    /// The multigrid set-up failed.
    #[error("multigrid set-up failed: {0}")]
    Amg(#[from] AmgError),
    /// CG did not reach its tolerance.
    #[error("conjugate gradients did not converge: relative residual {residual:e} after {iterations} iterations")]
    CgNotConverged { iterations: usize, residual: f64 },
    /// Memory or other failure inside faer.
    #[error("sparse solver failure: {0}")]
    Faer(String),
    /// A failure of the distributed solver (PETSc), with its message.
    #[error("distributed linear solver: {0}")]
    External(String),
}

impl LinearError {
    /// Whether the failure says the matrix is not positive definite (so Newton may switch to
    /// the projected Hessian), whichever solver found it.
    pub fn is_indefinite(&self) -> bool {
        matches!(
            self,
            LinearError::NotPositiveDefinite { .. }
                | LinearError::NonPositiveEigenvalues { .. }
                | LinearError::NegativeCurvature { .. }
                | LinearError::Amg(AmgError::CoarseNotPositiveDefinite { .. })
        )
    }

    /// A failure inside faer (an allocation, usually), with its message.
    pub(super) fn faer(e: impl std::fmt::Debug) -> Self {
        LinearError::Faer(format!("{e:?}"))
    }
}

/// Time and work of one linear solve.
#[derive(Clone, Copy, Debug, Default)]
pub struct LinearStats {
    /// Solve time (s), without the set-ups below.
    pub t_solve: f64,
    /// Iterations (1 for a direct solve).
    pub iterations: usize,
    /// Factorisations or multigrid set-ups the solve had to do itself: a reused factor or
    /// hierarchy too stale to converge, or `auto`'s switch to Cholesky.
    pub setups: usize,
    /// Their time (s).
    pub t_setup: f64,
}

impl LinearStats {
    /// The stats of a solve that took `elapsed` seconds in all, `setup` of them (if any) in
    /// one set-up of its own.
    pub(super) fn with_setup(elapsed: f64, iterations: usize, setup: Option<f64>) -> Self {
        let t_setup = setup.unwrap_or(0.0);
        LinearStats {
            t_solve: elapsed - t_setup,
            iterations,
            setups: usize::from(setup.is_some()),
            t_setup,
        }
    }
}
