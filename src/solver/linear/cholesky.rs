//! Direct sparse Cholesky LLᵀ (faer's supernodal factorisation): the symbolic analysis once per
//! pattern, with an AMD or nested-dissection ordering, a numeric factorisation per new matrix
//! (skipped when the values are bit for bit the factored ones), and triangular solves.

use super::error::{LinearError, LinearStats};
use super::triangular::solve_with_factor;
use crate::assembly::Assembly;
use crate::solver::ordering::{nested_dissection, FillOrdering};
use crate::solver::tree_solve::{TreeSolve, TreeWork};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltError as DenseLltError;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, SymbolicCholesky, SymmetricOrdering,
};
use faer::{Par, Side};
use std::time::Instant;

/// Systems from this many free dofs are factorised on all threads. Measured with nested
/// dissection on ice cubes, 2 cores (`icefem bench --tets 10000,100000,300000 --steps 3`,
/// medians of 3): the numeric factorisation takes 0.93 instead of 1.33 s at 56 862 dofs and
/// 6.1 instead of 10.5 s at 160 284, but 0.033 instead of 0.022 s at 6 084, where the
/// supernodes are too small to share.
pub const PARALLEL_FACTOR_MIN_DOFS: usize = 20_000;

/// Triangular solves share the elimination tree between threads
/// ([`tree_solve`](crate::solver::tree_solve)) from this many free dofs; below, the copies and
/// the hand-over between threads cost more than the second core gives. Two f64 solves per step
/// (`icefem bench --tets 1000,10000,30000 --steps 3`, 2 cores, medians of 3, faer's one-thread
/// solve / the tree solve): 0.0001 / 0.0004 s at 882 dofs, 0.0029 / 0.0043 s at 6 084,
/// 0.022 / 0.014 s at 16 524, 0.13 / 0.085 s at 56 862.
pub const TREE_SOLVE_MIN_DOFS: usize = 10_000;

/// faer's parallelism for factorising `n` free dofs (see [`PARALLEL_FACTOR_MIN_DOFS`]).
pub(super) fn factor_parallelism(n: usize) -> Par {
    if n >= PARALLEL_FACTOR_MIN_DOFS {
        Par::rayon(0)
    } else {
        Par::Seq
    }
}

/// A sparse Cholesky factorisation in double precision: the symbolic analysis (once per
/// pattern), the factor's values, faer's scratch, and the matrix they were computed from.
pub struct Cholesky {
    pub(super) symbolic: SymbolicCholesky<usize>,
    /// Values of L in the symbolic factor's layout (allocated on first use: a factor kept in
    /// single precision never needs them).
    pub(super) l: Vec<f64>,
    pub(super) work: MemBuffer,
    /// How triangular solves share the elimination tree between threads (`None`: faer's
    /// solve on one thread).
    pub(super) tree: Option<TreeSolve>,
    pub(super) tree_work: TreeWork<f64>,
    /// The matrix values the current factor was computed from (empty before the first, and
    /// after a failed factorisation).
    pub(super) factored: Vec<f64>,
    /// Time of the symbolic analysis (s).
    t_symbolic: f64,
    /// Whether nested dissection (rather than AMD) ordered the factor.
    nested_dissection: bool,
}

impl Cholesky {
    /// The symbolic analysis of `assembly`'s pattern with `ordering`, and the scratch of the
    /// numeric factorisation and of the solves.
    pub fn new(ordering: FillOrdering, assembly: &Assembly) -> Result<Self, LinearError> {
        let n = assembly.dofs().num_free();
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
        .map_err(LinearError::faer)?;
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(
                factor_parallelism(symbolic.nrows()),
                Default::default(),
            )
            .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        let work = MemBuffer::try_new(req).map_err(LinearError::faer)?;
        Ok(Cholesky {
            tree: (n >= TREE_SOLVE_MIN_DOFS)
                .then(|| TreeSolve::new(&symbolic, rayon::current_num_threads()))
                .flatten(),
            symbolic,
            // Allocated by the first double-precision factorisation.
            l: Vec::new(),
            work,
            tree_work: TreeWork::default(),
            factored: Vec::new(),
            t_symbolic: start.elapsed().as_secs_f64(),
            nested_dissection,
        })
    }

    /// Time of the symbolic analysis (s).
    pub fn symbolic_time(&self) -> f64 {
        self.t_symbolic
    }

    /// Whether nested dissection ordered the factor.
    pub fn uses_nested_dissection(&self) -> bool {
        self.nested_dissection
    }

    /// Number of nonzeros of the factor.
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Whether the current factor was computed from exactly these values (bit for bit).
    pub fn is_of(&self, values: &[f64]) -> bool {
        self.factored.len() == values.len()
            && self
                .factored
                .iter()
                .zip(values)
                .all(|(a, b)| a.to_bits() == b.to_bits())
    }

    /// Whether a factorisation succeeded since the last failed one (there is a factor).
    pub fn has_factor(&self) -> bool {
        !self.factored.is_empty()
    }

    /// Prepares solves with the matrix of these values: factorises it unless the current
    /// factor is of exactly these values. Returns whether it factorised.
    pub fn factorize(&mut self, assembly: &Assembly, values: &[f64]) -> Result<bool, LinearError> {
        if self.is_of(values) {
            return Ok(false);
        }
        self.factor(assembly, values)?;
        Ok(true)
    }

    /// Numeric factorisation of the matrix with `values`.
    pub fn factor(&mut self, assembly: &Assembly, values: &[f64]) -> Result<(), LinearError> {
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

    /// x ← (L Lᵀ)⁻¹ b with the double-precision factor.
    pub fn solve_direct(&mut self, b: &[f64], x: &mut [f64]) {
        x.copy_from_slice(b);
        solve_with_factor(
            &self.symbolic,
            &self.l,
            self.tree.as_ref(),
            &mut self.tree_work,
            &mut self.work,
            x,
        );
    }

    /// Solves `A x = b` with the factor of the matrix last passed to
    /// [`Cholesky::factorize`].
    pub fn solve(&mut self, b: &[f64], x: &mut [f64]) -> LinearStats {
        let start = Instant::now();
        self.solve_direct(b, x);
        LinearStats {
            t_solve: start.elapsed().as_secs_f64(),
            iterations: 1,
            ..Default::default()
        }
    }
}
