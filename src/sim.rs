//! The step loop: owns the model, the state and the solver data, and advances time.

use crate::assembly::{Assembly, DofMap};
use crate::physics::contact::{ContactForces, ContactStep};
use crate::physics::ice_contact::{Candidate, IceContact};
use crate::physics::Model;
use crate::solver::timestep::{IceFriction, IceStep, Inertia, StepPotential};
use crate::solver::{
    minimize, FillOrdering, LinearSolver, LinearSolverKind, NewtonError, NewtonParams,
    NewtonReport, NewtonWorkspace, Potential,
};
use std::time::Instant;

/// Static equilibrium per step, or backward-Euler dynamics.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Analysis {
    /// Each step solves for equilibrium at its end time (quasi-static load stepping).
    Static,
    /// Backward-Euler dynamics.
    Dynamic,
}

/// How a run steps and solves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepSettings {
    /// Static or dynamic.
    pub analysis: Analysis,
    /// Time step (s).
    pub dt: f64,
    /// Newton tolerances.
    pub newton: NewtonParams,
    /// Linear solver.
    pub linear: LinearSolverKind,
    /// Fill-reducing ordering of the Cholesky factor.
    pub ordering: FillOrdering,
    /// CG relative tolerance.
    pub cg_tolerance: f64,
    /// CG iteration cap.
    pub cg_max_iterations: usize,
    /// Multigrid-preconditioned CG keeps its hierarchy across Newton iterations and steps
    /// until the iterations grow (false: a new set-up at every Hessian refresh).
    pub amg_reuse: bool,
    /// Cholesky keeps a factorisation across Hessian refreshes and steps, solving with CG
    /// preconditioned by it until that needs more than
    /// [`crate::solver::linear::reuse_iteration_budget`] iterations (opt-in: the results
    /// then depend on when the factor was made, so a resumed run is no longer bit-identical).
    pub factor_reuse: bool,
    /// Precision of that kept factor.
    pub factor_precision: crate::solver::linear::FactorPrecision,
}

impl StepSettings {
    /// The iterative-solver part of the settings.
    pub fn iterative(&self) -> crate::solver::IterativeSettings {
        crate::solver::IterativeSettings {
            tolerance: self.cg_tolerance,
            max_iterations: self.cg_max_iterations,
            amg_reuse: self.amg_reuse,
            factor_reuse: self.factor_reuse,
            factor_precision: self.factor_precision,
        }
    }
}

/// The time-dependent state: everything a step depends on besides the model.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Nodal displacement from the rest position (m), 3 per node.
    pub u: Vec<f64>,
    /// Nodal velocity (m/s), 3 per node.
    pub v: Vec<f64>,
    /// Time (s).
    pub time: f64,
    /// Completed steps.
    pub step: u64,
}

/// The state a step started from, kept so that the step can be taken again (after fracture
/// changed the mesh at its end).
#[derive(Clone, Debug, PartialEq)]
pub struct StepStart {
    /// Displacements (m), 3 per node.
    pub u: Vec<f64>,
    /// Velocities (m/s), 3 per node.
    pub v: Vec<f64>,
    /// Plastic strain per element (empty without plasticity).
    pub plastic_strain: Vec<nalgebra::Matrix3<f64>>,
    /// Time (s).
    pub time: f64,
}

/// Energies of a state (J).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energies {
    /// ½ vᵀ M v.
    pub kinetic: f64,
    /// Σ elastic element energies.
    pub elastic: f64,
    /// Potential of the dead loads, −f·u.
    pub potential: f64,
    /// Penalty energy stored in contact with obstacles.
    pub contact: f64,
}

impl Energies {
    /// Kinetic + elastic + load potential + contact penalty.
    pub fn total(&self) -> f64 {
        self.kinetic + self.elastic + self.potential + self.contact
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default)]
pub struct StepReport {
    /// Newton statistics.
    pub newton: NewtonReport,
    /// Energies after the step.
    pub energies: Energies,
    /// Wall time of the whole step (s).
    pub t_step: f64,
    /// Solves the step took (1 unless Newton failed and the step was halved).
    pub substeps: u32,
    /// Newton solves, summed over substeps: one per substep, plus one per re-solve after
    /// friction's normal force was re-lagged or a mesh obstacle's planes were re-picked
    /// (at most [`MAX_FRICTION_UPDATES`] per substep).
    pub newton_solves: u32,
    /// Contact broad phase: ice–ice candidate search and pattern update, and the choice of
    /// each node's plane on mesh obstacles (s).
    pub t_contact_broad: f64,
    /// Contact narrow phase: gaps, forces and Jacobians of all contact pairs, inside the
    /// assembly time of `newton` (s).
    pub t_contact_narrow: f64,
}

/// Re-solves of a step with the friction normal force updated from its end.
pub const MAX_FRICTION_UPDATES: usize = 4;

/// The friction normal force has settled when re-lagging it changes no pair's friction force
/// at the solution by more than this fraction of the largest α λ (see
/// [`ContactStep::relag`]; ice–ice pairs: no normal force by more than this fraction of the
/// largest). Each re-solve costs a Newton solve; in a freezing container, where every step
/// moves the wall pressures, 1e-4 took all four re-solves every step, while 1e-2 bounds the
/// friction force's error by 1 % of the largest α λ.
pub const FRICTION_RELAG_TOLERANCE: f64 = 1e-2;

/// How often a failing step may be halved (down to dt/16).
pub const MAX_HALVINGS: u32 = 4;

impl StepReport {
    /// The report of two consecutive substeps as one step.
    fn merge(&self, next: &StepReport) -> StepReport {
        StepReport {
            newton: self.newton.then(&next.newton),
            energies: next.energies,
            t_step: self.t_step + next.t_step,
            substeps: self.substeps + next.substeps,
            newton_solves: self.newton_solves + next.newton_solves,
            t_contact_broad: self.t_contact_broad + next.t_contact_broad,
            t_contact_narrow: self.t_contact_narrow + next.t_contact_narrow,
        }
    }
}

/// Errors while setting up or stepping.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A static analysis needs Dirichlet conditions (or a later contact term) to be solvable.
    #[error("singular: no Dirichlet conditions, so a static solve has unconstrained rigid-body modes; add a [[dirichlet]] region or use analysis = \"dynamic\"")]
    NoDirichlet,
    /// A Dirichlet region matched no node.
    #[error("dirichlet condition {index} (region {min:?} – {max:?}) holds no node of the mesh")]
    EmptyDirichlet {
        index: usize,
        min: [f64; 3],
        max: [f64; 3],
    },
    /// Newton failed in a step.
    // The cause is part of the message (not a `#[source]`), so that `to_string()` tells the
    // whole story and error chains do not print it twice.
    #[error("step {step} (t = {time:.6} s) failed even at dt/{}: {cause}", 1u32 << MAX_HALVINGS)]
    Step {
        step: u64,
        time: f64,
        cause: NewtonError,
    },
    /// Building the problem failed.
    #[error("set-up failed: {0}")]
    Setup(String),
    /// Linear solver set-up failed.
    #[error(transparent)]
    Linear(#[from] crate::solver::LinearError),
}

/// A model, its state, and the solver data built for its mesh.
pub struct Simulation {
    /// The mechanics.
    pub model: Model,
    /// The current state.
    pub state: State,
    /// Step settings.
    pub settings: StepSettings,
    assembly: Assembly,
    linear: LinearSolver,
    workspace: NewtonWorkspace,
    element_energy: Vec<f64>,
    scratch: Vec<f64>,
    previous: Vec<f64>,
    predictor: Vec<f64>,
    damping_stiffness: Vec<f64>,
    /// Per node, the CSC value indices of its 3 × 3 block (only built with contact).
    block_slots: Vec<[u32; 9]>,
    /// Contact forces on the ice after the last step (N, 3 per node; empty without contact).
    contact_forces: ContactForces,
    /// Node pairs coupled in the pattern by ice–ice contact (sorted, unique).
    couplings: Vec<(usize, usize)>,
    /// Ice–ice contact candidates of the current step.
    candidates: Vec<Candidate>,
    /// CSC value indices of each candidate's 12 × 12 block.
    candidate_slots: Vec<Vec<u32>>,
    /// Where the last step started (none before the first step or after a remesh).
    start: Option<StepStart>,
}

impl Simulation {
    /// Builds the pattern, slot map, colouring and (for Cholesky) the symbolic factorisation,
    /// starting from rest at t = 0.
    pub fn new(model: Model, settings: StepSettings) -> Result<Self, SimError> {
        for (index, bc) in model.dirichlet.iter().enumerate() {
            if bc.nodes(&model.mesh).next().is_none() {
                return Err(SimError::EmptyDirichlet {
                    index,
                    min: bc.region.min.into(),
                    max: bc.region.max.into(),
                });
            }
        }
        let mut model = model;
        model.apply_schedule(0.0);
        if model.plasticity.is_some() && model.elasticity.plastic_strain.is_empty() {
            model.elasticity.plastic_strain = vec![Default::default(); model.mesh.num_tets()];
        }
        let constrained = model.constrained_dofs();
        if settings.analysis == Analysis::Static && !constrained.iter().any(|c| *c) {
            return Err(SimError::NoDirichlet);
        }
        let assembly = Assembly::new(&model.mesh, DofMap::new(&constrained));
        let linear = LinearSolver::new(
            settings.linear,
            settings.ordering,
            &assembly,
            &model.mesh.rest,
            &settings.iterative(),
        )?;
        let workspace = NewtonWorkspace::new(&assembly);
        let n = 3 * model.num_nodes();
        let state = State {
            u: vec![0.0; n],
            v: vec![0.0; n],
            time: 0.0,
            step: 0,
        };
        let with_beta = model.damping.is_some_and(|d| d.stiffness > 0.0);
        Ok(Simulation {
            element_energy: vec![0.0; model.mesh.num_tets()],
            scratch: vec![0.0; 2 * assembly.dofs().num_free()],
            previous: vec![0.0; n],
            predictor: vec![0.0; n],
            block_slots: match &model.contact {
                Some(_) => (0..model.num_nodes())
                    .map(|i| assembly.node_block_slots(i))
                    .collect(),
                None => Vec::new(),
            },
            contact_forces: ContactForces::default(),
            couplings: Vec::new(),
            candidates: Vec::new(),
            candidate_slots: Vec::new(),
            start: None,
            damping_stiffness: if with_beta {
                vec![0.0; assembly.nnz()]
            } else {
                Vec::new()
            },
            model,
            state,
            settings,
            assembly,
            linear,
            workspace,
        })
    }

    /// Continues with `model` on a new mesh after a topology change (fracture; see
    /// [`Model::remeshed`]), with the nodal displacements `u` and velocities `v` (3 per node)
    /// on the new mesh. Pattern, colouring and symbolic factorisation are rebuilt (only here);
    /// time and step count carry on.
    pub fn remesh(&mut self, model: Model, u: Vec<f64>, v: Vec<f64>) -> Result<(), SimError> {
        let (time, step) = (self.state.time, self.state.step);
        let mut next = Simulation::new(model, self.settings)?;
        next.model.apply_schedule(time);
        next.state = State { u, v, time, step };
        *self = next;
        Ok(())
    }

    /// Where the last step started (none before the first step and after a remesh).
    pub fn step_start(&self) -> Option<&StepStart> {
        self.start.as_ref()
    }

    /// Takes the last step again from `start` (the step's start state, on the current mesh
    /// — after a remesh it must be carried over to the new nodes and elements). On failure
    /// the state is left at `start`.
    pub fn retake_step(&mut self, start: StepStart) -> Result<StepReport, SimError> {
        self.state.u = start.u;
        self.state.v = start.v;
        self.state.time = start.time;
        self.state.step -= 1;
        self.model.elasticity.plastic_strain = start.plastic_strain;
        self.model.apply_schedule(start.time);
        self.step()
    }

    /// The assembled pattern (for statistics).
    pub fn assembly(&self) -> &Assembly {
        &self.assembly
    }
    /// Number of ice–ice candidate pairs of the last step (for statistics).
    pub fn ice_candidates(&self) -> usize {
        self.candidates.len()
    }
    /// The linear solver (for statistics).
    pub fn linear_solver(&self) -> &LinearSolver {
        &self.linear
    }

    /// Advances one step of `settings.dt`. If Newton fails, the step is retried as two half
    /// steps, recursively, down to `dt / 2^MAX_HALVINGS`; the step then reports how many
    /// substeps it took. On failure the state is left unchanged.
    pub fn step(&mut self) -> Result<StepReport, SimError> {
        let start = Instant::now();
        let t0 = self.state.time;
        // Kept for fracture's retake, and to roll back a failed step.
        self.start = Some(StepStart {
            u: self.state.u.clone(),
            v: self.state.v.clone(),
            plastic_strain: self.model.elasticity.plastic_strain.clone(),
            time: t0,
        });
        let t_end = t0 + self.settings.dt;
        if self.model.ice_contact.is_some() {
            self.prepare_ice_contact()?;
        }
        let t_contact_broad = start.elapsed().as_secs_f64();
        let result = self.advance(self.settings.dt, t_end, 0);
        if let (Err(_), Some(s)) = (&result, &self.start) {
            self.state.time = t0;
            self.state.u.clone_from(&s.u);
            self.state.v.clone_from(&s.v);
            self.model
                .elasticity
                .plastic_strain
                .clone_from(&s.plastic_strain);
            self.model.apply_schedule(t0);
        }
        let mut report = result.map_err(|(source, time)| SimError::Step {
            step: self.state.step + 1,
            time,
            cause: source,
        })?;
        self.state.step += 1;
        report.t_step = start.elapsed().as_secs_f64();
        report.t_contact_broad += t_contact_broad;
        report.energies = self.energies();
        Ok(report)
    }

    /// Finds the ice–ice candidate pairs of the coming step and makes the sparsity pattern
    /// couple exactly their nodes: the pattern, slot map, colouring and symbolic factorisation
    /// are rebuilt when that set changes (and only then). Keeping the pattern a function of the
    /// step's start state (never a history-dependent superset) keeps resumed runs bit-identical.
    fn prepare_ice_contact(&mut self) -> Result<(), SimError> {
        let Some(term) = &self.model.ice_contact else {
            return Ok(());
        };
        self.candidates = term.candidates(
            &self.model.mesh.rest,
            &self.state.u,
            &self.state.v,
            self.settings.dt,
        );
        let mut couplings: Vec<(usize, usize)> = self
            .candidates
            .iter()
            .flat_map(|c| c.face.map(|f| (c.node.min(f), c.node.max(f))))
            .collect();
        couplings.sort_unstable();
        couplings.dedup();
        if couplings != self.couplings {
            let dofs = self.assembly.dofs().clone();
            self.assembly = Assembly::with_couplings(&self.model.mesh, dofs, &couplings);
            let s = &self.settings;
            self.linear = LinearSolver::new(
                s.linear,
                s.ordering,
                &self.assembly,
                &self.model.mesh.rest,
                &s.iterative(),
            )?;
            self.workspace = NewtonWorkspace::new(&self.assembly);
            if self.model.contact.is_some() {
                self.block_slots = (0..self.model.num_nodes())
                    .map(|i| self.assembly.node_block_slots(i))
                    .collect();
            }
            if !self.damping_stiffness.is_empty() {
                self.damping_stiffness = vec![0.0; self.assembly.nnz()];
            }
            self.couplings = couplings;
        }
        let assembly = &self.assembly;
        self.candidate_slots = self
            .candidates
            .iter()
            .map(|c| {
                let nodes = IceContact::pair_nodes(c);
                (0..144)
                    .map(|rc| {
                        let (r, col) = (rc / 12, rc % 12);
                        let (dr, dc) = (3 * nodes[r / 3] + r % 3, 3 * nodes[col / 3] + col % 3);
                        match (assembly.dofs().free(dr), assembly.dofs().free(dc)) {
                            (Some(fr), Some(fc)) => {
                                assembly.slot(fr, fc).map_or(u32::MAX, |s| s as u32)
                            }
                            _ => u32::MAX,
                        }
                    })
                    .collect()
            })
            .collect();
        Ok(())
    }

    /// Advances by `h` to `t_end` (passed so that halves land exactly on the full step's end
    /// time), halving on failure up to `MAX_HALVINGS` times.
    fn advance(
        &mut self,
        h: f64,
        t_end: f64,
        depth: u32,
    ) -> Result<StepReport, (NewtonError, f64)> {
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

    /// One backward-Euler (or static) solve of length `h` ending at `t_new`.
    fn try_step(&mut self, h: f64, t_new: f64) -> Result<StepReport, NewtonError> {
        let dynamic = self.settings.analysis == Analysis::Dynamic;
        self.model.apply_schedule(t_new);
        self.previous.copy_from_slice(&self.state.u);
        let mut u = self.state.u.clone();
        if dynamic {
            for ((p, u0), v) in self
                .predictor
                .iter_mut()
                .zip(&self.state.u)
                .zip(&self.state.v)
            {
                *p = u0 + h * v;
            }
            u.copy_from_slice(&self.predictor);
        }
        self.model.apply_dirichlet(t_new, &mut u);
        let damping = self.model.damping.unwrap_or_default();
        if dynamic && damping.stiffness > 0.0 {
            self.stiffness_at_previous(damping.stiffness);
        }
        let force_floor = self.force_scale(h, dynamic);
        let rest = &self.model.mesh.rest;
        let t_start = self.state.time;
        let selection = Instant::now();
        let contact = self.model.contact.as_ref().map(|c| {
            // Mesh obstacles look for nodes as far as the step can carry them, and an edge.
            let vmax = self.state.v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let reach = c.edge + 2.0 * h * vmax * 3f64.sqrt();
            ContactStep::new(
                c,
                rest,
                &self.previous,
                (t_start, t_new),
                dynamic.then_some(h),
                reach,
            )
        });
        // Friction's normal force starts extrapolated from the step before, uₙ − h vₙ.
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
        let contact = contact.map(|mut c| {
            c.extrapolate_lagged(&earlier);
            c
        });
        let mut t_contact_broad = selection.elapsed().as_secs_f64();
        let mut potential = StepPotential {
            model: &self.model,
            assembly: &self.assembly,
            inertia: dynamic.then(|| Inertia {
                dt: h,
                predictor: &self.predictor,
                previous: &self.previous,
                alpha: damping.mass,
                beta_stiffness: (damping.stiffness > 0.0).then_some(&self.damping_stiffness[..]),
            }),
            element_energy: &mut self.element_energy,
            scratch: &mut self.scratch,
            contact,
            block_slots: &self.block_slots,
            project: false,
            ice: self.model.ice_contact.as_ref().map(|term| {
                let mut ice = IceStep {
                    term,
                    candidates: &self.candidates,
                    slots: &self.candidate_slots,
                    anticipated: Vec::new(),
                    friction: None,
                };
                if dynamic && term.friction > 0.0 {
                    let frames = ice.extrapolated_friction_frames(rest, &self.previous, &earlier);
                    ice.friction = Some(IceFriction {
                        dt: h,
                        previous: &self.previous,
                        frames,
                    });
                }
                ice
            }),
            t_contact: 0.0,
            contact_blocks: Vec::new(),
        };
        // Friction uses the normal force extrapolated to the end of the step; after each solve it
        // is re-lagged to the solution's and the step re-solved (warm-started) until it settles
        // to FRICTION_RELAG_TOLERANCE of the largest. Mesh obstacles' planes are re-picked the
        // same way.
        let mut newton: Option<NewtonReport> = None;
        let mut newton_solves = 0;
        for _ in 0..=MAX_FRICTION_UPDATES {
            if newton.is_some() {
                let mut change: f64 = 0.0;
                if let Some(c) = potential.contact.as_mut() {
                    let reselection = Instant::now();
                    if c.reselect_node_planes(&u) {
                        change = f64::INFINITY;
                    }
                    t_contact_broad += reselection.elapsed().as_secs_f64();
                }
                if let Some(c) = potential.contact.as_mut() {
                    change = change.max(c.relag(&u));
                }
                if let Some(ice) = potential.ice.as_mut() {
                    change = change.max(ice.relag(rest, &u));
                }
                if change <= FRICTION_RELAG_TOLERANCE {
                    break;
                }
            }
            let report = minimize(
                &mut potential,
                &mut u,
                &self.assembly,
                &mut self.linear,
                &self.settings.newton,
                force_floor,
                &mut self.workspace,
            )?;
            newton = Some(newton.map_or(report, |n| n.then(&report)));
            newton_solves += 1;
        }
        let newton = newton.unwrap_or_default();
        if dynamic {
            for ((v, un), u0) in self.state.v.iter_mut().zip(&u).zip(&self.previous) {
                *v = (un - u0) / h;
            }
        }
        if potential.contact.is_some() || potential.ice.is_some() {
            let n = u.len();
            let mut forces = ContactForces {
                normal: vec![0.0; n],
                friction: vec![0.0; n],
            };
            if let Some(contact) = &potential.contact {
                contact.evaluate(&u, None, None, Some(&mut forces));
            }
            if let Some(ice) = &potential.ice {
                ice.add(&self.model.mesh.rest, &u, None, None, Some(&mut forces));
            }
            self.contact_forces = forces;
        }
        let t_contact_narrow = potential.t_contact;
        self.model.update_plastic_strain(&u);
        self.state.u = u;
        self.state.time = t_new;
        Ok(StepReport {
            newton,
            substeps: 1,
            newton_solves,
            t_contact_narrow,
            t_contact_broad,
            ..Default::default()
        })
    }

    /// β Kₙ: the elastic Hessian at the start of the step, scaled by β.
    fn stiffness_at_previous(&mut self, beta: f64) {
        let mut potential = StepPotential {
            model: &self.model,
            assembly: &self.assembly,
            inertia: None,
            element_energy: &mut self.element_energy,
            scratch: &mut self.scratch,
            contact: None,
            block_slots: &[],
            // β K must be positive semi-definite to damp.
            project: true,
            ice: None,
            t_contact: 0.0,
            contact_blocks: Vec::new(),
        };
        let mut gradient = vec![0.0; self.previous.len()];
        potential.evaluate(&self.previous, &mut gradient, &mut self.damping_stiffness);
        self.damping_stiffness.iter_mut().for_each(|k| *k *= beta);
    }

    /// A force scale of the step (N): the largest dead load, momentum change M v / h on a free
    /// dof, or load of the strain offsets (expansion, plastic strain). Newton's residual is
    /// judged relative to it.
    fn force_scale(&self, h: f64, dynamic: bool) -> f64 {
        let dofs = self.assembly.dofs();
        let offsets = self.model.elasticity.offset_force_scale();
        dofs.free_dofs()
            .iter()
            .map(|&d| {
                let inertial = if dynamic {
                    self.model.mass[d / 3] * self.state.v[d].abs() / h
                } else {
                    0.0
                };
                self.model.external_force[d].abs().max(inertial)
            })
            .fold(offsets, f64::max)
    }

    /// Energies of the current state.
    pub fn energies(&mut self) -> Energies {
        let u = &self.state.u;
        let el = &self.model.elasticity;
        let tets = &self.model.mesh.tets;
        self.assembly.energies(
            |e, out| el.element(tets, u, e, false, out),
            &mut self.element_energy,
        );
        let elastic = self.element_energy.iter().sum();
        let kinetic = self
            .state
            .v
            .iter()
            .enumerate()
            .map(|(d, v)| 0.5 * self.model.mass[d / 3] * v * v)
            .sum();
        let potential = -self
            .model
            .external_force
            .iter()
            .zip(u)
            .map(|(f, u)| f * u)
            .sum::<f64>();
        let contact = self.model.contact.as_ref().map_or(0.0, |c| {
            let t = self.state.time;
            ContactStep::new(c, &self.model.mesh.rest, u, (t, t), None, c.edge)
                .evaluate(u, None, None, None)
        }) + self.model.ice_contact.as_ref().map_or(0.0, |term| {
            let ice = IceStep {
                friction: None,
                term,
                candidates: &self.candidates,
                slots: &[],
                anticipated: Vec::new(),
            };
            ice.add(&self.model.mesh.rest, u, None, None, None)
        });
        Energies {
            kinetic,
            elastic,
            potential,
            contact,
        }
    }

    /// Element stresses (Pa, Voigt xx yy zz yz xz xy) of the current state.
    pub fn stresses(&self) -> Vec<[f64; 6]> {
        self.model
            .elasticity
            .stresses(&self.model.mesh.tets, &self.state.u)
    }

    /// Number of entries held by contact bookkeeping (block slots, output
    /// forces); zero for a model without obstacles.
    pub fn contact_structures_len(&self) -> usize {
        self.block_slots.len() + self.contact_forces.normal.len()
    }

    /// Contact forces on the ice after the last step (N, 3 per node), if the model has contact.
    pub fn contact_forces(&self) -> Option<&ContactForces> {
        (self.model.contact.is_some() || self.model.ice_contact.is_some())
            .then_some(&self.contact_forces)
    }

    /// Current positions X + u (m).
    pub fn positions(&self) -> Vec<[f64; 3]> {
        self.model
            .mesh
            .rest
            .iter()
            .enumerate()
            .map(|(i, p)| std::array::from_fn(|a| p[a] + self.state.u[3 * i + a]))
            .collect()
    }

    /// Displacement of node `i` (m).
    pub fn displacement(&self, i: usize) -> [f64; 3] {
        std::array::from_fn(|a| self.state.u[3 * i + a])
    }
}
