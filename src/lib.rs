//! icefem — an implicit finite-element simulator of ice that cracks as it freezes.
//!
//! Linear tetrahedra, backward-Euler dynamics with Newton iterations, sparse Cholesky or
//! preconditioned CG. SI units throughout (m, kg, s, Pa, N, J).

pub mod assembly;
pub mod bench;
#[cfg(feature = "mpi")]
pub mod distributed;
pub mod eta;
pub mod export;
pub mod fem;
pub mod fracture;
pub mod launch;
pub mod mesh;
pub mod output;
pub mod parallel;
pub mod physics;
pub mod render;
pub mod run;
pub mod scene;
pub mod sim;
pub mod solver;
pub mod thermal;
