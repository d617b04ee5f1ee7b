//! Low-rank correction of a kept Cholesky factor for the few matrix entries that changed by a
//! large factor since the factorisation (Sherman–Morrison–Woodbury).
//!
//! A factor kept across Newton iterations and steps preconditions CG on the current matrix
//! A = F + Δ, F the factored matrix. Most of Δ is small relative to F — a freezing band, the
//! friction stiffness growing with the wall pressure — and leaves the preconditioned spectrum
//! clustered at 1; but a contact switching on or off changes a handful of diagonal entries by
//! orders of magnitude (k A = 3.4e9 N/m, some 400× the stiffness of the water nodes they
//! hold), and each such entry is an outlying eigenvalue that costs CG about one iteration in
//! every solve until the factor is replaced. Measured on the 1e5-tet freezing container (steps 91–102):
//! a factor one step old sees ~21 000 diagonal entries changed by more than 1 %, but only 6–24
//! by more than a factor 2 — and those 6–24 are the same set at 50 %, 100 % and 1000 %.
//!
//! The correction takes those entries, S, exactly: with E the columns of the identity at S
//! and G = (A − F)[S, S], the preconditioner is (F + E G Eᵀ)⁻¹ =
//! F⁻¹ − Y (I + G H)⁻¹ G Yᵀ with Y = F⁻¹ E (one triangular solve per corrected dof, kept for
//! the factor's life) and H = Eᵀ Y. G is re-read from the current matrix at every solve, so a
//! dof that changes further costs nothing more.

use crate::assembly::Assembly;
use nalgebra::DMatrix;
use rayon::prelude::*;

/// A diagonal entry is corrected exactly when it grew or shrank by more than this factor since
/// the factorisation (the measured sets are the same from 1.5 to 11).
pub const LARGE_CHANGE_RATIO: f64 = 2.0;

/// At most this many corrected dofs per factor: each costs one triangular solve to set up and
/// an axpy of the system's length per CG iteration, and the longer a factor lives the more the
/// small changes it leaves to CG add up. Steps 91–102 of the 1e5-tet container (resumed from
/// step 90, same hour): 10.7 s with 48 (the factor lasts 8 steps), 11.3 s with 96 (11 steps,
/// 26 more CG and 4 more Newton iterations). Beyond it CG's iteration budget replaces the
/// factor.
pub const MAX_CORRECTED_DOFS: usize = 48;

/// Rows per parallel chunk of the correction's update of z.
const CHUNK: usize = 4096;

/// The Woodbury correction of one kept factor: the corrected dofs and their columns of F⁻¹.
#[derive(Default)]
pub struct LowRankCorrection {
    /// The corrected dofs S, in the order their columns were added.
    dofs: Vec<usize>,
    /// Per free dof: whether it is in `dofs`.
    selected: Vec<bool>,
    /// Y = F⁻¹ E, column-major (n × |S|).
    y: Vec<f64>,
    /// (I + G H)⁻¹ G for the current matrix, |S| × |S|, symmetrised.
    gain: DMatrix<f64>,
    /// z at S, and gain · z[S] (per application).
    z_s: Vec<f64>,
    update: Vec<f64>,
}

impl LowRankCorrection {
    /// Forgets every corrected dof (the factor was replaced); keeps the allocations.
    pub fn clear(&mut self) {
        self.dofs.clear();
        self.selected.fill(false);
        self.y.clear();
        self.gain = DMatrix::zeros(0, 0);
    }

    /// Brings the correction to the matrix with `values` (on `assembly`'s pattern) for the
    /// factor of `factored`: adds the dofs whose diagonal changed by more than
    /// [`LARGE_CHANGE_RATIO`] (up to [`MAX_CORRECTED_DOFS`]), computing their columns of F⁻¹
    /// in one call of `solve_factor` (an n × k column-major block, X ← F⁻¹ X), and recomputes
    /// the gain from the current values. An error of `solve_factor` is returned, the
    /// correction left as it was.
    pub fn update<E>(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
        factored: &[f64],
        solve_factor: impl FnOnce(&mut [f64]) -> Result<(), E>,
    ) -> Result<(), E> {
        let n = assembly.symbolic().nrows();
        if self.selected.len() != n {
            self.clear();
            self.selected = vec![false; n];
        }
        if factored.len() != values.len() {
            // No record of the factored matrix (a failed factorisation): nothing to correct.
            self.clear();
            return Ok(());
        }
        let first_new = self.dofs.len();
        for c in 0..n {
            if self.dofs.len() == MAX_CORRECTED_DOFS {
                break;
            }
            if self.selected[c] {
                continue;
            }
            let k = assembly.diagonal_slot(c);
            let (new, old) = (values[k], factored[k]);
            // Written so that a NaN or non-positive diagonal is never selected: the
            // factorisation, not the correction, has to deal with those.
            let grew = new > LARGE_CHANGE_RATIO * old && old > 0.0;
            let shrank = old > LARGE_CHANGE_RATIO * new && new > 0.0;
            if grew || shrank {
                self.selected[c] = true;
                self.dofs.push(c);
            }
        }
        let added = self.dofs.len() - first_new;
        if added > 0 {
            // All columns' room at once: growing by doubling would hold twice the columns,
            // and old and new buffers at the moment of a reallocation.
            self.y.reserve_exact(MAX_CORRECTED_DOFS * n - self.y.len());
            let start = self.y.len();
            self.y.resize(start + added * n, 0.0);
            for (j, &d) in self.dofs[first_new..].iter().enumerate() {
                self.y[start + j * n + d] = 1.0;
            }
            if let Err(e) = solve_factor(&mut self.y[start..]) {
                // No half-made columns: the correction stays as it was.
                for &d in &self.dofs[first_new..] {
                    self.selected[d] = false;
                }
                self.dofs.truncate(first_new);
                self.y.truncate(start);
                return Err(e);
            }
        }
        let m = self.dofs.len();
        let g = DMatrix::from_fn(m, m, |a, b| {
            assembly
                .slot(self.dofs[a], self.dofs[b])
                .map_or(0.0, |k| values[k] - factored[k])
        });
        let h = DMatrix::from_fn(m, m, |a, b| self.y[b * n + self.dofs[a]]);
        let system = DMatrix::identity(m, m) + &g * h;
        // (I + G H) is invertible whenever F + E G Eᵀ is (it is the current matrix with
        // the small changes left out); if round-off says otherwise, no correction.
        self.gain = system
            .lu()
            .solve(&g)
            .map(|k| (&k + k.transpose()) * 0.5)
            .unwrap_or_else(|| DMatrix::zeros(m, m));
        self.z_s.resize(m, 0.0);
        self.update.resize(m, 0.0);
        Ok(())
    }

    /// z ← z − Y · gain · z\[S\]: turns z = F⁻¹ r into (F + E G Eᵀ)⁻¹ r.
    pub fn apply(&mut self, z: &mut [f64]) {
        let m = self.dofs.len();
        if m == 0 {
            return;
        }
        let n = z.len();
        for (z_s, &d) in self.z_s.iter_mut().zip(&self.dofs) {
            *z_s = z[d];
        }
        for (a, u) in self.update.iter_mut().enumerate() {
            *u = (0..m).map(|b| self.gain[(a, b)] * self.z_s[b]).sum();
        }
        let (y, update) = (&self.y, &self.update);
        z.par_chunks_mut(CHUNK).enumerate().for_each(|(chunk, z)| {
            let start = chunk * CHUNK;
            for (j, &u) in update.iter().enumerate() {
                let column = &y[j * n + start..j * n + start + z.len()];
                for (z, &y) in z.iter_mut().zip(column) {
                    *z -= u * y;
                }
            }
        });
    }
}
