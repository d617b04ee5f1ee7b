//! The step loop: owns the model, the state and the solver data, and advances time.
//!
//! Each solve minimises the sum of the step's terms (see `physics::term` and [`potential`]):
//! the elastic energy, the dead loads, the terms the scene enables (obstacle contact, ice–ice
//! contact) and, in a dynamic step, inertia and damping.

mod acceleration;
pub mod adaptive;
pub mod balance;
pub mod handover;
mod hessians;
pub mod integrator;
pub mod part;
pub mod potential;
mod rigid_start;
mod shared;
mod step;
mod terms;

use crate::assembly::{Assembly, DofMap};
use crate::fem::StrainOffset;
use crate::mesh::TetMesh;
use crate::physics::contact::ContactForces;
use crate::physics::freezing::{Schedule, ThermalPoint};
use crate::physics::history::ElementHistory;
use crate::physics::term::TermHistory;
use crate::physics::Model;
use crate::solver::{
    FillOrdering, LinearSolver, LinearSolverKind, NewtonError, NewtonParams, NewtonReport,
    NewtonWorkspace,
};
use crate::thermal::HeatLink;
pub use adaptive::Adaptive;
use balance::{energies_of, EnergyRise};
use hessians::KeptHessians;
pub use integrator::{Scheme, SchemeState, TimeIntegrator};
use nalgebra::Vector3;
pub use potential::Collective;
use rigid_start::RigidStart;
pub use shared::Distribution;
use shared::Shared;
use terms::ElasticInputs;

/// Static equilibrium per step, or dynamics (integrated by the [`Scheme`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Analysis {
    /// Each step solves for equilibrium at its end time (quasi-static load stepping).
    Static,
    /// Dynamics: inertia, integrated in time by the [`Scheme`].
    Dynamic,
}

/// How a run steps and solves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepSettings {
    /// Static or dynamic.
    pub analysis: Analysis,
    /// Time integration of a dynamic analysis.
    pub scheme: Scheme,
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
    /// Adaptive step control (dynamic analyses); `None`: every step is `dt`.
    pub adaptive: Option<Adaptive>,
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

/// The time-dependent state: everything a step depends on besides the model. Rolling a step
/// back is restoring a copy of it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct State {
    /// Nodal displacement from the rest position (m), 3 per node.
    pub u: Vec<f64>,
    /// Nodal velocity (m/s), 3 per node.
    pub v: Vec<f64>,
    /// Time (s).
    pub time: f64,
    /// Completed steps.
    pub step: u64,
    /// What the elements carry from step to step.
    pub history: ElementHistory,
    /// Temperature of each node of the scene's mesh (°C), where the heat model is solved;
    /// empty without `[thermal]`.
    pub temperature: Vec<f64>,
    /// What the time scheme carries from step to step (Newmark's acceleration, BDF2's step
    /// back; empty before the first step and after a remesh).
    pub carried: SchemeState,
    /// What the model's terms carry from step to step (the gaps of the pairs of copies of
    /// split nodes).
    pub term_history: TermHistory,
    /// The step length the adaptive control proposes for the next step (s; 0 without
    /// adaptive steps, or before the first step: then the scene's `dt`).
    pub next_dt: f64,
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
    /// The heat step that preceded the mechanics (with `[thermal]`).
    pub heat: Option<crate::thermal::HeatStep>,
    /// Estimated local displacement error of the step (m, largest over the free dofs; the
    /// largest of its substeps'; 0 in a static analysis): see `TimeIntegrator::local_error`.
    pub local_error: f64,
    /// Largest |displacement| of a free dof after the step (m): the adaptive control's
    /// scale for the relative error.
    pub displacement_scale: f64,
    /// Order of accuracy of the step's formula (the lowest of its substeps').
    pub order: u32,
    /// Tries of the step the adaptive control rejected before this one (their time is in
    /// `t_step`).
    pub rejected: u32,
    /// The adaptive control's error measure of the step: `local_error` / (relative
    /// tolerance × `displacement_scale` + absolute tolerance); ≤ 1 unless the step was at
    /// the smallest step allowed. 0 without adaptive steps.
    pub error_ratio: f64,
    /// Passes over the elements of the step's solves, summed over substeps: evaluations of
    /// the elastic term (energy, gradient, and Hessian when assembled), one per Newton
    /// iteration; none where the elastic energy is a fixed quadratic whose Hessian is kept
    /// (see `ElasticQuadratic`). The energy balance check's passes are not counted.
    pub element_passes: u32,
}

/// Re-solves of a step with the friction normal force updated from its end.
pub const MAX_FRICTION_UPDATES: usize = 4;

/// The friction normal force has settled when re-lagging it changes no pair's friction force
/// at the solution by more than this fraction of the largest α λ (see
/// `ContactStep::relag`; ice–ice pairs: no normal force by more than this fraction of the
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
            heat: self.heat.or(next.heat),
            local_error: self.local_error.max(next.local_error),
            displacement_scale: next.displacement_scale,
            order: self.order.min(next.order),
            rejected: self.rejected + next.rejected,
            error_ratio: self.error_ratio.max(next.error_ratio),
            element_passes: self.element_passes + next.element_passes,
        }
    }
}

/// Why a solve failed.
#[derive(Debug, thiserror::Error)]
pub enum SolveFailure {
    /// Newton found no solution; where its last iterate is furthest from balance, if known.
    #[error("{error}{}", imbalance.as_ref().map_or(String::new(), |i| format!("; {i}")))]
    Newton {
        /// Newton's failure.
        error: NewtonError,
        /// The node of the largest force imbalance at Newton's last iterate and the term that
        /// pushes hardest there.
        imbalance: Option<Box<Imbalance>>,
    },
    /// The solution holds energy no work accounts for.
    #[error(transparent)]
    EnergyRise(#[from] EnergyRise),
}

impl From<NewtonError> for SolveFailure {
    fn from(error: NewtonError) -> Self {
        SolveFailure::Newton {
            error,
            imbalance: None,
        }
    }
}

/// Where a failed solve's last iterate is furthest from balance.
#[derive(Clone, Debug, PartialEq)]
pub struct Imbalance {
    /// The node with the largest free-dof force imbalance.
    pub node: usize,
    /// Its rest position (m).
    pub rest: Vector3<f64>,
    /// The imbalance there, the norm of the node's summed forces (N).
    pub force: f64,
    /// The term with the largest force on that node.
    pub term: &'static str,
    /// That term's force on the node (N, norm).
    pub term_force: f64,
}

impl std::fmt::Display for Imbalance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let x = &self.rest;
        write!(
            f,
            "the largest force imbalance, {:.3e} N, is at node {} (rest position {:.4}, {:.4}, {:.4} m), where {} exerts {:.3e} N",
            self.force, self.node, x.x, x.y, x.z, self.term, self.term_force
        )
    }
}

/// Errors while setting up or stepping.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// A static analysis needs Dirichlet conditions (or a later contact term) to be solvable.
    #[error("singular: no Dirichlet conditions, so a static solve has unconstrained rigid-body modes; add a [[dirichlet]] region or use analysis = \"dynamic\"")]
    NoDirichlet,
    /// A Dirichlet region matched no node.
    #[error("[[dirichlet]] number {} ({region}) holds no node of the mesh", index + 1)]
    EmptyDirichlet { index: usize, region: String },
    /// Newton failed in a step.
    // The cause is part of the message (not a `#[source]`), so that `to_string()` tells the
    // whole story and error chains do not print it twice.
    #[error("step {step} (t = {time:.6} s) failed even at dt/{}: {cause}", 1u32 << MAX_HALVINGS)]
    Step {
        step: u64,
        time: f64,
        cause: SolveFailure,
    },
    /// Building the problem failed.
    #[error("set-up failed: {0}")]
    Setup(String),
    /// The scene uses something a distributed run does not do.
    #[error("a run on several processes does not support {0}; run this scene on one process")]
    NotDistributed(&'static str),
    /// Linear solver set-up failed.
    #[error(transparent)]
    Linear(#[from] crate::solver::LinearError),
    /// The heat model failed.
    #[error(transparent)]
    Heat(#[from] crate::thermal::ThermalError),
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
    /// Origin p of the step's velocity vₙ₊₁ = (u − p)/h_d, for the damping terms.
    damping_origin: Vec<f64>,
    damping_stiffness: Vec<f64>,
    /// Contact forces on the ice after the last step (N, 3 per node; empty without contact).
    contact_forces: ContactForces,
    /// Node pairs the terms couple in the pattern beyond the elements (sorted, unique).
    couplings: Vec<(usize, usize)>,
    /// Node pairs the elastic energy couples beyond the elements (the nodal volumetric
    /// energy's stars), always in the pattern.
    elastic_couplings: Vec<(usize, usize)>,
    /// Where the last step started (none before the first step or after a remesh).
    start: Option<State>,
    /// Where Newton starts the next full step instead of the predictor (a retaken step's
    /// previous solution), used once.
    initial_guess: Option<Vec<f64>>,
    /// The strain offsets of the last solve (lent to the solve while it runs; empty if it
    /// failed), from which the next forms only those that changed.
    offsets: Vec<StrainOffset>,
    /// Element energies of the balance check's start energies (J, scratch, one per element).
    balance_scratch: Vec<f64>,
    /// The heat model that drives the freezing (with `[thermal]`).
    heat: Option<HeatLink>,
    /// The freeze states over the current step that the heat model gave (with `[thermal]`):
    /// step data, in place of the scene's freezing schedule.
    thermal_schedule: Option<Schedule>,
    /// The dead loads (N, 3 per node) at the time last set ([`Simulation::set_time`]): step
    /// data.
    loads: Vec<f64>,
    /// The Hessians kept between solves while they cannot change.
    hessians: KeptHessians,
    /// The time scheme of a dynamic analysis.
    integrator: Box<dyn TimeIntegrator>,
    /// The supports hold every part of the mesh against rigid motion
    /// (`physics::dirichlet::hold_every_part`).
    parts_held: bool,
    /// The parts that move freely, for Newton's start of a turning part.
    rigid_start: RigidStart,
    /// This process's share of a distributed run.
    shared: Option<Shared>,
}

impl Simulation {
    /// Builds the pattern, slot map, colouring and (for Cholesky) the symbolic factorisation,
    /// starting at t = 0 from rest or from the model's initial displacement and velocity.
    pub fn new(model: Model, settings: StepSettings) -> Result<Self, SimError> {
        Self::check(&model, &settings)?;
        Self::for_part(model, settings)
    }

    /// The checks [`Simulation::new`] makes on a model: every support holds a node, and a
    /// static analysis has one.
    pub fn check(model: &Model, settings: &StepSettings) -> Result<(), SimError> {
        Simulation::check_shared(model, settings, &|flag| flag)
    }

    /// [`Simulation::check`] of a process's part `model` of a model built on parts: a check
    /// fails when it fails on every process (`anywhere` tells whether a flag is set on any).
    pub fn check_shared(
        model: &Model,
        settings: &StepSettings,
        anywhere: &dyn Fn(bool) -> bool,
    ) -> Result<(), SimError> {
        for (index, bc) in model.dirichlet.iter().enumerate() {
            if !anywhere(bc.nodes(&model.mesh).next().is_some()) {
                return Err(SimError::EmptyDirichlet {
                    index,
                    region: bc.region.describe(),
                });
            }
        }
        let constrained = model.constrained_dofs().iter().any(|c| *c);
        if settings.analysis == Analysis::Static && !anywhere(constrained) {
            return Err(SimError::NoDirichlet);
        }
        Ok(())
    }

    /// As [`Simulation::new`], for a process's part of a distributed run
    /// ([`part::Part::model`]): without the checks that concern the whole model (a support
    /// region may hold no node of a part), which the caller made on it.
    pub fn for_part(model: Model, settings: StepSettings) -> Result<Self, SimError> {
        let mut model = model;
        // A scene's model describes its elements without their rest data, built here for
        // the mesh this simulation runs (a part's elements already have theirs).
        model.elasticity.build(&model.mesh);
        if let Some(f) = &model.freezing {
            // The water's constants, for the elements a freezing schedule leaves unfrozen.
            model.elasticity.water_bulk = f.water_bulk();
            model.elasticity.water_shear = f.water_shear;
        }
        let mut history = model.elasticity.initial_history();
        model.apply_freezing(0.0, &mut history, None);
        let loads = model.dead_loads_at(0.0);
        let constrained = model.constrained_dofs();
        // The elastic energy's own couplings (nodal volumetric averaging) are always in the
        // pattern; the terms' are added at the start of each step.
        let couplings = model.elasticity.couplings();
        let assembly = Assembly::with_couplings(&model.mesh, DofMap::new(&constrained), &couplings);
        model.elasticity.pattern_ready(&assembly);
        let linear = LinearSolver::new(
            settings.linear,
            settings.ordering,
            &assembly,
            &model.mesh.rest,
            &settings.iterative(),
        )?;
        let workspace = NewtonWorkspace::new(&assembly);
        for term in &mut model.terms {
            term.pattern_ready(&assembly, true);
        }
        let n = 3 * model.num_nodes();
        let v = if model.initial_velocity.len() == n {
            model.initial_velocity.clone()
        } else {
            vec![0.0; n]
        };
        let u = if model.initial_displacement.len() == n {
            model.initial_displacement.clone()
        } else {
            vec![0.0; n]
        };
        let state = State {
            u,
            v,
            time: 0.0,
            step: 0,
            history,
            temperature: Vec::new(),
            carried: SchemeState::default(),
            term_history: TermHistory::default(),
            next_dt: 0.0,
        };
        let with_beta = model.damping.is_some_and(|d| d.stiffness > 0.0);
        Ok(Simulation {
            element_energy: vec![0.0; model.mesh.num_tets()],
            scratch: vec![0.0; 2 * assembly.dofs().num_free()],
            previous: vec![0.0; n],
            predictor: vec![0.0; n],
            damping_origin: vec![0.0; n],
            contact_forces: ContactForces::default(),
            elastic_couplings: couplings,
            couplings: Vec::new(),
            start: None,
            initial_guess: None,
            offsets: Vec::new(),
            balance_scratch: Vec::new(),
            heat: None,
            thermal_schedule: None,
            loads,
            hessians: KeptHessians::default(),
            integrator: settings.scheme.integrator(),
            parts_held: crate::physics::dirichlet::hold_every_part(&model.mesh, &constrained),
            rigid_start: RigidStart::new(&model.mesh, &constrained),
            shared: None,
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
    /// and what the terms carry, `term_history`, on the new mesh; new element `e` inherits the
    /// history of element `parent[e]`. Pattern, colouring and symbolic factorisation are
    /// rebuilt (only here); time and step count carry on. In a distributed run every process
    /// calls it with the same split (`model` the whole model on the new mesh, which every
    /// process holds: see [`Distribution::remeshed`]) and continues on its share of it.
    pub fn remesh(
        &mut self,
        model: Model,
        u: Vec<f64>,
        v: Vec<f64>,
        term_history: TermHistory,
        parent: &[usize],
    ) -> Result<(), SimError> {
        Self::check(&model, &self.settings)?;
        // In a distributed run, every process splits alike and continues on its part of the
        // new mesh.
        let shared = match &self.shared {
            Some(shared) => Some(shared.distribution.remeshed(&model, parent)?),
            None => None,
        };
        let model = match &shared {
            // A split changes elements of several parts at once: on parts, fracture splits
            // through `distributed::part_fracture`; here only where every process holds the
            // whole mesh.
            Some((_, part)) if !part.is_whole() => {
                return Err(SimError::NotDistributed(
                    "remeshing a process's part of the mesh (fracture on parts splits through the processes' fracture)",
                ))
            }
            Some((_, part)) => part.whole_model(model),
            None => model,
        };
        let (time, step) = (self.state.time, self.state.step);
        let history = self.state.history.inherit(parent);
        let mut next = Simulation::for_part(model, self.settings)?;
        self.hand_heat_to(&mut next, parent, |link, mesh| {
            Ok(link.remeshed(&mesh.rest, &mesh.tets, parent))
        })?;
        next.state = State {
            u,
            v,
            time,
            step,
            history,
            temperature: std::mem::take(&mut self.state.temperature),
            carried: SchemeState::default(),
            term_history,
            next_dt: self.state.next_dt,
        };
        next.set_time(time);
        if let Some((distribution, _)) = shared {
            next.distribute(distribution)?;
        }
        *self = next;
        Ok(())
    }

    /// Drives the freezing by `link`'s heat model from now on, from its current temperatures
    /// (the state's, when it has them: a resumed run). The model must freeze (`[freezing]`
    /// with a thermal schedule).
    pub fn attach_heat(&mut self, mut link: HeatLink) {
        if self.state.temperature.len() == link.heat.temperature().len() {
            link.heat.set_temperature(&self.state.temperature);
        }
        self.state.temperature = link.heat.temperature().to_vec();
        self.heat = Some(link);
        self.set_thermal_schedule(self.state.time, self.state.time, None);
    }

    /// Gives `next` — this run continued on a split mesh, its element `e` made from element
    /// `parent[e]` — the heat model (with `[thermal]`), linked to `next`'s mesh by `relink`,
    /// and the freeze states over the current step, element by element. The temperatures
    /// travel with the state.
    pub fn hand_heat_to(
        &mut self,
        next: &mut Simulation,
        parent: &[usize],
        relink: impl FnOnce(HeatLink, &TetMesh) -> Result<HeatLink, SimError>,
    ) -> Result<(), SimError> {
        next.thermal_schedule = (self.thermal_schedule.take()).map(|s| s.inherit(parent));
        next.heat = match self.heat.take() {
            Some(link) => Some(relink(link, &next.model.mesh)?),
            None => None,
        };
        Ok(())
    }

    /// Takes the heat model away (with `[thermal]`; the simulation goes on without it).
    pub fn take_heat(&mut self) -> Option<HeatLink> {
        self.thermal_schedule = None;
        self.heat.take()
    }

    /// Sets the scene-mesh temperatures (°C; a resumed run's) and the freeze states they give.
    pub fn set_temperature(&mut self, temperature: Vec<f64>) {
        if self.heat.is_some() {
            self.state.temperature = temperature;
            self.freeze_states_from_temperatures();
        }
    }

    /// Sets the elements' freeze states to those the state's temperatures give through the
    /// heat model's link to the current mesh, as a resumed run finds them (nothing without
    /// `[thermal]`).
    pub fn freeze_states_from_temperatures(&mut self) {
        self.set_thermal_schedule(self.state.time, self.state.time, None);
    }

    /// The heat model, with `[thermal]`.
    pub fn heat(&self) -> Option<&HeatLink> {
        self.heat.as_ref()
    }

    /// Temperature of every node of the mechanics mesh (°C), with `[thermal]`.
    pub fn node_temperatures(&self) -> Option<Vec<f64>> {
        self.heat
            .as_ref()
            .map(|link| link.node_temperatures(&self.state.temperature))
    }

    /// Makes the freeze states run from the elements' current ones at `t0` to those of the
    /// state's temperatures at `t1` (s), and the element temperatures from those of the
    /// scene-mesh temperatures `before` (°C; the state's when `None`) to the state's, and
    /// applies them at `t0`.
    fn set_thermal_schedule(&mut self, t0: f64, t1: f64, before: Option<&[f64]>) {
        let Some(link) = &self.heat else { return };
        let tets = &self.model.mesh.tets;
        let (fraction, temperature) = link.element_states(&self.state.temperature, tets);
        let end = ThermalPoint {
            time: t1,
            fraction,
            temperature,
        };
        let mut start = end.clone();
        start.time = t0;
        if t1 > t0 && self.state.history.freeze_state.len() == end.fraction.len() {
            start.fraction.clone_from(&self.state.history.freeze_state);
        }
        if let Some(before) = before {
            start.temperature = link.element_temperatures(before, tets);
        }
        if self.model.freezing.is_some() {
            self.thermal_schedule = Some(Schedule::Thermal { start, end });
        }
        self.set_time(t0);
    }

    /// Sets what depends on time to its value at `t` (s): the elements' freeze states and
    /// expansion in the state's history, and the dead loads.
    pub fn set_time(&mut self, t: f64) {
        let schedule = self.thermal_schedule.as_ref();
        (self.model).apply_freezing(t, &mut self.state.history, schedule);
        self.model.dead_loads_into(t, &mut self.loads);
    }

    /// Puts the state back where the last step started (a failed step, or one the adaptive
    /// control rejected).
    fn undo_step(&mut self) {
        if let Some(s) = &self.start {
            self.state.clone_from(s);
            self.set_time(self.state.time);
        }
    }

    /// Where the last step started (none before the first step and after a remesh).
    pub fn step_start(&self) -> Option<&State> {
        self.start.as_ref()
    }

    /// Takes the last step again from `start` (the step's start state, on the current mesh
    /// — after a remesh it must be carried over to the new nodes and elements). On failure
    /// the state is left at `start`.
    ///
    /// Newton starts from the current displacements (the step's solution before the change,
    /// carried onto the new mesh), not from the predictor: they differ from the new solution
    /// only around the change, and a split re-solved from the predictor took ~45 Newton
    /// iterations in the 1 728-tet paper scene.
    pub fn retake_step(&mut self, start: State) -> Result<StepReport, SimError> {
        let guess = std::mem::replace(&mut self.state, start).u;
        self.initial_guess = Some(guess);
        self.set_time(self.state.time);
        self.step()
    }

    /// Forgets what the solves carry from step to step outside the state: the next solve
    /// starts from a fresh Hessian rather than the factor kept from the solves before (see
    /// [`NewtonWorkspace::forget_factor`]). It changes the iterates, not the tolerance the
    /// solutions meet. A run does this at every frame on its output grid, so that a run
    /// resumed from such a frame repeats the uninterrupted run's iterations bit for bit.
    pub fn forget_solver_memory(&mut self) {
        self.workspace.forget_factor();
    }

    /// The linear solver of the settings for the current pattern; in a distributed run the
    /// processes' shared one, with this process's elements on the pattern updated.
    fn linear_solver_for_pattern(&mut self) -> Result<LinearSolver, SimError> {
        let s = &self.settings;
        Ok(match &mut self.shared {
            Some(shared) => {
                let owned = shared.distribution.owned_elements();
                shared.elements = self.assembly.subset(owned);
                LinearSolver::External(shared.distribution.solver(&self.assembly, s.linear)?)
            }
            None => LinearSolver::new(
                s.linear,
                s.ordering,
                &self.assembly,
                &self.model.mesh.rest,
                &s.iterative(),
            )?,
        })
    }

    /// The time scheme of a dynamic analysis.
    pub fn integrator(&self) -> &dyn TimeIntegrator {
        &*self.integrator
    }

    /// The assembled pattern (for statistics).
    pub fn assembly(&self) -> &Assembly {
        &self.assembly
    }
    /// Number of ice–ice candidate pairs of the last step (for statistics).
    pub fn ice_candidates(&self) -> usize {
        self.model
            .term::<crate::physics::ice_contact::IceContactTerm>()
            .map_or(0, |t| t.num_candidates())
    }
    /// The linear solver (for statistics).
    pub fn linear_solver(&self) -> &LinearSolver {
        &self.linear
    }

    /// Energies of the current state.
    pub fn energies(&mut self) -> Energies {
        let subset = self
            .shared
            .as_ref()
            .map(|s| (&s.elements, s.distribution.owned_dofs()));
        let offsets = self.state.history.offsets();
        let elastic = ElasticInputs {
            history: &self.state.history,
            offsets: &offsets,
            element_energy: &mut self.element_energy,
            subset,
            // The stored energy: creep acts only inside a solve.
            creep: None,
        };
        let state = &self.state;
        let parts = energies_of(
            &self.model,
            &self.assembly,
            elastic,
            (&state.u, &state.v, state.time, &self.loads),
        );
        self.energies_over_processes(parts)
    }

    /// Element stresses (Pa, Voigt xx yy zz yz xz xy) of the current state.
    pub fn stresses(&self) -> Vec<[f64; 6]> {
        self.model
            .elasticity
            .stresses(&self.model.mesh.tets, &self.state.history, &self.state.u)
    }

    /// Number of entries held by contact bookkeeping (block slots, output
    /// forces); zero for a model without obstacles.
    pub fn contact_structures_len(&self) -> usize {
        let terms: usize = (self.model.terms.iter())
            .filter_map(|t| t.as_contact())
            .map(|c| c.bookkeeping_len())
            .sum();
        terms + self.contact_forces.normal.len()
    }

    /// Contact forces on the ice after the last step (N, 3 per node), if the model has contact.
    pub fn contact_forces(&self) -> Option<&ContactForces> {
        self.model
            .terms
            .iter()
            .any(|t| t.as_contact().is_some_and(|c| c.exerts_forces()))
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
