//! The potential Newton minimises in one solve: the sum of the terms of the step (see
//! `physics::term`), the backward-Euler incremental potential of a dynamic step or the total
//! potential energy of a static one.

use crate::assembly::Assembly;
use crate::physics::term::StepTerm;
use crate::solver::Potential;
use std::time::Instant;

/// How the parts of a potential evaluated on several processes combine into the whole, the
/// same on every process (implemented by `distributed` over MPI).
pub trait Collective {
    /// Σ over the processes of `x`, the same on every process.
    fn sum(&self, x: f64) -> f64;
    /// Σ over the processes of each dof's parts in `v` (3 per node of this process's mesh),
    /// in place: every process that holds the dof gets the sum, the same bits on each.
    fn exchange(&self, v: &mut [f64]);
    /// Largest `x` over the processes.
    fn max(&self, x: f64) -> f64;
}

/// A process's share of a solve distributed over several processes. Each process evaluates
/// the elastic energy of its own elements (the elastic term's subset), like it the terms held
/// by elements ([`StepTerm::shared_by_elements`]: Rayleigh's β Kₙ), and the other terms on
/// the nodes it owns (its model's masses, loads and obstacle contact nodes are those of its
/// owned nodes; ice–ice contact pairs with an owned node), keeping only the owned dofs'
/// gradient entries and Hessian columns, so that the processes' parts add up to the
/// potential. Energies and gradients are then summed across the processes; the Hessian stays
/// in parts, which the distributed linear solver adds up.
#[derive(Clone, Copy)]
pub struct Share<'a> {
    /// The sums across processes.
    pub collective: &'a dyn Collective,
    /// Whether this process owns each dof (all 3n).
    pub owned: &'a [bool],
    /// The pattern the Hessian's values are on.
    pub assembly: &'a Assembly,
}

impl Share<'_> {
    /// Clears the gradient entries and Hessian columns of the dofs this process does not own.
    fn keep_owned(&self, gradient: Option<&mut [f64]>, hessian: Option<&mut [f64]>) {
        if let Some(g) = gradient {
            for (g, &owned) in g.iter_mut().zip(self.owned) {
                if !owned {
                    *g = 0.0;
                }
            }
        }
        if let Some(h) = hessian {
            let col_ptr = self.assembly.symbolic().col_ptr();
            for (c, &d) in self.assembly.dofs().free_dofs().iter().enumerate() {
                if !self.owned[d] {
                    h[col_ptr[c]..col_ptr[c + 1]].fill(0.0);
                }
            }
        }
    }
}

/// The sum of a solve's terms.
///
/// The elastic energy is assembled element by element in parallel and summed over the
/// elements in order; the other terms accumulate their energies in order into a second sum,
/// and the potential is the elastic sum plus that one. The order is fixed, so a run is
/// reproducible bit for bit. Hooks beyond evaluation (anticipation, projection, refresh,
/// re-lagging) go to the elastic term first, then to the others in order.
pub struct StepPotential<'a> {
    /// The elastic energy of the elements.
    pub elastic: Box<dyn StepTerm + 'a>,
    /// The other terms, in the order their energies are summed.
    pub terms: Vec<Box<dyn StepTerm + 'a>>,
    /// Wall time spent evaluating contact terms (s).
    pub t_contact: f64,
    /// The elastic term's energy at the last u the potential was evaluated at (J): after
    /// Newton returns, its solution's.
    pub last_elastic: f64,
    /// The Hessian when it does not depend on u or on the step (a linear model without
    /// contact, plasticity or freezing, at a fixed step): copied instead of assembled.
    pub fixed_hessian: Option<&'a [f64]>,
    /// The elastic term as a fixed quadratic on a pattern, used instead of a pass over the
    /// elements wherever it holds.
    pub elastic_quadratic: Option<(&'a ElasticQuadratic, &'a Assembly)>,
    /// Passes over the elements (evaluations of the elastic term) so far.
    pub element_passes: u32,
    /// This process's share, in a run distributed over several processes.
    pub share: Option<Share<'a>>,
}

/// The elastic energy when it is a fixed quadratic (a linear model without plasticity or
/// freezing): its energy E₀ (J) and gradient g₀ (N) at a reference displacement u₀ — the
/// constrained dofs' prescribed values, zero on the free dofs — and its free-system Hessian
/// K (N/m). At any u with the same constrained values the free dofs' gradient is g₀ + K u
/// and the energy E₀ + (g₀ + ½ K u)·u (free dofs), exactly: one sparse product instead of a
/// pass over the elements. Its round-off, ~ε Σⱼ |Kᵢⱼ uⱼ| per entry, is within the round-off
/// floor Newton allows its residual (`solver::newton::roundoff_floor`, 10 ε max Kᵢᵢ max |uᵢ|);
/// it grows with a rigid motion of the body, which a pass's strains cancel, so the
/// simulation uses it only where the supports hold every part of the mesh. The gradient on
/// the constrained dofs (the reactions) stays g₀'s.
#[derive(Clone, Debug)]
pub struct ElasticQuadratic {
    /// The reference displacement u₀ (m, all dofs).
    reference: Vec<f64>,
    /// Elastic energy at u₀ (J).
    energy: f64,
    /// Elastic gradient at u₀ (N, all dofs).
    gradient: Vec<f64>,
    /// Free-system Hessian (N/m; CSC values of the assembly's pattern).
    hessian: Vec<f64>,
}

impl ElasticQuadratic {
    /// Evaluates the fixed quadratic `elastic` term on `assembly`'s pattern, referenced at
    /// the constrained values of `u` (one pass over the elements, with the Hessian).
    pub fn new(elastic: &mut dyn StepTerm, u: &[f64], assembly: &Assembly) -> Self {
        let mut quadratic = ElasticQuadratic {
            reference: Vec::new(),
            energy: 0.0,
            gradient: Vec::new(),
            hessian: vec![0.0; assembly.nnz()],
        };
        quadratic.evaluate(elastic, u, assembly, true);
        quadratic
    }

    /// Moves the reference to the constrained values of `u` (moved supports): a pass over
    /// the elements without the Hessian, which does not change.
    pub fn rereference(&mut self, elastic: &mut dyn StepTerm, u: &[f64], assembly: &Assembly) {
        self.evaluate(elastic, u, assembly, false);
    }

    /// Evaluates the reference at the constrained values of `u`, with the Hessian if asked.
    fn evaluate(
        &mut self,
        elastic: &mut dyn StepTerm,
        u: &[f64],
        assembly: &Assembly,
        with_hessian: bool,
    ) {
        // In place: a moved support re-references every step.
        self.reference.clear();
        self.reference.extend_from_slice(u);
        for &d in assembly.dofs().free_dofs() {
            self.reference[d] = 0.0;
        }
        self.energy = 0.0;
        self.gradient.clear();
        self.gradient.resize(u.len(), 0.0);
        elastic.add(
            &self.reference,
            &mut self.energy,
            Some(&mut self.gradient),
            with_hessian.then_some(&mut self.hessian[..]),
        );
    }

    /// Its free-system Hessian (N/m; CSC values of the assembly's pattern).
    pub fn hessian(&self) -> &[f64] {
        &self.hessian
    }

    /// Whether it holds at `u`: the same constrained values as its reference.
    pub fn holds_at(&self, u: &[f64], assembly: &Assembly) -> bool {
        let dofs = assembly.dofs();
        u.len() == self.reference.len()
            && (0..u.len())
                .filter(|&d| dofs.free(d).is_none())
                .all(|d| u[d] == self.reference[d])
    }

    /// The energy at `u` (J, where it holds), adding the gradient to `gradient` (N, all
    /// dofs) and the Hessian to `hessian` (CSC values of `assembly`'s pattern).
    fn add(
        &self,
        assembly: &Assembly,
        u: &[f64],
        gradient: Option<&mut [f64]>,
        hessian: Option<&mut [f64]>,
    ) -> f64 {
        let free = assembly.dofs().free_dofs();
        let x: Vec<f64> = free.iter().map(|&d| u[d]).collect();
        let mut kx = vec![0.0; x.len()];
        assembly.multiply(&self.hessian, &x, &mut kx);
        let mut energy = self.energy;
        for ((&d, xi), kxi) in free.iter().zip(&x).zip(&kx) {
            energy += (self.gradient[d] + 0.5 * kxi) * xi;
        }
        if let Some(g) = gradient {
            for (g, g0) in g.iter_mut().zip(&self.gradient) {
                *g += g0;
            }
            for (&d, kxi) in free.iter().zip(&kx) {
                g[d] += kxi;
            }
        }
        if let Some(h) = hessian {
            for (h, k) in h.iter_mut().zip(&self.hessian) {
                *h += k;
            }
        }
        energy
    }
}

impl<'a> StepPotential<'a> {
    /// The potential of the `elastic` energy and the other `terms`.
    pub fn new(elastic: Box<dyn StepTerm + 'a>, terms: Vec<Box<dyn StepTerm + 'a>>) -> Self {
        StepPotential {
            elastic,
            terms,
            t_contact: 0.0,
            last_elastic: 0.0,
            fixed_hessian: None,
            elastic_quadratic: None,
            element_passes: 0,
            share: None,
        }
    }

    /// [`StepPotential::sum`] on one process's share: the other terms first, kept on the
    /// owned dofs, then the elastic energy of the process's elements; the energy and the
    /// gradient summed across the processes.
    fn sum_shared(
        &mut self,
        share: Share<'_>,
        u: &[f64],
        mut gradient: Option<&mut [f64]>,
        mut hessian: Option<&mut [f64]>,
    ) -> f64 {
        let (elastic_term, others) = (&mut self.elastic, &mut self.terms);
        // Each process keeps what it owns.
        let rest = add_in_order(
            others,
            &mut self.t_contact,
            u,
            (gradient.as_deref_mut(), hessian.as_deref_mut()),
            Pass::Owned,
        );
        share.keep_owned(gradient.as_deref_mut(), hessian.as_deref_mut());
        let mut elastic = 0.0;
        self.element_passes += 1;
        elastic_term.add(
            u,
            &mut elastic,
            gradient.as_deref_mut(),
            hessian.as_deref_mut(),
        );
        // The terms held by elements, as the elastic energy is.
        let by_elements = add_in_order(
            others,
            &mut self.t_contact,
            u,
            (gradient.as_deref_mut(), hessian),
            Pass::ByElements,
        );
        let elastic = share.collective.sum(elastic);
        let rest = share.collective.sum(rest + by_elements);
        if let Some(g) = gradient {
            share.collective.exchange(g);
        }
        self.last_elastic = elastic;
        elastic + rest
    }

    /// Potential at `u`, adding the gradient and Hessian into those given.
    fn sum(
        &mut self,
        u: &[f64],
        mut gradient: Option<&mut [f64]>,
        mut hessian: Option<&mut [f64]>,
    ) -> f64 {
        if let Some(share) = self.share {
            return self.sum_shared(share, u, gradient, hessian);
        }
        let (elastic_term, others) = (&mut self.elastic, &mut self.terms);
        let mut elastic = 0.0;
        match self
            .elastic_quadratic
            .filter(|(q, assembly)| q.holds_at(u, assembly))
        {
            Some((quadratic, assembly)) => {
                elastic =
                    quadratic.add(assembly, u, gradient.as_deref_mut(), hessian.as_deref_mut());
            }
            None => {
                self.element_passes += 1;
                elastic_term.add(
                    u,
                    &mut elastic,
                    gradient.as_deref_mut(),
                    hessian.as_deref_mut(),
                );
            }
        }
        let rest = add_in_order(
            others,
            &mut self.t_contact,
            u,
            (gradient, hessian),
            Pass::All,
        );
        self.last_elastic = elastic;
        elastic + rest
    }

    /// Re-lags every term to the solution `u`; returns the largest relative change (over
    /// the processes of a distributed run).
    pub fn relag(&mut self, u: &[f64]) -> f64 {
        let mut relative: f64 = 0.0;
        let share = self.share;
        for term in std::iter::once(&mut self.elastic).chain(&mut self.terms) {
            let mut lag = term.relag(u);
            if let Some(share) = share {
                // Each process has its part of a term's lagged values.
                lag.change = share.collective.max(lag.change);
                lag.scale = share.collective.max(lag.scale);
            }
            relative = relative.max(lag.relative());
        }
        relative
    }

    /// Whether `b` holds on any process of a distributed run (`b` itself on one): the
    /// decisions Newton takes from a term's answer are the same on every process.
    fn any_over_processes(&self, b: bool) -> bool {
        self.share.map_or(b, |share| {
            share.collective.max(f64::from(u8::from(b))) > 0.0
        })
    }

    /// Every term, the elastic energy first.
    fn all_terms(&self) -> impl Iterator<Item = &Box<dyn StepTerm + 'a>> {
        std::iter::once(&self.elastic).chain(&self.terms)
    }

    /// Every term, the elastic energy first.
    fn all_terms_mut(&mut self) -> impl Iterator<Item = &mut Box<dyn StepTerm + 'a>> {
        std::iter::once(&mut self.elastic).chain(&mut self.terms)
    }

    /// The node of the largest free-dof force imbalance at `u` and the term with the largest
    /// force on it, with the rest positions `rest` (m); `None` in a distributed run (each
    /// process holds a part of the forces) or where every free force is zero.
    pub fn largest_imbalance(
        &mut self,
        u: &[f64],
        assembly: &Assembly,
        rest: &[nalgebra::Vector3<f64>],
    ) -> Option<super::Imbalance> {
        if self.share.is_some() {
            return None;
        }
        let dofs = assembly.dofs();
        let at_node = |g: &[f64], node: usize| -> f64 {
            (3 * node..3 * node + 3)
                .filter(|&d| dofs.free(d).is_some())
                .map(|d| g[d] * g[d])
                .sum::<f64>()
                .sqrt()
        };
        let mut total = vec![0.0; u.len()];
        self.sum(u, Some(&mut total), None);
        let node =
            (0..rest.len()).max_by(|&a, &b| at_node(&total, a).total_cmp(&at_node(&total, b)))?;
        let force = at_node(&total, node);
        if force == 0.0 {
            return None;
        }
        let (mut term, mut term_force) = ("", -1.0);
        for t in self.all_terms_mut() {
            let mut g = vec![0.0; u.len()];
            let mut energy = 0.0;
            t.add(u, &mut energy, Some(&mut g), None);
            let f = at_node(&g, node);
            if f > term_force {
                (term, term_force) = (t.name(), f);
            }
        }
        Some(super::Imbalance {
            node,
            rest: rest[node],
            force,
            term,
            term_force,
        })
    }

    /// Wall time the terms spent choosing contact pairs (s).
    pub fn broad_phase_time(&self) -> f64 {
        self.terms
            .iter()
            .filter_map(|t| t.as_contact())
            .map(|c| c.broad_phase_time())
            .sum()
    }
}

/// Which of a potential's other terms a pass over them adds.
#[derive(Clone, Copy, PartialEq)]
enum Pass {
    /// Every term (one process).
    All,
    /// A process's terms on its owned nodes (a distributed run).
    Owned,
    /// A process's terms held by elements ([`StepTerm::shared_by_elements`]).
    ByElements,
}

/// The energy of the `pass`'s `terms` at `u`, summed in order, adding their gradients and
/// Hessians into those given; contact terms' time is added to `t_contact` (s).
fn add_in_order(
    terms: &mut [Box<dyn StepTerm + '_>],
    t_contact: &mut f64,
    u: &[f64],
    (mut gradient, mut hessian): (Option<&mut [f64]>, Option<&mut [f64]>),
    pass: Pass,
) -> f64 {
    let mut energy = 0.0;
    for term in terms {
        if pass != Pass::All && term.shared_by_elements() != (pass == Pass::ByElements) {
            continue;
        }
        let clock = term.as_contact().is_some().then(Instant::now);
        term.add(
            u,
            &mut energy,
            gradient.as_deref_mut(),
            hessian.as_deref_mut(),
        );
        if let Some(clock) = clock {
            *t_contact += clock.elapsed().as_secs_f64();
        }
    }
    energy
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

    fn max_over_processes(&self, x: f64) -> f64 {
        self.share.map_or(x, |share| share.collective.max(x))
    }

    fn sum_over_processes(&self, x: f64) -> f64 {
        self.share.map_or(x, |share| share.collective.sum(x))
    }

    fn owned_dofs(&self) -> Option<&[bool]> {
        self.share.map(|share| share.owned)
    }

    fn project_hessian(&mut self, project: bool) -> bool {
        let mut changed = false;
        for term in self.all_terms_mut() {
            changed |= term.project_hessian(project);
        }
        self.any_over_processes(changed)
    }

    fn anticipate(&mut self, u: &[f64], trial: &[f64]) -> bool {
        let mut any = false;
        for term in self.all_terms_mut() {
            any |= term.anticipate(u, trial);
        }
        self.any_over_processes(any)
    }

    fn forget_anticipated(&mut self) {
        for term in self.all_terms_mut() {
            term.forget_anticipated();
        }
    }

    fn add_anticipated_gradient(&self, u: &[f64], gradient: &mut [f64]) -> bool {
        let mut any = false;
        let Some(share) = self.share else {
            for term in self.all_terms() {
                any |= term.add_anticipated_gradient(u, gradient);
            }
            return any;
        };
        // `gradient` holds the sum already: the processes' parts of what is added are summed
        // on their own.
        let mut added = vec![0.0; gradient.len()];
        for term in self.all_terms() {
            any |= term.add_anticipated_gradient(u, &mut added);
        }
        share.keep_owned(Some(&mut added), None);
        share.collective.exchange(&mut added);
        for (g, a) in gradient.iter_mut().zip(&added) {
            *g += a;
        }
        self.any_over_processes(any)
    }

    fn refresh_hessian(&mut self, u: &[f64], hessian: &mut [f64]) -> bool {
        let mut changed = false;
        for term in std::iter::once(&mut self.elastic).chain(&mut self.terms) {
            let clock = term.as_contact().is_some().then(Instant::now);
            changed |= term.refresh_hessian(u, hessian);
            if let Some(clock) = clock {
                self.t_contact += clock.elapsed().as_secs_f64();
            }
        }
        self.any_over_processes(changed)
    }
}
