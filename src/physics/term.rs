//! The interface of everything that contributes to a step's incremental potential.
//!
//! A solve (a time step, or a part of a halved one) minimises a sum of terms. Each term adds
//! its energy (J), gradient (N, over all 3n dofs) and Hessian (N/m, into the CSC values of the
//! free system) at a displacement u; Newton and its line search see only the sum (see
//! `sim::potential`). Optional hooks, with do-nothing defaults, let a term take part in what
//! Newton does beyond evaluating: anticipate constraints a step would activate, refresh the
//! cheap part of a kept Hessian, re-lag a lagged quantity between solves.
//!
//! Two traits split a term's life:
//! - [`StepTerm`]: the term during one solve, holding what is fixed for it (the obstacles'
//!   planes at the step's end, the lagged friction normal force, the inertia predictor).
//! - [`Term`]: a term a scene enables (obstacle contact, ice–ice contact); it lives in the
//!   model, prepares itself at the start of each step (its candidate pairs, the sparsity it
//!   needs), makes a [`StepTerm`] for each solve, and rebuilds itself on a remeshed mesh.
//!
//! Elasticity, dead loads, inertia and Rayleigh damping are the mechanics every model has;
//! the simulation makes their [`StepTerm`]s from the model's fields. Adding a term means one
//! file implementing [`Term`] and [`StepTerm`], and its scene table.

use super::contact_forces::{SceneContact, SolveContact};
use crate::assembly::Assembly;
use crate::mesh::{BoundaryFace, TetMesh};
use nalgebra::Vector3;
use std::any::Any;

/// A term during one solve.
pub trait StepTerm {
    /// What the term is, for messages ("elasticity", "obstacle contact", …).
    fn name(&self) -> &'static str;
    /// Adds the term's energy at `u` (all dofs, m) to `energy` (J), its gradient to
    /// `gradient` (N, all dofs) and its Hessian to `hessian` (CSC values of the free system,
    /// N/m), each if given.
    fn add(
        &mut self,
        u: &[f64],
        energy: &mut f64,
        gradient: Option<&mut [f64]>,
        hessian: Option<&mut [f64]>,
    );
    /// Switches to a positive semi-definite approximation of the Hessian (`project`) or back
    /// to the exact one from the next evaluation on; returns whether anything changed.
    fn project_hessian(&mut self, _project: bool) -> bool {
        false
    }
    /// Given the iterate `u` and the full Newton step `trial`, adds to later Hessians the
    /// stiffness of constraints the step would activate; returns whether any was added.
    fn anticipate(&mut self, _u: &[f64], _trial: &[f64]) -> bool {
        false
    }
    /// Forgets what [`StepTerm::anticipate`] added.
    fn forget_anticipated(&mut self) {}
    /// Adds to `gradient` what the anticipated constraints would contribute at `u` if they
    /// were already active; returns whether there was any.
    fn add_anticipated_gradient(&self, _u: &[f64], _gradient: &mut [f64]) -> bool {
        false
    }
    /// Brings this term's part of `hessian` (the last one assembled, or the last this
    /// refreshed) to `u` in place; returns whether it changed. Only terms far from quadratic
    /// and cheap to evaluate (contact) do this.
    fn refresh_hessian(&mut self, _u: &[f64], _hessian: &mut [f64]) -> bool {
        false
    }
    /// Re-lags what the term holds fixed during a solve (friction's normal force, the plane a
    /// node meets a mesh obstacle on) to the solution `u`; returns how much that changes it.
    fn relag(&mut self, _u: &[f64]) -> LagChange {
        LagChange::default()
    }
    /// Whether the term's Hessian is the same at every u of this solve and of every later
    /// solve with the same inertia step (a quadratic with fixed coefficients): a solve whose
    /// terms all say so assembles its Hessian once and copies it after that.
    fn hessian_is_fixed(&self) -> bool {
        false
    }
    /// The term as a contact (its evaluation counts as contact narrow-phase time), if it is
    /// one.
    fn as_contact(&self) -> Option<&dyn SolveContact> {
        None
    }
    /// Whether a process of a distributed run holds its share of the term by elements, as it
    /// does the elastic energy (its own elements and the nodal parts of its owned nodes): its
    /// gradient and Hessian are then partial at every node it holds and summed across the
    /// processes, instead of kept on its owned nodes.
    fn shared_by_elements(&self) -> bool {
        false
    }
}

/// How much re-lagging changed what a term holds fixed (see [`StepTerm::relag`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LagChange {
    /// The largest change of a lagged value (its unit; ∞ when the solve must be repeated
    /// regardless).
    pub change: f64,
    /// The largest lagged value (its unit; 0 when nothing is lagged).
    pub scale: f64,
}

impl LagChange {
    /// The change relative to the scale (∞ if the change is, 0 when nothing is lagged).
    pub fn relative(&self) -> f64 {
        if self.change == f64::INFINITY {
            f64::INFINITY
        } else if self.scale > 0.0 {
            self.change / self.scale
        } else {
            0.0
        }
    }
}

/// What a term sees at the start of a step.
pub struct StepStartView<'a> {
    /// Rest positions (m).
    pub rest: &'a [Vector3<f64>],
    /// Displacement at the start of the step (m), 3 per node.
    pub u: &'a [f64],
    /// Velocity at the start of the step (m/s), 3 per node.
    pub v: &'a [f64],
    /// The largest velocity component at the start of the step over the whole mesh (m/s):
    /// on a process's part of a distributed run, over every process's.
    pub max_speed: f64,
    /// The step (s).
    pub dt: f64,
    /// What the terms carry, at the start of the step.
    pub carried: &'a TermHistory,
}

/// What terms carry from step to step, by name: rows of numbers each term defines (ice–ice
/// contact: one row p, q, g per pair of copies of a split node — see `ice_contact`). Part of
/// the simulation's state, so a rolled-back step restores it, frames store it for resuming,
/// and a remesh hands it to the term on the new mesh to inherit (see [`Term::inherit`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TermHistory(pub Vec<CarriedRows>);

/// Rows of numbers a term carries (see [`TermHistory`]).
#[derive(Clone, Debug, PartialEq)]
pub struct CarriedRows {
    /// The name (of the dataset in frames, too).
    pub name: &'static str,
    /// Numbers in a row.
    pub columns: usize,
    /// The rows, row-major.
    pub data: Vec<f64>,
}

impl TermHistory {
    /// The rows `name` carries (empty if none).
    pub fn get(&self, name: &str) -> &[f64] {
        self.0
            .iter()
            .find(|r| r.name == name)
            .map_or(&[], |r| &r.data[..])
    }

    /// Replaces the rows `name` carries, of `columns` numbers each.
    pub fn set(&mut self, name: &'static str, columns: usize, data: Vec<f64>) {
        let rows = CarriedRows {
            name,
            columns,
            data,
        };
        match self.0.iter_mut().find(|r| r.name == name) {
            Some(entry) => *entry = rows,
            None => self.0.push(rows),
        }
    }
}

/// What a term sees of one solve: fixed while it lasts.
pub struct Solve<'a> {
    /// Rest positions (m).
    pub rest: &'a [Vector3<f64>],
    /// Displacement at the start of the solve (m), 3 per node.
    pub previous: &'a [f64],
    /// Velocity at the start of the solve (m/s), 3 per node.
    pub velocity: &'a [f64],
    /// The largest velocity component at the start of the solve over the whole mesh (m/s):
    /// on a process's part of a distributed run, over every process's.
    pub max_speed: f64,
    /// Displacement one step before the start, uₙ − h vₙ (m), for extrapolating lagged
    /// quantities; empty in a static solve.
    pub earlier: &'a [f64],
    /// The solve's step h (s).
    pub h: f64,
    /// Whether the solve is dynamic (backward Euler) rather than static.
    pub dynamic: bool,
    /// Start and end time of the solve (s).
    pub times: (f64, f64),
}

/// What a term needs to rebuild itself on a mesh made by splitting elements.
pub struct Remesh<'a> {
    /// The new mesh.
    pub mesh: &'a TetMesh,
    /// For each new element, the element of the old mesh it came from.
    pub parent: &'a [usize],
    /// Crack faces of the new mesh (node triples): their two sides must not interpenetrate.
    pub cracks: &'a [[usize; 3]],
    /// Young's modulus of the ice (Pa), for default penalty stiffnesses.
    pub young: f64,
    /// What the new mesh is of the whole mesh (itself, or a process's part of it).
    pub whole: &'a WholeMesh<'a>,
}

/// What the terms of a remeshed model need of the whole new mesh, which a process's part of it
/// cannot tell alone (on one process: the mesh's own).
pub struct WholeMesh<'a> {
    /// The new mesh's faces on the whole mesh's boundary, ordered as
    /// `TetMesh::boundary_faces` orders them.
    pub boundary: &'a [BoundaryFace],
    /// The perimeters (m) of the whole mesh's boundary faces, in `TetMesh::boundary_faces`'s
    /// order on the whole mesh: the mean edges that scale contact come from them.
    pub perimeters: &'a [f64],
    /// The whole mesh's rest bounding box (m).
    pub bounds: (Vector3<f64>, Vector3<f64>),
    /// The connected piece of the whole mesh each node of the new mesh is in, and the number
    /// of pieces.
    pub pieces: (&'a [u32], usize),
}

/// A term a scene enables, kept in the model.
pub trait Term: Send + Sync + std::fmt::Debug {
    /// Short name (for messages and statistics).
    fn name(&self) -> &'static str;
    /// The term as `Any`, for reading its configuration back (tests, statistics).
    fn as_any(&self) -> &dyn Any;
    /// A copy of the term.
    fn clone_box(&self) -> Box<dyn Term>;
    /// Prepares the step that starts at `start`; returns the node pairs the term couples in
    /// the sparsity pattern beyond the elements' (sorted, unique), if it couples any.
    fn start_step(&mut self, _start: &StepStartView) -> Option<Vec<(usize, usize)>> {
        None
    }
    /// The name under which the term carries rows of numbers from step to step (see
    /// [`TermHistory`]) and the number of numbers in a row, if it carries any.
    fn carried(&self) -> Option<(&'static str, usize)> {
        None
    }
    /// What the term carries at the solution `u` (m) of the step prepared by
    /// [`Term::start_step`].
    fn carry(&self, _rest: &[Vector3<f64>], _u: &[f64]) -> Vec<f64> {
        Vec::new()
    }
    /// What this term, on a mesh made by splitting elements, carries from `old`, what the
    /// term on the mesh before carried; `node_parent[i]` is the node that node `i` of the new
    /// mesh copies (itself if none).
    fn inherit(&self, _old: &[f64], _node_parent: &[usize]) -> Vec<f64> {
        Vec::new()
    }
    /// Called with the pattern a step is solved on, after [`Term::start_step`] (and when the
    /// simulation is built); `changed` tells whether the pattern is new.
    fn pattern_ready(&mut self, _assembly: &Assembly, _changed: bool) {}
    /// The term for one solve; `None` if it contributes nothing to it.
    fn begin_solve<'a>(&'a self, solve: &Solve<'a>) -> Option<Box<dyn StepTerm + 'a>>;
    /// Energy the term stores at `u` and time `t` (s), reported with the contact energy (J).
    fn stored_energy(&self, _rest: &[Vector3<f64>], _u: &[f64], _t: f64) -> f64 {
        0.0
    }
    /// The term as a contact, if it is one.
    fn as_contact(&self) -> Option<&dyn SceneContact> {
        None
    }
    /// The term on a mesh made by splitting elements of this one's.
    fn remeshed(&self, remesh: &Remesh) -> Box<dyn Term>;
    /// The term on the nodes `part` keeps (a process's owned nodes in a distributed run),
    /// numbered as in its mesh: its per-node contributions on those nodes only.
    fn restricted(&self, part: &NodeRestriction) -> Box<dyn Term>;
}

/// Which nodes of a mesh a process keeps, and their numbers in its own mesh (a part of the
/// whole, or the whole).
#[derive(Clone, Debug)]
pub struct NodeRestriction {
    /// For each node of the whole mesh, its number in the process's mesh (`usize::MAX`: not
    /// in it).
    pub local: Vec<usize>,
    /// Whether the process keeps each node of the whole mesh (owns it).
    pub kept: Vec<bool>,
    /// Number of nodes of the process's mesh.
    pub local_nodes: usize,
}

impl NodeRestriction {
    /// The restriction of a mesh to itself, keeping the nodes marked in `kept`.
    pub fn all(kept: &[bool]) -> Self {
        NodeRestriction {
            local: (0..kept.len()).collect(),
            kept: kept.to_vec(),
            local_nodes: kept.len(),
        }
    }

    /// Node `i` of the whole mesh in the process's mesh, if it is in it.
    pub fn held(&self, i: usize) -> Option<usize> {
        Some(self.local[i]).filter(|&k| k != usize::MAX)
    }
    /// Node `i` of the whole mesh in the process's mesh, if the process keeps it.
    pub fn kept(&self, i: usize) -> Option<usize> {
        self.kept[i].then(|| self.local[i])
    }
    /// Node `i` of the whole mesh in the process's mesh (it must be in it).
    pub fn local(&self, i: usize) -> usize {
        self.local[i]
    }
    /// Number of nodes of the process's mesh.
    pub fn num_nodes(&self) -> usize {
        self.local_nodes
    }
}

impl Clone for Box<dyn Term> {
    fn clone(&self) -> Self {
        self.clone_box()
    }
}
