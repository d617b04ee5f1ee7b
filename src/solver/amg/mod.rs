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

mod block_csr;
mod fine;
mod setup;

pub use block_csr::BlockCsr;
pub use setup::{AmgError, STRENGTH};

use block_csr::{block_diagonal_apply, Transpose, MIN_ROWS};
use fine::{gather, rigid_body_modes, scatter, FineMap, MODES};
use setup::{aggregate, block_inverses, galerkin, smooth_prolongator, spectral_radius, tentative};

use crate::assembly::Assembly;
use faer::linalg::solvers::SolveCore;
use faer::{Conj, Mat, MatMut, Side};
use nalgebra::Vector3;
use rayon::prelude::*;

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

/// x += y.
fn add_assign(x: &mut [f64], y: &[f64]) {
    x.par_iter_mut()
        .with_min_len(4 * MIN_ROWS)
        .zip(y)
        .for_each(|(x, y)| *x += y);
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
