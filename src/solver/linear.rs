//! Sparse symmetric positive-definite linear solvers behind one interface: faer's supernodal
//! Cholesky (symbolic analysis once per pattern, numeric factorisation per call),
//! Jacobi-preconditioned conjugate gradients, and conjugate gradients preconditioned by
//! smoothed-aggregation multigrid (whose hierarchy is reused across Newton iterations and
//! steps while it stays effective).

use super::amg::{Amg, AmgError, AmgInfo};
use super::ordering::{nested_dissection, FillOrdering};
use super::pcg::{pcg, symmetric_multiply, PcgFailure, PcgOperators, PcgWork};
use crate::assembly::Assembly;
use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltError as DenseLltError;
use faer::matrix_free::conjugate_gradient::{
    conjugate_gradient, conjugate_gradient_scratch, CgParams,
};
use faer::matrix_free::InitialGuessStatus;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::{Conj, MatMut, MatRef, Par, Side};
use nalgebra::Vector3;
use std::time::Instant;

/// Which linear solver a Newton iteration uses.
#[derive(Clone, Copy, Debug, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LinearSolverKind {
    /// Sparse Cholesky LLᵀ with fill-reducing (AMD) ordering.
    Cholesky,
    /// Conjugate gradients with a Jacobi (diagonal) preconditioner.
    Cg,
    /// Conjugate gradients preconditioned by one V-cycle of smoothed-aggregation algebraic
    /// multigrid ([`super::amg`]).
    Amg,
    /// Cholesky below [`AUTO_DIRECT_MAX_DOFS`] free dofs, multigrid-preconditioned CG above.
    Auto,
}

/// Largest free-dof count for which `Auto` picks the direct solver. Measured with
/// `icefem bench` on the corotated ice cube (backward-Euler steps, 2 cores): see the README's
/// benchmark section for the crossover.
pub const AUTO_DIRECT_MAX_DOFS: usize = 50_000;

/// A multigrid-preconditioned CG solve is re-set-up on the next Newton refresh when it needed
/// more than `REFRESH_GROWTH` × (iterations of the first solve after the last set-up) +
/// [`REFRESH_SLACK`] iterations.
pub const REFRESH_GROWTH: f64 = 1.5;
/// Absolute slack of the refresh test, so that a change of one or two iterations at small
/// counts does not trigger a set-up.
pub const REFRESH_SLACK: usize = 2;

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
}

impl LinearError {
    /// Whether the failure says the matrix is not positive definite (so Newton may switch to
    /// the projected Hessian), whichever solver found it.
    pub fn is_indefinite(&self) -> bool {
        matches!(
            self,
            LinearError::NotPositiveDefinite { .. }
                | LinearError::NegativeCurvature { .. }
                | LinearError::Amg(AmgError::CoarseNotPositiveDefinite { .. })
        )
    }
}

/// Time and work of one linear solve.
#[derive(Clone, Copy, Debug, Default)]
pub struct LinearStats {
    /// Solve time (s).
    pub t_solve: f64,
    /// Iterations (1 for a direct solve).
    pub iterations: usize,
}

/// A linear solver bound to one sparsity pattern.
// One instance per simulation: the size difference between the variants does not matter.
#[allow(clippy::large_enum_variant)]
pub enum LinearSolver {
    /// Cholesky with its symbolic analysis, factor storage and workspace kept between calls.
    Cholesky {
        symbolic: SymbolicCholesky<usize>,
        l_values: Vec<f64>,
        work: MemBuffer,
        t_symbolic: f64,
        /// Whether nested dissection (rather than AMD) ordered the factor.
        nested_dissection: bool,
        /// The matrix values the current factor was computed from (empty before the first).
        factored: Vec<f64>,
    },
    /// Preconditioned CG.
    Cg {
        tolerance: f64,
        max_iterations: usize,
        inv_diag: Vec<f64>,
        work: MemBuffer,
    },
    /// Multigrid-preconditioned CG.
    Amg(Box<AmgSolver>),
}

/// CG preconditioned by a smoothed-aggregation hierarchy that is kept across Newton iterations
/// and steps: within a run the matrix changes slowly, and a hierarchy built for an earlier
/// matrix is still a good (symmetric positive-definite) preconditioner for the current one.
/// It is rebuilt on the next [`LinearSolver::factorize`] once a solve needed more than
/// [`REFRESH_GROWTH`] times the iterations of the first solve after the last set-up.
pub struct AmgSolver {
    amg: Amg,
    tolerance: f64,
    max_iterations: usize,
    /// Keep the hierarchy between refreshes (false: set up at every factorisation).
    reuse: bool,
    /// Iterations of the first solve after the last set-up.
    baseline: Option<usize>,
    /// A set-up is due at the next factorisation.
    refresh_due: bool,
    /// The matrix changed since the last set-up.
    stale: bool,
    work: PcgWork,
    /// Set-ups so far.
    setups: usize,
    /// Set-up time so far (s).
    t_setup: f64,
    /// Iterations and time (s) of every solve so far, for statistics.
    history: Vec<(usize, f64)>,
}

impl AmgSolver {
    /// Builds the hierarchy for these values.
    fn setup(&mut self, assembly: &Assembly, values: &[f64]) -> Result<f64, LinearError> {
        let start = Instant::now();
        self.amg.setup(assembly, values)?;
        self.baseline = None;
        self.refresh_due = false;
        self.stale = false;
        self.setups += 1;
        let t = start.elapsed().as_secs_f64();
        self.t_setup += t;
        Ok(t)
    }

    /// One PCG solve; a stale hierarchy that lets it fail is rebuilt once and the solve
    /// repeated.
    fn solve(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
        b: &[f64],
        x: &mut [f64],
    ) -> Result<usize, LinearError> {
        let n = b.len();
        loop {
            let mut ops = AmgOperators {
                amg: &mut self.amg,
                assembly,
                values,
            };
            let result = pcg(
                &mut ops,
                b,
                x,
                self.tolerance,
                self.max_iterations,
                &mut self.work,
            );
            match result {
                Ok(iterations) => {
                    match self.baseline {
                        None => self.baseline = Some(iterations),
                        Some(base) => {
                            if iterations as f64 > REFRESH_GROWTH * base as f64 + REFRESH_SLACK as f64 {
                                self.refresh_due = true;
                            }
                        }
                    }
                    return Ok(iterations);
                }
                Err(PcgFailure::NegativeCurvature { iteration }) => {
                    return Err(LinearError::NegativeCurvature { iteration, n })
                }
                Err(_) if self.stale => {
                    self.setup(assembly, values)?;
                }
                Err(PcgFailure::NoConvergence { residual }) => {
                    return Err(LinearError::CgNotConverged {
                        iterations: self.max_iterations,
                        residual,
                    })
                }
                Err(PcgFailure::Breakdown { iteration }) => {
                    return Err(LinearError::Faer(format!(
                        "the multigrid preconditioner lost positive definiteness at CG iteration {iteration}"
                    )))
                }
            }
        }
    }
}

/// What multigrid-preconditioned CG has done so far.
#[derive(Clone, Debug)]
pub struct AmgStats<'a> {
    /// The current hierarchy.
    pub hierarchy: AmgInfo,
    /// Set-ups so far.
    pub setups: usize,
    /// Their total time (s).
    pub t_setup: f64,
    /// Iterations and time (s) of every solve so far.
    pub solves: &'a [(usize, f64)],
}

/// The current matrix (CSC, parallel product) and the hierarchy as PCG's operators.
struct AmgOperators<'a> {
    amg: &'a mut Amg,
    assembly: &'a Assembly,
    values: &'a [f64],
}

impl PcgOperators for AmgOperators<'_> {
    fn apply(&mut self, x: &[f64], y: &mut [f64]) {
        symmetric_multiply(self.assembly, self.values, x, y);
    }
    fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        self.amg.apply(r, z);
    }
}

impl LinearSolver {
    /// Prepares a solver for the pattern of `assembly`: the symbolic analysis for Cholesky (done
    /// here once, reused by every [`LinearSolver::solve`]), the workspace for CG.
    ///
    /// `coords` are the rest positions of the mesh nodes (m), from which multigrid builds the
    /// rigid-body modes; `amg_reuse` keeps its hierarchy between refreshes.
    pub fn new(
        kind: LinearSolverKind,
        ordering: FillOrdering,
        assembly: &Assembly,
        coords: &[Vector3<f64>],
        cg_tolerance: f64,
        cg_max_iterations: usize,
        amg_reuse: bool,
    ) -> Result<Self, LinearError> {
        let n = assembly.dofs().num_free();
        match kind.resolve(n) {
            LinearSolverKind::Amg | LinearSolverKind::Auto => {
                Ok(LinearSolver::Amg(Box::new(AmgSolver {
                    amg: Amg::new(coords),
                    tolerance: cg_tolerance,
                    max_iterations: cg_max_iterations,
                    reuse: amg_reuse,
                    baseline: None,
                    refresh_due: false,
                    stale: false,
                    work: PcgWork::new(n),
                    setups: 0,
                    t_setup: 0.0,
                    history: Vec::new(),
                })))
            }
            LinearSolverKind::Cholesky => {
                let start = Instant::now();
                let permutation = if ordering.uses_metis(n) {
                    nested_dissection(assembly)
                } else {
                    None
                };
                let nested_dissection = permutation.is_some();
                let faer_ordering = match &permutation {
                    Some((forward, inverse)) => {
                        SymmetricOrdering::Custom(PermRef::new_checked(forward, inverse, n))
                    }
                    None => SymmetricOrdering::Amd,
                };
                let symbolic = factorize_symbolic_cholesky(
                    assembly.symbolic(),
                    Side::Lower,
                    faer_ordering,
                    Default::default(),
                )
                .map_err(|e| LinearError::Faer(format!("{e:?}")))?;
                let req = symbolic
                    .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
                    .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
                let work =
                    MemBuffer::try_new(req).map_err(|e| LinearError::Faer(format!("{e:?}")))?;
                let l_values = vec![0.0; symbolic.len_val()];
                Ok(LinearSolver::Cholesky {
                    symbolic,
                    l_values,
                    work,
                    t_symbolic: start.elapsed().as_secs_f64(),
                    nested_dissection,
                    factored: Vec::new(),
                })
            }
            LinearSolverKind::Cg => {
                let req = conjugate_gradient_scratch::<f64>(
                    Diag::<f64>::zeros(n).as_ref(),
                    assembly.matrix(&vec![0.0; assembly.nnz()]),
                    1,
                    Par::Seq,
                );
                let work =
                    MemBuffer::try_new(req).map_err(|e| LinearError::Faer(format!("{e:?}")))?;
                Ok(LinearSolver::Cg {
                    tolerance: cg_tolerance,
                    max_iterations: cg_max_iterations,
                    inv_diag: vec![0.0; n],
                    work,
                })
            }
        }
    }

    /// Time of the symbolic analysis (s), zero for CG.
    pub fn symbolic_time(&self) -> f64 {
        match self {
            LinearSolver::Cholesky { t_symbolic, .. } => *t_symbolic,
            LinearSolver::Cg { .. } | LinearSolver::Amg(_) => 0.0,
        }
    }

    /// The solver in use (`Auto` resolved).
    pub fn kind(&self) -> LinearSolverKind {
        match self {
            LinearSolver::Cholesky { .. } => LinearSolverKind::Cholesky,
            LinearSolver::Cg { .. } => LinearSolverKind::Cg,
            LinearSolver::Amg(_) => LinearSolverKind::Amg,
        }
    }

    /// Multigrid statistics (`None` for the other solvers).
    pub fn amg_stats(&self) -> Option<AmgStats<'_>> {
        match self {
            LinearSolver::Amg(s) => Some(AmgStats {
                hierarchy: s.amg.info(),
                setups: s.setups,
                t_setup: s.t_setup,
                solves: &s.history,
            }),
            _ => None,
        }
    }

    /// Whether the Cholesky factor was ordered by nested dissection.
    pub fn uses_nested_dissection(&self) -> bool {
        matches!(
            self,
            LinearSolver::Cholesky {
                nested_dissection: true,
                ..
            }
        )
    }

    /// Number of nonzeros of the Cholesky factor, if direct.
    pub fn factor_nnz(&self) -> Option<usize> {
        match self {
            LinearSolver::Cholesky { l_values, .. } => Some(l_values.len()),
            LinearSolver::Cg { .. } | LinearSolver::Amg(_) => None,
        }
    }

    /// Prepares solves with the matrix of `assembly`'s pattern and these values: the numeric
    /// Cholesky factorisation, the Jacobi preconditioner for CG, or the multigrid set-up.
    /// Returns its time (s), or `None` when nothing was computed: the values are bit for bit
    /// those of the current factor (a linear model at a fixed step has the same matrix every
    /// step), or the multigrid hierarchy of an earlier matrix is kept.
    pub fn factorize(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
    ) -> Result<Option<f64>, LinearError> {
        let start = Instant::now();
        match self {
            LinearSolver::Cholesky {
                symbolic,
                l_values,
                work,
                factored,
                ..
            } => {
                let same = factored.len() == values.len()
                    && factored
                        .iter()
                        .zip(values)
                        .all(|(a, b)| a.to_bits() == b.to_bits());
                if same {
                    return Ok(None);
                }
                let n = symbolic.nrows();
                // Forget the old values first: a failed factorisation leaves `l_values` invalid.
                factored.clear();
                symbolic
                    .factorize_numeric_llt::<f64>(
                        l_values,
                        assembly.matrix(values),
                        Side::Lower,
                        Default::default(),
                        Par::Seq,
                        MemStack::new(work),
                        Default::default(),
                    )
                    .map_err(|e| match e {
                        DenseLltError::NonPositivePivot { index } => {
                            LinearError::NotPositiveDefinite { pivot: index, n }
                        }
                    })?;
                factored.extend_from_slice(values);
            }
            LinearSolver::Cg { inv_diag, .. } => jacobi_inverse(assembly, values, inv_diag),
            LinearSolver::Amg(s) => {
                if s.amg.is_built() && s.reuse && !s.refresh_due {
                    s.stale = true;
                    return Ok(None);
                }
                s.setup(assembly, values)?;
            }
        }
        Ok(Some(start.elapsed().as_secs_f64()))
    }

    /// Solves `A x = b` with the matrix last passed to [`LinearSolver::factorize`]: `values`
    /// must still hold it (CG multiplies by it; Cholesky uses its factor). `x` is overwritten.
    pub fn solve(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
        b: &[f64],
        x: &mut [f64],
    ) -> Result<LinearStats, LinearError> {
        let n = b.len();
        let start = Instant::now();
        match self {
            LinearSolver::Cholesky {
                symbolic,
                l_values,
                work,
                ..
            } => {
                x.copy_from_slice(b);
                LltRef::new(symbolic, l_values).solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(x, n, 1),
                    Par::Seq,
                    MemStack::new(work),
                );
                Ok(LinearStats {
                    t_solve: start.elapsed().as_secs_f64(),
                    iterations: 1,
                })
            }
            LinearSolver::Cg {
                tolerance,
                max_iterations,
                inv_diag,
                work,
            } => {
                x.fill(0.0);
                // faer 0.24.4 mis-handles `InitialGuessStatus::Zero`; a zeroed x with
                // `MaybeNonZero` is equivalent and works.
                let params = CgParams {
                    initial_guess: InitialGuessStatus::MaybeNonZero,
                    abs_tolerance: 0.0,
                    rel_tolerance: *tolerance,
                    max_iters: *max_iterations,
                    ..Default::default()
                };
                let info = conjugate_gradient(
                    MatMut::from_column_major_slice_mut(x, n, 1),
                    faer::diag::DiagRef::from_slice(inv_diag),
                    assembly.matrix(values),
                    MatRef::from_column_major_slice(b, n, 1),
                    params,
                    |_| {},
                    Par::Seq,
                    MemStack::new(work),
                );
                let t_solve = start.elapsed().as_secs_f64();
                match info {
                    Ok(info) => Ok(LinearStats {
                        t_solve,
                        iterations: info.iter_count,
                    }),
                    Err(faer::matrix_free::conjugate_gradient::CgError::NoConvergence {
                        rel_residual,
                        ..
                    }) => Err(LinearError::CgNotConverged {
                        iterations: *max_iterations,
                        residual: rel_residual,
                    }),
                    Err(e) => Err(LinearError::Faer(format!("{e:?}"))),
                }
            }
            LinearSolver::Amg(s) => {
                let iterations = s.solve(assembly, values, b, x)?;
                let t_solve = start.elapsed().as_secs_f64();
                s.history.push((iterations, t_solve));
                Ok(LinearStats {
                    t_solve,
                    iterations,
                })
            }
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
