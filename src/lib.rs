//! icefem — an implicit finite-element simulator of ice that cracks as it freezes.
//!
//! Linear tetrahedra, backward-Euler dynamics with Newton iterations, sparse Cholesky or
//! preconditioned CG. SI units throughout (m, kg, s, Pa, N, J).

pub mod fem;
pub mod mesh;
pub mod assembly;
pub mod solver;
pub mod physics;
pub mod sim;
pub mod scene;
pub mod output;
pub mod run;
pub mod bench;
