//! A simulation's share of a run distributed over several processes: the distribution it is
//! given (see `distributed`), and the sums and maxima over the processes that keep every
//! process's decisions the same.

use super::part::Part;
use super::potential::Collective;
use super::{Energies, SimError, Simulation};
use crate::assembly::{Assembly, ElementSubset};
use crate::physics::Model;
use crate::solver::{ExternalSolver, LinearError, LinearSolver, LinearSolverKind};
use crate::thermal::system::ScalarSystem;
use crate::thermal::HeatShare;

/// How a simulation is shared among several processes (implemented by `distributed` over
/// MPI and PETSc). Every process holds its part of the mesh and state (see [`super::part`]) and
/// takes the same steps; each evaluates the elastic energy of its own elements and the rest
/// on its owned nodes, and the linear solves are shared.
pub trait Distribution {
    /// The sums across the processes.
    fn collective(&self) -> &dyn Collective;
    /// Whether this process owns each dof of its part (3 per node): every dof has one owner.
    fn owned_dofs(&self) -> &[bool];
    /// Whether this process evaluates each element of its part: every element has one.
    fn owned_elements(&self) -> &[bool];
    /// A linear solver shared by the processes, for `assembly`'s pattern: a factorisation
    /// where `linear` asks one process for one (Cholesky, or `Auto` on a small system), else
    /// an iterative solver.
    fn solver(
        &self,
        assembly: &Assembly,
        linear: LinearSolverKind,
    ) -> Result<Box<dyn ExternalSolver>, LinearError>;
    /// The distribution of `model` (the whole model), whose mesh was made from this
    /// distribution's by splitting elements (fracture): element `e` came from element
    /// `parent[e]` and stays with its process. Called by every process at the same split (it
    /// exchanges the new ghosts). Returns it with this process's part of the new mesh, of
    /// which [`Part::model`] makes the process's model.
    fn remeshed(
        &self,
        model: &Model,
        parent: &[usize],
    ) -> Result<(Box<dyn Distribution>, Part), SimError>;
}

/// A simulation's share of a distributed run: the distribution and this process's elements
/// on the current pattern's colouring.
pub(super) struct Shared {
    pub(super) distribution: Box<dyn Distribution>,
    pub(super) elements: ElementSubset,
}

impl Simulation {
    /// Shares the simulation among the processes of `distribution` from its next step on
    /// (fails only if the distributed solver cannot be made). Its model is this process's
    /// part ([`super::part::Part::model`]). Rayleigh damping's β Kₙ is shared by elements, as
    /// the elastic energy is.
    pub fn distribute(&mut self, distribution: Box<dyn Distribution>) -> Result<(), SimError> {
        let linear = distribution.solver(&self.assembly, self.settings.linear)?;
        self.linear = LinearSolver::External(linear);
        self.workspace.forget_factor();
        self.hessians.forget();
        self.shared = Some(Shared {
            elements: self.assembly.subset(distribution.owned_elements()),
            distribution,
        });
        Ok(())
    }

    /// Shares the heat model (with `[thermal]`) among the processes: its mesh is this
    /// process's part, and `make` builds its share (see [`crate::thermal::Heat::distribute`]).
    pub fn distribute_heat(
        &mut self,
        make: impl FnOnce(&ScalarSystem, &[Option<usize>]) -> Result<Box<dyn HeatShare>, String>,
    ) -> Result<(), SimError> {
        match &mut self.heat {
            Some(link) => Ok(link.heat.distribute(make)?),
            None => Ok(()),
        }
    }

    /// Whether the simulation is shared among several processes.
    pub fn is_distributed(&self) -> bool {
        self.shared.is_some()
    }

    /// The largest `x` over the processes of a distributed run (`x` on one).
    pub fn max_over_processes(&self, x: f64) -> f64 {
        match &self.shared {
            Some(shared) => shared.distribution.collective().max(x),
            None => x,
        }
    }

    /// The largest velocity component of the state (m/s), over every process of a
    /// distributed run.
    pub(super) fn max_speed(&self) -> f64 {
        let v = self.state.v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        self.max_over_processes(v)
    }

    /// Σ over the processes of a distributed run of `x` (`x` on one).
    pub fn sum_over_processes(&self, x: f64) -> f64 {
        match &self.shared {
            Some(shared) => shared.distribution.collective().sum(x),
            None => x,
        }
    }

    /// Whether this process evaluates element `e` (its own; always on one process): each
    /// element counts in sums over the elements on one process.
    pub fn evaluates(&self, e: usize) -> bool {
        self.shared
            .as_ref()
            .is_none_or(|shared| shared.distribution.owned_elements()[e])
    }

    /// Whether this process owns node `i` (always on one process): each node counts in sums
    /// over the nodes on one process.
    pub fn owns_node(&self, i: usize) -> bool {
        self.counts(3 * i)
    }

    /// Whether this process counts dof `d` in sums over the dofs: it owns it (always on one
    /// process).
    pub(super) fn counts(&self, d: usize) -> bool {
        self.shared
            .as_ref()
            .is_none_or(|shared| shared.distribution.owned_dofs()[d])
    }

    /// Sums the processes' parts of `v` (3 per node) at every node several of them hold, in
    /// place (nothing on one process).
    pub(super) fn exchange_sum(&self, v: &mut [f64]) {
        if let Some(shared) = &self.shared {
            shared.distribution.collective().exchange(v);
        }
    }

    /// Keeps `v` (3 per node) on the dofs this process owns and makes every process's copy
    /// the sum of those parts (nothing on one process).
    pub(super) fn exchange_owned(&self, v: &mut [f64]) {
        if let Some(shared) = &self.shared {
            let owned = shared.distribution.owned_dofs();
            for (x, &o) in v.iter_mut().zip(owned) {
                if !o {
                    *x = 0.0;
                }
            }
            shared.distribution.collective().exchange(v);
        }
    }

    /// The energies `mine` (this process's share) summed over the processes of a distributed
    /// run; on one process, `mine`.
    pub(super) fn energies_over_processes(&self, mine: Energies) -> Energies {
        if self.shared.is_none() {
            return mine;
        }
        Energies {
            kinetic: self.sum_over_processes(mine.kinetic),
            elastic: self.sum_over_processes(mine.elastic),
            potential: self.sum_over_processes(mine.potential),
            contact: self.sum_over_processes(mine.contact),
        }
    }
}
