//! Preconditioned conjugate gradients, parallel (rayon) and bit-reproducible: every product
//! writes disjoint entries and every dot product sums fixed chunks in a fixed order.

use super::vector::dot;
use crate::assembly::Assembly;
use rayon::prelude::*;

/// Entries per parallel task in vector loops.
const MIN_LEN: usize = 4096;

/// The operator and the preconditioner of a PCG solve.
pub trait PcgOperators {
    /// y = A x.
    fn apply(&mut self, x: &[f64], y: &mut [f64]);
    /// z = M⁻¹ r (M symmetric positive definite).
    fn precondition(&mut self, r: &[f64], z: &mut [f64]);
}

/// A preconditioner of PCG.
pub trait Preconditioner {
    /// z = M⁻¹ r (M symmetric positive definite).
    fn precondition(&mut self, r: &[f64], z: &mut [f64]);
}

/// The free-system matrix of an [`Assembly`] with these values (its product by
/// [`symmetric_multiply`]) and a preconditioner, as PCG's operators.
pub struct MatrixOperators<'a, P> {
    /// The pattern (both triangles of the free system).
    pub assembly: &'a Assembly,
    /// The matrix values on that pattern.
    pub values: &'a [f64],
    /// M⁻¹.
    pub preconditioner: P,
}

impl<P: Preconditioner> PcgOperators for MatrixOperators<'_, P> {
    fn apply(&mut self, x: &[f64], y: &mut [f64]) {
        symmetric_multiply(self.assembly, self.values, x, y);
    }
    fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        self.preconditioner.precondition(r, z);
    }
}

/// Why PCG stopped without converging.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PcgFailure {
    /// pᵀAp ≤ 0: the matrix is not positive definite (at this iteration, 1-based).
    NegativeCurvature { iteration: usize },
    /// rᵀM⁻¹r ≤ 0 or not finite: the preconditioner is not positive definite.
    Breakdown { iteration: usize },
    /// Stopped without converging (the iteration cap, or the checkpoint missed) after
    /// `iterations`, at this relative residual.
    NoConvergence { iterations: usize, residual: f64 },
}

impl PcgFailure {
    /// Iterations done before stopping (paid for, whatever the outcome).
    pub fn iterations(&self) -> usize {
        match *self {
            PcgFailure::NegativeCurvature { iteration } | PcgFailure::Breakdown { iteration } => {
                iteration
            }
            PcgFailure::NoConvergence { iterations, .. } => iterations,
        }
    }
}

/// Work vectors of PCG (allocated once per system size).
#[derive(Clone, Debug, Default)]
pub struct PcgWork {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
}

impl PcgWork {
    /// Vectors for `n` unknowns.
    pub fn new(n: usize) -> Self {
        PcgWork {
            r: vec![0.0; n],
            z: vec![0.0; n],
            p: vec![0.0; n],
            q: vec![0.0; n],
        }
    }
}

/// Solves A x = b from x = 0 until ‖b − A x‖₂ ≤ `tolerance` ‖b‖₂; returns the iterations.
/// `checkpoint = Some((k, r))`: give up if the relative residual after k iterations is still
/// above r (a stale preconditioner that is going to fail shows it early).
pub fn pcg(
    ops: &mut impl PcgOperators,
    b: &[f64],
    x: &mut [f64],
    tolerance: f64,
    max_iterations: usize,
    checkpoint: Option<(usize, f64)>,
    work: &mut PcgWork,
) -> Result<usize, PcgFailure> {
    let PcgWork { r, z, p, q } = work;
    x.fill(0.0);
    r.copy_from_slice(b);
    let b_norm = dot(b, b).sqrt();
    if b_norm == 0.0 {
        return Ok(0);
    }
    let target = tolerance * b_norm;
    ops.precondition(r, z);
    p.copy_from_slice(z);
    let mut rz = dot(r, z);
    if !(rz > 0.0 && rz.is_finite()) {
        return Err(PcgFailure::Breakdown { iteration: 0 });
    }
    let mut residual = b_norm;
    for iteration in 1..=max_iterations {
        ops.apply(p, q);
        let pq = dot(p, q);
        // Not `pq <= 0.0`: a NaN must stop here too.
        if pq.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(PcgFailure::NegativeCurvature { iteration });
        }
        let alpha = rz / pq;
        x.par_iter_mut()
            .with_min_len(MIN_LEN)
            .zip(p.par_iter())
            .for_each(|(x, p)| *x += alpha * p);
        r.par_iter_mut()
            .with_min_len(MIN_LEN)
            .zip(q.par_iter())
            .for_each(|(r, q)| *r -= alpha * q);
        residual = dot(r, r).sqrt();
        if residual <= target {
            return Ok(iteration);
        }
        if checkpoint.is_some_and(|(k, limit)| iteration == k && residual > limit * b_norm) {
            return Err(PcgFailure::NoConvergence {
                iterations: iteration,
                residual: residual / b_norm,
            });
        }
        ops.precondition(r, z);
        let rz_next = dot(r, z);
        if !(rz_next > 0.0 && rz_next.is_finite()) {
            return Err(PcgFailure::Breakdown { iteration });
        }
        let beta = rz_next / rz;
        rz = rz_next;
        p.par_iter_mut()
            .with_min_len(MIN_LEN)
            .zip(z.par_iter())
            .for_each(|(p, z)| *p = z + beta * *p);
    }
    Err(PcgFailure::NoConvergence {
        iterations: max_iterations,
        residual: residual / b_norm,
    })
}

/// y = A x for the free-system matrix of `assembly` with `values`, in parallel: the pattern
/// stores both triangles of a symmetric matrix, so column c of the CSC arrays is row c, and
/// every entry of y is an independent gather.
pub fn symmetric_multiply(assembly: &Assembly, values: &[f64], x: &[f64], y: &mut [f64]) {
    let s = assembly.symbolic();
    y.par_iter_mut()
        .with_min_len(MIN_LEN / 8)
        .enumerate()
        .for_each(|(c, y)| {
            let range = s.col_range(c);
            *y = s
                .row_idx_of_col_raw(c)
                .iter()
                .zip(&values[range])
                .map(|(&r, v)| v * x[r])
                .sum();
        });
}
