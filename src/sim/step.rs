//! One step: the heat step (with `[thermal]`), then the solves of the mechanics, each in
//! stages read top to bottom in [`Simulation::try_step`]: prepare the solve → solve the step's
//! potential (with re-lagging) → finish (velocity, energy balance, local error) → commit.

use super::balance::{energies_of, energies_with};
use super::integrator::StepEnd;
use super::potential::{Share, StepPotential};
use super::terms::{solve_terms, ElasticInputs};
use super::{
    Analysis, Energies, SimError, Simulation, SolveFailure, StepReport, FRICTION_RELAG_TOLERANCE,
    MAX_FRICTION_UPDATES, MAX_HALVINGS,
};
use crate::assembly::Assembly;
use crate::fem::StrainOffset;
use crate::physics::contact::ContactForces;
use crate::physics::creep::CreepStep;
use crate::physics::elasticity::ElasticStep;
use crate::physics::inertia::{Inertia, StiffnessDamping};
use crate::physics::term::{Solve, StepStartView, StepTerm};
use crate::physics::{Model, Rayleigh};
use crate::solver::{
    minimize, minimize_quadratic, LinearSolver, NewtonParams, NewtonReport, NewtonWorkspace,
    Potential,
};
use std::time::Instant;

/// What a solve is set up with: fixed while it runs.
struct SolveSetup {
    /// The solve's length (s).
    h: f64,
    /// Its end time (s).
    t_new: f64,
    /// Whether it is dynamic (inertia) rather than static.
    dynamic: bool,
    /// The strain offsets of the elements, fixed for the solve (its elastic term and the
    /// energy balance).
    offsets: Vec<StrainOffset>,
    /// Newton's residual is judged relative to this force (N; see `force_scale`).
    force_floor: f64,
    /// Displacement one step before the start, uₙ − h vₙ (m; empty in a static solve): where
    /// lagged quantities (friction's normal force) start extrapolated from.
    earlier: Vec<f64>,
    /// The length of backward Euler's inertia term the scheme's equals (s).
    inertia_step: f64,
    /// The velocity's length h_d (s) of vₙ₊₁ = (u − p)/h_d, for the damping terms.
    damping_step: f64,
    /// Rayleigh damping (zero without).
    damping: Rayleigh,
    /// The order of accuracy of the scheme's formula for this solve.
    order: u32,
    /// Newton's other start where a part turns (see `rigid_start`): the solve starts from
    /// whichever of it and the predictor has the lower potential.
    turned_start: Option<Vec<f64>>,
    /// With creep, each element's compliance h B over the solve (Pa⁻ⁿ), at its temperature at
    /// the solve's end; empty otherwise.
    creep_compliance: Vec<f64>,
}

impl SolveSetup {
    /// The solve's creep, with creep on in `model`.
    fn creep(&self, model: &Model) -> Option<CreepStep<'_>> {
        model.elasticity.creep.map(|_| CreepStep {
            compliance: &self.creep_compliance,
        })
    }
}

/// The elastic energy at a solve's solution (J).
enum ElasticAtSolution {
    /// A quadratic solve's: no pass over the elements was made at the solution, and the
    /// energy balance holds identically.
    Quadratic(f64),
    /// Newton's last evaluation's (summed over the processes of a distributed run), with the
    /// energies of the solve's start the balance check compares it with.
    Evaluated { elastic: f64, before: Energies },
}

/// What a solve found, besides its solution.
struct Solved {
    newton: NewtonReport,
    newton_solves: u32,
    elastic: ElasticAtSolution,
    t_contact_narrow: f64,
    t_contact_broad: f64,
    element_passes: u32,
}

/// The end of a solve, checked: what the commit stage writes into the state.
struct Finished {
    end: StepEnd,
    energies: Energies,
    local_error: f64,
    displacement_scale: f64,
}

impl Simulation {
    /// Advances one step of `settings.dt`. If Newton fails, the step is retried as two half
    /// steps, recursively, down to `dt / 2^MAX_HALVINGS`; the step then reports how many
    /// substeps it took. On failure the state is left unchanged.
    pub fn step(&mut self) -> Result<StepReport, SimError> {
        let start = Instant::now();
        let t0 = self.state.time;
        // Kept for fracture's retake, and to roll back a failed step.
        self.start = Some(self.state.clone());
        let t_end = t0 + self.settings.dt;
        // Heat first (staggered): the mechanics of the step sees the freeze states move from
        // the start's to those of the new temperatures.
        let heat = match &mut self.heat {
            Some(link) => {
                link.heat.set_temperature(&self.state.temperature);
                let report = link.heat.step(self.settings.dt, t_end)?;
                let before = std::mem::replace(
                    &mut self.state.temperature,
                    link.heat.temperature().to_vec(),
                );
                self.set_thermal_schedule(t0, t_end, Some(&before));
                Some(report)
            }
            None => None,
        };
        self.start_terms()?;
        let t_contact_broad = start.elapsed().as_secs_f64();
        let result = self.advance(self.settings.dt, t_end, 0);
        if result.is_err() {
            self.undo_step();
        }
        let mut report = result.map_err(|(source, time)| SimError::Step {
            step: self.state.step + 1,
            time,
            cause: source,
        })?;
        self.carry_term_history();
        self.state.step += 1;
        report.t_step = start.elapsed().as_secs_f64();
        report.heat = heat;
        report.t_contact_broad += t_contact_broad;
        // The energies the balance check measured at the solution hold unless the plastic
        // strain was updated after it.
        if self.model.elasticity.inelastic() {
            report.energies = self.energies();
        }
        Ok(report)
    }

    /// Lets every term prepare the coming step, and makes the sparsity pattern couple exactly
    /// the node pairs they ask for: the pattern, slot map, colouring and symbolic
    /// factorisation are rebuilt when that set changes (and only then).
    fn start_terms(&mut self) -> Result<(), SimError> {
        let view = StepStartView {
            rest: &self.model.mesh.rest,
            u: &self.state.u,
            v: &self.state.v,
            max_speed: self.max_speed(),
            dt: self.settings.dt,
            carried: &self.state.term_history,
        };
        let mut asked: Option<Vec<(usize, usize)>> = None;
        for term in &mut self.model.terms {
            if let Some(pairs) = term.start_step(&view) {
                asked.get_or_insert_with(Vec::new).extend(pairs);
            }
        }
        let Some(mut couplings) = asked else {
            return Ok(());
        };
        couplings.sort_unstable();
        couplings.dedup();
        // Making the shared solver for a new pattern is every process's step: where one
        // process's couplings changed, all rebuild theirs.
        let here = couplings != self.couplings;
        let changed = self.max_over_processes(f64::from(u8::from(here))) > 0.0;
        if changed {
            self.rebuild_pattern(&couplings)?;
            self.couplings = couplings;
        }
        for term in &mut self.model.terms {
            term.pattern_ready(&self.assembly, changed);
        }
        Ok(())
    }

    /// Replaces what the terms carry with its values at the step's end.
    fn carry_term_history(&mut self) {
        for term in &self.model.terms {
            if let Some((name, columns)) = term.carried() {
                let rows = term.carry(&self.model.mesh.rest, &self.state.u);
                self.state.term_history.set(name, columns, rows);
            }
        }
    }

    /// Rebuilds the pattern, the linear solver and what depends on them for the terms'
    /// `couplings` and the elastic energy's own.
    fn rebuild_pattern(&mut self, couplings: &[(usize, usize)]) -> Result<(), SimError> {
        let dofs = self.assembly.dofs().clone();
        // The elastic energy's pairs are fixed for the mesh: added here, not compared.
        let all = [couplings, &self.elastic_couplings[..]].concat();
        self.assembly = Assembly::with_couplings(&self.model.mesh, dofs, &all);
        self.linear = self.linear_solver_for_pattern()?;
        self.workspace = crate::solver::NewtonWorkspace::new(&self.assembly);
        self.hessians.pattern_changed();
        self.model.elasticity.pattern_ready(&self.assembly);
        if !self.damping_stiffness.is_empty() {
            self.damping_stiffness = vec![0.0; self.assembly.nnz()];
        }
        Ok(())
    }

    /// Advances by `h` to `t_end` (passed so that halves land exactly on the full step's end
    /// time), halving on failure up to `MAX_HALVINGS` times.
    fn advance(
        &mut self,
        h: f64,
        t_end: f64,
        depth: u32,
    ) -> Result<StepReport, (SolveFailure, f64)> {
        match self.try_step(h, t_end) {
            Ok(report) => Ok(report),
            Err(_) if depth < MAX_HALVINGS => {
                let first = self.advance(0.5 * h, t_end - 0.5 * h, depth + 1)?;
                let second = self.advance(0.5 * h, t_end, depth + 1)?;
                Ok(first.merge(&second))
            }
            Err(e) => Err((e, t_end)),
        }
    }

    /// One solve of length `h` ending at `t_new`: a step of the time scheme, or a static one.
    /// On failure the state is as it was (the caller restores the schedules).
    fn try_step(&mut self, h: f64, t_new: f64) -> Result<StepReport, SolveFailure> {
        let (setup, mut u) = self.prepare_solve(h, t_new);
        let solved = self.solve(&setup, &mut u)?;
        let finished = self.finish_solve(&setup, &u, &solved)?;
        Ok(self.commit(setup, u, solved, finished))
    }

    /// Stage 1: applies the schedules at the solve's end, fixes the strain offsets, and
    /// returns the solve's set-up and Newton's start (the scheme's predictor, or a retaken
    /// step's earlier solution, with the supports' prescribed values).
    fn prepare_solve(&mut self, h: f64, t_new: f64) -> (SolveSetup, Vec<f64>) {
        let dynamic = self.settings.analysis == Analysis::Dynamic;
        if dynamic && self.integrator.needs_acceleration(&self.state) {
            // The first step (or the first after a remesh) of a scheme that carries the
            // acceleration: the acceleration of the state.
            let a = self.acceleration_at_start();
            self.integrator
                .start_from_acceleration(&mut self.state.carried, a);
        }
        let before = (self.model.elasticity.ice_formation).then(|| self.state.history.clone());
        self.set_time(t_new);
        if let Some(before) = before {
            self.form_ice(&before);
        }
        self.previous.copy_from_slice(&self.state.u);
        let mut offsets = std::mem::take(&mut self.offsets);
        self.state.history.update_offsets(&mut offsets);
        let mut u = self.state.u.clone();
        let mut turned_start = None;
        if dynamic {
            self.integrator.predict(&self.state, h, &mut self.predictor);
            u.copy_from_slice(&self.predictor);
            // A process of a distributed run holds a piece of a part, not a part.
            if self.shared.is_none() {
                let at = (&self.state.u[..], &self.predictor[..]);
                let young = self.model.elasticity.material.young();
                let (rest, mass) = (&self.model.mesh.rest, &self.model.mass);
                turned_start = (self.rigid_start).start(rest, at, mass, (h, young));
            }
        }
        // A retaken step starts from its earlier solution (only for the full step: a halved
        // one starts from the predictor).
        if let Some(guess) = self.initial_guess.take() {
            if h == self.settings.dt && guess.len() == u.len() {
                u = guess;
                turned_start = None;
            }
        }
        if let Some(start) = &mut turned_start {
            self.model.apply_dirichlet(t_new, start);
        }
        self.model.apply_dirichlet(t_new, &mut u);
        let damping = self.model.damping.unwrap_or_default();
        if dynamic && damping.stiffness > 0.0 {
            self.stiffness_at_previous(damping.stiffness);
        }
        let force_floor = self.force_scale(h, dynamic);
        let earlier: Vec<f64> = if dynamic {
            let v = &self.state.v;
            self.previous
                .iter()
                .zip(v)
                .map(|(u0, v)| u0 - h * v)
                .collect()
        } else {
            Vec::new()
        };
        let inertia_step = self.integrator.inertia_step(&self.state, h);
        let damping_step = if dynamic && (damping.mass > 0.0 || damping.stiffness > 0.0) {
            let (state, predictor) = (&self.state, &self.predictor);
            self.integrator
                .velocity_form(state, h, predictor, &mut self.damping_origin)
        } else {
            h
        };
        let creep_compliance = match &self.model.elasticity.creep {
            Some(creep) => {
                let schedule = self.thermal_schedule.as_ref();
                (0..self.model.mesh.num_tets())
                    .map(|e| creep.compliance(h, schedule.and_then(|s| s.temperature(e, t_new))))
                    .collect()
            }
            None => Vec::new(),
        };
        let setup = SolveSetup {
            h,
            t_new,
            dynamic,
            offsets,
            force_floor,
            earlier,
            inertia_step,
            damping_step,
            damping,
            order: self.integrator.order(&self.state, h),
            turned_start,
            creep_compliance,
        };
        (setup, u)
    }

    /// Stage 2: builds the step's potential (its terms, the kept Hessians) and minimises it
    /// from `u`, re-lagging lagged quantities (friction's normal force, mesh obstacles'
    /// planes) to each solution and re-solving, warm-started, until they settle to
    /// [`FRICTION_RELAG_TOLERANCE`]. Leaves the solution in `u` and the contact forces at it
    /// in `self.contact_forces`.
    fn solve(&mut self, setup: &SolveSetup, u: &mut [f64]) -> Result<Solved, SolveFailure> {
        let max_speed = self.max_speed();
        let mut balance_scratch = std::mem::take(&mut self.balance_scratch);
        balance_scratch.resize(self.model.mesh.num_tets(), 0.0);
        let Simulation {
            model,
            state,
            assembly,
            linear,
            workspace,
            element_energy,
            scratch,
            previous,
            predictor,
            damping_origin,
            damping_stiffness,
            hessians,
            shared,
            settings,
            parts_held,
            loads,
            ..
        } = self;
        // Nothing but the kept Hessians, the linear solver and its workspace and the scratch
        // the terms write changes during the solve.
        let (model, state, assembly, settings): (&Model, &super::State, &Assembly, _) =
            (model, state, assembly, &*settings);
        let (previous, predictor, loads) = (&previous[..], &predictor[..], &loads[..]);
        let (damping_origin, damping_stiffness) = (&damping_origin[..], &damping_stiffness[..]);
        let subset = shared
            .as_ref()
            .map(|s| (&s.elements, s.distribution.owned_dofs()));
        let solve = Solve {
            rest: &model.mesh.rest,
            previous,
            velocity: &state.v,
            max_speed,
            earlier: &setup.earlier,
            h: setup.h,
            dynamic: setup.dynamic,
            times: (state.time, setup.t_new),
        };
        let elastic = ElasticInputs {
            history: &state.history,
            offsets: &setup.offsets,
            element_energy,
            subset,
            creep: setup.creep(model),
        };
        let (mut elastic, mut terms) = solve_terms(model, assembly, elastic, loads, &solve);
        if setup.dynamic {
            let inertia = InertiaParts {
                mass: &model.mass,
                predictor,
                velocity_origin: damping_origin,
                beta_stiffness: damping_stiffness,
            };
            terms.extend(inertia_terms(setup, inertia, assembly, scratch));
        }
        // A Hessian that cannot change is assembled once per step length and then copied
        // (not in a distributed run, whose processes hold parts of it).
        let fixed = shared.is_none()
            && elastic.hessian_is_fixed()
            && terms.iter().all(|t| t.hessian_is_fixed());
        hessians.keep_fixed_if(fixed, setup.inertia_step);
        // The elastic energy is a fixed quadratic (see `KeptHessians::elastic_quadratic`)
        // where the supports hold every part, and not where the force scale comes from the
        // reactions, which its product does not update.
        let quadratic_elastic = fixed && setup.force_floor > 0.0 && *parts_held;
        let (element_passes, mut t_fixed_assembly) =
            hessians.update_elastic_quadratic(quadratic_elastic, elastic.as_mut(), u, assembly);
        let mut potential = StepPotential::new(elastic, terms);
        potential.share = shared.as_ref().map(|s| Share {
            collective: s.distribution.collective(),
            owned: s.distribution.owned_dofs(),
            assembly,
        });
        if let Some(start) = setup.turned_start.as_deref().filter(|_| !fixed) {
            // Only where Newton iterates: a quadratic solve is one linear solve from any start.
            if potential.energy(start) < potential.energy(u) {
                u.copy_from_slice(start);
            }
        }
        let fixed_step = fixed.then_some(setup.inertia_step);
        let lent = hessians.lend(&mut potential, fixed_step, u, assembly);
        t_fixed_assembly += lent.t_assembly;
        // The energies of the solve's start, which the balance check needs, do not depend on
        // the solution: computed on another thread while Newton runs (a pass over the
        // elements less on the solve's path). In a distributed run each process computes its
        // part of them, summed after the scope (MPI is called from this thread only).
        let mut before: Option<Energies> = None;
        let solved = rayon::in_place_scope(|scope| {
            if !fixed {
                let elastic = ElasticInputs {
                    history: &state.history,
                    offsets: &setup.offsets,
                    element_energy: &mut balance_scratch,
                    subset,
                    creep: setup.creep(model),
                };
                let (at, before) = ((previous, &state.v[..], setup.t_new, loads), &mut before);
                scope.spawn(move |_| *before = Some(energies_of(model, assembly, elastic, at)));
            }
            let newton = NewtonSolver {
                assembly,
                linear,
                workspace,
                params: &settings.newton,
                force_floor: setup.force_floor,
            };
            minimize_relagged(&mut potential, u, newton, (lent.fixed, lent.factored))
        });
        self.balance_scratch = balance_scratch;
        let (newton, newton_solves) = match solved {
            Err(SolveFailure::Newton { error, .. }) => {
                let imbalance =
                    (potential.largest_imbalance(u, assembly, &model.mesh.rest)).map(Box::new);
                return Err(SolveFailure::Newton { error, imbalance });
            }
            other => other?,
        };
        let before = (!fixed).then(|| before.unwrap_or_default());
        let mut solved = solved_at(&mut potential, u, newton, before);
        solved.newton_solves = newton_solves;
        solved.newton.t_assembly += t_fixed_assembly;
        solved.element_passes += element_passes;
        let forces = contact_forces_at(&potential.terms, u);
        drop(potential);
        self.set_contact_forces(forces);
        Ok(solved)
    }

    /// Keeps the contact forces of a solve (`None`: it had no contact term, so no contact
    /// force and no friction work), whole on every process of a distributed run.
    fn set_contact_forces(&mut self, forces: Option<ContactForces>) {
        match forces {
            Some(forces) => self.contact_forces = forces,
            None => {
                self.contact_forces.normal.fill(0.0);
                self.contact_forces.friction.fill(0.0);
            }
        }
        let mut forces = std::mem::take(&mut self.contact_forces);
        self.exchange_owned(&mut forces.normal);
        self.exchange_owned(&mut forces.friction);
        self.contact_forces = forces;
    }

    /// Stage 3: the velocity the scheme gives the solution `u`, the energies at it —
    /// checked against the solve's start and the work done on the ice (see `balance`) —
    /// and the local error estimate.
    fn finish_solve(
        &mut self,
        setup: &SolveSetup,
        u: &[f64],
        solved: &Solved,
    ) -> Result<Finished, SolveFailure> {
        let (h, t_new) = (setup.h, setup.t_new);
        let end = if setup.dynamic {
            self.integrator.finish(&self.state, h, u, &self.predictor)
        } else {
            StepEnd {
                velocity: self.state.v.clone(),
                carried: self.state.carried.clone(),
            }
        };
        let slack = self.settings.newton.tolerance * solved.newton.force_scale;
        let energies = match solved.elastic {
            // The minimiser of a convex quadratic potential meets the balance identically, up
            // to the residual the Newton test already bounds: no check, no passes for it.
            ElasticAtSolution::Quadratic(elastic) => energies_with(
                &self.model,
                elastic,
                (u, &end.velocity),
                (t_new, &self.loads),
            ),
            ElasticAtSolution::Evaluated { elastic, before } => {
                // The potential's elastic energy at the solution is summed over the
                // processes already.
                let time = (t_new, &self.loads[..]);
                let after = energies_with(&self.model, 0.0, (u, &end.velocity), time);
                let after = Energies {
                    elastic,
                    ..self.energies_over_processes(after)
                };
                let before = self.energies_over_processes(before);
                self.check_balance(before, after, u, slack)?
            }
        };
        let free = self.assembly.dofs().free_dofs();
        let local_error = if setup.dynamic {
            self.integrator.local_error(&self.state, h, u, &end, free)
        } else {
            0.0
        };
        let local_error = self.max_over_processes(local_error);
        let displacement_scale = free.iter().map(|&d| u[d].abs()).fold(0.0, f64::max);
        let displacement_scale = self.max_over_processes(displacement_scale);
        Ok(Finished {
            end,
            energies,
            local_error,
            displacement_scale,
        })
    }

    /// Stage 4: the solution becomes the state (velocity, what the scheme carries, the
    /// elements' plastic strain, time).
    fn commit(
        &mut self,
        setup: SolveSetup,
        u: Vec<f64>,
        solved: Solved,
        finished: Finished,
    ) -> StepReport {
        let Finished {
            end,
            energies,
            local_error,
            displacement_scale,
        } = finished;
        self.state.v = end.velocity;
        self.state.carried = end.carried;
        let creep = setup.creep(&self.model);
        (self.model).update_inelastic_strain(
            &mut self.state.history,
            &setup.offsets,
            &u,
            creep.as_ref(),
        );
        self.offsets = setup.offsets;
        self.state.u = u;
        self.state.time = setup.t_new;
        StepReport {
            newton: solved.newton,
            energies,
            local_error,
            displacement_scale,
            order: setup.order,
            substeps: 1,
            newton_solves: solved.newton_solves,
            t_contact_narrow: solved.t_contact_narrow,
            t_contact_broad: solved.t_contact_broad,
            element_passes: solved.element_passes,
            ..Default::default()
        }
    }

    /// With ice that forms in water: the inelastic strains of the state's history (at the
    /// solve's end time) take what the ice formed since `before` (the history at the solve's
    /// start) was born with, and the water its expansion (`physics::ice_formation`), at the
    /// state's displacements.
    fn form_ice(&mut self, before: &crate::physics::history::ElementHistory) {
        let Some(freezing) = &self.model.freezing else {
            return;
        };
        let mesh = &self.model.mesh;
        crate::physics::ice_formation::form_ice(
            &self.model.elasticity,
            freezing,
            (before, &mut self.state.history),
            (&mesh.tets, mesh.num_nodes(), &self.state.u),
        );
    }

    /// β Kₙ: the elastic Hessian at the start of the step, scaled by β; in a distributed run,
    /// this process's share of it (its elements' and its owned nodes' nodal parts, as the
    /// elastic energy is shared).
    pub(super) fn stiffness_at_previous(&mut self, beta: f64) {
        if let Some(quadratic) = &self.hessians.elastic_quadratic {
            // A fixed quadratic's Hessian is Kₙ at every step: no pass over the elements.
            let k = quadratic.hessian();
            for (damping, k) in self.damping_stiffness.iter_mut().zip(k) {
                *damping = beta * k;
            }
            return;
        }
        let offsets = self.state.history.offsets();
        let mut elastic = ElasticStep::new(
            &self.model.elasticity,
            (&self.model.mesh.tets, &self.state.history, &offsets),
            &self.assembly,
            &mut self.element_energy,
            // β K must be positive semi-definite to damp.
            true,
        );
        elastic.subset = (self.shared.as_ref()).map(|s| (&s.elements, s.distribution.owned_dofs()));
        let mut gradient = vec![0.0; self.previous.len()];
        self.damping_stiffness.fill(0.0);
        elastic.add(
            &self.previous,
            &mut 0.0,
            Some(&mut gradient),
            Some(&mut self.damping_stiffness),
        );
        self.damping_stiffness.iter_mut().for_each(|k| *k *= beta);
    }

    /// A force scale of the step (N): the largest dead load, momentum change M v / h on a free
    /// dof, or load of the strain offsets (expansion, plastic strain). Newton's residual is
    /// judged relative to it.
    fn force_scale(&self, h: f64, dynamic: bool) -> f64 {
        let dofs = self.assembly.dofs();
        let offsets = self
            .model
            .elasticity
            .offset_force_scale(&self.state.history);
        let scale = dofs
            .free_dofs()
            .iter()
            .map(|&d| {
                let inertial = if dynamic {
                    self.model.mass[d / 3] * self.state.v[d].abs() / h
                } else {
                    0.0
                };
                self.loads[d].abs().max(inertial)
            })
            .fold(offsets, f64::max);
        self.max_over_processes(scale)
    }
}

/// What the solve of `potential` found at its solution `u`, with Newton's `report` (none if
/// no solve ran); `before`: the energies of the solve's start where its Hessian is not fixed
/// (none: a quadratic solve, whose elastic energy at the solution the potential gives).
fn solved_at(
    potential: &mut StepPotential,
    u: &[f64],
    report: Option<NewtonReport>,
    before: Option<Energies>,
) -> Solved {
    let newton = report.unwrap_or_default();
    let elastic = match before {
        // Newton's last evaluation was at its solution.
        Some(before) => ElasticAtSolution::Evaluated {
            elastic: potential.last_elastic,
            before,
        },
        None => {
            // A quadratic solve knows the potential at its solution: the elastic energy is
            // that less the other terms' (cheap, per dof), with no pass over the elements.
            let mut others = 0.0;
            for term in potential.terms.iter_mut() {
                term.add(u, &mut others, None, None);
            }
            ElasticAtSolution::Quadratic(newton.energy - others)
        }
    };
    Solved {
        newton,
        newton_solves: 0,
        elastic,
        t_contact_narrow: potential.t_contact,
        t_contact_broad: potential.broad_phase_time(),
        element_passes: potential.element_passes,
    }
}

/// What Newton solves on: the pattern, the linear solver and its workspace, the tolerances.
struct NewtonSolver<'a> {
    assembly: &'a Assembly,
    linear: &'a mut LinearSolver,
    workspace: &'a mut NewtonWorkspace,
    params: &'a NewtonParams,
    /// The step's force scale (N; see `Simulation::force_scale`).
    force_floor: f64,
}

/// Minimises `potential` from `u` (the solution left in it) and re-lags what its terms hold
/// fixed to the solution, re-solving warm-started until that changes by no more than
/// [`FRICTION_RELAG_TOLERANCE`] or [`MAX_FRICTION_UPDATES`] re-solves were made. With
/// `fixed` Hessian (N/m, CSC values of the free system; `factored`: whether the linear
/// solver holds its factorisation) each solve is a quadratic one. Returns Newton's report of
/// the solves and their number.
fn minimize_relagged(
    potential: &mut StepPotential,
    u: &mut [f64],
    newton: NewtonSolver,
    (fixed, factored): (Option<&[f64]>, &mut bool),
) -> Result<(Option<NewtonReport>, u32), SolveFailure> {
    let NewtonSolver {
        assembly,
        linear,
        workspace,
        params,
        force_floor,
    } = newton;
    let mut report: Option<NewtonReport> = None;
    let mut solves = 0;
    for _ in 0..=MAX_FRICTION_UPDATES {
        if report.is_some() && potential.relag(u) <= FRICTION_RELAG_TOLERANCE {
            break;
        }
        let this = match fixed {
            Some(hessian) => minimize_quadratic(
                potential,
                (hessian, &mut *factored),
                u,
                assembly,
                linear,
                (params, force_floor),
                workspace,
            )?,
            None => {
                // Newton factorises other matrices.
                *factored = false;
                minimize(
                    potential,
                    u,
                    assembly,
                    linear,
                    params,
                    force_floor,
                    workspace,
                )?
            }
        };
        report = Some(report.map_or(this, |n| n.then(&this)));
        solves += 1;
    }
    Ok((report, solves))
}

/// What the inertia and damping terms of a dynamic solve read.
struct InertiaParts<'a> {
    /// Lumped nodal masses (kg).
    mass: &'a [f64],
    /// The scheme's predictor ũ (m, all dofs).
    predictor: &'a [f64],
    /// The origin p of the velocity vₙ₊₁ = (u − p)/h_d (m, all dofs).
    velocity_origin: &'a [f64],
    /// β Kₙ (CSC values of the free system, N s/m; empty without stiffness damping).
    beta_stiffness: &'a [f64],
}

/// The inertia term of a dynamic solve, and Rayleigh stiffness damping if the model has it;
/// `scratch` is the damping term's (two free-system vectors).
fn inertia_terms<'a>(
    setup: &SolveSetup,
    parts: InertiaParts<'a>,
    assembly: &'a Assembly,
    scratch: &'a mut [f64],
) -> Vec<Box<dyn StepTerm + 'a>> {
    let velocity_form = (setup.damping_step, parts.velocity_origin);
    let mut terms: Vec<Box<dyn StepTerm + 'a>> = vec![Box::new(Inertia {
        dt: setup.inertia_step,
        mass: parts.mass,
        predictor: parts.predictor,
        velocity_form,
        alpha: setup.damping.mass,
        assembly,
    })];
    if setup.damping.stiffness > 0.0 {
        terms.push(Box::new(StiffnessDamping {
            velocity_form,
            beta_stiffness: parts.beta_stiffness,
            assembly,
            scratch,
        }));
    }
    terms
}

/// The contact forces on the ice at `u` of a solve's `terms` (N, 3 per node); `None` if none
/// of them is a contact.
fn contact_forces_at(terms: &[Box<dyn StepTerm + '_>], u: &[f64]) -> Option<ContactForces> {
    if !terms.iter().any(|t| t.as_contact().is_some()) {
        return None;
    }
    let n = u.len();
    let mut forces = ContactForces {
        normal: vec![0.0; n],
        friction: vec![0.0; n],
    };
    for contact in terms.iter().filter_map(|t| t.as_contact()) {
        contact.add_contact_forces(u, &mut forces);
    }
    Some(forces)
}
