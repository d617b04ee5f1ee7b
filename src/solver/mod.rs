//! Linear solvers and Newton's method.

pub mod amg;
pub mod linear;
pub mod low_rank;
pub mod newton;
pub mod ordering;
pub mod pcg;
pub mod tree_solve;
mod vector;

pub use linear::{
    ExternalSolver, FactorPrecision, IterativeSettings, LinearError, LinearSolver,
    LinearSolverKind, LinearStats,
};
pub use newton::{
    minimize, minimize_quadratic, NewtonError, NewtonParams, NewtonReport, NewtonWorkspace,
    Potential,
};
pub use ordering::FillOrdering;
