//! Triangular solves with a Cholesky factor in f32 or f64: one right-hand side (tree-parallel
//! or faer's one-thread solve), blocks of columns shared between the threads, and [`Factor`],
//! a factor of either precision applied to f64 vectors as a preconditioner.

use super::error::LinearError;
use crate::solver::tree_solve::{self, FactorScalar, TreeSolve, TreeWork};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{LltRef, SymbolicCholesky};
use faer::{Conj, MatMut, Par};
use rayon::prelude::*;

/// Solves L Lᵀ x = `x` in place with the factor `l` of `symbolic`: tree-parallel when there is
/// a `tree` plan ([`tree_solve`]), else faer's solve on one thread (its parallel solve shares
/// only each supernode's dense kernels, too small for one right-hand side).
pub(super) fn solve_with_factor<T: FactorScalar>(
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

/// X ← (L Lᵀ)⁻¹ X for an n × k column-major block, on this thread, with scratch of its own.
fn solve_block<T: FactorScalar>(
    symbolic: &SymbolicCholesky<usize>,
    l: &[T],
    x: &mut [T],
) -> Result<(), LinearError> {
    let k = x.len() / symbolic.nrows();
    let mut scratch = MemBuffer::try_new(symbolic.solve_in_place_scratch::<T>(k, Par::Seq))
        .map_err(LinearError::faer)?;
    faer_solve(symbolic, l, &mut scratch, x);
    Ok(())
}

/// A Cholesky factor applied as a preconditioner: its symbolic part and tree plan, its values
/// and their solve's buffers.
pub(super) struct Factor<'a> {
    pub symbolic: &'a SymbolicCholesky<usize>,
    pub tree: Option<&'a TreeSolve>,
    pub values: FactorValues<'a>,
}

/// The values of a [`Factor`], in the precision it was computed in.
pub(super) enum FactorValues<'a> {
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

impl Factor<'_> {
    /// z ← (L Lᵀ)⁻¹ r.
    pub fn solve(&mut self, r: &[f64], z: &mut [f64]) {
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
    pub fn solve_columns(&self, x: &mut [f64]) -> Result<(), LinearError> {
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
