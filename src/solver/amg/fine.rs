//! The fine level: how the free-dof system maps onto 3 × 3 node blocks, its values in block
//! form, vectors between the two layouts, and the rigid-body modes of its nodes.

use super::block_csr::{BlockCsr, MIN_ROWS, NONE};
use crate::assembly::Assembly;
use nalgebra::Vector3;
use rayon::prelude::*;

/// Coarse dofs per aggregate: the six rigid-body modes.
pub(super) const MODES: usize = 6;

/// How the fine (free-dof) system maps onto node blocks.
#[derive(Clone, Debug)]
pub(super) struct FineMap {
    /// For each block row (node with a free dof), the free index of each component or NONE.
    dofs: Vec<[u32; 3]>,
    /// Global node of each block row.
    nodes: Vec<u32>,
    /// Block row of each free dof.
    block_of: Vec<u32>,
}

impl FineMap {
    pub(super) fn new(assembly: &Assembly) -> Self {
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
    pub(super) fn pattern(&self, assembly: &Assembly) -> BlockCsr {
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
    pub(super) fn gather(&self, assembly: &Assembly, values: &[f64], a: &mut BlockCsr) {
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

/// Free-dof vector → padded block vector (zero on constrained components).
pub(super) fn scatter(fine: &FineMap, v: &[f64], out: &mut [f64]) {
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
pub(super) fn gather(fine: &FineMap, v: &[f64], out: &mut [f64]) {
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

/// Near-null space of the fine level: the six rigid-body modes (three translations, three
/// rotations about the centroid, lengths scaled by the bounding-box size so all columns are of
/// one order), `3 × 6` per block row, zero rows on constrained components.
pub(super) fn rigid_body_modes(fine: &FineMap, coords: &[Vector3<f64>]) -> Vec<f64> {
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
