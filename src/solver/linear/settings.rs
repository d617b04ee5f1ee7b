//! What the caller chooses: the linear method, the iterative solvers' settings and the
//! precision of a kept factorisation.

/// Which linear solver a Newton iteration uses.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LinearSolverKind {
    /// Sparse Cholesky LLᵀ with fill-reducing (AMD) ordering.
    Cholesky,
    /// Conjugate gradients with a Jacobi (diagonal) preconditioner.
    Cg,
    /// Conjugate gradients preconditioned by one V-cycle of smoothed-aggregation algebraic
    /// multigrid ([`crate::solver::amg`]).
    Amg,
    /// Cholesky below [`AUTO_DIRECT_MAX_DOFS`] free dofs, multigrid-preconditioned CG above.
    Auto,
    /// PETSc's solver of a distributed run (`distributed`): not chosen in a scene. A
    /// distributed run solves through PETSc whatever the scene says: by a factorisation
    /// where the scene's choice resolves to [`LinearSolverKind::Cholesky`], else by CG with
    /// algebraic multigrid.
    #[serde(skip)]
    Petsc,
}

/// Largest free-dof count for which `Auto` picks the direct solver. Measured with
/// `icefem bench --tets 10000,30000,60000,100000 --steps 3 --solver cholesky|amg` on the
/// corotated ice cube (backward Euler at 1/30 s, 2 cores, medians of 3 runs, 2026-12-01):
/// per step, Cholesky / multigrid CG took 0.073 / 0.087 s at 6.1e3 free dofs, 0.22 / 0.17 s at
/// 1.7e4, 0.74 / 0.42 s at 3.5e4 and 1.74 / 0.90 s at 5.7e4: on ice the crossover is near 1e4
/// dofs. Up to 2e4 dofs both take under 0.3 s a step, and there the direct solver's robustness
/// — nearly incompressible water, stiff contact penalties, indefinite tangents, E up to
/// 1e13 Pa, where multigrid needs hundreds of iterations — is worth more than the difference.
pub const AUTO_DIRECT_MAX_DOFS: usize = 20_000;

impl LinearSolverKind {
    /// The solver actually used for `n` free dofs (`Auto` resolved).
    pub fn resolve(self, n: usize) -> LinearSolverKind {
        match self {
            LinearSolverKind::Auto if n <= AUTO_DIRECT_MAX_DOFS => LinearSolverKind::Cholesky,
            LinearSolverKind::Auto => LinearSolverKind::Amg,
            other => other,
        }
    }
}

/// Settings of the iterative solvers and of the reuse of preconditioners.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IterativeSettings {
    /// Relative residual ‖b − A x‖ / ‖b‖ at which CG stops.
    pub tolerance: f64,
    /// CG iteration cap.
    pub max_iterations: usize,
    /// Multigrid: keep the hierarchy across Newton iterations and steps until the iterations
    /// grow (false: a set-up at every Hessian refresh).
    pub amg_reuse: bool,
    /// Cholesky: keep a factorisation across Hessian refreshes and steps, solving with CG
    /// preconditioned by it, until CG needs more than
    /// [`reuse_iteration_budget`](super::reuse::reuse_iteration_budget).
    pub factor_reuse: bool,
    /// Precision of that kept factorisation (ignored without `factor_reuse`).
    pub factor_precision: FactorPrecision,
}

/// Precision of a Cholesky factor kept as the preconditioner of CG (`factor_reuse`).
///
/// A preconditioner need not be exact, and single precision halves the bytes a triangular
/// solve reads and cuts the factorisation's time by a third (measured on the 1e5-tet freezing
/// container, 59 049 dofs, 4.6e7 entries in L, 2 cores: 0.70 instead of 1.05–1.1 s per
/// factorisation, 0.045 instead of 0.07 s per CG iteration with faer's one-thread solves,
/// with the same CG iteration counts).
/// CG itself runs in double precision on the exact matrix, so the solution is as accurate as
/// asked. Single precision can fail where the matrix is too ill-conditioned for 24-bit
/// mantissas (a non-positive pivot, or a fresh factor that cannot bring CG to the tolerance);
/// the solver then switches to double precision for good.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FactorPrecision {
    /// f32 factor, solves in f32 inside the f64 CG (default), double precision on failure.
    Single,
    /// f64 factor; a fresh one is used as a direct solver.
    Double,
}
