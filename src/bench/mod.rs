//! `icefem bench`: benchmark problems and the driver that times them.
//!
//! - [`problems`]: each problem run once in this process, with its measurements (s, bytes).
//! - [`driver`]: the subcommand itself — sizes, repeats (the solver benchmark runs each in a
//!   fresh process of this executable, so that peak memory is per run), medians and the
//!   markdown tables, handed over line by line.
//!
//! `validation/bench` (with `validation/bench.py`) runs the solver benchmark one size at a time
//! through [`BenchCommand::Single`] (`icefem bench --single N`), whose one line of numbers is
//! [`SINGLE_FIELDS`].

pub mod driver;
pub mod json;
pub mod problems;

pub use driver::{
    loglog_slope, ordering_name, run, solver_name, BenchCommand, SolverOptions, SINGLE_FIELDS,
};
pub use problems::{
    cells_for, clamped_ice_cube, contact_cost, fracture_cost, open_box_surface, peak_memory,
    run_size, BenchResult, ContactCost, FractureCost,
};

use crate::sim::SimError;

/// Why a benchmark could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The problem could not be set up or stepped.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The path of the running executable (which the solver benchmark runs once per run) is
    /// unknown.
    #[error("locating the icefem executable")]
    Executable(#[source] std::io::Error),
    /// A benchmark process could not be started.
    #[error("running a benchmark process")]
    Spawn(#[source] std::io::Error),
    /// A benchmark process exited with an error.
    #[error("benchmark at {tets} tets failed: {stderr}")]
    Failed {
        /// Approximate tet count of the run.
        tets: usize,
        /// What the process wrote to stderr.
        stderr: String,
    },
    /// A benchmark process printed something other than [`SINGLE_FIELDS`] numbers.
    #[error("malformed benchmark output: {0}")]
    Malformed(String),
}

/// Median of `values`: the middle one, the upper of the two middle ones for an even count.
/// Panics on an empty list.
pub(crate) fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// [`median`] of `field` over `runs`.
pub(crate) fn median_of<T>(runs: &[T], field: impl Fn(&T) -> f64) -> f64 {
    median(runs.iter().map(field).collect())
}
