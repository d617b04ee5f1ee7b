//! Sparse symmetric positive-definite linear solvers behind one interface, [`LinearSolver`]:
//! faer's supernodal Cholesky ([`cholesky`]: symbolic analysis once per pattern, numeric
//! factorisation per call), Cholesky whose factor is kept as the preconditioner of CG
//! ([`kept_factor`]), Jacobi-preconditioned conjugate gradients ([`cg`]), and conjugate
//! gradients preconditioned by smoothed-aggregation multigrid ([`amg_cg`], whose hierarchy is
//! reused across Newton iterations and steps while it stays effective). When a kept factor or
//! hierarchy is rebuilt is decided in [`reuse`]; `Auto`'s switch from multigrid to Cholesky
//! is made here.
//!
//! Layers, each importing only those below it: [`settings`] and [`error`]; [`reuse`] and
//! `triangular`; [`cholesky`], [`cg`] and [`amg_cg`]; [`kept_factor`]; this dispatcher.

pub mod amg_cg;
pub mod cg;
pub mod cholesky;
pub mod error;
pub mod kept_factor;
pub mod reuse;
pub mod settings;
mod triangular;

pub use amg_cg::{AmgCg, AmgStats};
pub use cg::JacobiCg;
pub use cholesky::{Cholesky, PARALLEL_FACTOR_MIN_DOFS, TREE_SOLVE_MIN_DOFS};
pub use error::{LinearError, LinearStats};
pub use kept_factor::KeptFactor;
pub use reuse::{
    reuse_iteration_budget, FACTOR_REUSE_ITERATIONS_PER_DECADE, FORCING_LATER_MAX, FORCING_MAX,
    REFRESH_GROWTH, REFRESH_SLACK, STALE_ITERATION_CAP, STALE_PROBE_PERIOD,
};
pub use settings::{FactorPrecision, IterativeSettings, LinearSolverKind, AUTO_DIRECT_MAX_DOFS};

use super::ordering::FillOrdering;
use crate::assembly::Assembly;
use nalgebra::Vector3;
use std::time::Instant;

/// `Auto` switches from multigrid CG to Cholesky for good when a solve with a fresh hierarchy
/// needs more than this many iterations (on ice it needs 15–40 up to 1e6 dofs; a nearly
/// incompressible body such as unfrozen water needs hundreds) — if the system has at most
/// [`FALLBACK_DIRECT_MAX_DOFS`] free dofs.
pub const AMG_FALLBACK_ITERATIONS: usize = 200;
/// Largest system `Auto` hands to Cholesky when multigrid struggles: a nested-dissection
/// factor of 3e5 dofs holds ~2e8 entries (1.6 GB).
pub const FALLBACK_DIRECT_MAX_DOFS: usize = 300_000;

/// A linear solver that lives outside this crate's methods (PETSc across processes, see
/// `distributed`). Like a direct solver it solves with the matrix last given to
/// [`ExternalSolver::factorize`] until the next, so Newton may keep it for chord steps.
pub trait ExternalSolver {
    /// Takes the matrix with `values` on `assembly`'s pattern (this process's part of it, in
    /// a distributed run) and prepares its preconditioner.
    fn factorize(&mut self, assembly: &Assembly, values: &[f64]) -> Result<(), LinearError>;
    /// Solves with the matrix of the last [`ExternalSolver::factorize`]; `b` and `x` are
    /// the free dofs, whole on every process.
    fn solve(&mut self, b: &[f64], x: &mut [f64]) -> Result<LinearStats, LinearError>;
}

/// A linear solver bound to one sparsity pattern: one of the linear methods.
// One instance per simulation: the size difference between the variants does not matter.
#[allow(clippy::large_enum_variant)]
pub enum LinearSolver {
    /// Cholesky with its symbolic analysis, factor storage and workspace kept between calls.
    Cholesky(Cholesky),
    /// Cholesky whose factor is kept across refreshes as CG's preconditioner
    /// ([`IterativeSettings::factor_reuse`]).
    KeptFactor(Box<KeptFactor>),
    /// Jacobi-preconditioned CG.
    Cg(JacobiCg),
    /// Multigrid-preconditioned CG.
    Amg {
        /// The solver, with its hierarchy and statistics.
        solver: Box<AmgCg>,
        /// `Auto`'s Cholesky solver for when multigrid struggles (see
        /// [`AMG_FALLBACK_ITERATIONS`]).
        fallback: Option<DirectFallback>,
    },
    /// A solver outside this crate (PETSc in a distributed run).
    External(Box<dyn ExternalSolver>),
}

/// The Cholesky solver `Auto` switches to when multigrid struggles: its ordering and
/// settings (with or without a kept factor).
#[derive(Clone, Copy, Debug)]
pub struct DirectFallback {
    ordering: FillOrdering,
    iterative: IterativeSettings,
}

impl LinearSolver {
    /// Prepares a solver for the pattern of `assembly`: the symbolic analysis for Cholesky (done
    /// here once, reused by every [`LinearSolver::solve`]), the workspace for CG.
    ///
    /// `coords` are the rest positions of the mesh nodes (m), from which multigrid builds the
    /// rigid-body modes.
    pub fn new(
        kind: LinearSolverKind,
        ordering: FillOrdering,
        assembly: &Assembly,
        coords: &[Vector3<f64>],
        iterative: &IterativeSettings,
    ) -> Result<Self, LinearError> {
        let n = assembly.dofs().num_free();
        match kind.resolve(n) {
            LinearSolverKind::Amg | LinearSolverKind::Auto => {
                let fallback = (kind == LinearSolverKind::Auto && n <= FALLBACK_DIRECT_MAX_DOFS)
                    .then_some(DirectFallback {
                        ordering,
                        iterative: *iterative,
                    });
                let fresh_cap = match fallback {
                    Some(_) => iterative.max_iterations.min(AMG_FALLBACK_ITERATIONS),
                    None => iterative.max_iterations,
                };
                Ok(LinearSolver::Amg {
                    solver: Box::new(AmgCg::new(coords, n, iterative, fresh_cap)),
                    fallback,
                })
            }
            // PETSc's solver is made by a distributed run itself (`ExternalSolver`); asked
            // for here, on one process, the direct solver stands in for it.
            LinearSolverKind::Cholesky | LinearSolverKind::Petsc => {
                LinearSolver::direct(ordering, assembly, iterative)
            }
            LinearSolverKind::Cg => Ok(LinearSolver::Cg(JacobiCg::new(n, iterative))),
        }
    }

    /// A Cholesky solver, keeping its factor as CG's preconditioner if `iterative` says so.
    fn direct(
        ordering: FillOrdering,
        assembly: &Assembly,
        iterative: &IterativeSettings,
    ) -> Result<Self, LinearError> {
        let cholesky = Cholesky::new(ordering, assembly)?;
        Ok(if iterative.factor_reuse {
            let n = assembly.dofs().num_free();
            LinearSolver::KeptFactor(Box::new(KeptFactor::new(cholesky, iterative, n)))
        } else {
            LinearSolver::Cholesky(cholesky)
        })
    }

    /// The Cholesky factorisation, kept or not (`None` for the iterative solvers).
    fn cholesky(&self) -> Option<&Cholesky> {
        match self {
            LinearSolver::Cholesky(c) => Some(c),
            LinearSolver::KeptFactor(k) => Some(k.direct()),
            LinearSolver::Cg(_) | LinearSolver::Amg { .. } | LinearSolver::External(_) => None,
        }
    }

    /// Time of the symbolic analysis (s), zero for CG.
    pub fn symbolic_time(&self) -> f64 {
        self.cholesky().map_or(0.0, Cholesky::symbolic_time)
    }

    /// The solver in use (`Auto` resolved).
    pub fn kind(&self) -> LinearSolverKind {
        match self {
            LinearSolver::Cholesky(_) | LinearSolver::KeptFactor(_) => LinearSolverKind::Cholesky,
            LinearSolver::Cg(_) => LinearSolverKind::Cg,
            LinearSolver::Amg { .. } => LinearSolverKind::Amg,
            LinearSolver::External(_) => LinearSolverKind::Petsc,
        }
    }

    /// Multigrid statistics (`None` for the other solvers).
    pub fn amg_stats(&self) -> Option<AmgStats<'_>> {
        match self {
            LinearSolver::Amg { solver, .. } => Some(solver.stats()),
            _ => None,
        }
    }

    /// Whether the Cholesky factor was ordered by nested dissection.
    pub fn uses_nested_dissection(&self) -> bool {
        self.cholesky()
            .is_some_and(Cholesky::uses_nested_dissection)
    }

    /// Precision of a Cholesky factor kept as CG's preconditioner (`None` without
    /// `factor_reuse`, or for the iterative solvers): where single precision failed, `Double`.
    pub fn factor_precision(&self) -> Option<FactorPrecision> {
        match self {
            LinearSolver::KeptFactor(k) => Some(k.precision()),
            _ => None,
        }
    }

    /// Number of nonzeros of the Cholesky factor, if direct.
    pub fn factor_nnz(&self) -> Option<usize> {
        self.cholesky().map(Cholesky::factor_nnz)
    }

    /// A new Newton solve begins (a time step, or a re-solve with updated friction): a reused
    /// factor is one solve older (see [`STALE_PROBE_PERIOD`]).
    pub fn start_newton_solve(&mut self) {
        if let LinearSolver::KeptFactor(k) = self {
            k.start_newton_solve();
        }
    }

    /// Sets the relative residual ‖b − A x‖ / ‖b‖ the next solves need (Newton's forcing term),
    /// clamped to [`IterativeSettings::tolerance`, [`FORCING_MAX`]] for a first solve (η = ∞)
    /// and to [`IterativeSettings::tolerance`, [`FORCING_LATER_MAX`]] after. Only solves
    /// with a kept factor use it: a fresh double-precision factor solves exactly at no extra
    /// cost, and the multigrid and Jacobi solvers keep their tolerance (their iteration counts
    /// are what the benchmarks compare with pyamg).
    pub fn set_forcing(&mut self, eta: f64) {
        if let LinearSolver::KeptFactor(k) = self {
            k.set_forcing(eta);
        }
    }

    /// Whether this is a plain direct solver: a solve uses the factor only, so a factor kept
    /// from an earlier matrix solves with that matrix (a chord step).
    pub fn is_direct(&self) -> bool {
        matches!(self, LinearSolver::Cholesky(_) | LinearSolver::External(_))
    }

    /// Whether [`LinearSolver::solve`] works with the matrix values themselves (CG and the
    /// multigrid, and CG preconditioned by a kept factor) rather than with a factor only (a
    /// plain direct solve): only then does a change of the values in place reach the solves.
    pub fn iterates_on_matrix(&self) -> bool {
        match self {
            LinearSolver::Cholesky(_) | LinearSolver::External(_) => false,
            LinearSolver::KeptFactor(_) | LinearSolver::Cg(_) => true,
            LinearSolver::Amg { solver, .. } => solver.reuses(),
        }
    }

    /// The matrix values changed in place since [`LinearSolver::factorize`] (a chord
    /// iteration's contact update; see [`LinearSolver::iterates_on_matrix`]): a kept factor
    /// or hierarchy is now merely a preconditioner of them, Jacobi's diagonal is recomputed.
    pub fn matrix_changed(&mut self, assembly: &Assembly, values: &[f64]) {
        match self {
            LinearSolver::Cholesky(_) | LinearSolver::External(_) => {}
            LinearSolver::KeptFactor(k) => k.matrix_changed(),
            LinearSolver::Cg(cg) => cg.factorize(assembly, values),
            LinearSolver::Amg { solver, .. } => solver.matrix_changed(),
        }
    }

    /// Prepares solves with the matrix of `assembly`'s pattern and these values: the numeric
    /// Cholesky factorisation, the Jacobi preconditioner for CG, or the multigrid set-up.
    /// Returns its time (s), or `None` when nothing was computed: the values are bit for bit
    /// those of the current factor (a linear model at a fixed step has the same matrix every
    /// step), or a kept factor or multigrid hierarchy of an earlier matrix serves this one.
    pub fn factorize(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
    ) -> Result<Option<f64>, LinearError> {
        let start = Instant::now();
        let computed = match self {
            LinearSolver::Cholesky(c) => c.factorize(assembly, values)?,
            LinearSolver::KeptFactor(k) => k.factorize(assembly, values)?,
            LinearSolver::Cg(cg) => {
                cg.factorize(assembly, values);
                true
            }
            LinearSolver::Amg { solver, .. } => solver.factorize(assembly, values)?,
            LinearSolver::External(external) => {
                external.factorize(assembly, values)?;
                true
            }
        };
        Ok(computed.then(|| start.elapsed().as_secs_f64()))
    }

    /// Solves `A x = b` with the matrix last passed to [`LinearSolver::factorize`]: `values`
    /// must still hold it (CG multiplies by it; Cholesky uses its factor). `x` is overwritten.
    ///
    /// Under `Auto`, a multigrid solve that struggles (more than [`AMG_FALLBACK_ITERATIONS`],
    /// or a failure other than indefiniteness) replaces the solver by Cholesky for good, which
    /// then solves if multigrid failed.
    pub fn solve(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
        b: &[f64],
        x: &mut [f64],
    ) -> Result<LinearStats, LinearError> {
        let start = Instant::now();
        match self {
            LinearSolver::Cholesky(c) => Ok(c.solve(b, x)),
            LinearSolver::KeptFactor(k) => k.solve(assembly, values, b, x),
            LinearSolver::Cg(cg) => cg.solve(assembly, values, b, x),
            LinearSolver::External(external) => external.solve(b, x),
            LinearSolver::Amg { solver, fallback } => {
                let multigrid = solver.solve(assembly, values, b, x);
                let Some(direct) = fallback.filter(|_| multigrid_struggled(&multigrid)) else {
                    return multigrid;
                };
                let t_switch = self.fall_back_to_direct(direct, assembly, values)?;
                match multigrid {
                    // Multigrid's solution stands; the switch was this solve's set-up.
                    Ok(stats) => Ok(LinearStats::with_setup(
                        start.elapsed().as_secs_f64(),
                        stats.iterations,
                        Some(t_switch),
                    )),
                    Err(_) => {
                        let mut stats = self.solve(assembly, values, b, x)?;
                        stats.setups += 1;
                        stats.t_setup += t_switch;
                        stats.t_solve = start.elapsed().as_secs_f64() - stats.t_setup;
                        Ok(stats)
                    }
                }
            }
        }
    }

    /// `Auto`'s switch from multigrid to Cholesky, for good: the Cholesky solver `direct`
    /// factorises the matrix with `values` and replaces this one. Returns the time of the
    /// switch (s); on an error this solver is left as it was.
    fn fall_back_to_direct(
        &mut self,
        direct: DirectFallback,
        assembly: &Assembly,
        values: &[f64],
    ) -> Result<f64, LinearError> {
        let switching = Instant::now();
        let mut cholesky = LinearSolver::direct(direct.ordering, assembly, &direct.iterative)?;
        cholesky.factorize(assembly, values)?;
        let t_switch = switching.elapsed().as_secs_f64();
        *self = cholesky;
        Ok(t_switch)
    }
}

/// Whether a multigrid solve that gave `result` struggled: more than
/// [`AMG_FALLBACK_ITERATIONS`], or a failure that is not the matrix's indefiniteness (which
/// Cholesky would meet too).
fn multigrid_struggled(result: &Result<LinearStats, LinearError>) -> bool {
    match result {
        Ok(stats) => stats.iterations > AMG_FALLBACK_ITERATIONS,
        Err(e) => !e.is_indefinite(),
    }
}
