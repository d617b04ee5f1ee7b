//! Cholesky whose factorisation is kept across Hessian refreshes and steps as the
//! preconditioner of CG on the current matrix, in single or double precision, with the
//! low-rank correction of the few entries that changed by a large factor. A fresh
//! double-precision factor solves directly. When to factorise again is decided by
//! [`FactorReuse`]; a single-precision factor that fails gives way to double precision for good.

use super::cholesky::{factor_parallelism, Cholesky};
use super::error::{LinearError, LinearStats};
use super::reuse::FactorReuse;
use super::settings::{FactorPrecision, IterativeSettings};
use super::triangular::{Factor, FactorValues};
use crate::assembly::Assembly;
use crate::solver::low_rank::LowRankCorrection;
use crate::solver::pcg::{pcg, MatrixOperators, PcgFailure, PcgWork, Preconditioner};
use crate::solver::tree_solve::TreeWork;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::SymbolicCholesky;
use faer::sparse::SparseColMatRef;
use faer::{Par, Side};
use std::time::Instant;

/// A Cholesky factor kept as CG's preconditioner, with its reuse state.
pub struct KeptFactor {
    /// The symbolic analysis and the double-precision factor (the factor used in double
    /// precision, and the record of the factored matrix in either).
    direct: Cholesky,
    /// When the factor is replaced.
    reuse: FactorReuse,
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

impl SingleFactor {
    /// Factorises `values` in single precision; `false` if the factorisation meets a
    /// non-positive pivot.
    fn factor(
        &mut self,
        symbolic: &SymbolicCholesky<usize>,
        assembly: &Assembly,
        values: &[f64],
    ) -> Result<bool, LinearError> {
        let par = factor_parallelism(symbolic.nrows());
        let work = match self.work {
            Some(ref mut work) => work,
            None => {
                let req = symbolic
                    .factorize_numeric_llt_scratch::<f32>(par, Default::default())
                    .or(symbolic.solve_in_place_scratch::<f32>(1, Par::Seq));
                let work = MemBuffer::try_new(req).map_err(LinearError::faer)?;
                self.l = vec![0.0; symbolic.len_val()];
                self.rhs = vec![0.0; symbolic.nrows()];
                self.work.insert(work)
            }
        };
        self.matrix.clear();
        self.matrix.extend(values.iter().map(|&v| v as f32));
        let result = symbolic.factorize_numeric_llt::<f32>(
            &mut self.l,
            SparseColMatRef::new(assembly.symbolic(), &self.matrix),
            Side::Lower,
            Default::default(),
            par,
            MemStack::new(work),
            Default::default(),
        );
        Ok(result.is_ok())
    }
}

/// What a [`KeptFactor::solve`] did before its last attempt.
#[derive(Default)]
struct KeptSolve {
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

impl KeptFactor {
    /// Keeps the factors of `direct` with `settings` (CG's tolerance and cap, the precision).
    pub fn new(direct: Cholesky, settings: &IterativeSettings, n: usize) -> Self {
        KeptFactor {
            direct,
            reuse: FactorReuse::new(settings),
            precision: settings.factor_precision,
            single: SingleFactor::default(),
            correction: LowRankCorrection::default(),
            work: PcgWork::new(n),
        }
    }

    /// The symbolic analysis and the double-precision factor.
    pub fn direct(&self) -> &Cholesky {
        &self.direct
    }

    /// Precision of the factor: where single precision failed, `Double`.
    pub fn precision(&self) -> FactorPrecision {
        self.precision
    }

    /// A new Newton solve begins: the factor is one solve older.
    pub fn start_newton_solve(&mut self) {
        self.reuse.start_newton_solve();
    }

    /// Sets the relative residual the next solves need (see [`FactorReuse::set_forcing`]).
    pub fn set_forcing(&mut self, eta: f64) {
        self.reuse.set_forcing(eta);
    }

    /// The matrix values changed in place since the factorisation: the factor is now merely a
    /// preconditioner of them.
    pub fn matrix_changed(&mut self) {
        self.reuse.matrix_changed();
    }

    /// Prepares solves with the matrix of these values: keeps the factor if [`FactorReuse`]
    /// says so, else factorises. Returns whether it factorised.
    pub fn factorize(&mut self, assembly: &Assembly, values: &[f64]) -> Result<bool, LinearError> {
        let same = self.direct.is_of(values);
        if self.reuse.keeps_factor(same, self.direct.has_factor()) {
            return Ok(false);
        }
        self.refactor(assembly, values)?;
        Ok(true)
    }

    /// Whether the current factor solves the current matrix exactly (a fresh double-precision
    /// factor): then a direct solve, else CG preconditioned by the factor.
    fn exact(&self) -> bool {
        !self.reuse.is_stale() && self.precision == FactorPrecision::Double
    }

    /// Double precision from now on; the single-precision buffers are freed. The caller
    /// factorises in double precision next: until then no factor is valid.
    fn switch_to_double(&mut self) {
        self.precision = FactorPrecision::Double;
        self.single = SingleFactor::default();
    }

    /// Factorises the matrix with `values`: in single precision while the factor is kept so
    /// (double precision from now on when that fails), else in double precision.
    fn refactor(&mut self, assembly: &Assembly, values: &[f64]) -> Result<(), LinearError> {
        if self.precision == FactorPrecision::Single && self.factor_single(assembly, values)? {
            self.direct.factored.clear();
            self.direct.factored.extend_from_slice(values);
        } else {
            self.direct.factor(assembly, values)?;
        }
        self.reuse.renewed();
        self.correction.clear();
        Ok(())
    }

    /// Factorises `values` in single precision; `false` (and double precision from now on)
    /// if the factorisation meets a non-positive pivot.
    fn factor_single(&mut self, assembly: &Assembly, values: &[f64]) -> Result<bool, LinearError> {
        let factored = self
            .single
            .factor(&self.direct.symbolic, assembly, values)?;
        if !factored {
            self.switch_to_double();
        }
        Ok(factored)
    }

    /// [`KeptFactor::refactor`] inside a solve, counted and timed in `kept`.
    fn refactor_in_solve(
        &mut self,
        kept: &mut KeptSolve,
        assembly: &Assembly,
        values: &[f64],
    ) -> Result<(), LinearError> {
        let factoring = Instant::now();
        self.refactor(assembly, values)?;
        kept.setups += 1;
        kept.t_setup += factoring.elapsed().as_secs_f64();
        Ok(())
    }

    /// Solves `A x = b` with CG preconditioned by the kept factor (a stale one, or a fresh
    /// single-precision one), or directly with a fresh double-precision one. A factor that
    /// cannot bring CG to the forcing is replaced and the solve repeated: a stale one by a
    /// fresh factorisation, a fresh single-precision one by double precision for good.
    /// `values` must hold the current matrix. `x` is overwritten.
    pub fn solve(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
        b: &[f64],
        x: &mut [f64],
    ) -> Result<LinearStats, LinearError> {
        let start = Instant::now();
        let mut kept = KeptSolve::default();
        while !self.exact() {
            let fresh = !self.reuse.is_stale();
            let limits = self.reuse.limits();
            let KeptFactor {
                direct,
                precision,
                single,
                correction,
                work: pcg_work,
                ..
            } = &mut *self;
            let factor_values = match (*precision, single.work.as_mut()) {
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
            let mut operators = MatrixOperators {
                assembly,
                values,
                preconditioner: CorrectedFactor {
                    factor,
                    correction: None,
                },
            };
            if !fresh {
                correction.update(assembly, values, &direct.factored, |x| {
                    operators.preconditioner.factor.solve_columns(x)
                })?;
                operators.preconditioner.correction = Some(correction);
            }
            let result = pcg(
                &mut operators,
                b,
                x,
                limits.forcing,
                limits.cap,
                Some(limits.checkpoint),
                pcg_work,
            );
            match result {
                Ok(iterations) => {
                    if self.reuse.converged(iterations, &limits) {
                        // A fresh single-precision factor this slow is short of precision:
                        // double from now on, starting with this matrix (later solves may
                        // reuse it without another factorisation call).
                        self.switch_to_double();
                        self.refactor_in_solve(&mut kept, assembly, values)?;
                    }
                    return Ok(kept.stats(start, iterations + kept.abandoned));
                }
                Err(PcgFailure::NegativeCurvature { iteration }) => {
                    return Err(LinearError::NegativeCurvature {
                        iteration,
                        n: b.len(),
                    })
                }
                Err(failure) => {
                    kept.abandoned += failure.iterations();
                    // A fresh factor that fails is short of precision; an old one, of
                    // freshness.
                    if self.reuse.failed() {
                        self.switch_to_double();
                    }
                    self.refactor_in_solve(&mut kept, assembly, values)?;
                }
            }
        }
        self.direct.solve_direct(b, x);
        Ok(kept.stats(start, 1 + kept.abandoned))
    }
}

/// A Cholesky factor (of the current matrix, or of an earlier one) and its low-rank
/// correction as a preconditioner.
struct CorrectedFactor<'a> {
    factor: Factor<'a>,
    /// Applied after the factor's solve, if any.
    correction: Option<&'a mut LowRankCorrection>,
}

impl Preconditioner for CorrectedFactor<'_> {
    fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        self.factor.solve(r, z);
        if let Some(correction) = &mut self.correction {
            correction.apply(z);
        }
    }
}
