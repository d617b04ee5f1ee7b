//! The Hessians a simulation keeps between solves while they cannot change.

use super::potential::{ElasticQuadratic, StepPotential};
use crate::assembly::Assembly;
use crate::physics::term::StepTerm;
use crate::solver::Potential;
use std::time::Instant;

/// The Hessians kept between solves.
#[derive(Default)]
pub(super) struct KeptHessians {
    /// The step's Hessian for an inertia step length (s), kept while it cannot change (see
    /// `StepTerm::hessian_is_fixed`): later solves use it instead of assembling.
    pub(super) fixed: Option<(f64, Vec<f64>)>,
    /// Whether the linear solver holds the factorisation of `fixed`.
    pub(super) factored: bool,
    /// The elastic energy while it is a fixed quadratic, for the constrained values it was
    /// built with: its Hessian is kept and its gradient found by a sparse product instead of
    /// a pass over the elements (see [`ElasticQuadratic`]).
    pub(super) elastic_quadratic: Option<ElasticQuadratic>,
}

impl KeptHessians {
    /// Forgets everything (the solver changed).
    pub(super) fn forget(&mut self) {
        *self = KeptHessians::default();
    }

    /// The pattern changed: the solver holds no factor, and the elastic quadratic's Hessian
    /// is on the old pattern. (The fixed Hessian goes at the next solve: a pattern changes
    /// only for terms whose Hessian is not fixed.)
    pub(super) fn pattern_changed(&mut self) {
        self.factored = false;
        self.elastic_quadratic = None;
    }

    /// Keeps the fixed Hessian only for a solve whose terms all have fixed Hessians
    /// (`fixed`) with the same inertia step (s): the Hessian's only dependence on the step.
    pub(super) fn keep_fixed_if(&mut self, fixed: bool, inertia_step: f64) {
        if !fixed || self.fixed.as_ref().is_some_and(|(k, _)| *k != inertia_step) {
            self.fixed = None;
        }
        if self.fixed.is_none() {
            self.factored = false;
        }
    }

    /// Keeps the elastic term `elastic` as a fixed quadratic at `u`'s constrained values if
    /// `wanted` (built, or re-referenced to moved supports), or drops it. Its Hessian is kept
    /// only where the supports hold every part (a rigid motion of any size would enter the
    /// product's round-off, while a pass's strains cancel it). Returns the passes over the
    /// elements it made and their time (s).
    pub(super) fn update_elastic_quadratic(
        &mut self,
        wanted: bool,
        elastic: &mut dyn StepTerm,
        u: &[f64],
        assembly: &Assembly,
    ) -> (u32, f64) {
        if !wanted {
            self.elastic_quadratic = None;
            return (0, 0.0);
        }
        let start = Instant::now();
        let passes = match &mut self.elastic_quadratic {
            Some(q) if q.holds_at(u, assembly) => 0,
            Some(q) => {
                q.rereference(elastic, u, assembly);
                1
            }
            None => {
                self.elastic_quadratic = Some(ElasticQuadratic::new(elastic, u, assembly));
                1
            }
        };
        (passes, start.elapsed().as_secs_f64())
    }

    /// Lends the kept Hessians to `potential` for a solve, first assembling the fixed
    /// Hessian if the solve's is fixed for the inertia step `fixed_step` (s) and none is
    /// kept.
    pub(super) fn lend<'a>(
        &'a mut self,
        potential: &mut StepPotential<'a>,
        fixed_step: Option<f64>,
        u: &[f64],
        assembly: &'a Assembly,
    ) -> Lent<'a> {
        let KeptHessians {
            fixed,
            factored,
            elastic_quadratic,
        } = self;
        potential.elastic_quadratic = elastic_quadratic.as_ref().map(|q| (q, assembly));
        let mut t_assembly = 0.0;
        if let (Some(step), None) = (fixed_step, &fixed) {
            let start = Instant::now();
            let mut gradient = vec![0.0; u.len()];
            let mut hessian = vec![0.0; assembly.nnz()];
            Potential::evaluate(potential, u, &mut gradient, &mut hessian);
            *fixed = Some((step, hessian));
            t_assembly = start.elapsed().as_secs_f64();
        }
        let fixed = fixed.as_ref().map(|(_, k)| &k[..]);
        potential.fixed_hessian = fixed;
        Lent {
            fixed: fixed.filter(|_| fixed_step.is_some()),
            factored,
            t_assembly,
        }
    }
}

/// The kept Hessians as a solve uses them.
pub(super) struct Lent<'a> {
    /// The fixed Hessian, if the solve's is fixed (N/m, CSC values of the free system).
    pub(super) fixed: Option<&'a [f64]>,
    /// Whether the linear solver holds the factorisation of the fixed Hessian.
    pub(super) factored: &'a mut bool,
    /// Time spent assembling the fixed Hessian (s).
    pub(super) t_assembly: f64,
}
