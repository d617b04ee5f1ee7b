//! The terms every solve of a step sums, made from the model: elasticity, dead loads and the
//! terms the scene enables.

use crate::assembly::{Assembly, ElementSubset};
use crate::fem::StrainOffset;
use crate::physics::creep::CreepStep;
use crate::physics::elasticity::ElasticStep;
use crate::physics::history::ElementHistory;
use crate::physics::loads::DeadLoads;
use crate::physics::term::{Solve, StepTerm};
use crate::physics::Model;

/// What the elastic term of a solve reads and writes besides the model.
pub(super) struct ElasticInputs<'a> {
    /// The elements' history.
    pub history: &'a ElementHistory,
    /// Its strain offsets, fixed for the solve.
    pub offsets: &'a [StrainOffset],
    /// Element energies (J, scratch, one per element).
    pub element_energy: &'a mut [f64],
    /// A process's elements and owned dofs, in a distributed run.
    pub subset: Option<(&'a ElementSubset, &'a [bool])>,
    /// The solve's creep, with creep on (none outside a solve: the state's stored energy).
    pub creep: Option<CreepStep<'a>>,
}

/// The elastic energy of `model` as a term (exact tangents), on a process's elements and
/// owned dofs if `inputs` name them.
pub(super) fn elastic_term<'a>(
    model: &'a Model,
    assembly: &'a Assembly,
    inputs: ElasticInputs<'a>,
) -> ElasticStep<'a> {
    let mut elastic = ElasticStep::new(
        &model.elasticity,
        (&model.mesh.tets, inputs.history, inputs.offsets),
        assembly,
        inputs.element_energy,
        false,
    );
    elastic.subset = inputs.subset;
    elastic.creep = inputs.creep;
    elastic
}

/// The terms every solve sums — the elastic energy, and the dead `loads` (N, 3 per node) and
/// the model's terms that act in `solve` (contact) — without inertia and damping, which a
/// dynamic step adds.
pub(super) fn solve_terms<'a>(
    model: &'a Model,
    assembly: &'a Assembly,
    inputs: ElasticInputs<'a>,
    loads: &'a [f64],
    solve: &Solve<'a>,
) -> (Box<dyn StepTerm + 'a>, Vec<Box<dyn StepTerm + 'a>>) {
    let elastic = Box::new(elastic_term(model, assembly, inputs));
    let mut terms: Vec<Box<dyn StepTerm + 'a>> = vec![Box::new(DeadLoads { force: loads })];
    terms.extend(model.terms.iter().filter_map(|t| t.begin_solve(solve)));
    (elastic, terms)
}
