//! Smoothed-aggregation algebraic multigrid (SA-AMG, Vaněk, Mandel & Brezina 1996) for 3-D
//! elasticity, used as the preconditioner of conjugate gradients.
//!
//! - **Fine level**: the free-dof matrix of an [`Assembly`] regrouped into 3 × 3 node blocks
//!   (block CSR over the nodes that have at least one free dof). A constrained component of such
//!   a node becomes a decoupled row with a unit diagonal and a zero row of the near-null space,
//!   so the hierarchy on the padded system restricted to the free dofs is exactly a hierarchy
//!   for the free system.
//! - **Aggregation** on the block graph (pyamg's "standard" three-pass aggregation) with the
//!   symmetric strength of connection ‖A_ij‖_F ≥ θ √(‖A_ii‖_F ‖A_jj‖_F) (θ = [`STRENGTH`]).
//! - **Tentative prolongator** from the six rigid-body modes (three translations, three
//!   rotations about the centroid, from the nodes' rest coordinates): a QR factorisation per
//!   aggregate (modified Gram–Schmidt, columns that are numerically dependent are dropped — a
//!   one-node aggregate carries only 3 modes) gives T = Q and the coarse near-null space R.
//! - **Prolongator smoothing** P = (I − ω D⁻¹A) T with block-diagonal D and
//!   ω = 4/3 / ρ(D⁻¹A), ρ estimated by Lanczos.
//! - **Galerkin coarse operators** A_c = Pᵀ A P with 6 × 6 blocks, computed row by row of A_c in
//!   chunks of consecutive aggregates (A P is formed only for the fine rows a chunk needs, so
//!   the setup never holds A P for the whole level — at 1e6 dofs that would be ~0.6 GB).
//! - **Smoother**: Chebyshev polynomial of degree [`CHEBYSHEV_DEGREE`] in D⁻¹A on
//!   [0.1, 1.15] · ρ(D⁻¹A), the same polynomial before and after the coarse correction, so the
//!   V-cycle is a symmetric positive-definite operator as CG requires; it needs only block
//!   products (parallel, no colouring) unlike Gauss–Seidel.
//! - **Coarsest level** (≤ [`MAX_COARSE`] dofs): dense Cholesky (faer).
//!
//! Every parallel loop writes disjoint rows and every reduction sums fixed chunks in a fixed
//! order, so the preconditioner is bit-reproducible whatever the thread count.

use crate::assembly::Assembly;
use faer::linalg::solvers::SolveCore;
use faer::{Conj, Mat, MatMut, Side};
use nalgebra::Vector3;
use rayon::prelude::*;

/// Strength threshold θ of the block strength of connection. 0 keeps every coupling (pyamg's
/// default for smoothed aggregation): on ice meshes all couplings are of one order, and with
/// θ = 0 the aggregation depends on the pattern only, so it stays valid while the pattern does.
pub const STRENGTH: f64 = 0.0;
/// Coarsening stops when a level has at most this many dofs; that level is solved by dense
/// Cholesky (1500³/3 flops ≈ 0.1 s to factor, 2 · 1500² per solve).
pub const MAX_COARSE: usize = 1500;
/// Levels at most (a safeguard; 1e6 dofs need 5).
pub const MAX_LEVELS: usize = 12;
/// Degree of the Chebyshev smoother (matrix products per smoothing).
pub const CHEBYSHEV_DEGREE: usize = 2;
/// Lower end of the Chebyshev interval as a fraction of ρ(D⁻¹A): the smoother damps the upper
/// part of the spectrum; the coarse grid handles the rest (the usual choice, e.g. PETSc GAMG).
const CHEBYSHEV_LOWER: f64 = 0.1;
/// Safety factor on the Lanczos estimate of ρ(D⁻¹A), which approaches it from below: an
/// interval that misses the top eigenvalue would let the smoother amplify those modes.
const RHO_SAFETY: f64 = 1.15;
/// Lanczos steps for the estimate of ρ(D⁻¹A).
const LANCZOS_STEPS: usize = 20;
/// Coarse dofs per aggregate: the six rigid-body modes.
const MODES: usize = 6;
/// Rows of a parallel task in block-row loops.
const MIN_ROWS: usize = 512;
/// Aggregates per chunk of the Galerkin product.
const RAP_CHUNK: usize = 512;
/// Marks an empty slot.
const NONE: u32 = u32::MAX;

/// Failures of the multigrid set-up.
#[derive(Debug, thiserror::Error)]
pub enum AmgError {
    /// The coarsest matrix is not positive definite (the fine matrix is not).
    #[error("the coarsest multigrid matrix ({n} dofs) is not positive definite")]
    CoarseNotPositiveDefinite { n: usize },
    /// A diagonal block is singular (a node with no stiffness on one of its free dofs).
    #[error("diagonal block of node {node} on multigrid level {level} is singular")]
    SingularBlock { level: usize, node: usize },
}

/// Block compressed-sparse-row matrix: `br × bc` dense blocks stored row-major.
#[derive(Clone, Debug, Default)]
pub struct BlockCsr {
    /// Block rows.
    pub nrows: usize,
    /// Block columns.
    pub ncols: usize,
    /// Rows per block.
    pub br: usize,
    /// Columns per block.
    pub bc: usize,
    /// Start of each block row in `col` (length `nrows + 1`).
    pub ptr: Vec<usize>,
    /// Block column of each block.
    pub col: Vec<u32>,
    /// Block values, `br · bc` per block, row-major.
    pub val: Vec<f64>,
}

impl BlockCsr {
    /// Stored blocks.
    pub fn nnzb(&self) -> usize {
        self.col.len()
    }

    /// Bytes held by the arrays.
    pub fn bytes(&self) -> usize {
        self.ptr.len() * 8 + self.col.len() * 4 + self.val.len() * 8
    }

    /// y = A x (scalar vectors of length `nrows · br` and `ncols · bc`), parallel over rows.
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        match (self.br, self.bc) {
            (3, 3) => self.mul_fixed::<3, 3>(x, y),
            (3, 6) => self.mul_fixed::<3, 6>(x, y),
            (6, 6) => self.mul_fixed::<6, 6>(x, y),
            _ => unreachable!("block sizes are 3 or 6"),
        }
    }

    fn mul_fixed<const R: usize, const C: usize>(&self, x: &[f64], y: &mut [f64]) {
        y.par_chunks_mut(R)
            .with_min_len(MIN_ROWS)
            .enumerate()
            .for_each(|(i, yi)| {
                let mut acc = [0.0; R];
                for k in self.ptr[i]..self.ptr[i + 1] {
                    let j = self.col[k] as usize;
                    let b = &self.val[k * R * C..(k + 1) * R * C];
                    let xj = &x[j * C..j * C + C];
                    for r in 0..R {
                        acc[r] += (0..C).map(|c| b[r * C + c] * xj[c]).sum::<f64>();
                    }
                }
                yi.copy_from_slice(&acc);
            });
    }

    /// r = b − A x.
    fn residual(&self, b: &[f64], x: &[f64], r: &mut [f64]) {
        self.mul(x, r);
        r.par_iter_mut()
            .with_min_len(MIN_ROWS)
            .zip(b)
            .for_each(|(r, b)| *r = b - *r);
    }

    /// Index of the block (i, i) of each row (square matrices; every row has one).
    fn diagonal_index(&self) -> Vec<usize> {
        (0..self.nrows)
            .into_par_iter()
            .map(|i| {
                (self.ptr[i]..self.ptr[i + 1])
                    .find(|&k| self.col[k] as usize == i)
                    .unwrap_or(usize::MAX)
            })
            .collect()
    }

    /// Builds a matrix row by row in parallel: `row(scratch, i, cols, vals)` appends the blocks
    /// of row `i` (and must append the same ones when called again). Two passes — count, then
    /// fill the exactly sized arrays — so the set-up never holds a matrix twice (concatenating
    /// per-task pieces would, and the fine-level prolongator is ~0.3 GB at 1e6 dofs).
    fn from_rows<S, I, F>(
        nrows: usize,
        ncols: usize,
        br: usize,
        bc: usize,
        init: I,
        row: F,
    ) -> BlockCsr
    where
        S: Send,
        I: Fn() -> (S, Vec<u32>, Vec<f64>) + Sync + Send,
        F: Fn(&mut S, usize, &mut Vec<u32>, &mut Vec<f64>) + Sync + Send,
    {
        let bb = br * bc;
        let counts: Vec<usize> = (0..nrows)
            .into_par_iter()
            .with_min_len(MIN_ROWS)
            .map_init(&init, |(scratch, cols, vals), i| {
                cols.clear();
                vals.clear();
                row(scratch, i, cols, vals);
                cols.len()
            })
            .collect();
        let mut ptr = Vec::with_capacity(nrows + 1);
        ptr.push(0);
        for n in &counts {
            ptr.push(ptr.last().copied().unwrap_or(0) + n);
        }
        drop(counts);
        let nnzb = ptr[nrows];
        let mut col = vec![0u32; nnzb];
        let mut val = vec![0.0; nnzb * bb];
        let mut rows: Vec<(&mut [u32], &mut [f64])> = Vec::with_capacity(nrows);
        let (mut col_rest, mut val_rest) = (col.as_mut_slice(), val.as_mut_slice());
        for i in 0..nrows {
            let n = ptr[i + 1] - ptr[i];
            let (c, c_tail) = col_rest.split_at_mut(n);
            let (v, v_tail) = val_rest.split_at_mut(n * bb);
            rows.push((c, v));
            col_rest = c_tail;
            val_rest = v_tail;
        }
        rows.into_par_iter()
            .with_min_len(MIN_ROWS)
            .enumerate()
            .for_each_init(&init, |(scratch, cols, vals), (i, (c, v))| {
                cols.clear();
                vals.clear();
                row(scratch, i, cols, vals);
                c.copy_from_slice(cols);
                v.copy_from_slice(vals);
            });
        BlockCsr {
            nrows,
            ncols,
            br,
            bc,
            ptr,
            col,
            val,
        }
    }
}

/// For every block column of a prolongator, the blocks in it: (fine block row, block index).
/// Restriction (Pᵀ r) and the Galerkin product gather through it instead of holding Pᵀ.
#[derive(Clone, Debug, Default)]
struct Transpose {
    ptr: Vec<usize>,
    entries: Vec<(u32, u32)>,
}

impl Transpose {
    fn new(p: &BlockCsr) -> Self {
        let mut ptr = vec![0usize; p.ncols + 1];
        for &c in &p.col {
            ptr[c as usize + 1] += 1;
        }
        for k in 0..p.ncols {
            ptr[k + 1] += ptr[k];
        }
        let mut fill = ptr.clone();
        let mut entries = vec![(0u32, 0u32); p.nnzb()];
        for i in 0..p.nrows {
            for k in p.ptr[i]..p.ptr[i + 1] {
                let c = p.col[k] as usize;
                entries[fill[c]] = (i as u32, k as u32);
                fill[c] += 1;
            }
        }
        Transpose { ptr, entries }
    }
    fn of(&self, c: usize) -> &[(u32, u32)] {
        &self.entries[self.ptr[c]..self.ptr[c + 1]]
    }
    fn bytes(&self) -> usize {
        self.ptr.len() * 8 + self.entries.len() * 8
    }
}

/// How the fine (free-dof) system maps onto node blocks.
#[derive(Clone, Debug)]
struct FineMap {
    /// For each block row (node with a free dof), the free index of each component or NONE.
    dofs: Vec<[u32; 3]>,
    /// Global node of each block row.
    nodes: Vec<u32>,
    /// Block row of each free dof.
    block_of: Vec<u32>,
}

impl FineMap {
    fn new(assembly: &Assembly) -> Self {
        let mut dofs: Vec<[u32; 3]> = Vec::new();
        let mut nodes = Vec::new();
        let free = assembly.dofs().free_dofs();
        let mut block_of = Vec::with_capacity(free.len());
        for (f, &d) in free.iter().enumerate() {
            if nodes.last() != Some(&((d / 3) as u32)) {
                nodes.push((d / 3) as u32);
                dofs.push([NONE; 3]);
            }
            let b = dofs.len() - 1;
            dofs[b][d % 3] = f as u32;
            block_of.push(b as u32);
        }
        FineMap {
            dofs,
            nodes,
            block_of,
        }
    }

    /// Block pattern of the free system (free dofs are ordered by node, so each CSC column
    /// lists its neighbour blocks in increasing order).
    fn pattern(&self, assembly: &Assembly) -> BlockCsr {
        let s = assembly.symbolic();
        let n = self.dofs.len();
        BlockCsr::from_rows(
            n,
            n,
            3,
            3,
            || ((), Vec::new(), Vec::new()),
            |_, i, cols, vals| {
                let f = self.dofs[i].iter().find(|&&f| f != NONE).copied();
                let Some(f) = f else { return };
                let mut last = NONE;
                for &r in s.row_idx_of_col_raw(f as usize) {
                    let b = self.block_of[r];
                    if b != last {
                        cols.push(b);
                        vals.extend_from_slice(&[0.0; 9]);
                        last = b;
                    }
                }
            },
        )
    }

    /// Copies the free-system values into the block pattern `a` (from [`FineMap::pattern`]);
    /// constrained components get a unit diagonal.
    fn gather(&self, assembly: &Assembly, values: &[f64], a: &mut BlockCsr) {
        let s = assembly.symbolic();
        let BlockCsr { ptr, col, val, .. } = a;
        let (ptr, col) = (&*ptr, &*col);
        // Rows own disjoint value ranges: split the value array at the row starts.
        let mut rows: Vec<&mut [f64]> = Vec::with_capacity(self.dofs.len());
        let mut rest: &mut [f64] = val;
        for i in 0..self.dofs.len() {
            let (head, tail) = rest.split_at_mut(9 * (ptr[i + 1] - ptr[i]));
            rows.push(head);
            rest = tail;
        }
        rows.into_par_iter()
            .with_min_len(MIN_ROWS)
            .enumerate()
            .for_each(|(i, row)| {
                row.fill(0.0);
                let cols = &col[ptr[i]..ptr[i + 1]];
                for (ci, &f) in self.dofs[i].iter().enumerate() {
                    if f == NONE {
                        let k = cols.iter().position(|&c| c as usize == i).unwrap_or(0);
                        row[9 * k + 4 * ci] = 1.0;
                        continue;
                    }
                    let f = f as usize;
                    let range = s.col_range(f);
                    let mut k = 0;
                    for (&r, &v) in s.row_idx_of_col_raw(f).iter().zip(&values[range]) {
                        let b = self.block_of[r];
                        while cols[k] != b {
                            k += 1;
                        }
                        let cj = self.dofs[b as usize]
                            .iter()
                            .position(|&g| g as usize == r)
                            .unwrap_or(0);
                        row[9 * k + 3 * ci + cj] = v;
                    }
                }
            });
    }
}

/// One level of the hierarchy (all but the coarsest).
#[derive(Debug)]
struct Level {
    a: BlockCsr,
    /// Inverse diagonal blocks (`bs²` per row, row-major).
    dinv: Vec<f64>,
    /// Estimate of ρ(D⁻¹A) (before the safety factor).
    rho: f64,
    /// Prolongator to the next level.
    p: BlockCsr,
    pt: Transpose,
    /// Work vectors of the level's size: iterate, right-hand side, residual, two temporaries.
    x: Vec<f64>,
    b: Vec<f64>,
    r: Vec<f64>,
    d: Vec<f64>,
    t: Vec<f64>,
}

/// Aggregation of every level, kept while the sparsity pattern does not change.
#[derive(Clone, Debug)]
struct Structure {
    fine: FineMap,
    /// Aggregate of each block row, per level.
    aggregates: Vec<Vec<u32>>,
}

/// Summary of a hierarchy.
#[derive(Clone, Debug, Default)]
pub struct AmgInfo {
    /// Dofs per level, fine to coarse.
    pub level_dofs: Vec<usize>,
    /// Stored scalar entries per level.
    pub level_nnz: Vec<usize>,
    /// Operator complexity: Σ nnz(A_l) / nnz(A_0).
    pub operator_complexity: f64,
    /// Bytes held by the hierarchy (matrices, prolongators, work vectors).
    pub bytes: usize,
}

/// A smoothed-aggregation multigrid hierarchy for the free system of one [`Assembly`].
pub struct Amg {
    /// Rest coordinates of the mesh nodes (m).
    coords: Vec<Vector3<f64>>,
    structure: Option<Structure>,
    levels: Vec<Level>,
    /// Fine block pattern kept for the next set-up when the hierarchy has no levels.
    spare_pattern: Option<BlockCsr>,
    coarse: Option<faer::linalg::solvers::Llt<f64>>,
    coarse_b: Vec<f64>,
    coarse_x: Vec<f64>,
}

impl Amg {
    /// An empty hierarchy for the nodes at `coords` (rest positions, m); [`Amg::setup`] builds
    /// it.
    pub fn new(coords: &[Vector3<f64>]) -> Self {
        Amg {
            coords: coords.to_vec(),
            structure: None,
            levels: Vec::new(),
            spare_pattern: None,
            coarse: None,
            coarse_b: Vec::new(),
            coarse_x: Vec::new(),
        }
    }

    /// Whether a hierarchy has been built.
    pub fn is_built(&self) -> bool {
        self.coarse.is_some()
    }

    /// Builds the hierarchy for the free-system matrix with these `values` (both triangles of
    /// `assembly`'s pattern). The aggregation of the first call is kept by later calls (the
    /// pattern of an assembly never changes, and with θ = 0 aggregation depends on nothing
    /// else); everything numeric is recomputed.
    pub fn setup(&mut self, assembly: &Assembly, values: &[f64]) -> Result<(), AmgError> {
        let structure = self.structure.take();
        let fine = match &structure {
            Some(s) => s.fine.clone(),
            None => FineMap::new(assembly),
        };
        let mut a = match (self.levels.first_mut(), self.spare_pattern.take()) {
            (Some(l), _) => std::mem::take(&mut l.a),
            (None, Some(p)) => p,
            (None, None) => fine.pattern(assembly),
        };
        fine.gather(assembly, values, &mut a);
        let mut near_null = rigid_body_modes(&fine, &self.coords);
        self.levels.clear();
        self.coarse = None;
        let mut aggregates = structure.map(|s| s.aggregates).unwrap_or_default();
        let keep = !aggregates.is_empty();
        let mut level = 0;
        loop {
            let n = a.nrows * a.br;
            let stop = if keep {
                level >= aggregates.len()
            } else {
                n <= MAX_COARSE || level + 1 >= MAX_LEVELS
            };
            if stop {
                break;
            }
            if !keep {
                let agg = aggregate(&a);
                let count = agg.iter().map(|&g| g as usize + 1).max().unwrap_or(0);
                // A level that barely coarsens is not worth its cost: solve it directly.
                if 5 * count * MODES > 4 * n {
                    break;
                }
                aggregates.push(agg);
            }
            let dinv = block_inverses(&a, level)?;
            let rho = spectral_radius(&a, &dinv);
            let (t, coarse_null) = tentative(&aggregates[level], &near_null, a.br);
            let p = smooth_prolongator(&a, &dinv, &t, 4.0 / 3.0 / rho);
            drop(t);
            let pt = Transpose::new(&p);
            let coarse = galerkin(&a, &p, &pt);
            self.levels.push(Level {
                x: vec![0.0; n],
                b: vec![0.0; n],
                r: vec![0.0; n],
                d: vec![0.0; n],
                t: vec![0.0; n],
                a,
                dinv,
                rho,
                p,
                pt,
            });
            a = coarse;
            near_null = coarse_null;
            level += 1;
        }
        let n = a.nrows * a.br;
        let mut dense = Mat::<f64>::zeros(n, n);
        for i in 0..a.nrows {
            for k in a.ptr[i]..a.ptr[i + 1] {
                let j = a.col[k] as usize;
                let block = &a.val[k * a.br * a.bc..(k + 1) * a.br * a.bc];
                for r in 0..a.br {
                    for c in 0..a.bc {
                        dense[(i * a.br + r, j * a.bc + c)] = block[r * a.bc + c];
                    }
                }
            }
        }
        let llt = dense
            .llt(Side::Lower)
            .map_err(|_| AmgError::CoarseNotPositiveDefinite { n })?;
        self.coarse = Some(llt);
        self.coarse_b = vec![0.0; n];
        self.coarse_x = vec![0.0; n];
        if self.levels.is_empty() {
            self.spare_pattern = Some(a);
        }
        self.structure = Some(Structure { fine, aggregates });
        Ok(())
    }

    /// Summary of the hierarchy.
    pub fn info(&self) -> AmgInfo {
        let mut level_dofs: Vec<usize> = self.levels.iter().map(|l| l.a.nrows * l.a.br).collect();
        let mut level_nnz: Vec<usize> = self.levels.iter().map(|l| l.a.val.len()).collect();
        let nc = self.coarse_x.len();
        level_dofs.push(nc);
        level_nnz.push(nc * nc);
        let bytes = self
            .levels
            .iter()
            .map(|l| l.a.bytes() + l.p.bytes() + l.pt.bytes() + 8 * (l.dinv.len() + 5 * l.x.len()))
            .sum::<usize>()
            + 8 * nc * (nc + 2);
        AmgInfo {
            operator_complexity: level_nnz.iter().sum::<usize>() as f64
                / level_nnz.first().copied().unwrap_or(1).max(1) as f64,
            level_dofs,
            level_nnz,
            bytes,
        }
    }

    /// z = M⁻¹ r: one V-cycle from zero (free-dof vectors).
    pub fn apply(&mut self, r: &[f64], z: &mut [f64]) {
        let Some(structure) = self.structure.take() else {
            z.copy_from_slice(r);
            return;
        };
        let fine = &structure.fine;
        if self.levels.is_empty() {
            scatter(fine, r, &mut self.coarse_b);
            self.coarse_solve();
            gather(fine, &self.coarse_x, z);
            self.structure = Some(structure);
            return;
        }
        scatter(fine, r, &mut self.levels[0].b);
        let depth = self.levels.len();
        // Down: pre-smooth, restrict the residual.
        for l in 0..depth {
            let (this, rest) = self.levels.split_at_mut(l + 1);
            let lv = &mut this[l];
            chebyshev(lv, true);
            lv.a.residual(&lv.b, &lv.x, &mut lv.r);
            let next_b = match rest.first_mut() {
                Some(next) => &mut next.b,
                None => &mut self.coarse_b,
            };
            restrict(&lv.p, &lv.pt, &lv.r, next_b);
        }
        self.coarse_solve();
        // Up: prolongate the correction, post-smooth.
        for l in (0..depth).rev() {
            let (this, rest) = self.levels.split_at_mut(l + 1);
            let lv = &mut this[l];
            let next_x = match rest.first() {
                Some(next) => &next.x,
                None => &self.coarse_x,
            };
            lv.p.mul(next_x, &mut lv.t);
            add_assign(&mut lv.x, &lv.t);
            chebyshev(lv, false);
        }
        gather(fine, &self.levels[0].x, z);
        self.structure = Some(structure);
    }

    fn coarse_solve(&mut self) {
        self.coarse_x.copy_from_slice(&self.coarse_b);
        if let Some(llt) = &self.coarse {
            let n = self.coarse_x.len();
            llt.solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(&mut self.coarse_x, n, 1),
            );
        }
    }
}

/// Free-dof vector → padded block vector (zero on constrained components).
fn scatter(fine: &FineMap, v: &[f64], out: &mut [f64]) {
    out.par_chunks_mut(3)
        .with_min_len(MIN_ROWS)
        .zip(&fine.dofs)
        .for_each(|(o, d)| {
            for c in 0..3 {
                o[c] = if d[c] == NONE { 0.0 } else { v[d[c] as usize] };
            }
        });
}

/// Padded block vector → free-dof vector.
fn gather(fine: &FineMap, v: &[f64], out: &mut [f64]) {
    out.par_iter_mut()
        .with_min_len(3 * MIN_ROWS)
        .zip(&fine.block_of)
        .enumerate()
        .for_each(|(f, (o, &b))| {
            let c = fine.dofs[b as usize]
                .iter()
                .position(|&g| g as usize == f)
                .unwrap_or(0);
            *o = v[3 * b as usize + c];
        });
}

/// x += y.
fn add_assign(x: &mut [f64], y: &[f64]) {
    x.par_iter_mut()
        .with_min_len(4 * MIN_ROWS)
        .zip(y)
        .for_each(|(x, y)| *x += y);
}

/// out_i = D_i⁻¹ v_i (block diagonal, blocks of `bs`).
fn block_diagonal_apply(dinv: &[f64], bs: usize, v: &[f64], out: &mut [f64]) {
    out.par_chunks_mut(bs)
        .with_min_len(MIN_ROWS)
        .enumerate()
        .for_each(|(i, o)| {
            let d = &dinv[i * bs * bs..(i + 1) * bs * bs];
            let vi = &v[i * bs..(i + 1) * bs];
            for (r, o) in o.iter_mut().enumerate() {
                *o = (0..bs).map(|c| d[r * bs + c] * vi[c]).sum();
            }
        });
}

/// Chebyshev smoothing of A x = b on one level (`lv.b`, `lv.x`), preconditioned by the block
/// diagonal, on the interval [CHEBYSHEV_LOWER, 1] · RHO_SAFETY · ρ(D⁻¹A) (Saad, *Iterative
/// Methods for Sparse Linear Systems*, Alg. 12.1). `zero_start`: x is taken as zero.
fn chebyshev(lv: &mut Level, zero_start: bool) {
    let bs = lv.a.br;
    let upper = RHO_SAFETY * lv.rho;
    let lower = CHEBYSHEV_LOWER * upper;
    let theta = 0.5 * (upper + lower);
    let delta = 0.5 * (upper - lower);
    let sigma = theta / delta;
    let mut rho = 1.0 / sigma;
    if zero_start {
        lv.r.copy_from_slice(&lv.b);
    } else {
        lv.a.residual(&lv.b, &lv.x, &mut lv.r);
    }
    block_diagonal_apply(&lv.dinv, bs, &lv.r, &mut lv.d);
    lv.d.par_iter_mut()
        .with_min_len(4 * MIN_ROWS)
        .for_each(|d| *d /= theta);
    for k in 0..CHEBYSHEV_DEGREE {
        if zero_start && k == 0 {
            lv.x.copy_from_slice(&lv.d);
        } else {
            add_assign(&mut lv.x, &lv.d);
        }
        if k + 1 == CHEBYSHEV_DEGREE {
            break;
        }
        lv.a.mul(&lv.d, &mut lv.t);
        lv.r.par_iter_mut()
            .with_min_len(4 * MIN_ROWS)
            .zip(&lv.t)
            .for_each(|(r, t)| *r -= t);
        let rho_next = 1.0 / (2.0 * sigma - rho);
        block_diagonal_apply(&lv.dinv, bs, &lv.r, &mut lv.t);
        let (a, b) = (rho_next * rho, 2.0 * rho_next / delta);
        lv.d.par_iter_mut()
            .with_min_len(4 * MIN_ROWS)
            .zip(&lv.t)
            .for_each(|(d, t)| *d = a * *d + b * t);
        rho = rho_next;
    }
}

/// out = Pᵀ r, gathered per coarse block row through the transpose map.
fn restrict(p: &BlockCsr, pt: &Transpose, r: &[f64], out: &mut [f64]) {
    let (br, bc) = (p.br, p.bc);
    out.par_chunks_mut(bc)
        .with_min_len(MIN_ROWS / 4)
        .enumerate()
        .for_each(|(c, o)| {
            o.fill(0.0);
            for &(i, k) in pt.of(c) {
                let (i, k) = (i as usize, k as usize);
                let block = &p.val[k * br * bc..(k + 1) * br * bc];
                let ri = &r[i * br..(i + 1) * br];
                for (row, rv) in ri.iter().enumerate() {
                    for (col, o) in o.iter_mut().enumerate() {
                        *o += block[row * bc + col] * rv;
                    }
                }
            }
        });
}

/// Near-null space of the fine level: the six rigid-body modes (three translations, three
/// rotations about the centroid, lengths scaled by the bounding-box size so all columns are of
/// one order), `3 × 6` per block row, zero rows on constrained components.
fn rigid_body_modes(fine: &FineMap, coords: &[Vector3<f64>]) -> Vec<f64> {
    let n = fine.nodes.len();
    let mut centre = Vector3::zeros();
    let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
    for &v in &fine.nodes {
        let x = coords[v as usize];
        centre += x;
        lo = lo.inf(&x);
        hi = hi.sup(&x);
    }
    centre /= n.max(1) as f64;
    let scale = 1.0 / (hi - lo).max().max(f64::MIN_POSITIVE);
    let mut b = vec![0.0; n * 3 * MODES];
    for (i, (&v, dofs)) in fine.nodes.iter().zip(&fine.dofs).enumerate() {
        let x = (coords[v as usize] - centre) * scale;
        // Rows: u_x, u_y, u_z; columns: t_x, t_y, t_z, r_x, r_y, r_z (ω × x).
        let rows = [
            [1.0, 0.0, 0.0, 0.0, x.z, -x.y],
            [0.0, 1.0, 0.0, -x.z, 0.0, x.x],
            [0.0, 0.0, 1.0, x.y, -x.x, 0.0],
        ];
        for c in 0..3 {
            if dofs[c] != NONE {
                b[(3 * i + c) * MODES..(3 * i + c + 1) * MODES].copy_from_slice(&rows[c]);
            }
        }
    }
    b
}

/// Standard aggregation (pyamg's three passes) on the block graph of `a` with the symmetric
/// strength of connection. Returns the aggregate of every block row (0-based, dense).
fn aggregate(a: &BlockCsr) -> Vec<u32> {
    let n = a.nrows;
    let bb = a.br * a.bc;
    let strong = |i: usize, k: usize, norms: &[f64], diag: &[usize]| -> bool {
        let j = a.col[k] as usize;
        if j == i {
            return false;
        }
        if STRENGTH == 0.0 {
            return true;
        }
        norms[k] * norms[k] >= STRENGTH * STRENGTH * norms[diag[i]] * norms[diag[j]]
    };
    let (norms, diag) = if STRENGTH == 0.0 {
        (Vec::new(), Vec::new())
    } else {
        let norms: Vec<f64> = a
            .val
            .par_chunks(bb)
            .map(|b| b.iter().map(|v| v * v).sum::<f64>().sqrt())
            .collect();
        (norms, a.diagonal_index())
    };
    let mut agg = vec![NONE; n];
    let mut count = 0u32;
    // Pass 1: a node whose strong neighbours are all free seeds an aggregate with them.
    for i in 0..n {
        if agg[i] != NONE {
            continue;
        }
        let free = (a.ptr[i]..a.ptr[i + 1])
            .filter(|&k| strong(i, k, &norms, &diag))
            .all(|k| agg[a.col[k] as usize] == NONE);
        if free {
            agg[i] = count;
            for k in a.ptr[i]..a.ptr[i + 1] {
                if strong(i, k, &norms, &diag) {
                    agg[a.col[k] as usize] = count;
                }
            }
            count += 1;
        }
    }
    // Pass 2: remaining nodes join a neighbouring aggregate of pass 1.
    let first_pass = agg.clone();
    for (i, g) in agg.iter_mut().enumerate() {
        if *g != NONE {
            continue;
        }
        if let Some(k) = (a.ptr[i]..a.ptr[i + 1])
            .find(|&k| strong(i, k, &norms, &diag) && first_pass[a.col[k] as usize] != NONE)
        {
            *g = first_pass[a.col[k] as usize];
        }
    }
    // Pass 3: what is left (nodes without strong neighbours in any aggregate) seeds new
    // aggregates with its free neighbours.
    for i in 0..n {
        if agg[i] != NONE {
            continue;
        }
        agg[i] = count;
        for k in a.ptr[i]..a.ptr[i + 1] {
            let j = a.col[k] as usize;
            if agg[j] == NONE && strong(i, k, &norms, &diag) {
                agg[j] = count;
            }
        }
        count += 1;
    }
    agg
}

/// Inverses of the diagonal blocks of `a`.
fn block_inverses(a: &BlockCsr, level: usize) -> Result<Vec<f64>, AmgError> {
    let bs = a.br;
    let diag = a.diagonal_index();
    let mut dinv = vec![0.0; a.nrows * bs * bs];
    let failed = dinv
        .par_chunks_mut(bs * bs)
        .with_min_len(MIN_ROWS)
        .enumerate()
        .filter_map(|(i, out)| {
            let k = diag[i];
            if k == usize::MAX {
                return Some(i);
            }
            let block =
                nalgebra::DMatrix::from_row_slice(bs, bs, &a.val[k * bs * bs..(k + 1) * bs * bs]);
            match block.try_inverse() {
                Some(inv) => {
                    for r in 0..bs {
                        for c in 0..bs {
                            out[r * bs + c] = inv[(r, c)];
                        }
                    }
                    None
                }
                None => Some(i),
            }
        })
        .min();
    match failed {
        Some(node) => Err(AmgError::SingularBlock { level, node }),
        None => Ok(dinv),
    }
}

/// Deterministic parallel dot product: fixed chunks summed in order.
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    const CHUNK: usize = 8192;
    let partial: Vec<f64> = a
        .par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(x, y)| x.iter().zip(y).map(|(x, y)| x * y).sum::<f64>())
        .collect();
    partial.iter().sum()
}

/// Estimate of ρ(D⁻¹A) by [`LANCZOS_STEPS`] steps of Lanczos on D⁻¹A in the D inner product
/// (D⁻¹A is self-adjoint there): the largest Ritz value approaches ρ from below much faster
/// than power iteration — on the freezing container, whose largest eigenvectors sit on a few
/// contact nodes, 12 power iterations gave 1.49 where ρ ≈ 1.98, and a Chebyshev interval
/// that short made the V-cycle indefinite.
fn spectral_radius(a: &BlockCsr, dinv: &[f64]) -> f64 {
    let n = a.nrows * a.br;
    let bs = a.br;
    let diag = a.diagonal_index();
    let d_times = |x: &[f64], out: &mut [f64]| {
        out.par_chunks_mut(bs)
            .with_min_len(MIN_ROWS)
            .enumerate()
            .for_each(|(i, o)| {
                let k = diag[i];
                let d = &a.val[k * bs * bs..(k + 1) * bs * bs];
                for (r, o) in o.iter_mut().enumerate() {
                    *o = (0..bs).map(|c| d[r * bs + c] * x[i * bs + c]).sum();
                }
            });
    };
    // A fixed pseudo-random start (a linear congruential sequence): every mode present.
    let mut v: Vec<f64> = (0..n as u64)
        .map(|i| {
            let h = i
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((h >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        })
        .collect();
    let mut previous = vec![0.0; n];
    let mut y = vec![0.0; n];
    let mut z = vec![0.0; n];
    let mut dz = vec![0.0; n];
    d_times(&v, &mut dz);
    let norm = dot(&v, &dz).sqrt();
    if !(norm > 0.0 && norm.is_finite()) {
        return 1.0;
    }
    v.iter_mut().for_each(|x| *x /= norm);
    let (mut alphas, mut betas) = (Vec::new(), Vec::new());
    let mut beta = 0.0;
    for _ in 0..LANCZOS_STEPS.min(n) {
        a.mul(&v, &mut y);
        let alpha = dot(&v, &y);
        block_diagonal_apply(dinv, bs, &y, &mut z);
        z.par_iter_mut()
            .with_min_len(4 * MIN_ROWS)
            .zip(v.par_iter().zip(previous.par_iter()))
            .for_each(|(z, (v, p))| *z -= alpha * v + beta * p);
        alphas.push(alpha);
        d_times(&z, &mut dz);
        beta = dot(&z, &dz).max(0.0).sqrt();
        // The Krylov space is exhausted (or the numbers broke down).
        if beta <= 1e-12 * alpha.abs() || !beta.is_finite() {
            break;
        }
        betas.push(beta);
        std::mem::swap(&mut previous, &mut v);
        v.par_iter_mut()
            .with_min_len(4 * MIN_ROWS)
            .zip(z.par_iter())
            .for_each(|(v, z)| *v = z / beta);
    }
    let k = alphas.len();
    let t = nalgebra::DMatrix::from_fn(k, k, |i, j| {
        if i == j {
            alphas[i]
        } else if i == j + 1 || j == i + 1 {
            betas[i.min(j)]
        } else {
            0.0
        }
    });
    let largest = t
        .symmetric_eigenvalues()
        .iter()
        .copied()
        .fold(0.0, f64::max);
    if largest > 0.0 && largest.is_finite() {
        largest
    } else {
        1.0
    }
}

/// Tentative prolongator T (`br × 6` blocks, one per row, in its aggregate's column) and the
/// coarse near-null space (`6 × 6` per aggregate), from a QR factorisation of the near-null
/// space restricted to each aggregate: T = Q, B_c = R.
fn tentative(agg: &[u32], near_null: &[f64], br: usize) -> (BlockCsr, Vec<f64>) {
    let n = agg.len();
    let count = agg.iter().map(|&g| g as usize + 1).max().unwrap_or(0);
    let mut ptr = vec![0usize; count + 1];
    for &g in agg {
        ptr[g as usize + 1] += 1;
    }
    for k in 0..count {
        ptr[k + 1] += ptr[k];
    }
    let mut fill = ptr.clone();
    let mut members = vec![0u32; n];
    for (i, &g) in agg.iter().enumerate() {
        members[fill[g as usize]] = i as u32;
        fill[g as usize] += 1;
    }
    let rb = br * MODES; // near-null values per block row
    let factors: Vec<(Vec<f64>, [f64; MODES * MODES])> = (0..count)
        .into_par_iter()
        .with_min_len(64)
        .map(|g| {
            let rows = &members[ptr[g]..ptr[g + 1]];
            let m = rows.len() * br;
            // Column-major local copy of B restricted to the aggregate.
            let mut q = vec![0.0; m * MODES];
            for (li, &i) in rows.iter().enumerate() {
                for r in 0..br {
                    for c in 0..MODES {
                        q[c * m + li * br + r] = near_null[i as usize * rb + r * MODES + c];
                    }
                }
            }
            let mut rr = [0.0; MODES * MODES];
            for c in 0..MODES {
                let original = q[c * m..(c + 1) * m]
                    .iter()
                    .map(|v| v * v)
                    .sum::<f64>()
                    .sqrt();
                // Modified Gram–Schmidt, twice ("twice is enough", Giraud et al. 2005).
                for _ in 0..2 {
                    for p in 0..c {
                        let (head, tail) = q.split_at_mut(c * m);
                        let qp = &head[p * m..(p + 1) * m];
                        let qc = &mut tail[..m];
                        let s: f64 = qp.iter().zip(qc.iter()).map(|(a, b)| a * b).sum();
                        for (x, y) in qc.iter_mut().zip(qp) {
                            *x -= s * y;
                        }
                        rr[p * MODES + c] += s;
                    }
                }
                let norm = q[c * m..(c + 1) * m]
                    .iter()
                    .map(|v| v * v)
                    .sum::<f64>()
                    .sqrt();
                // A mode (numerically) spanned by the previous ones carries nothing new: its
                // column of T is zero and its coarse dof decoupled.
                if norm <= 1e-10 * original || norm == 0.0 {
                    q[c * m..(c + 1) * m].fill(0.0);
                } else {
                    q[c * m..(c + 1) * m].iter_mut().for_each(|v| *v /= norm);
                    rr[c * MODES + c] = norm;
                }
            }
            (q, rr)
        })
        .collect();
    let mut t = BlockCsr {
        nrows: n,
        ncols: count,
        br,
        bc: MODES,
        ptr: (0..=n).collect(),
        col: agg.to_vec(),
        val: vec![0.0; n * rb],
    };
    let mut coarse_null = vec![0.0; count * MODES * MODES];
    for (g, (q, rr)) in factors.iter().enumerate() {
        let rows = &members[ptr[g]..ptr[g + 1]];
        let m = rows.len() * br;
        for (li, &i) in rows.iter().enumerate() {
            for r in 0..br {
                for c in 0..MODES {
                    t.val[i as usize * rb + r * MODES + c] = q[c * m + li * br + r];
                }
            }
        }
        coarse_null[g * MODES * MODES..(g + 1) * MODES * MODES].copy_from_slice(rr);
    }
    (t, coarse_null)
}

/// P = (I − ω D⁻¹ A) T, row by row (T has one block per row).
fn smooth_prolongator(a: &BlockCsr, dinv: &[f64], t: &BlockCsr, omega: f64) -> BlockCsr {
    let br = a.br;
    let rb = br * MODES;
    BlockCsr::from_rows(
        a.nrows,
        t.ncols,
        br,
        MODES,
        || {
            (
                (Vec::<u32>::new(), Vec::<f64>::new()),
                Vec::new(),
                Vec::new(),
            )
        },
        |(cols, sums), i, out_cols, out_vals| {
            cols.clear();
            sums.clear();
            // S = Σ_m A_im T_m, grouped by the aggregate of m.
            for k in a.ptr[i]..a.ptr[i + 1] {
                let m = a.col[k] as usize;
                let g = t.col[m];
                let pos = match cols.iter().position(|&c| c == g) {
                    Some(p) => p,
                    None => {
                        cols.push(g);
                        sums.extend(std::iter::repeat_n(0.0, rb));
                        cols.len() - 1
                    }
                };
                let ablock = &a.val[k * br * br..(k + 1) * br * br];
                let tblock = &t.val[m * rb..(m + 1) * rb];
                let s = &mut sums[pos * rb..(pos + 1) * rb];
                for r in 0..br {
                    for j in 0..br {
                        let av = ablock[r * br + j];
                        if av != 0.0 {
                            for c in 0..MODES {
                                s[r * MODES + c] += av * tblock[j * MODES + c];
                            }
                        }
                    }
                }
            }
            let d = &dinv[i * br * br..(i + 1) * br * br];
            let own = t.col[i];
            for (pos, &g) in cols.iter().enumerate() {
                out_cols.push(g);
                let s = &sums[pos * rb..(pos + 1) * rb];
                for r in 0..br {
                    for c in 0..MODES {
                        let ds: f64 = (0..br).map(|j| d[r * br + j] * s[j * MODES + c]).sum();
                        let tv = if g == own {
                            t.val[i * rb + r * MODES + c]
                        } else {
                            0.0
                        };
                        out_vals.push(tv - omega * ds);
                    }
                }
            }
        },
    )
}

/// Scratch of one Galerkin-product task.
struct GalerkinScratch {
    /// Local index of each fine row in the chunk's A P, or NONE.
    local: Vec<u32>,
    /// Position of each coarse column in the row being built, or NONE.
    mark: Vec<u32>,
}

/// A_c = Pᵀ A P (`6 × 6` blocks). Coarse rows are built in chunks of consecutive aggregates;
/// each chunk forms the rows of A P its aggregates need, then gathers Pᵀ through the transpose
/// map. Coarse dofs whose prolongator column is zero (dropped modes) get a unit diagonal.
fn galerkin(a: &BlockCsr, p: &BlockCsr, pt: &Transpose) -> BlockCsr {
    match a.br {
        3 => galerkin_fixed::<3>(a, p, pt),
        6 => galerkin_fixed::<6>(a, p, pt),
        _ => unreachable!("block sizes are 3 or 6"),
    }
}

fn galerkin_fixed<const R: usize>(a: &BlockCsr, p: &BlockCsr, pt: &Transpose) -> BlockCsr {
    const K: usize = MODES;
    let nc = p.ncols;
    type Chunk = (Vec<usize>, Vec<u32>, Vec<f64>);
    let chunks: Vec<Chunk> = (0..nc.div_ceil(RAP_CHUNK))
        .into_par_iter()
        .map_init(
            || GalerkinScratch {
                local: vec![NONE; a.nrows],
                mark: vec![NONE; nc],
            },
            |s, chunk| {
                let rows = chunk * RAP_CHUNK..((chunk + 1) * RAP_CHUNK).min(nc);
                let mut fine_rows: Vec<u32> = Vec::new();
                for c in rows.clone() {
                    for &(i, _) in pt.of(c) {
                        if s.local[i as usize] == NONE {
                            s.local[i as usize] = fine_rows.len() as u32;
                            fine_rows.push(i);
                        }
                    }
                }
                // A P for the fine rows of this chunk.
                let mut ap_ptr = Vec::with_capacity(fine_rows.len() + 1);
                let mut ap_col: Vec<u32> = Vec::new();
                let mut ap_val: Vec<f64> = Vec::new();
                ap_ptr.push(0);
                for &i in &fine_rows {
                    let start = ap_col.len();
                    for k in a.ptr[i as usize]..a.ptr[i as usize + 1] {
                        let m = a.col[k] as usize;
                        let ablock = &a.val[k * R * R..(k + 1) * R * R];
                        for kp in p.ptr[m]..p.ptr[m + 1] {
                            let j = p.col[kp] as usize;
                            let pos = if s.mark[j] == NONE {
                                s.mark[j] = (ap_col.len() - start) as u32;
                                ap_col.push(j as u32);
                                ap_val.extend(std::iter::repeat_n(0.0, R * K));
                                ap_col.len() - 1
                            } else {
                                start + s.mark[j] as usize
                            };
                            let pblock = &p.val[kp * R * K..(kp + 1) * R * K];
                            let out = &mut ap_val[pos * R * K..(pos + 1) * R * K];
                            for r in 0..R {
                                for q in 0..R {
                                    let av = ablock[r * R + q];
                                    for c in 0..K {
                                        out[r * K + c] += av * pblock[q * K + c];
                                    }
                                }
                            }
                        }
                    }
                    for &j in &ap_col[start..] {
                        s.mark[j as usize] = NONE;
                    }
                    ap_ptr.push(ap_col.len());
                }
                // Coarse rows: Σ_i P_iIᵀ (A P)_i.
                let mut counts = Vec::with_capacity(rows.len());
                let mut cols: Vec<u32> = Vec::new();
                let mut vals: Vec<f64> = Vec::new();
                for c in rows {
                    let start = cols.len();
                    for &(i, kp) in pt.of(c) {
                        let pblock = &p.val[kp as usize * R * K..(kp as usize + 1) * R * K];
                        let li = s.local[i as usize] as usize;
                        for q in ap_ptr[li]..ap_ptr[li + 1] {
                            let j = ap_col[q] as usize;
                            let pos = if s.mark[j] == NONE {
                                s.mark[j] = (cols.len() - start) as u32;
                                cols.push(j as u32);
                                vals.extend(std::iter::repeat_n(0.0, K * K));
                                cols.len() - 1
                            } else {
                                start + s.mark[j] as usize
                            };
                            let apb = &ap_val[q * R * K..(q + 1) * R * K];
                            let out = &mut vals[pos * K * K..(pos + 1) * K * K];
                            for r in 0..R {
                                for x in 0..K {
                                    let pv = pblock[r * K + x];
                                    if pv != 0.0 {
                                        for y in 0..K {
                                            out[x * K + y] += pv * apb[r * K + y];
                                        }
                                    }
                                }
                            }
                        }
                    }
                    for (off, &j) in cols[start..].iter().enumerate() {
                        s.mark[j as usize] = NONE;
                        if j as usize == c {
                            let block = &mut vals[(start + off) * K * K..(start + off + 1) * K * K];
                            for d in 0..K {
                                if block[d * K + d] == 0.0 {
                                    block[d * K + d] = 1.0;
                                }
                            }
                        }
                    }
                    counts.push(cols.len() - start);
                }
                for &i in &fine_rows {
                    s.local[i as usize] = NONE;
                }
                (counts, cols, vals)
            },
        )
        .collect();
    let nnzb: usize = chunks.iter().map(|c| c.1.len()).sum();
    let mut ptr = Vec::with_capacity(nc + 1);
    let mut col = Vec::with_capacity(nnzb);
    let mut val = Vec::with_capacity(nnzb * K * K);
    ptr.push(0);
    for (counts, cols, vals) in chunks {
        for n in counts {
            ptr.push(ptr.last().copied().unwrap_or(0) + n);
        }
        col.extend_from_slice(&cols);
        val.extend_from_slice(&vals);
    }
    BlockCsr {
        nrows: nc,
        ncols: nc,
        br: K,
        bc: K,
        ptr,
        col,
        val,
    }
}
