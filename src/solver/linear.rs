//! Sparse symmetric positive-definite linear solvers behind one interface: faer's supernodal
//! Cholesky (symbolic analysis once per pattern, numeric factorisation per call),
//! Jacobi-preconditioned conjugate gradients, and conjugate gradients preconditioned by
//! smoothed-aggregation multigrid (whose hierarchy is reused across Newton iterations and
//! steps while it stays effective).

use super::amg::{Amg, AmgError, AmgInfo};
use super::low_rank::LowRankCorrection;
use super::ordering::{nested_dissection, FillOrdering};
use super::pcg::{pcg, symmetric_multiply, PcgFailure, PcgOperators, PcgWork};
use super::tree_solve::{self, FactorScalar, TreeSolve, TreeWork};
use crate::assembly::Assembly;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltError as DenseLltError;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::SparseColMatRef;
use faer::{Conj, MatMut, Par, Side};
use nalgebra::Vector3;
use rayon::prelude::*;
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
/// `icefem bench --tets 10000,30000,60000,100000 --steps 3 --solver cholesky|amg` on the
/// corotated ice cube (backward Euler at 1/30 s, 2 cores, medians of 3 runs, 2026-12-01):
/// per step, Cholesky / multigrid CG took 0.073 / 0.087 s at 6.1e3 free dofs, 0.22 / 0.17 s at
/// 1.7e4, 0.74 / 0.42 s at 3.5e4 and 1.74 / 0.90 s at 5.7e4: on ice the crossover is near 1e4
/// dofs. Up to 2e4 dofs both take under 0.3 s a step, and there the direct solver's robustness
/// — nearly incompressible water, stiff contact penalties, indefinite tangents, E up to
/// 1e13 Pa, where multigrid needs hundreds of iterations — is worth more than the difference.
pub const AUTO_DIRECT_MAX_DOFS: usize = 20_000;

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
    /// preconditioned by it, until CG needs more than [`reuse_iteration_budget`].
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

/// A reused Cholesky factor is refreshed on the next Hessian refresh once a CG solve
/// preconditioned by it needed more than this many iterations per decade of residual
/// reduction (see [`reuse_iteration_budget`]): each costs one pair of triangular solves and a
/// product with the matrix, a fresh factorisation about as much as 25–30 of them on the 1e5-tet
/// freezing container (single precision: 0.8 s against 0.028 s with the tree-parallel solves),
/// and a step makes a few solves with the same factor. There a factor from the step before
/// reaches Newton's first forcing ([`FORCING_MAX`], 3 decades) in 1–13 iterations, typically 5.
/// Steps 91–102 of that scene (resumed from step 90, two runs each): 14.1 s with 5, 14.2–15.0 s
/// with 7, 14.8–16.2 s with 10 iterations per decade.
pub const FACTOR_REUSE_ITERATIONS_PER_DECADE: f64 = 5.0;

/// CG iterations a reused factor may take to reach the relative residual `forcing` before it
/// is refreshed: [`FACTOR_REUSE_ITERATIONS_PER_DECADE`] per decade (15 at 1e-3, 60 at 1e-12).
pub fn reuse_iteration_budget(forcing: f64) -> usize {
    let decades = -forcing.log10();
    (FACTOR_REUSE_ITERATIONS_PER_DECADE * decades)
        .ceil()
        .max(2.0) as usize
}

/// A solve preconditioned by a stale factor or hierarchy stops after this many times the
/// iterations that trigger a refresh (the factor's cap, or the hierarchy's first count) and
/// refreshes at once: after a large change of the matrix (contacts switching on) the old
/// preconditioner can need hundreds of iterations.
pub const STALE_ITERATION_CAP: usize = 3;

/// The first solve of a Newton solve, preconditioned by a reused factor, needs a relative
/// residual of at most this: the Newton direction far from the solution need not be exact
/// (the nonlinear error dominates), and nearer the solution [`LinearSolver::set_forcing`]
/// asks for what Newton's convergence can use. Measured on the 1e5-tet freezing container:
/// the first Newton step of a frame leaves a relative residual of ~4e-4 whether its linear
/// solve reached 1e-4 or 1e-12, and steps 62–75 took 1.00 s on average at 1e-3 against 1.20 s
/// at 1e-4 (same Newton iterations).
pub const FORCING_MAX: f64 = 1e-3;

/// Loosest relative residual a later solve of a Newton solve may stop at (Eisenstat and
/// Walker's safeguard η_max, smaller than their 0.9: a direction good to 10 % keeps Newton's
/// step count).
pub const FORCING_LATER_MAX: f64 = 0.1;

/// After a reused factor had to be abandoned (or converged too slowly) at some age — Newton
/// solves since it was computed, see [`LinearSolver::start_newton_solve`] — a factor reaching
/// that age is replaced at the first Hessian refresh, without the doomed attempt. It is tried
/// again (a probe) after 1 such replacement, then after 2, 4, … up to `STALE_PROBE_PERIOD` as
/// long as the probes fail. (Within one Newton solve an earlier iterate's factor is a good
/// preconditioner; across the steps of a freezing run it is not: a band of elements changes
/// stiffness every step. A failed probe costs a few CG iterations, a needless factorisation
/// 10–20 of them.)
pub const STALE_PROBE_PERIOD: usize = 8;

/// State of a Cholesky factor reused as a preconditioner.
pub struct FactorReuse {
    settings: IterativeSettings,
    /// The matrix changed since the factorisation.
    stale: bool,
    /// A factorisation is due at the next refresh.
    refresh_due: bool,
    /// Relative residual the next solves need (see [`LinearSolver::set_forcing`]).
    forcing: f64,
    /// Newton solves begun since the current factor was computed.
    age: usize,
    /// Smallest age at which a factor had to be abandoned, if it has not done since.
    failed_age: Option<usize>,
    /// Factorisations made early because of `failed_age` since the last probe.
    skipped_attempts: usize,
    /// Early factorisations before the next probe (1, 2, 4, … [`STALE_PROBE_PERIOD`]).
    probe_period: usize,
    /// Precision of the factor: `Single` until a single-precision factorisation fails.
    precision: FactorPrecision,
    /// The single-precision factor and its work space (empty in double precision).
    single: SingleFactor,
    /// Exact treatment of the few entries that changed by a large factor since the
    /// factorisation (contacts switching on or off).
    correction: LowRankCorrection,
    work: PcgWork,
}

/// A single-precision Cholesky factor with the buffers to compute and apply it.
#[derive(Default)]
struct SingleFactor {
    /// Values of L, in the symbolic factor's layout.
    l: Vec<f32>,
    /// The matrix rounded to f32 (the factorisation's input).
    matrix: Vec<f32>,
    /// Right-hand side and solution of a triangular solve.
    rhs: Vec<f32>,
    /// faer's scratch for the factorisation and the solves.
    work: Option<MemBuffer>,
    /// Buffers of the tree-parallel solves.
    tree_work: TreeWork<f32>,
}

impl FactorReuse {
    fn new(settings: IterativeSettings, n: usize) -> Self {
        FactorReuse {
            settings,
            stale: false,
            refresh_due: false,
            forcing: settings.tolerance,
            age: 0,
            failed_age: None,
            skipped_attempts: 0,
            probe_period: 1,
            precision: settings.factor_precision,
            single: SingleFactor::default(),
            correction: LowRankCorrection::default(),
            work: PcgWork::new(n),
        }
    }

    /// Whether the current factor solves the current matrix exactly (a fresh double-precision
    /// factor): then a direct solve, else CG preconditioned by the factor.
    fn exact(&self) -> bool {
        !self.stale && self.precision == FactorPrecision::Double
    }

    /// Factorises `values` in single precision; `false` (and double precision from now on)
    /// if the factorisation meets a non-positive pivot.
    fn factor_single(
        &mut self,
        symbolic: &SymbolicCholesky<usize>,
        assembly: &Assembly,
        values: &[f64],
    ) -> Result<bool, LinearError> {
        let single = &mut self.single;
        let par = factor_parallelism(symbolic.nrows());
        let work = match single.work {
            Some(ref mut work) => work,
            None => {
                let req = symbolic
                    .factorize_numeric_llt_scratch::<f32>(par, Default::default())
                    .or(symbolic.solve_in_place_scratch::<f32>(1, Par::Seq));
                let work =
                    MemBuffer::try_new(req).map_err(|e| LinearError::Faer(format!("{e:?}")))?;
                single.l = vec![0.0; symbolic.len_val()];
                single.rhs = vec![0.0; symbolic.nrows()];
                single.work.insert(work)
            }
        };
        single.matrix.clear();
        single.matrix.extend(values.iter().map(|&v| v as f32));
        let result = symbolic.factorize_numeric_llt::<f32>(
            &mut single.l,
            SparseColMatRef::new(assembly.symbolic(), &single.matrix),
            Side::Lower,
            Default::default(),
            par,
            MemStack::new(work),
            Default::default(),
        );
        let factored = result.is_ok();
        if !factored {
            self.switch_to_double();
        }
        Ok(factored)
    }

    /// Double precision from now on; the single-precision buffers are freed. The caller
    /// factorises in double precision next: until then no factor is valid.
    fn switch_to_double(&mut self) {
        self.precision = FactorPrecision::Double;
        self.single = SingleFactor::default();
    }

    /// Whether the factor, about to be kept through one more refresh, should rather be
    /// replaced now: it is due, or factors of that age have been failing.
    fn replace_before_use(&mut self) -> bool {
        if self.refresh_due {
            return true;
        }
        if self.failed_age.is_some_and(|a| self.age >= a) {
            if self.skipped_attempts < self.probe_period {
                self.skipped_attempts += 1;
                return true;
            }
            self.skipped_attempts = 0;
        }
        false
    }

    /// The factor had to be abandoned, or converged too slowly, at its current age. Only
    /// factors from earlier Newton solves are remembered: within a solve a failure is rare
    /// (contacts switching on) and says nothing about the next refresh.
    fn note_failure(&mut self) {
        if self.age > 0 {
            self.probe_period = match self.failed_age {
                // A probe failed: wait longer before the next.
                Some(a) if self.age >= a => (2 * self.probe_period).min(STALE_PROBE_PERIOD),
                _ => 1,
            };
            self.failed_age = Some(self.failed_age.map_or(self.age, |a| a.min(self.age)));
            self.skipped_attempts = 0;
        }
    }

    /// A fresh factor.
    fn renewed(&mut self) {
        self.stale = false;
        self.refresh_due = false;
        self.age = 0;
        self.correction.clear();
    }
}

/// `Auto` switches from multigrid CG to Cholesky for good when a solve with a fresh hierarchy
/// needs more than this many iterations (on ice it needs 15–40 up to 1e6 dofs; a nearly
/// incompressible body such as unfrozen water needs hundreds) — if the system has at most
/// [`FALLBACK_DIRECT_MAX_DOFS`] free dofs.
pub const AMG_FALLBACK_ITERATIONS: usize = 200;
/// Largest system `Auto` hands to Cholesky when multigrid struggles: a nested-dissection
/// factor of 3e5 dofs holds ~2e8 entries (1.6 GB).
pub const FALLBACK_DIRECT_MAX_DOFS: usize = 300_000;

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
    fn with_setup(elapsed: f64, iterations: usize, setup: Option<f64>) -> Self {
        let t_setup = setup.unwrap_or(0.0);
        LinearStats {
            t_solve: elapsed - t_setup,
            iterations,
            setups: usize::from(setup.is_some()),
            t_setup,
        }
    }
}

/// A linear solver bound to one sparsity pattern.
// One instance per simulation: the size difference between the variants does not matter.
#[allow(clippy::large_enum_variant)]
pub enum LinearSolver {
    /// Cholesky with its symbolic analysis, factor storage and workspace kept between calls.
    Cholesky {
        factor: DirectFactor,
        t_symbolic: f64,
        /// Whether nested dissection (rather than AMD) ordered the factor.
        nested_dissection: bool,
        /// Reuse of the factor as a CG preconditioner for later matrices (opt-in).
        reuse: Option<Box<FactorReuse>>,
    },
    /// Jacobi-preconditioned CG.
    Cg {
        tolerance: f64,
        max_iterations: usize,
        inv_diag: Vec<f64>,
        work: PcgWork,
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
    /// What `Auto` falls back to when multigrid struggles (see [`AMG_FALLBACK_ITERATIONS`]).
    fallback: Option<(FillOrdering, IterativeSettings)>,
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
    /// repeated. Returns the iterations and the time (s) of that rebuild, if any.
    fn solve(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
        b: &[f64],
        x: &mut [f64],
    ) -> Result<(usize, Option<f64>), LinearError> {
        let n = b.len();
        // Iterations of an attempt with a stale hierarchy that was abandoned (counted: they
        // were paid for).
        let mut abandoned = 0;
        let mut rebuilt = None;
        loop {
            let mut ops = AmgOperators {
                amg: &mut self.amg,
                assembly,
                values,
            };
            let cap = match (self.stale, self.baseline) {
                (true, Some(base)) => self
                    .max_iterations
                    .min(STALE_ITERATION_CAP * base + 10 * REFRESH_SLACK),
                _ if self.fallback.is_some() => self.max_iterations.min(AMG_FALLBACK_ITERATIONS),
                _ => self.max_iterations,
            };
            // A stale hierarchy should reach half the digits within the first solve's count.
            let checkpoint = match (self.stale, self.baseline) {
                (true, Some(base)) => Some((base.max(1), self.tolerance.sqrt())),
                _ => None,
            };
            let result = pcg(
                &mut ops,
                b,
                x,
                self.tolerance,
                cap,
                checkpoint,
                &mut self.work,
            );
            match result {
                Ok(iterations) => {
                    match self.baseline {
                        None => self.baseline = Some(iterations),
                        Some(base) => {
                            if iterations as f64
                                > REFRESH_GROWTH * base as f64 + REFRESH_SLACK as f64
                            {
                                self.refresh_due = true;
                            }
                        }
                    }
                    return Ok((iterations + abandoned, rebuilt));
                }
                Err(PcgFailure::NegativeCurvature { iteration }) => {
                    return Err(LinearError::NegativeCurvature { iteration, n })
                }
                Err(failure) if self.stale => {
                    abandoned += failure.iterations();
                    rebuilt = Some(self.setup(assembly, values)?);
                }
                Err(PcgFailure::NoConvergence { residual, .. }) => {
                    return Err(LinearError::CgNotConverged {
                        iterations: self.max_iterations,
                        residual,
                    })
                }
                // A V-cycle built on a positive-definite matrix is positive definite; one built
                // on an indefinite tangent (compressed corotated elements) is not, and CG sees
                // rᵀM⁻¹r ≤ 0 before it meets negative curvature: the same verdict.
                Err(PcgFailure::Breakdown { iteration }) => {
                    return Err(LinearError::NegativeCurvature { iteration, n })
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
    /// rigid-body modes.
    pub fn new(
        kind: LinearSolverKind,
        ordering: FillOrdering,
        assembly: &Assembly,
        coords: &[Vector3<f64>],
        iterative: &IterativeSettings,
    ) -> Result<Self, LinearError> {
        let n = assembly.dofs().num_free();
        let (cg_tolerance, cg_max_iterations, amg_reuse) = (
            iterative.tolerance,
            iterative.max_iterations,
            iterative.amg_reuse,
        );
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
                    fallback: (kind == LinearSolverKind::Auto && n <= FALLBACK_DIRECT_MAX_DOFS)
                        .then_some((ordering, *iterative)),
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
                    .factorize_numeric_llt_scratch::<f64>(
                        factor_parallelism(symbolic.nrows()),
                        Default::default(),
                    )
                    .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
                let work =
                    MemBuffer::try_new(req).map_err(|e| LinearError::Faer(format!("{e:?}")))?;
                Ok(LinearSolver::Cholesky {
                    factor: DirectFactor {
                        tree: (n >= TREE_SOLVE_MIN_DOFS)
                            .then(|| TreeSolve::new(&symbolic, rayon::current_num_threads()))
                            .flatten(),
                        symbolic,
                        // Allocated by the first double-precision factorisation.
                        l: Vec::new(),
                        work,
                        tree_work: TreeWork::default(),
                        factored: Vec::new(),
                    },
                    t_symbolic: start.elapsed().as_secs_f64(),
                    nested_dissection,
                    reuse: iterative
                        .factor_reuse
                        .then(|| Box::new(FactorReuse::new(*iterative, n))),
                })
            }
            LinearSolverKind::Cg => Ok(LinearSolver::Cg {
                tolerance: cg_tolerance,
                max_iterations: cg_max_iterations,
                inv_diag: vec![0.0; n],
                work: PcgWork::new(n),
            }),
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

    /// Precision of a Cholesky factor kept as CG's preconditioner (`None` without
    /// `factor_reuse`, or for the iterative solvers): where single precision failed, `Double`.
    pub fn factor_precision(&self) -> Option<FactorPrecision> {
        match self {
            LinearSolver::Cholesky { reuse: Some(r), .. } => Some(r.precision),
            _ => None,
        }
    }

    /// Number of nonzeros of the Cholesky factor, if direct.
    pub fn factor_nnz(&self) -> Option<usize> {
        match self {
            LinearSolver::Cholesky { factor, .. } => Some(factor.symbolic.len_val()),
            LinearSolver::Cg { .. } | LinearSolver::Amg(_) => None,
        }
    }

    /// A new Newton solve begins (a time step, or a re-solve with updated friction): a reused
    /// factor is one solve older (see [`STALE_PROBE_PERIOD`]).
    pub fn start_newton_solve(&mut self) {
        if let LinearSolver::Cholesky { reuse: Some(r), .. } = self {
            r.age += 1;
        }
    }

    /// Sets the relative residual ‖b − A x‖ / ‖b‖ the next solves need (Newton's forcing term),
    /// clamped to [`IterativeSettings::tolerance`, [`FORCING_MAX`]] for a first solve (η = ∞)
    /// and to [`IterativeSettings::tolerance`, [`FORCING_LATER_MAX`]] after. Only solves
    /// with a kept factor use it: a fresh double-precision factor solves exactly at no extra
    /// cost, and the multigrid and Jacobi solvers keep their tolerance (their iteration counts
    /// are what the benchmarks compare with pyamg).
    pub fn set_forcing(&mut self, eta: f64) {
        if let LinearSolver::Cholesky { reuse: Some(r), .. } = self {
            // The first solve (η = ∞) has no rate to go by.
            let cap = if eta == f64::INFINITY {
                FORCING_MAX
            } else {
                FORCING_LATER_MAX
            };
            // max/min rather than clamp: a NaN request falls back to CG's own tolerance.
            r.forcing = eta
                .max(r.settings.tolerance)
                .min(cap.max(r.settings.tolerance));
        }
    }

    /// Whether [`LinearSolver::solve`] works with the matrix values themselves (CG and the
    /// multigrid, and CG preconditioned by a kept factor) rather than with a factor only (a
    /// plain direct solve): only then does a change of the values in place reach the solves.
    pub fn iterates_on_matrix(&self) -> bool {
        match self {
            LinearSolver::Cholesky { reuse, .. } => reuse.is_some(),
            LinearSolver::Cg { .. } => true,
            LinearSolver::Amg(s) => s.reuse,
        }
    }

    /// The matrix values changed in place since [`LinearSolver::factorize`] (a chord
    /// iteration's contact update; see [`LinearSolver::iterates_on_matrix`]): a kept factor
    /// or hierarchy is now merely a preconditioner of them, Jacobi's diagonal is recomputed.
    pub fn matrix_changed(&mut self, assembly: &Assembly, values: &[f64]) {
        match self {
            LinearSolver::Cholesky { reuse: Some(r), .. } => r.stale = true,
            LinearSolver::Cholesky { reuse: None, .. } => {}
            LinearSolver::Cg { inv_diag, .. } => jacobi_inverse(assembly, values, inv_diag),
            LinearSolver::Amg(s) => s.stale = true,
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
            LinearSolver::Cholesky { factor, reuse, .. } => {
                let same = factor.is_of(values);
                if let Some(r) = reuse.as_mut() {
                    r.stale = !same;
                    if !same && !factor.factored.is_empty() && !r.replace_before_use() {
                        return Ok(None);
                    }
                }
                if same {
                    return Ok(None);
                }
                refactor(factor, reuse.as_deref_mut(), assembly, values)?;
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
            LinearSolver::Cholesky { factor, reuse, .. } => {
                let mut kept = KeptSolve::default();
                if let Some(r) = reuse.as_mut() {
                    kept = solve_with_kept_factor(r, factor, assembly, values, b, x)?;
                    if let Some(iterations) = kept.iterations {
                        return Ok(kept.stats(start, iterations));
                    }
                }
                x.copy_from_slice(b);
                solve_with_factor(
                    &factor.symbolic,
                    &factor.l,
                    factor.tree.as_ref(),
                    &mut factor.tree_work,
                    &mut factor.work,
                    x,
                );
                Ok(kept.stats(start, 1 + kept.abandoned))
            }
            LinearSolver::Cg {
                tolerance,
                max_iterations,
                inv_diag,
                work,
            } => {
                let mut ops = JacobiOperators {
                    assembly,
                    values,
                    inv_diag,
                };
                match pcg(&mut ops, b, x, *tolerance, *max_iterations, None, work) {
                    Ok(iterations) => Ok(LinearStats {
                        t_solve: start.elapsed().as_secs_f64(),
                        iterations,
                        ..Default::default()
                    }),
                    Err(PcgFailure::NoConvergence { residual, .. }) => {
                        Err(LinearError::CgNotConverged {
                            iterations: *max_iterations,
                            residual,
                        })
                    }
                    // Jacobi is positive definite exactly when the diagonal is positive: a
                    // breakdown, like negative curvature, says the matrix is not.
                    Err(
                        PcgFailure::NegativeCurvature { iteration }
                        | PcgFailure::Breakdown { iteration },
                    ) => Err(LinearError::NegativeCurvature { iteration, n }),
                }
            }
            LinearSolver::Amg(s) => {
                let result = s.solve(assembly, values, b, x);
                let struggling = match &result {
                    Ok((iterations, _)) => *iterations > AMG_FALLBACK_ITERATIONS,
                    Err(e) => !e.is_indefinite(),
                };
                if let (true, Some((ordering, iterative))) = (struggling, s.fallback) {
                    let switching = Instant::now();
                    let mut direct = LinearSolver::new(
                        LinearSolverKind::Cholesky,
                        ordering,
                        assembly,
                        &[],
                        &iterative,
                    )?;
                    direct.factorize(assembly, values)?;
                    let t_switch = switching.elapsed().as_secs_f64();
                    *self = direct;
                    if result.is_err() {
                        let mut stats = self.solve(assembly, values, b, x)?;
                        stats.setups += 1;
                        stats.t_setup += t_switch;
                        stats.t_solve = start.elapsed().as_secs_f64() - stats.t_setup;
                        return Ok(stats);
                    }
                    let (iterations, _) = result?;
                    return Ok(LinearStats::with_setup(
                        start.elapsed().as_secs_f64(),
                        iterations,
                        Some(t_switch),
                    ));
                }
                let (iterations, rebuilt) = result?;
                let stats =
                    LinearStats::with_setup(start.elapsed().as_secs_f64(), iterations, rebuilt);
                if let LinearSolver::Amg(s) = self {
                    s.history.push((iterations, stats.t_solve));
                }
                Ok(stats)
            }
        }
    }
}

/// Systems from this many free dofs are factorised on all threads. Measured with nested
/// dissection on ice cubes, 2 cores (`icefem bench --tets 10000,100000,300000 --steps 3`,
/// medians of 3): the numeric factorisation takes 0.93 instead of 1.33 s at 56 862 dofs and
/// 6.1 instead of 10.5 s at 160 284, but 0.033 instead of 0.022 s at 6 084, where the
/// supernodes are too small to share.
pub const PARALLEL_FACTOR_MIN_DOFS: usize = 20_000;

/// Triangular solves share the elimination tree between threads ([`tree_solve`]) from this
/// many free dofs; below, the copies and the hand-over between threads cost more than the
/// second core gives. Two f64 solves per step (`icefem bench --tets 1000,10000,30000 --steps 3`,
/// 2 cores, medians of 3, faer's one-thread solve / the tree solve): 0.0001 / 0.0004 s at 882
/// dofs, 0.0029 / 0.0043 s at 6 084, 0.022 / 0.014 s at 16 524, 0.13 / 0.085 s at 56 862.
pub const TREE_SOLVE_MIN_DOFS: usize = 10_000;

/// faer's parallelism for factorising `n` free dofs (see [`PARALLEL_FACTOR_MIN_DOFS`]).
fn factor_parallelism(n: usize) -> Par {
    if n >= PARALLEL_FACTOR_MIN_DOFS {
        Par::rayon(0)
    } else {
        Par::Seq
    }
}

/// Solves L Lᵀ x = `x` in place with the factor `l` of `symbolic`: tree-parallel when there is
/// a `tree` plan ([`tree_solve`]), else faer's solve on one thread (its parallel solve shares
/// only each supernode's dense kernels, too small for one right-hand side).
fn solve_with_factor<T: FactorScalar>(
    symbolic: &SymbolicCholesky<usize>,
    l: &[T],
    tree: Option<&TreeSolve>,
    tree_work: &mut TreeWork<T>,
    faer_work: &mut MemBuffer,
    x: &mut [T],
) {
    match tree {
        Some(plan) => tree_solve::solve_in_place(symbolic, l, plan, tree_work, x),
        None => faer_solve(symbolic, l, faer_work, x),
    }
}

/// X ← (L Lᵀ)⁻¹ X by faer's supernodal solve on this thread, for an n × k column-major block
/// `x` (k = 1: one vector); `work` must hold faer's scratch for k columns.
fn faer_solve<T: FactorScalar>(
    symbolic: &SymbolicCholesky<usize>,
    l: &[T],
    work: &mut MemBuffer,
    x: &mut [T],
) {
    let n = symbolic.nrows();
    let k = x.len() / n;
    LltRef::new(symbolic, l).solve_in_place_with_conj(
        Conj::No,
        MatMut::from_column_major_slice_mut(x, n, k),
        Par::Seq,
        MemStack::new(work),
    );
}

/// Factorises the matrix with `values`: in single precision if `reuse` keeps its factor so
/// (double precision when that fails), else in double precision.
fn refactor(
    factor: &mut DirectFactor,
    reuse: Option<&mut FactorReuse>,
    assembly: &Assembly,
    values: &[f64],
) -> Result<(), LinearError> {
    let Some(r) = reuse else {
        return factor.factor(assembly, values);
    };
    if r.precision == FactorPrecision::Single
        && r.factor_single(&factor.symbolic, assembly, values)?
    {
        factor.factored.clear();
        factor.factored.extend_from_slice(values);
    } else {
        factor.factor(assembly, values)?;
    }
    r.renewed();
    Ok(())
}

/// What [`solve_with_kept_factor`] did.
#[derive(Default)]
struct KeptSolve {
    /// CG's iterations, or `None` when the factor is now exact and the caller solves directly.
    iterations: Option<usize>,
    /// CG iterations of abandoned attempts.
    abandoned: usize,
    /// Factorisations made on the way, and their time (s).
    setups: usize,
    t_setup: f64,
}

impl KeptSolve {
    /// The solve's statistics: `iterations` in all, since `start`, its set-ups apart.
    fn stats(&self, start: Instant, iterations: usize) -> LinearStats {
        LinearStats {
            t_solve: start.elapsed().as_secs_f64() - self.t_setup,
            iterations,
            setups: self.setups,
            t_setup: self.t_setup,
        }
    }
}

/// Solves with CG preconditioned by the kept factor (a stale one, or a fresh single-precision
/// one). A factor that cannot bring CG to the forcing is replaced and the solve repeated: a
/// stale one by a fresh factorisation, a fresh single-precision one by double precision for
/// good. Ends when CG converged, or when the factor is an exact (fresh double) one.
fn solve_with_kept_factor(
    r: &mut FactorReuse,
    direct: &mut DirectFactor,
    assembly: &Assembly,
    values: &[f64],
    b: &[f64],
    x: &mut [f64],
) -> Result<KeptSolve, LinearError> {
    let mut kept = KeptSolve::default();
    while !r.exact() {
        let fresh = !r.stale;
        // Beyond the cap a fresh factorisation is cheaper than going on.
        let budget = reuse_iteration_budget(r.forcing);
        let cap = r.settings.max_iterations.min(STALE_ITERATION_CAP * budget);
        let FactorReuse {
            single,
            work: pcg_work,
            precision,
            forcing,
            correction,
            ..
        } = &mut *r;
        let factor_values = match (precision, single.work.as_mut()) {
            (FactorPrecision::Single, Some(single_work)) => FactorValues::Single {
                l: &single.l,
                rhs: &mut single.rhs,
                tree_work: &mut single.tree_work,
                work: single_work,
            },
            _ => FactorValues::Double {
                l: &direct.l,
                tree_work: &mut direct.tree_work,
                work: &mut direct.work,
            },
        };
        let factor = Factor {
            symbolic: &direct.symbolic,
            tree: direct.tree.as_ref(),
            values: factor_values,
        };
        let mut operators = FactorOperators {
            assembly,
            values,
            factor,
            correction: None,
        };
        if !fresh {
            correction.update(assembly, values, &direct.factored, |x| {
                operators.factor.solve_columns(x)
            })?;
            operators.correction = Some(correction);
        }
        let result = pcg(
            &mut operators,
            b,
            x,
            *forcing,
            cap,
            // A good factor reaches half the digits in a few iterations.
            Some((budget / 2, forcing.sqrt())),
            pcg_work,
        );
        match result {
            Ok(iterations) => {
                if iterations > budget && fresh {
                    // A fresh single-precision factor this slow is short of precision: double
                    // from now on, starting with this matrix (later solves may reuse it
                    // without another factorisation call).
                    r.switch_to_double();
                    let factoring = Instant::now();
                    refactor(direct, Some(r), assembly, values)?;
                    kept.setups += 1;
                    kept.t_setup += factoring.elapsed().as_secs_f64();
                } else if iterations > budget {
                    // Too slow: replace it, and do not keep one this long again.
                    r.refresh_due = true;
                    r.note_failure();
                } else if !fresh && r.failed_age.is_some_and(|a| r.age >= a) {
                    r.failed_age = None;
                }
                kept.iterations = Some(iterations + kept.abandoned);
                return Ok(kept);
            }
            Err(PcgFailure::NegativeCurvature { iteration }) => {
                return Err(LinearError::NegativeCurvature {
                    iteration,
                    n: b.len(),
                })
            }
            Err(failure) => {
                kept.abandoned += failure.iterations();
                // A fresh factor that fails is short of precision; an old one, of freshness.
                if fresh {
                    r.switch_to_double();
                } else {
                    r.note_failure();
                }
                let factoring = Instant::now();
                refactor(direct, Some(r), assembly, values)?;
                kept.setups += 1;
                kept.t_setup += factoring.elapsed().as_secs_f64();
            }
        }
    }
    Ok(kept)
}

/// A sparse Cholesky factorisation in double precision: the symbolic analysis (once per
/// pattern), the factor's values, faer's scratch, and the matrix they were computed from.
pub struct DirectFactor {
    symbolic: SymbolicCholesky<usize>,
    /// Values of L in the symbolic factor's layout (allocated on first use: a factor kept in
    /// single precision never needs them).
    l: Vec<f64>,
    work: MemBuffer,
    /// How triangular solves share the elimination tree between threads (`None`: faer's
    /// solve on one thread).
    tree: Option<TreeSolve>,
    tree_work: TreeWork<f64>,
    /// The matrix values the current factor was computed from (empty before the first, and
    /// after a failed factorisation).
    factored: Vec<f64>,
}

impl DirectFactor {
    /// Whether the current factor was computed from exactly these values (bit for bit).
    fn is_of(&self, values: &[f64]) -> bool {
        self.factored.len() == values.len()
            && self
                .factored
                .iter()
                .zip(values)
                .all(|(a, b)| a.to_bits() == b.to_bits())
    }

    /// Numeric factorisation of the matrix with `values`.
    fn factor(&mut self, assembly: &Assembly, values: &[f64]) -> Result<(), LinearError> {
        let n = self.symbolic.nrows();
        self.factored.clear();
        self.l.resize(self.symbolic.len_val(), 0.0);
        self.symbolic
            .factorize_numeric_llt::<f64>(
                &mut self.l,
                assembly.matrix(values),
                Side::Lower,
                Default::default(),
                factor_parallelism(n),
                MemStack::new(&mut self.work),
                Default::default(),
            )
            .map_err(|e| match e {
                DenseLltError::NonPositivePivot { index } => {
                    LinearError::NotPositiveDefinite { pivot: index, n }
                }
            })?;
        self.factored.extend_from_slice(values);
        Ok(())
    }
}

/// A Cholesky factor applied as a preconditioner: its symbolic part and tree plan, its values
/// and their solve's buffers.
struct Factor<'a> {
    symbolic: &'a SymbolicCholesky<usize>,
    tree: Option<&'a TreeSolve>,
    values: FactorValues<'a>,
}

impl Factor<'_> {
    /// z ← (L Lᵀ)⁻¹ r.
    fn solve(&mut self, r: &[f64], z: &mut [f64]) {
        let Factor {
            symbolic,
            tree,
            values,
        } = self;
        match values {
            FactorValues::Double { l, tree_work, work } => {
                z.copy_from_slice(r);
                solve_with_factor(symbolic, l, *tree, tree_work, work, z);
            }
            FactorValues::Single {
                l,
                rhs,
                tree_work,
                work,
            } => {
                for (s, &r) in rhs.iter_mut().zip(r) {
                    *s = r as f32;
                }
                solve_with_factor(symbolic, l, *tree, tree_work, work, rhs);
                for (z, &s) in z.iter_mut().zip(rhs.iter()) {
                    *z = f64::from(s);
                }
            }
        }
    }

    /// X ← (L Lᵀ)⁻¹ X for an n × k column-major block `x`: the columns split evenly between
    /// the threads, each share solved by faer's supernodal solve on one thread with all its
    /// columns at once (the dense kernels are then matrix products). faer's parallel solve of
    /// the whole block synchronises the threads at every supernode and was slower: steps
    /// 91–102 of the 1e5-tet container spent 5.2 s in solves with it, 4.65 s with the whole
    /// block on one thread.
    fn solve_columns(&self, x: &mut [f64]) -> Result<(), LinearError> {
        let n = self.symbolic.nrows();
        let per_thread = (x.len() / n).div_ceil(rayon::current_num_threads()).max(1);
        let symbolic = self.symbolic;
        match &self.values {
            FactorValues::Double { l, .. } => x
                .par_chunks_mut(per_thread * n)
                .try_for_each(|share| solve_block(symbolic, l, share)),
            FactorValues::Single { l, .. } => {
                x.par_chunks_mut(per_thread * n).try_for_each(|share| {
                    let mut block: Vec<f32> = share.iter().map(|&v| v as f32).collect();
                    solve_block(symbolic, l, &mut block)?;
                    for (x, &b) in share.iter_mut().zip(&block) {
                        *x = f64::from(b);
                    }
                    Ok(())
                })
            }
        }
    }
}

/// X ← (L Lᵀ)⁻¹ X for an n × k column-major block, on this thread, with scratch of its own.
fn solve_block<T: FactorScalar>(
    symbolic: &SymbolicCholesky<usize>,
    l: &[T],
    x: &mut [T],
) -> Result<(), LinearError> {
    let k = x.len() / symbolic.nrows();
    let mut scratch = MemBuffer::try_new(symbolic.solve_in_place_scratch::<T>(k, Par::Seq))
        .map_err(|e| LinearError::Faer(format!("{e:?}")))?;
    faer_solve(symbolic, l, &mut scratch, x);
    Ok(())
}

/// The values of a [`Factor`], in the precision it was computed in.
enum FactorValues<'a> {
    Double {
        l: &'a [f64],
        tree_work: &'a mut TreeWork<f64>,
        work: &'a mut MemBuffer,
    },
    /// Solved in f32: the residual is rounded to f32 and the result widened back.
    Single {
        l: &'a [f32],
        rhs: &'a mut [f32],
        tree_work: &'a mut TreeWork<f32>,
        work: &'a mut MemBuffer,
    },
}

/// The current matrix and a Cholesky factor (of it, or of an earlier matrix) as PCG's
/// operators.
struct FactorOperators<'a> {
    assembly: &'a Assembly,
    values: &'a [f64],
    factor: Factor<'a>,
    /// Applied after the factor's solve, if any.
    correction: Option<&'a mut LowRankCorrection>,
}

impl PcgOperators for FactorOperators<'_> {
    fn apply(&mut self, x: &[f64], y: &mut [f64]) {
        symmetric_multiply(self.assembly, self.values, x, y);
    }
    fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        self.factor.solve(r, z);
        if let Some(correction) = &mut self.correction {
            correction.apply(z);
        }
    }
}

/// The current matrix and the inverse of its diagonal as PCG's operators.
struct JacobiOperators<'a> {
    assembly: &'a Assembly,
    values: &'a [f64],
    inv_diag: &'a [f64],
}

impl PcgOperators for JacobiOperators<'_> {
    fn apply(&mut self, x: &[f64], y: &mut [f64]) {
        symmetric_multiply(self.assembly, self.values, x, y);
    }
    fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        for ((z, r), d) in z.iter_mut().zip(r).zip(self.inv_diag) {
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
