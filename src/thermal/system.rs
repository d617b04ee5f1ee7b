//! The heat step's linear system on the free nodes: a fixed sparse pattern (lower triangle,
//! node adjacency through the elements), a slot per element-matrix entry, one symbolic
//! Cholesky analysis (AMD) for the run and a numeric factorisation per Newton iteration.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::mat::MatMut;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, Par, Side};

/// A symmetric positive definite matrix on the free nodes, its pattern and factor.
pub struct ScalarSystem {
    pattern: SymbolicSparseColMat<usize>,
    /// Slot in `values` of each element's (a, b) entry, a ≥ b in free numbering order, for
    /// the 10 pairs of [`PAIRS`]; `usize::MAX` where a node is not free.
    slots: Vec<[usize; 10]>,
    /// Slot of each free node's diagonal entry.
    diagonal: Vec<usize>,
    /// Matrix values in the pattern's order.
    pub values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    l: Vec<f64>,
    work: MemBuffer,
    /// The values the factor `l` is of (empty: none yet, or the last factorisation failed).
    factored: Vec<f64>,
}

/// The element-matrix entries stored per element: (a, b) with a ≤ b, row by row.
pub const PAIRS: [(usize, usize); 10] = [
    (0, 0),
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 1),
    (1, 2),
    (1, 3),
    (2, 2),
    (2, 3),
    (3, 3),
];

impl ScalarSystem {
    /// The pattern of `tets` restricted to the free nodes (`free[i]`: the free number of node
    /// i, or `None`), `n` of them, and its symbolic factorisation.
    pub fn new(tets: &[[usize; 4]], free: &[Option<usize>], n: usize) -> Result<Self, String> {
        // Lower-triangle neighbours of each free column.
        let mut columns: Vec<Vec<usize>> = (0..n).map(|c| vec![c]).collect();
        for tet in tets {
            for &(a, b) in &PAIRS {
                if let (Some(i), Some(j)) = (free[tet[a]], free[tet[b]]) {
                    let (row, col) = (i.max(j), i.min(j));
                    columns[col].push(row);
                }
            }
        }
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for c in &mut columns {
            c.sort_unstable();
            c.dedup();
            row_idx.extend_from_slice(c);
            col_ptr.push(row_idx.len());
        }
        let slot = |row: usize, col: usize| {
            let range = col_ptr[col]..col_ptr[col + 1];
            col_ptr[col] + row_idx[range].binary_search(&row).expect("in the pattern")
        };
        let slots = tets
            .iter()
            .map(|tet| {
                PAIRS.map(|(a, b)| match (free[tet[a]], free[tet[b]]) {
                    (Some(i), Some(j)) => slot(i.max(j), i.min(j)),
                    _ => usize::MAX,
                })
            })
            .collect();
        let diagonal = (0..n).map(|i| slot(i, i)).collect();
        let nnz = row_idx.len();
        let pattern = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let symbolic = factorize_symbolic_cholesky(
            pattern.as_ref(),
            Side::Lower,
            SymmetricOrdering::Amd,
            Default::default(),
        )
        .map_err(|e| format!("symbolic factorisation: {e:?}"))?;
        let req = symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        let work = MemBuffer::try_new(req).map_err(|e| format!("scratch: {e:?}"))?;
        Ok(ScalarSystem {
            l: vec![0.0; symbolic.len_val()],
            pattern,
            slots,
            diagonal,
            values: vec![0.0; nnz],
            symbolic,
            work,
            factored: Vec::new(),
        })
    }

    /// Zeroes the values.
    pub fn clear(&mut self) {
        self.values.fill(0.0);
    }

    /// Adds `entries` (the element matrix's [`PAIRS`]) of element `e` where both nodes are free.
    pub fn add_element(&mut self, e: usize, entries: &[f64; 10]) {
        for (slot, v) in self.slots[e].iter().zip(entries) {
            if *slot != usize::MAX {
                self.values[*slot] += v;
            }
        }
    }

    /// Adds `v` to entry `pair` (of [`PAIRS`]) of element `e`, if both its nodes are free.
    pub fn add_element_entry(&mut self, e: usize, pair: usize, v: f64) {
        let slot = self.slots[e][pair];
        if slot != usize::MAX {
            self.values[slot] += v;
        }
    }

    /// Adds `v` to free node `i`'s diagonal entry.
    pub fn add_diagonal(&mut self, i: usize, v: f64) {
        self.values[self.diagonal[i]] += v;
    }

    /// The largest diagonal entry of the rows marked in `counted` (0 for none).
    pub fn largest_diagonal(&self, counted: &[bool]) -> f64 {
        self.diagonal
            .iter()
            .zip(counted)
            .filter(|(_, &c)| c)
            .fold(0.0f64, |m, (&slot, _)| m.max(self.values[slot]))
    }

    /// Number of free nodes (rows).
    pub fn rows(&self) -> usize {
        self.diagonal.len()
    }

    /// The entries of each row of the symmetric matrix: (column, slot in `values`), both
    /// triangles.
    pub fn row_entries(&self) -> Vec<Vec<(usize, usize)>> {
        let mut rows = vec![Vec::new(); self.rows()];
        let (col_ptr, row_idx) = (self.pattern.col_ptr(), self.pattern.row_idx());
        for c in 0..self.rows() {
            let range = col_ptr[c]..col_ptr[c + 1];
            for (slot, &r) in range.clone().zip(&row_idx[range]) {
                rows[r].push((c, slot));
                if r != c {
                    rows[c].push((r, slot));
                }
            }
        }
        rows
    }

    /// Whether the last factorisation was of exactly the current values (bit for bit: the
    /// same step length and phases, no node in the mushy range — a frozen block cooling, or
    /// conduction without phase change).
    pub fn holds_factored(&self) -> bool {
        self.factored.len() == self.values.len()
            && self
                .factored
                .iter()
                .zip(&self.values)
                .all(|(a, b)| a.to_bits() == b.to_bits())
    }

    /// Records the current values as factorised (by a solver outside this system).
    pub fn remember_factored(&mut self) {
        self.factored.clone_from(&self.values);
    }

    /// Factorises the current values, unless the factor is already of exactly these values
    /// ([`ScalarSystem::holds_factored`]); returns whether it factorised. An error names the
    /// pivot that was not positive.
    pub fn factor(&mut self) -> Result<bool, String> {
        if self.holds_factored() {
            return Ok(false);
        }
        self.factored.clear();
        let matrix = SparseColMatRef::new(self.pattern.as_ref(), &self.values);
        self.symbolic
            .factorize_numeric_llt::<f64>(
                &mut self.l,
                matrix,
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut self.work),
                Default::default(),
            )
            .map_err(|e| format!("the heat system is not positive definite: {e:?}"))?;
        self.factored.clone_from(&self.values);
        Ok(true)
    }

    /// x ← A⁻¹ x with the last factor.
    pub fn solve_in_place(&mut self, x: &mut [f64]) {
        let n = x.len();
        LltRef::new(&self.symbolic, &self.l).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(x, n, 1),
            Par::Seq,
            MemStack::new(&mut self.work),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_entries_are_both_triangles_of_the_pattern() {
        // Two tets sharing the face 1-2-3; node 4 is held (not free).
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4]];
        let free = [Some(0), Some(1), Some(2), Some(3), None];
        let mut system = ScalarSystem::new(&tets, &free, 4).unwrap();
        for (k, v) in system.values.iter_mut().enumerate() {
            *v = k as f64 + 1.0;
        }
        let rows = system.row_entries();
        assert_eq!(rows.len(), 4);
        // Every free node couples with every other (they share tet 0), itself included.
        for (i, row) in rows.iter().enumerate() {
            let mut columns: Vec<usize> = row.iter().map(|&(c, _)| c).collect();
            columns.sort_unstable();
            assert_eq!(columns, vec![0, 1, 2, 3], "row {i}");
        }
        // (i, j) and (j, i) read the same stored value.
        for (i, row) in rows.iter().enumerate() {
            for &(j, slot) in row {
                let back = rows[j].iter().find(|&&(c, _)| c == i).unwrap().1;
                assert_eq!(slot, back);
            }
        }
        assert!(!system.holds_factored());
        system.remember_factored();
        assert!(system.holds_factored());
        assert_eq!(system.largest_diagonal(&[true, false, false, false]), {
            let slot = rows[0].iter().find(|&&(c, _)| c == 0).unwrap().1;
            system.values[slot]
        });
    }
}
