//! Triangular solves with a supernodal Cholesky factor that give the independent subtrees of
//! its elimination tree to separate threads.
//!
//! faer's supernodal solve walks the supernodes one after the other and parallelises only
//! inside each supernode's dense kernels, which for one right-hand side are too small to
//! share: on two cores it is no faster than one thread up to ~1e5 dofs. A nested-dissection
//! factor falls apart into subtrees whose columns are disjoint and which meet only in their
//! common ancestors (the separators above them). Forwards, each thread solves whole subtrees
//! in a copy of the right-hand side and gathers what they subtract from ancestor rows in a
//! buffer of its own; its rows are copied back, the buffers subtracted and the ancestors (the
//! *top* of the tree) solved on one thread. Backwards the order reverses: the top first, then
//! the subtrees in parallel, each in a copy that holds the finished top. Each supernode is
//! still solved by faer's dense kernels; the result is faer's up to the order in which
//! contributions to a top row are added, and does not depend on the threads' timing.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::supernodal::{SupernodalLltRef, SymbolicSupernodalCholesky};
use faer::sparse::linalg::cholesky::{SymbolicCholesky, SymbolicCholeskyRaw};
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;
use std::ops::{AddAssign, Neg, SubAssign};

/// The element type of a factor solved here (f32 or f64).
pub trait FactorScalar:
    faer::traits::ComplexField
    + Copy
    + Default
    + Send
    + Sync
    + AddAssign
    + SubAssign
    + Neg<Output = Self>
{
    /// 1.
    const ONE: Self;
}

impl FactorScalar for f32 {
    const ONE: f32 = 1.0;
}

impl FactorScalar for f64 {
    const ONE: f64 = 1.0;
}

/// Which thread solves which subtrees, and which supernodes are left for one thread.
#[derive(Debug)]
pub struct TreeSolve {
    /// Per thread, the supernodes of its subtrees in increasing order (faer numbers a parent
    /// after its children, so that is an order of elimination).
    bins: Vec<Vec<usize>>,
    /// Per column, the thread that owns it, or [`TOP`].
    owner: Vec<u32>,
    /// Supernodes above all the subtrees, in increasing order.
    top: Vec<usize>,
    /// Largest off-diagonal row count of a supernode (the gather buffer's length).
    max_pattern: usize,
}

/// Owner of the top's columns.
const TOP: u32 = u32::MAX;

/// The share of the solve's work (entries of L read) that the plan may leave idle: expansion
/// stops once the slowest thread's subtrees plus the top are within this of a perfect split.
const BALANCE_SLACK: f64 = 0.02;

/// Most supernodes the plan moves to the top while it looks for a balance.
const MAX_EXPANSIONS: usize = 256;

impl TreeSolve {
    /// A plan for `threads` threads, or `None` when there is nothing to share: one thread, a
    /// simplicial factor (faer's choice for small or very sparse systems), or a tree that does
    /// not split (a chain of supernodes).
    pub fn new(symbolic: &SymbolicCholesky<usize>, threads: usize) -> Option<TreeSolve> {
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            return None;
        };
        if threads < 2 || threads >= TOP as usize {
            return None;
        }
        let tree = SupernodeTree::new(sn)?;
        let mut candidates = tree.roots.clone();
        let mut top: Vec<usize> = Vec::new();
        let mut top_work = 0.0;
        let mut best: Option<(f64, Vec<Vec<usize>>, Vec<usize>)> = None;
        for _ in 0..MAX_EXPANSIONS {
            let (roots, slowest) = tree.assign(&candidates, threads);
            let time = top_work + slowest;
            if best.as_ref().is_none_or(|(t, _, _)| time < *t) {
                best = Some((time, roots, top.clone()));
            }
            if time <= (1.0 + BALANCE_SLACK) * tree.total / threads as f64 {
                break;
            }
            // The largest subtree keeps the split from balancing: solve its root on one thread
            // and share its children instead.
            let Some(k) = (0..candidates.len()).max_by(|&a, &b| {
                tree.subtree_work[candidates[a]].total_cmp(&tree.subtree_work[candidates[b]])
            }) else {
                break;
            };
            let s = candidates.swap_remove(k);
            top.push(s);
            top_work += tree.work[s];
            candidates.extend(&tree.children[s]);
            if candidates.is_empty() {
                break;
            }
        }
        let (time, roots, mut top) = best?;
        if time >= tree.total {
            return None;
        }
        top.sort_unstable();
        let begin = sn.supernode_begin();
        let end = sn.supernode_end();
        let mut owner = vec![TOP; sn.nrows()];
        let mut bins = Vec::with_capacity(threads);
        for (b, roots) in roots.iter().enumerate() {
            let mut supernodes = tree.descendants(roots);
            supernodes.sort_unstable();
            for &s in &supernodes {
                owner[begin[s]..end[s]].fill(b as u32);
            }
            bins.push(supernodes);
        }
        let max_pattern = (0..sn.n_supernodes())
            .map(|s| sn.supernode(s).pattern().len())
            .max()
            .unwrap_or(0);
        Some(TreeSolve {
            bins,
            owner,
            top,
            max_pattern,
        })
    }

    /// Threads the plan shares the solve between.
    pub fn threads(&self) -> usize {
        self.bins.len()
    }
}

/// The supernodal elimination tree with the work (entries of L) of each supernode and subtree.
struct SupernodeTree {
    children: Vec<Vec<usize>>,
    roots: Vec<usize>,
    work: Vec<f64>,
    subtree_work: Vec<f64>,
    total: f64,
}

impl SupernodeTree {
    /// The tree, or `None` if a parent were numbered before its child (then increasing order
    /// would not be an order of elimination).
    fn new(sn: &SymbolicSupernodalCholesky<usize>) -> Option<SupernodeTree> {
        let count = sn.n_supernodes();
        let begin = sn.supernode_begin();
        let end = sn.supernode_end();
        let mut supernode_of_column = vec![0; sn.nrows()];
        for s in 0..count {
            supernode_of_column[begin[s]..end[s]].fill(s);
        }
        let mut children = vec![Vec::new(); count];
        let mut roots = Vec::new();
        let mut work = vec![0.0; count];
        let mut subtree_work = vec![0.0; count];
        for s in 0..count {
            let pattern = sn.supernode(s).pattern();
            let cols = (end[s] - begin[s]) as f64;
            work[s] = cols * (cols + 1.0) / 2.0 + cols * pattern.len() as f64;
            subtree_work[s] += work[s];
            // The smallest row below the diagonal block lies in the parent.
            match pattern.iter().min() {
                Some(&row) => {
                    let parent = supernode_of_column[row];
                    if parent <= s {
                        return None;
                    }
                    children[parent].push(s);
                    subtree_work[parent] += subtree_work[s];
                }
                None => roots.push(s),
            }
        }
        let total = work.iter().sum();
        Some(SupernodeTree {
            children,
            roots,
            work,
            subtree_work,
            total,
        })
    }

    /// Longest-processing-time assignment of the subtrees rooted at `roots` to `threads`
    /// bins; the bins' roots and the largest bin's work.
    fn assign(&self, roots: &[usize], threads: usize) -> (Vec<Vec<usize>>, f64) {
        let mut order = roots.to_vec();
        order.sort_by(|&a, &b| self.subtree_work[b].total_cmp(&self.subtree_work[a]));
        let mut bins = vec![Vec::new(); threads];
        let mut load = vec![0.0f64; threads];
        for s in order {
            let lightest = (0..threads)
                .min_by(|&a, &b| load[a].total_cmp(&load[b]))
                .unwrap_or(0);
            bins[lightest].push(s);
            load[lightest] += self.subtree_work[s];
        }
        (bins, load.iter().copied().fold(0.0, f64::max))
    }

    /// The supernodes of the subtrees rooted at `roots`.
    fn descendants(&self, roots: &[usize]) -> Vec<usize> {
        let mut all = Vec::new();
        let mut stack = roots.to_vec();
        while let Some(s) = stack.pop() {
            all.push(s);
            stack.extend(&self.children[s]);
        }
        all
    }
}

/// Buffers of tree solves in one precision (allocated on first use).
#[derive(Default)]
pub struct TreeWork<T> {
    /// The right-hand side in the factor's ordering.
    x: Vec<T>,
    /// Per thread: its copy of `x`, what it subtracts from top rows, and a gather buffer.
    threads: Vec<ThreadWork<T>>,
    /// The gather buffer of the top.
    gather: Vec<T>,
}

#[derive(Default)]
struct ThreadWork<T> {
    x: Vec<T>,
    contribution: Vec<T>,
    gather: Vec<T>,
}

/// Solves L Lᵀ x = `rhs` in place, with the factor `values` of `symbolic` and the `plan`.
pub fn solve_in_place<T: FactorScalar>(
    symbolic: &SymbolicCholesky<usize>,
    values: &[T],
    plan: &TreeSolve,
    work: &mut TreeWork<T>,
    rhs: &mut [T],
) {
    let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
        unreachable!("a tree plan is only made for a supernodal factor");
    };
    let l = SupernodalLltRef::new(sn, values);
    let n = rhs.len();
    work.x.resize(n, T::default());
    work.gather.resize(plan.max_pattern, T::default());
    work.threads
        .resize_with(plan.threads(), ThreadWork::default);
    match symbolic.perm() {
        Some(perm) => {
            for (x, &f) in work.x.iter_mut().zip(perm.arrays().0) {
                *x = rhs[f];
            }
        }
        None => work.x.copy_from_slice(rhs),
    }
    let owner = &plan.owner;

    // Forwards: the subtrees in parallel, then their contributions, then the top.
    let x = &work.x;
    work.threads
        .par_iter_mut()
        .zip(&plan.bins)
        .enumerate()
        .for_each(|(b, (mine, supernodes))| {
            mine.x.clone_from(x);
            mine.contribution.clear();
            mine.contribution.resize(n, T::default());
            mine.gather.resize(plan.max_pattern, T::default());
            for &s in supernodes {
                forward(
                    &l,
                    s,
                    b as u32,
                    owner,
                    &mut mine.x,
                    &mut mine.gather,
                    &mut mine.contribution,
                );
            }
        });
    copy_owned_rows(sn, plan, work);
    for mine in &work.threads {
        for (x, &c) in work.x.iter_mut().zip(&mine.contribution) {
            *x -= c;
        }
    }
    for &s in &plan.top {
        forward(&l, s, TOP, owner, &mut work.x, &mut work.gather, &mut []);
    }

    // Backwards: the top, then the subtrees in parallel.
    for &s in plan.top.iter().rev() {
        backward(&l, s, &mut work.x, &mut work.gather);
    }
    let x = &work.x;
    work.threads
        .par_iter_mut()
        .zip(&plan.bins)
        .for_each(|(mine, supernodes)| {
            mine.x.clone_from(x);
            for &s in supernodes.iter().rev() {
                backward(&l, s, &mut mine.x, &mut mine.gather);
            }
        });
    copy_owned_rows(sn, plan, work);

    match symbolic.perm() {
        Some(perm) => {
            for (r, &i) in rhs.iter_mut().zip(perm.arrays().1) {
                *r = work.x[i];
            }
        }
        None => rhs.copy_from_slice(&work.x),
    }
}

/// Copies into `work.x` the rows each thread owns from that thread's copy.
fn copy_owned_rows<T: Copy>(
    sn: &SymbolicSupernodalCholesky<usize>,
    plan: &TreeSolve,
    work: &mut TreeWork<T>,
) {
    let (begin, end) = (sn.supernode_begin(), sn.supernode_end());
    for (mine, supernodes) in work.threads.iter().zip(&plan.bins) {
        for &s in supernodes {
            work.x[begin[s]..end[s]].copy_from_slice(&mine.x[begin[s]..end[s]]);
        }
    }
}

/// Supernode `s` of `l`: its first column, off-diagonal rows, and the diagonal and
/// below-diagonal blocks of its columns.
fn blocks<'a, T>(
    l: &SupernodalLltRef<'a, usize, T>,
    s: usize,
) -> (usize, &'a [usize], MatRef<'a, T>, MatRef<'a, T>) {
    let node = l.supernode(s);
    let matrix = node.val();
    let (diagonal, below) = matrix.split_at_row(matrix.ncols());
    (node.start(), node.pattern(), diagonal, below)
}

/// Forward substitution through supernode `s` of thread `me`: x_s ← L_ss⁻¹ x_s, then the rows
/// below lose L_bs x_s — in `x` where `me` owns them, else added to `contribution` (the top's
/// rows, of which `x` holds a stale copy).
fn forward<T: FactorScalar>(
    l: &SupernodalLltRef<'_, usize, T>,
    s: usize,
    me: u32,
    owner: &[u32],
    x: &mut [T],
    gather: &mut [T],
    contribution: &mut [T],
) {
    let (start, pattern, diagonal, below) = blocks(l, s);
    let size = diagonal.ncols();
    let mut xs = MatMut::from_column_major_slice_mut(&mut x[start..start + size], size, 1);
    solve_lower_triangular_in_place(diagonal, xs.rb_mut(), Par::Seq);
    let gather = &mut gather[..pattern.len()];
    matmul(
        MatMut::from_column_major_slice_mut(gather, pattern.len(), 1),
        Accum::Replace,
        below,
        xs.rb(),
        T::ONE,
        Par::Seq,
    );
    for (&row, &g) in pattern.iter().zip(gather.iter()) {
        if owner[row] == me {
            x[row] -= g;
        } else {
            contribution[row] += g;
        }
    }
}

/// Backward substitution through supernode `s`: x_s ← L_ssᵀ⁻¹ (x_s − L_bsᵀ x_b), the rows
/// below (`x_b`, finished) read from `x`.
fn backward<T: FactorScalar>(
    l: &SupernodalLltRef<'_, usize, T>,
    s: usize,
    x: &mut [T],
    gather: &mut [T],
) {
    let (start, pattern, diagonal, below) = blocks(l, s);
    let size = diagonal.ncols();
    let gather = &mut gather[..pattern.len()];
    for (g, &row) in gather.iter_mut().zip(pattern) {
        *g = x[row];
    }
    let mut xs = MatMut::from_column_major_slice_mut(&mut x[start..start + size], size, 1);
    matmul(
        xs.rb_mut(),
        Accum::Add,
        below.transpose(),
        MatMut::from_column_major_slice_mut(gather, pattern.len(), 1).rb(),
        -T::ONE,
        Par::Seq,
    );
    solve_upper_triangular_in_place(diagonal.transpose(), xs, Par::Seq);
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymmetricOrdering};
    use faer::sparse::{SparseColMat, Triplet};
    use faer::{Conj, Side};

    /// The 7-point Laplacian of an m³ grid plus a small shift (lower triangle).
    fn grid_laplacian(m: usize) -> SparseColMat<usize, f64> {
        let id = |i: usize, j: usize, k: usize| (i * m + j) * m + k;
        let mut t = Vec::new();
        for i in 0..m {
            for j in 0..m {
                for k in 0..m {
                    let c = id(i, j, k);
                    t.push(Triplet::new(c, c, 6.01));
                    if i + 1 < m {
                        t.push(Triplet::new(id(i + 1, j, k), c, -1.0));
                    }
                    if j + 1 < m {
                        t.push(Triplet::new(id(i, j + 1, k), c, -1.0));
                    }
                    if k + 1 < m {
                        t.push(Triplet::new(id(i, j, k + 1), c, -1.0));
                    }
                }
            }
        }
        SparseColMat::try_new_from_triplets(m * m * m, m * m * m, &t).unwrap()
    }

    /// faer's solve and the tree solve with 2–4 threads of `b`, for the factor of `a` in
    /// `ordering`; the largest difference relative to the solution's largest entry.
    fn tree_against_faer(
        a: &SparseColMat<usize, f64>,
        ordering: SymmetricOrdering<'_, usize>,
    ) -> f64 {
        let n = a.nrows();
        let symbolic =
            factorize_symbolic_cholesky(a.symbolic(), Side::Lower, ordering, Default::default())
                .unwrap();
        let par = Par::Seq;
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par));
        let mut stack = MemBuffer::new(req);
        let mut l = vec![0.0; symbolic.len_val()];
        symbolic
            .factorize_numeric_llt::<f64>(
                &mut l,
                a.as_ref(),
                Side::Lower,
                Default::default(),
                par,
                MemStack::new(&mut stack),
                Default::default(),
            )
            .unwrap();
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 101) as f64 - 50.0).collect();
        let mut expected = b.clone();
        LltRef::new(&symbolic, &l).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut expected, n, 1),
            par,
            MemStack::new(&mut stack),
        );
        let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let mut worst = 0.0f64;
        for threads in [2, 3, 4] {
            let plan = TreeSolve::new(&symbolic, threads).expect("a 3-D grid's tree splits");
            assert_eq!(plan.threads(), threads);
            assert!(plan.bins.iter().all(|b| !b.is_empty()));
            let mut work = TreeWork::default();
            // Twice: the buffers are reused.
            for _ in 0..2 {
                let mut x = b.clone();
                solve_in_place(&symbolic, &l, &plan, &mut work, &mut x);
                for (a, b) in x.iter().zip(&expected) {
                    worst = worst.max((a - b).abs() / scale);
                }
            }
            // In single precision (the kept preconditioner's case) too.
            let l32: Vec<f32> = l.iter().map(|&v| v as f32).collect();
            let mut x32: Vec<f32> = b.iter().map(|&v| v as f32).collect();
            solve_in_place(&symbolic, &l32, &plan, &mut TreeWork::default(), &mut x32);
            for (a, b) in x32.iter().zip(&expected) {
                // f32 round-off of a solve with condition number ~1e3.
                assert!((f64::from(*a) - b).abs() <= 1e-4 * scale);
            }
        }
        assert!(TreeSolve::new(&symbolic, 1).is_none());
        worst
    }

    #[test]
    fn tree_solve_matches_faers_sequential_solve() {
        // Only the order of the sums into separator rows differs from faer's solve: round-off
        // of a well-conditioned system (condition number ~1e3).
        let amd = tree_against_faer(&grid_laplacian(20), SymmetricOrdering::Amd);
        assert!(amd <= 1e-12, "AMD ordering: error {amd:e}");
        // A scrambled ordering, whose supernodes faer does not number in postorder (as with
        // the nested dissection of `super::ordering`): subtrees are not contiguous.
        let a = grid_laplacian(12);
        let n = a.nrows();
        let forward: Vec<usize> = (0..n).map(|i| (i * 1031) % n).collect();
        let mut inverse = vec![0; n];
        for (i, &f) in forward.iter().enumerate() {
            inverse[f] = i;
        }
        let perm = faer::perm::PermRef::new_checked(&forward, &inverse, n);
        let scrambled = tree_against_faer(&a, SymmetricOrdering::Custom(perm));
        assert!(
            scrambled <= 1e-12,
            "scrambled ordering: error {scrambled:e}"
        );
    }
}
