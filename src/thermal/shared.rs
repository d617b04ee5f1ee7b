//! The heat model shared among the processes of a distributed run. Each process holds the
//! heat model of its part of the mesh (its elements and the ring of elements around their
//! nodes, see `sim::part`): every element around a node it owns is there, so the node's
//! capacity, convection, conduction row and residual are whole on it. Each process computes
//! the residual and the Jacobian rows of its owned nodes; the Newton decisions (convergence,
//! line search, new extrema) are taken from sums and maxima over the processes, so every
//! process takes the same ones, and the linear solve is shared (PETSc, in `distributed`).

use super::system::ScalarSystem;

/// How a heat model is shared among the processes.
pub trait HeatShare {
    /// Whether this process owns each node of its part (every node has one owner).
    fn owned(&self) -> &[bool];
    /// The whole mesh's node of each node of the part.
    fn whole_nodes(&self) -> &[usize];
    /// Σ of `x` over the processes, the same bits on each.
    fn sum(&self, x: f64) -> f64;
    /// Largest `x` over the processes.
    fn max(&self, x: f64) -> f64;
    /// Every process's `edges` (pairs of the whole mesh's nodes), sorted and without
    /// repeats, the same on every process.
    fn union(&self, edges: &[(usize, usize)]) -> Vec<(usize, usize)>;
    /// Takes the owned nodes' rows of `system`'s current values as the processes' matrix
    /// and sets its solver up.
    fn set_matrix(&mut self, system: &ScalarSystem) -> Result<(), String>;
    /// x ← A⁻¹ x: `x` by free number, read at the owned free nodes, returned at every free
    /// node of the part.
    fn solve_in_place(&mut self, x: &mut [f64]) -> Result<(), String>;
}
