//! The numeric set-up of one level: aggregation, inverse diagonal blocks, the spectral-radius
//! estimate, the tentative and smoothed prolongators, and the Galerkin coarse operator.

use super::block_csr::{block_diagonal_apply, BlockCsr, Transpose, MIN_ROWS, NONE};
use super::fine::MODES;
use crate::solver::vector::dot;
use rayon::prelude::*;
use std::ops::Range;

/// Strength threshold θ of the block strength of connection. 0 keeps every coupling (pyamg's
/// default for smoothed aggregation): on ice meshes all couplings are of one order, and with
/// θ = 0 the aggregation depends on the pattern only, so it stays valid while the pattern does.
pub const STRENGTH: f64 = 0.0;
/// Lanczos steps for the estimate of ρ(D⁻¹A).
const LANCZOS_STEPS: usize = 20;
/// Aggregates per chunk of the Galerkin product.
const RAP_CHUNK: usize = 512;

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

/// Standard aggregation (pyamg's three passes) on the block graph of `a` with the symmetric
/// strength of connection. Returns the aggregate of every block row (0-based, dense).
pub(super) fn aggregate(a: &BlockCsr) -> Vec<u32> {
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
pub(super) fn block_inverses(a: &BlockCsr, level: usize) -> Result<Vec<f64>, AmgError> {
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

/// Estimate of ρ(D⁻¹A) by [`LANCZOS_STEPS`] steps of Lanczos on D⁻¹A in the D inner product
/// (D⁻¹A is self-adjoint there): the largest Ritz value approaches ρ from below much faster
/// than power iteration — on the freezing container, whose largest eigenvectors sit on a few
/// contact nodes, 12 power iterations gave 1.49 where ρ ≈ 1.98, and a Chebyshev interval
/// that short made the V-cycle indefinite.
pub(super) fn spectral_radius(a: &BlockCsr, dinv: &[f64]) -> f64 {
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
pub(super) fn tentative(agg: &[u32], near_null: &[f64], br: usize) -> (BlockCsr, Vec<f64>) {
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
pub(super) fn smooth_prolongator(a: &BlockCsr, dinv: &[f64], t: &BlockCsr, omega: f64) -> BlockCsr {
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
pub(super) fn galerkin(a: &BlockCsr, p: &BlockCsr, pt: &Transpose) -> BlockCsr {
    match a.br {
        3 => galerkin_fixed::<3>(a, p, pt),
        6 => galerkin_fixed::<6>(a, p, pt),
        _ => unreachable!("block sizes are 3 or 6"),
    }
}

fn galerkin_fixed<const R: usize>(a: &BlockCsr, p: &BlockCsr, pt: &Transpose) -> BlockCsr {
    let nc = p.ncols;
    let chunks: Vec<CoarseRows> = (0..nc.div_ceil(RAP_CHUNK))
        .into_par_iter()
        .map_init(
            || GalerkinScratch {
                local: vec![NONE; a.nrows],
                mark: vec![NONE; nc],
            },
            |s, chunk| {
                let rows = chunk * RAP_CHUNK..((chunk + 1) * RAP_CHUNK).min(nc);
                let fine_rows = chunk_fine_rows(pt, rows.clone(), s);
                let ap = ap_rows::<R>(a, p, &fine_rows, s);
                let coarse = coarse_rows::<R>(p, pt, rows, &ap, s);
                for &i in &fine_rows {
                    s.local[i as usize] = NONE;
                }
                coarse
            },
        )
        .collect();
    join_coarse_rows(chunks, nc)
}

/// Rows of A P (`R × MODES` blocks) for some fine rows, in CSR form.
struct ApRows {
    ptr: Vec<usize>,
    col: Vec<u32>,
    val: Vec<f64>,
}

/// Consecutive rows of A_c (`MODES × MODES` blocks): the entries of each row, their columns
/// and blocks.
struct CoarseRows {
    counts: Vec<usize>,
    cols: Vec<u32>,
    vals: Vec<f64>,
}

/// The fine rows the coarse `rows` gather from through Pᵀ, each numbered in `s.local` by its
/// position in the returned list.
fn chunk_fine_rows(pt: &Transpose, rows: Range<usize>, s: &mut GalerkinScratch) -> Vec<u32> {
    let mut fine_rows: Vec<u32> = Vec::new();
    for c in rows {
        for &(i, _) in pt.of(c) {
            if s.local[i as usize] == NONE {
                s.local[i as usize] = fine_rows.len() as u32;
                fine_rows.push(i);
            }
        }
    }
    fine_rows
}

/// A P for `fine_rows` (`s.mark` is left clear).
fn ap_rows<const R: usize>(
    a: &BlockCsr,
    p: &BlockCsr,
    fine_rows: &[u32],
    s: &mut GalerkinScratch,
) -> ApRows {
    const K: usize = MODES;
    let mut ap_ptr = Vec::with_capacity(fine_rows.len() + 1);
    let mut ap_col: Vec<u32> = Vec::new();
    let mut ap_val: Vec<f64> = Vec::new();
    ap_ptr.push(0);
    for &i in fine_rows {
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
    ApRows {
        ptr: ap_ptr,
        col: ap_col,
        val: ap_val,
    }
}

/// The coarse `rows` Σ_i P_iIᵀ (A P)_i, from the rows `ap` of A P numbered by `s.local`; a
/// zero on a diagonal block's diagonal becomes 1 (`s.mark` is left clear).
fn coarse_rows<const R: usize>(
    p: &BlockCsr,
    pt: &Transpose,
    rows: Range<usize>,
    ap: &ApRows,
    s: &mut GalerkinScratch,
) -> CoarseRows {
    const K: usize = MODES;
    let (ap_ptr, ap_col, ap_val) = (&ap.ptr, &ap.col, &ap.val);
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
    CoarseRows { counts, cols, vals }
}

/// A_c (`nc` block rows) from its chunks of rows, in order.
fn join_coarse_rows(chunks: Vec<CoarseRows>, nc: usize) -> BlockCsr {
    const K: usize = MODES;
    let nnzb: usize = chunks.iter().map(|c| c.cols.len()).sum();
    let mut ptr = Vec::with_capacity(nc + 1);
    let mut col = Vec::with_capacity(nnzb);
    let mut val = Vec::with_capacity(nnzb * K * K);
    ptr.push(0);
    for CoarseRows { counts, cols, vals } in chunks {
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
