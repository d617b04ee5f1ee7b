//! Block compressed-sparse-row matrices of the hierarchy, the transpose map through which a
//! prolongator is applied transposed, and the block-diagonal product.

use rayon::prelude::*;

/// Rows of a parallel task in block-row loops.
pub(super) const MIN_ROWS: usize = 512;
/// Marks an empty slot.
pub(super) const NONE: u32 = u32::MAX;

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
    pub(super) fn residual(&self, b: &[f64], x: &[f64], r: &mut [f64]) {
        self.mul(x, r);
        r.par_iter_mut()
            .with_min_len(MIN_ROWS)
            .zip(b)
            .for_each(|(r, b)| *r = b - *r);
    }

    /// Index of the block (i, i) of each row (square matrices; every row has one).
    pub(super) fn diagonal_index(&self) -> Vec<usize> {
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
    pub(super) fn from_rows<S, I, F>(
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
pub(super) struct Transpose {
    ptr: Vec<usize>,
    entries: Vec<(u32, u32)>,
}

impl Transpose {
    pub(super) fn new(p: &BlockCsr) -> Self {
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
    pub(super) fn of(&self, c: usize) -> &[(u32, u32)] {
        &self.entries[self.ptr[c]..self.ptr[c + 1]]
    }
    pub(super) fn bytes(&self) -> usize {
        self.ptr.len() * 8 + self.entries.len() * 8
    }
}

/// out_i = D_i⁻¹ v_i (block diagonal, blocks of `bs`).
pub(super) fn block_diagonal_apply(dinv: &[f64], bs: usize, v: &[f64], out: &mut [f64]) {
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
