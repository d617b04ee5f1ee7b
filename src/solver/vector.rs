//! Vector kernels shared by the solvers, bit-reproducible whatever the thread count.

use rayon::prelude::*;

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
