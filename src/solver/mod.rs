//! Linear solvers and Newton's method.

pub mod linear;
pub mod newton;
pub mod ordering;
pub mod timestep;

pub use linear::{LinearError, LinearSolver, LinearSolverKind, LinearStats};
pub use newton::{minimize, NewtonError, NewtonParams, NewtonReport, NewtonWorkspace, Potential};
pub use ordering::FillOrdering;
