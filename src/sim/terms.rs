//! The terms every solve of a step sums, made from the model: elasticity, dead loads and the
//! terms the scene enables.

use crate::assembly::{Assembly, ElementSubset};
use crate::fem::StrainOffset;
use crate::physics::elasticity::ElasticStep;
use crate::physics::history::ElementHistory;
use crate::physics::loads::DeadLoads;
use crate::physics::term::{Solve, StepTerm};
use crate::physics::Model;

/// The elastic energy of `model` as a term (exact tangents), on a process's elements and
/// owned dofs if `subset` is given; `element_energy` is scratch, one per element.
pub(super) fn elastic_term<'a>(
    model: &'a Model,
    assembly: &'a Assembly,
    (history, offsets): (&'a ElementHistory, &'a [StrainOffset]),
    (element_energy, subset): (&'a mut [f64], Option<(&'a ElementSubset, &'a [bool])>),
) -> ElasticStep<'a> {
    let mut elastic = ElasticStep::new(
        &model.elasticity,
        (&model.mesh.tets, history, offsets),
        assembly,
        element_energy,
        false,
    );
    elastic.subset = subset;
    elastic
}

/// The terms every solve sums — elasticity, dead loads and the model's terms that act in
/// `solve` (contact) — without inertia and damping, which a dynamic step adds.
pub(super) fn solve_terms<'a>(
    model: &'a Model,
    assembly: &'a Assembly,
    (history, offsets): (&'a ElementHistory, &'a [StrainOffset]),
    (element_energy, subset): (&'a mut [f64], Option<(&'a ElementSubset, &'a [bool])>),
    solve: &Solve<'a>,
) -> Vec<Box<dyn StepTerm + 'a>> {
    let mut terms: Vec<Box<dyn StepTerm + 'a>> = vec![
        Box::new(elastic_term(
            model,
            assembly,
            (history, offsets),
            (element_energy, subset),
        )),
        Box::new(DeadLoads {
            force: &model.external_force,
        }),
    ];
    terms.extend(model.terms.iter().filter_map(|t| t.begin_solve(solve)));
    terms
}
