//! The potential Newton minimises in one solve: the sum of the terms of the step (see
//! `physics::term`), the backward-Euler incremental potential of a dynamic step or the total
//! potential energy of a static one.

use crate::physics::term::StepTerm;
use crate::solver::Potential;
use std::time::Instant;

/// The sum of a solve's terms.
///
/// The first term is the elastic energy, assembled element by element in parallel and summed
/// over the elements in order; the others accumulate their energies in order into a second
/// sum, and the potential is the elastic sum plus that one. The order is fixed, so a run is
/// reproducible bit for bit.
pub struct StepPotential<'a> {
    /// The terms, the elastic energy first.
    pub terms: Vec<Box<dyn StepTerm + 'a>>,
    /// Wall time spent evaluating contact terms (s).
    pub t_contact: f64,
    /// The elastic term's energy at the last u the potential was evaluated at (J): after
    /// Newton returns, its solution's.
    pub last_elastic: f64,
    /// The Hessian when it does not depend on u or on the step (a linear model without
    /// contact, plasticity or freezing, at a fixed step): copied instead of assembled.
    pub fixed_hessian: Option<&'a [f64]>,
}

impl<'a> StepPotential<'a> {
    /// The potential of `terms` (the elastic energy first).
    pub fn new(terms: Vec<Box<dyn StepTerm + 'a>>) -> Self {
        StepPotential {
            terms,
            t_contact: 0.0,
            last_elastic: 0.0,
            fixed_hessian: None,
        }
    }

    /// Potential at `u`, adding the gradient and Hessian into those given.
    fn sum(
        &mut self,
        u: &[f64],
        mut gradient: Option<&mut [f64]>,
        mut hessian: Option<&mut [f64]>,
    ) -> f64 {
        let Some((elastic_term, others)) = self.terms.split_first_mut() else {
            return 0.0;
        };
        let mut elastic = 0.0;
        elastic_term.add(
            u,
            &mut elastic,
            gradient.as_deref_mut(),
            hessian.as_deref_mut(),
        );
        let mut rest = 0.0;
        for term in others {
            let clock = term.is_contact().then(Instant::now);
            term.add(
                u,
                &mut rest,
                gradient.as_deref_mut(),
                hessian.as_deref_mut(),
            );
            if let Some(clock) = clock {
                self.t_contact += clock.elapsed().as_secs_f64();
            }
        }
        self.last_elastic = elastic;
        elastic + rest
    }

    /// Re-lags every term to the solution `u`; returns the largest relative change.
    pub fn relag(&mut self, u: &[f64]) -> f64 {
        let mut change: f64 = 0.0;
        for term in &mut self.terms {
            change = change.max(term.relag(u));
        }
        change
    }

    /// Wall time the terms spent choosing contact pairs (s).
    pub fn broad_phase_time(&self) -> f64 {
        self.terms.iter().map(|t| t.broad_phase_time()).sum()
    }
}

impl Potential for StepPotential<'_> {
    fn energy(&mut self, u: &[f64]) -> f64 {
        self.sum(u, None, None)
    }

    fn evaluate(&mut self, u: &[f64], gradient: &mut [f64], hessian: &mut [f64]) -> f64 {
        gradient.fill(0.0);
        if let Some(fixed) = self.fixed_hessian {
            hessian.copy_from_slice(fixed);
            return self.sum(u, Some(gradient), None);
        }
        hessian.fill(0.0);
        self.sum(u, Some(gradient), Some(hessian))
    }

    fn gradient(&mut self, u: &[f64], gradient: &mut [f64]) -> f64 {
        gradient.fill(0.0);
        self.sum(u, Some(gradient), None)
    }

    fn project_hessian(&mut self) -> bool {
        let mut changed = false;
        for term in &mut self.terms {
            changed |= term.project_hessian();
        }
        changed
    }

    fn anticipate(&mut self, u: &[f64], trial: &[f64]) -> bool {
        let mut any = false;
        for term in &mut self.terms {
            any |= term.anticipate(u, trial);
        }
        any
    }

    fn forget_anticipated(&mut self) {
        for term in &mut self.terms {
            term.forget_anticipated();
        }
    }

    fn add_anticipated_gradient(&self, u: &[f64], gradient: &mut [f64]) -> bool {
        let mut any = false;
        for term in &self.terms {
            any |= term.add_anticipated_gradient(u, gradient);
        }
        any
    }

    fn refresh_hessian(&mut self, u: &[f64], hessian: &mut [f64]) -> bool {
        let mut changed = false;
        for term in &mut self.terms {
            let clock = term.is_contact().then(Instant::now);
            changed |= term.refresh_hessian(u, hessian);
            if let Some(clock) = clock {
                self.t_contact += clock.elapsed().as_secs_f64();
            }
        }
        changed
    }
}
