//! Newton's method with a backtracking line search on a scalar potential (the incremental
//! potential of a backward-Euler step, or the total potential energy of a static step).
//!
//! The first iteration of a solve assembles and factorises the Hessian, unless a direct solver
//! holds the factor of an earlier solve's Hessian (see [`NewtonWorkspace::forget_factor`]):
//! then it starts with that. Iterations keep the factorisation they have (a chord step: any
//! positive-definite matrix gives a descent direction, and the line search and the residual
//! test see the true potential) as long as each iteration reduces the residual at least
//! [`CHORD_CONTRACTION`]-fold; otherwise they reassemble and refactorise. Ice is stiff and
//! nearly linear at the strains it survives, so a factor serves several solves (modified
//! Newton with the Jacobian kept across steps, as in stiff ODE codes). With a solver that
//! multiplies by the matrix (CG, possibly preconditioned by a kept factor) a chord iteration
//! also brings the cheap, far-from-quadratic part of the matrix to the iterate
//! ([`Potential::refresh_hessian`]), which costs little against a whole assembly.

use super::linear::{LinearError, LinearSolver, LinearStats};
use crate::assembly::{Assembly, DofMap};
use std::time::Instant;

/// A smooth potential over all dofs (3 per node) whose free part Newton minimises.
pub trait Potential {
    /// Potential at the full dof vector `u` (J).
    fn energy(&mut self, u: &[f64]) -> f64;
    /// Potential, its gradient over all dofs (N) and the Hessian of the free system (N/m)
    /// written into `hessian` (CSC values of `assembly`'s pattern; overwritten).
    fn evaluate(&mut self, u: &[f64], gradient: &mut [f64], hessian: &mut [f64]) -> f64;
    /// Potential and its gradient over all dofs (N), without the Hessian.
    fn gradient(&mut self, u: &[f64], gradient: &mut [f64]) -> f64;
    /// The largest of `x` over the processes of a distributed run (`x` itself on one): what
    /// Newton computes from this process's part of the Hessian must be the same on all.
    fn max_over_processes(&self, x: f64) -> f64 {
        x
    }
    /// Σ over the processes of `x` (`x` itself on one), the same on every process.
    fn sum_over_processes(&self, x: f64) -> f64 {
        x
    }
    /// The dofs this process owns in a distributed run (None: all). A process may hold
    /// other processes' dofs (ghosts) with the same values; sums over dofs count each dof
    /// on its owner only.
    fn owned_dofs(&self) -> Option<&[bool]> {
        None
    }
    /// Switches to a positive semi-definite approximation of the Hessian (`project`) or back
    /// to the exact one from the next evaluation on; returns whether anything changed (false
    /// if it already was, or there is nothing to project).
    fn project_hessian(&mut self, _project: bool) -> bool {
        false
    }
    /// Given the current iterate `u` and the full Newton step `trial`, lets the potential add
    /// to its Hessian the stiffness of constraints the step would activate; returns whether
    /// the Hessian changed, in which case Newton recomputes the step.
    fn anticipate(&mut self, _u: &[f64], _trial: &[f64]) -> bool {
        false
    }
    /// Forgets what [`Potential::anticipate`] added: each iteration starts from the true
    /// Hessian, or Newton would converge only linearly towards states where an anticipated
    /// constraint stays inactive.
    fn forget_anticipated(&mut self) {}
    /// Adds to `gradient` the gradient the anticipated constraints would have at `u` if they
    /// were already active; returns whether there was any. Newton puts it into the
    /// right-hand side only: with the stiffness of a constraint in the Hessian but not its
    /// force, a node approaching an obstacle would creep towards it by (load / penalty
    /// stiffness) per iteration; with both, the step lands it on the obstacle, pressed in to
    /// equilibrium, as the active constraint's quadratic model predicts.
    fn add_anticipated_gradient(&self, _u: &[f64], _gradient: &mut [f64]) -> bool {
        false
    }
    /// Brings the part of `hessian` (the last assembled Hessian, or the last one this
    /// updated) that is cheap to re-evaluate and far from quadratic to the iterate `u` in
    /// place, leaving the rest as assembled; returns whether it changed.
    fn refresh_hessian(&mut self, _u: &[f64], _hessian: &mut [f64]) -> bool {
        false
    }
}

/// A chord iteration (reusing the last factorisation) must cut the residual at least this
/// much, or the next iteration refreshes the Hessian. Newton on ice contracts by ~1e-6 per
/// iteration; 0.1 keeps the chord only while it is nearly as good.
pub const CHORD_CONTRACTION: f64 = 0.1;

/// After the exact Hessian was found indefinite and projected, Newton tries the exact one
/// again at the first refresh where the residual has fallen below this fraction of where it
/// was projected. Far from the solution compressed elements make the exact Hessian
/// indefinite; near a minimum it is positive definite again, and Newton with it converges
/// quadratically, while the projection (|c| for each negative twist curvature c) converges
/// only linearly: 0.89 per iteration, 50 iterations without converging, on a cracked water
/// column that kept the projection for the whole solve. A retry that is indefinite again
/// costs one failed factorisation.
pub const EXACT_AGAIN: f64 = 0.1;

/// Newton settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonParams {
    /// Converged when max |free residual| ≤ `tolerance` × force scale (dimensionless).
    pub tolerance: f64,
    /// Also converged when the Newton update is below `step_tolerance` (m): round-off level.
    pub step_tolerance: f64,
    /// Iteration cap.
    pub max_iterations: usize,
}

/// What one Newton solve did.
#[derive(Clone, Copy, Debug, Default)]
pub struct NewtonReport {
    /// Newton iterations (linear solves).
    pub iterations: usize,
    /// Numeric factorisations or multigrid set-ups (Hessian refreshes, and those a solve had to
    /// do itself when a reused preconditioner was too stale).
    pub factorizations: usize,
    /// Switches to the projected Hessian after the exact one was found indefinite.
    pub projections: usize,
    /// Linear-solver iterations summed over Newton iterations.
    pub linear_iterations: usize,
    /// Final max |free residual| (N).
    pub residual: f64,
    /// Force scale the residual was judged against (N).
    pub force_scale: f64,
    /// Round-off floor of the residual at the solution (N), see [`roundoff_floor`].
    pub roundoff_floor: f64,
    /// Final potential (J).
    pub energy: f64,
    /// Assembly time (s).
    pub t_assembly: f64,
    /// Factorisation / preconditioner time (s).
    pub t_factorization: f64,
    /// Linear solve time (s).
    pub t_solve: f64,
}

impl NewtonReport {
    /// Adds one linear solve's work, counting the set-ups it did itself as factorisations.
    fn add_solve(&mut self, stats: &LinearStats) {
        self.linear_iterations += stats.iterations;
        self.t_solve += stats.t_solve;
        self.factorizations += stats.setups;
        self.t_factorization += stats.t_setup;
    }

    /// Two consecutive solves as one: work and times add, the state is the second's.
    pub fn then(&self, next: &NewtonReport) -> NewtonReport {
        NewtonReport {
            iterations: self.iterations + next.iterations,
            factorizations: self.factorizations + next.factorizations,
            projections: self.projections + next.projections,
            linear_iterations: self.linear_iterations + next.linear_iterations,
            residual: self.residual.max(next.residual),
            force_scale: next.force_scale,
            roundoff_floor: next.roundoff_floor,
            energy: next.energy,
            t_assembly: self.t_assembly + next.t_assembly,
            t_factorization: self.t_factorization + next.t_factorization,
            t_solve: self.t_solve + next.t_solve,
        }
    }
}

/// Newton failures.
#[derive(Debug, thiserror::Error)]
pub enum NewtonError {
    /// The linear solve failed.
    #[error(transparent)]
    Linear(#[from] LinearError),
    /// No convergence within the iteration cap.
    #[error("Newton did not converge in {iterations} iterations (residual {residual:e} N against a tolerance of {target:e} N)")]
    NotConverged {
        iterations: usize,
        residual: f64,
        target: f64,
    },
    /// The line search found no decrease of the potential along the Newton direction.
    #[error("the line search found no descent along the Newton direction (iteration {iteration}, residual {residual:e} N)")]
    LineSearch { iteration: usize, residual: f64 },
    /// The potential became NaN or infinite.
    #[error("the state became non-finite (NaN or infinity) during Newton iteration {iteration}")]
    NonFinite { iteration: usize },
}

/// Buffers reused across Newton solves (allocated once per pattern).
pub struct NewtonWorkspace {
    gradient: Vec<f64>,
    hessian: Vec<f64>,
    rhs: Vec<f64>,
    direction: Vec<f64>,
    trial: Vec<f64>,
    /// A second direction (free dofs), for the anticipated-constraint step.
    landing: Vec<f64>,
    /// Gradient at the line search's full step (all dofs): the next iterate's, if accepted.
    trial_gradient: Vec<f64>,
    /// The linear solver holds the factorisation of a Hessian of these buffers' problem (the
    /// last one assembled into `hessian`, or its projection), which the next solve may start
    /// with.
    factor_kept: bool,
}

impl NewtonWorkspace {
    /// Buffers for `assembly`'s system.
    pub fn new(assembly: &Assembly) -> Self {
        let nf = assembly.dofs().num_free();
        let n = assembly.dofs().num_dofs();
        NewtonWorkspace {
            gradient: vec![0.0; n],
            hessian: vec![0.0; assembly.nnz()],
            rhs: vec![0.0; nf],
            direction: vec![0.0; nf],
            trial: vec![0.0; n],
            landing: vec![0.0; nf],
            trial_gradient: vec![0.0; n],
            factor_kept: false,
        }
    }

    /// Makes the next solve assemble and factorise the Hessian at its first iteration
    /// instead of starting with the factor kept from the solves before. The factor a solve
    /// starts with changes its iterates (not its tolerance): a caller that must repeat a
    /// computation bit for bit from a saved state (a resumed run, from a frame) forgets the
    /// factor wherever such a state is saved.
    pub fn forget_factor(&mut self) {
        self.factor_kept = false;
    }
    /// Gradient over all dofs at the last evaluated iterate (N).
    pub fn gradient(&self) -> &[f64] {
        &self.gradient
    }
}

/// Prepares `linear` for the Hessian in `work`: the exact Hessian first; if it is indefinite
/// (compressed corotated elements), its positive semi-definite projection, re-evaluated at
/// `u` (updating `energy` and the gradient), which later evaluations keep until Newton
/// switches back (see [`EXACT_AGAIN`]).
fn factorize_or_project(
    potential: &mut impl Potential,
    u: &[f64],
    assembly: &Assembly,
    linear: &mut LinearSolver,
    work: &mut NewtonWorkspace,
    report: &mut NewtonReport,
    energy: &mut f64,
) -> Result<(), NewtonError> {
    work.factor_kept = false;
    let t = match linear.factorize(assembly, &work.hessian) {
        Err(e) if e.is_indefinite() && potential.project_hessian(true) => {
            report.projections += 1;
            let start = Instant::now();
            *energy = potential.evaluate(u, &mut work.gradient, &mut work.hessian);
            report.t_assembly += start.elapsed().as_secs_f64();
            linear.factorize(assembly, &work.hessian)?
        }
        other => other?,
    };
    work.factor_kept = linear.is_direct();
    if let Some(t) = t {
        report.t_factorization += t;
        report.factorizations += 1;
    }
    Ok(())
}

/// Solves for the Newton direction with the prepared `linear`. An iterative solver finds
/// indefiniteness only while solving: it then switches to the projected Hessian as a failed
/// factorisation does ([`factorize_or_project`]) and solves again.
fn solve_or_project(
    potential: &mut impl Potential,
    u: &[f64],
    assembly: &Assembly,
    linear: &mut LinearSolver,
    work: &mut NewtonWorkspace,
    report: &mut NewtonReport,
) -> Result<LinearStats, NewtonError> {
    match linear.solve(assembly, &work.hessian, &work.rhs, &mut work.direction) {
        Err(e) if e.is_indefinite() && potential.project_hessian(true) => {
            report.projections += 1;
            let start = Instant::now();
            potential.evaluate(u, &mut work.gradient, &mut work.hessian);
            report.t_assembly += start.elapsed().as_secs_f64();
            work.factor_kept = false;
            if let Some(t) = linear.factorize(assembly, &work.hessian)? {
                report.t_factorization += t;
                report.factorizations += 1;
            }
            work.factor_kept = linear.is_direct();
            Ok(linear.solve(assembly, &work.hessian, &work.rhs, &mut work.direction)?)
        }
        other => Ok(other?),
    }
}

/// Minimises `potential` over the free dofs of `u` (constrained dofs keep their values).
/// `force_floor` (N) is a force scale of the problem (external and inertial forces per node);
/// the residual is judged against it (or the support reactions when it is zero), and never
/// below the round-off floor of [`roundoff_floor`]. Starts with the factor a direct solver
/// kept from the solves before, if any (see [`NewtonWorkspace::forget_factor`]).
pub fn minimize(
    potential: &mut impl Potential,
    u: &mut [f64],
    assembly: &Assembly,
    linear: &mut LinearSolver,
    params: &NewtonParams,
    force_floor: f64,
    work: &mut NewtonWorkspace,
) -> Result<NewtonReport, NewtonError> {
    let result = iterate(potential, u, assembly, linear, (params, force_floor), work);
    if result.is_err() {
        // A failed solve may have left a factor of a state far from any solution.
        work.factor_kept = false;
    }
    result
}

/// Newton's iterations of [`minimize`].
fn iterate(
    potential: &mut impl Potential,
    u: &mut [f64],
    assembly: &Assembly,
    linear: &mut LinearSolver,
    (params, force_floor): (&NewtonParams, f64),
    work: &mut NewtonWorkspace,
) -> Result<NewtonReport, NewtonError> {
    let dofs = assembly.dofs();
    let mut report = NewtonReport::default();
    linear.start_newton_solve();
    // A kept factor serves as the first iteration's matrix; the chord test below replaces it
    // once it stops contracting.
    let mut refresh = !(work.factor_kept && linear.is_direct());
    let mut previous_residual = f64::INFINITY;
    let mut floor = 0.0;
    // Potential at `u` when `work.gradient` already holds its gradient (from the line search).
    let mut known: Option<f64> = None;
    let mut projection = Projection::default();
    // Whether the last step was damped: then a constraint it ran into is anticipated even
    // past ANTICIPATION_ITERATIONS.
    let mut damped = false;
    for iteration in 0..=params.max_iterations {
        let start = Instant::now();
        let mut energy = if refresh {
            potential.forget_anticipated();
            projection.try_exact(potential, previous_residual);
            potential.evaluate(u, &mut work.gradient, &mut work.hessian)
        } else if let Some(e) = known {
            e
        } else {
            potential.gradient(u, &mut work.gradient)
        };
        // Maxima and sums over the dofs are taken over every process of a distributed run,
        // so that all take the same decisions.
        let residual = potential.max_over_processes(free_max(assembly, &work.gradient));
        report.t_assembly += start.elapsed().as_secs_f64();
        if !energy.is_finite() || !residual.is_finite() {
            return Err(NewtonError::NonFinite { iteration });
        }
        report.force_scale =
            potential.max_over_processes(force_scale(assembly, force_floor, &work.gradient));
        report.residual = residual;
        report.energy = energy;
        report.roundoff_floor = floor;
        if refresh || iteration == 0 {
            // A kept factor's Hessian is still in the buffer.
            // In a distributed run each process holds a part of the Hessian: the largest
            // part of the diagonal stands for it, at most its whole.
            floor = potential.max_over_processes(roundoff_floor(assembly, &work.hessian, u));
        }
        let target = (params.tolerance * report.force_scale).max(floor);
        if residual <= target {
            return Ok(report);
        }
        if iteration == params.max_iterations {
            return Err(NewtonError::NotConverged {
                iterations: iteration,
                residual,
                target,
            });
        }
        if !refresh && residual > CHORD_CONTRACTION * previous_residual {
            // The chord stalled: take the true Hessian at this iterate.
            refresh = true;
            potential.forget_anticipated();
            projection.try_exact(potential, residual);
            let start = Instant::now();
            energy = potential.evaluate(u, &mut work.gradient, &mut work.hessian);
            report.t_assembly += start.elapsed().as_secs_f64();
        } else if !refresh && linear.iterates_on_matrix() {
            // A chord iteration of a solver that multiplies by the matrix: its cheap part
            // follows the iterate (the factor or hierarchy stays as it is, now stale).
            let start = Instant::now();
            if potential.refresh_hessian(u, &mut work.hessian) {
                linear.matrix_changed(assembly, &work.hessian);
            }
            report.t_assembly += start.elapsed().as_secs_f64();
        }
        // A chord iteration steps with a factor of an earlier iterate (or solve).
        let mut chord = !refresh;
        if refresh {
            factorize_or_project(
                potential,
                u,
                assembly,
                linear,
                work,
                &mut report,
                &mut energy,
            )?;
        }
        for (r, &d) in work.rhs.iter_mut().zip(dofs.free_dofs()) {
            *r = -work.gradient[d];
        }
        linear.set_forcing(forcing(residual, previous_residual, target));
        let stats = solve_or_project(potential, u, assembly, linear, work, &mut report)?;
        report.add_solve(&stats);
        if iteration < ANTICIPATION_ITERATIONS || damped {
            let solver = NewtonSystem {
                assembly,
                linear: &mut *linear,
                work: &mut *work,
            };
            chord &= !anticipate(potential, u, solver, &mut report, &mut energy)?;
        }
        projection.note(&report, residual);
        report.iterations += 1;
        let start = Instant::now();
        let searched = line_search(potential, u, dofs, work, energy);
        report.t_assembly += start.elapsed().as_secs_f64();
        if chord && searched.is_none_or(|(alpha, _)| alpha < 1.0) {
            // A stale factor's step that the line search must damp (or cannot use) is not
            // worth taking: the true Hessian at this iterate gives the step instead.
            refresh = true;
            known = None;
            continue;
        }
        let (alpha, accepted) = searched.ok_or(NewtonError::LineSearch {
            iteration,
            residual,
        })?;
        known = accepted;
        let step_max = potential.max_over_processes(advance(u, dofs, &work.direction, alpha));
        if step_max <= params.step_tolerance {
            report.energy = match known {
                Some(e) => e,
                None => potential.gradient(u, &mut work.gradient),
            };
            report.residual = potential.max_over_processes(free_max(assembly, &work.gradient));
            return Ok(report);
        }
        // A damped step means the model changed enough that the next iteration should see
        // the true Hessian.
        refresh = alpha < 1.0;
        damped = alpha < 1.0;
        previous_residual = residual;
    }
    unreachable!("the loop returns at iteration max_iterations")
}

/// Moves the free dofs of `u` by `alpha` × `direction`; returns the largest move (m).
fn advance(u: &mut [f64], dofs: &DofMap, direction: &[f64], alpha: f64) -> f64 {
    let mut step_max: f64 = 0.0;
    for (&d, dx) in dofs.free_dofs().iter().zip(direction) {
        u[d] += alpha * dx;
        step_max = step_max.max((alpha * dx).abs());
    }
    step_max
}

/// When a solve last switched to the projected Hessian (see [`EXACT_AGAIN`]).
#[derive(Default)]
struct Projection {
    /// The residual (N) at the last switch, while the projection holds.
    at: Option<f64>,
    /// The report's switches seen so far.
    seen: usize,
}

impl Projection {
    /// Switches `potential` back to the exact Hessian if the residual has fallen below
    /// [`EXACT_AGAIN`] × the one where it projected.
    fn try_exact(&mut self, potential: &mut impl Potential, residual: f64) {
        if self.at.is_some_and(|r| residual < EXACT_AGAIN * r) {
            potential.project_hessian(false);
            self.at = None;
        }
    }

    /// Records a switch the iteration at `residual` made (counted in `report`).
    fn note(&mut self, report: &NewtonReport, residual: f64) {
        if report.projections > self.seen {
            self.seen = report.projections;
            self.at = Some(residual);
        }
    }
}

/// What a Newton iteration solves with: the pattern, the linear solver and the workspace.
struct NewtonSystem<'a> {
    assembly: &'a Assembly,
    linear: &'a mut LinearSolver,
    work: &'a mut NewtonWorkspace,
}

/// Contacts the Newton step in `work.direction` would create: puts their stiffness into the
/// Hessian and solves again (a few rounds at most; each marks pairs for good within this
/// solve), then solves with the anticipated constraints' force in the right-hand side too
/// and takes that step if it still descends. `energy` is the potential at `u`, re-evaluated
/// with the Hessian. Returns whether it factorised the Hessian at `u`.
fn anticipate(
    potential: &mut impl Potential,
    u: &[f64],
    system: NewtonSystem,
    report: &mut NewtonReport,
    energy: &mut f64,
) -> Result<bool, NewtonError> {
    let NewtonSystem {
        assembly,
        linear,
        work,
    } = system;
    let dofs = assembly.dofs();
    let mut refactored = false;
    for _ in 0..3 {
        work.trial.copy_from_slice(u);
        for (&d, dx) in dofs.free_dofs().iter().zip(&work.direction) {
            work.trial[d] += dx;
        }
        if !potential.anticipate(u, &work.trial) {
            break;
        }
        let start = Instant::now();
        *energy = potential.evaluate(u, &mut work.gradient, &mut work.hessian);
        report.t_assembly += start.elapsed().as_secs_f64();
        factorize_or_project(potential, u, assembly, linear, work, report, energy)?;
        refactored = true;
        let stats = solve_or_project(potential, u, assembly, linear, work, report)?;
        report.add_solve(&stats);
    }
    work.trial.copy_from_slice(&work.gradient);
    if potential.add_anticipated_gradient(u, &mut work.trial) {
        let mut rhs = std::mem::take(&mut work.rhs);
        for (r, &d) in rhs.iter_mut().zip(dofs.free_dofs()) {
            *r = -work.trial[d];
        }
        let landing = linear.solve(assembly, &work.hessian, &rhs, &mut work.landing)?;
        report.add_solve(&landing);
        work.rhs = rhs;
        if slope_along(&*potential, dofs, &work.gradient, &work.landing) < 0.0 {
            std::mem::swap(&mut work.direction, &mut work.landing);
        }
    }
    Ok(refactored)
}

/// Backtracking (Armijo) line search on the potential along `work.direction` from `u`, where
/// the potential is `energy`: the step length taken, and the potential there if it is the
/// full step (whose gradient is then in `work.gradient`); `None` if no step down to 1e-6
/// decreases the potential. Near convergence the decrease is below the round-off of the
/// potential itself, so a step that changes the energy by less than that round-off is
/// accepted as it is.
fn line_search(
    potential: &mut impl Potential,
    u: &[f64],
    dofs: &DofMap,
    work: &mut NewtonWorkspace,
    energy: f64,
) -> Option<(f64, Option<f64>)> {
    let slope = slope_along(&*potential, dofs, &work.gradient, &work.direction);
    let roundoff = 1e-13 * energy.abs().max(f64::MIN_POSITIVE);
    let mut alpha = 1.0;
    loop {
        work.trial.copy_from_slice(u);
        for (&d, dx) in dofs.free_dofs().iter().zip(&work.direction) {
            work.trial[d] += alpha * dx;
        }
        // The full step is nearly always taken, and the next iteration then needs the
        // gradient there: computed with the energy (one pass over the elements for both).
        let e = if alpha == 1.0 {
            potential.gradient(&work.trial, &mut work.trial_gradient)
        } else {
            potential.energy(&work.trial)
        };
        if e.is_finite() && (e <= energy + 1e-4 * alpha * slope || e <= energy + roundoff) {
            if alpha == 1.0 {
                std::mem::swap(&mut work.gradient, &mut work.trial_gradient);
                return Some((alpha, Some(e)));
            }
            return Some((alpha, None));
        }
        alpha *= 0.5;
        if alpha < 1e-6 {
            return None;
        }
    }
}

/// Slope of `potential` along the free-dof direction `direction` (J per unit step) for its
/// gradient `gradient` (all dofs), each dof counted on the process that owns it.
fn slope_along(
    potential: &impl Potential,
    dofs: &DofMap,
    gradient: &[f64],
    direction: &[f64],
) -> f64 {
    let owned = potential.owned_dofs();
    let slope = dofs
        .free_dofs()
        .iter()
        .zip(direction)
        .filter(|(&d, _)| owned.is_none_or(|o| o[d]))
        .map(|(&d, x)| gradient[d] * x)
        .sum();
    potential.sum_over_processes(slope)
}

/// Largest |gradient| over the free dofs of `assembly` (N).
fn free_max(assembly: &Assembly, gradient: &[f64]) -> f64 {
    assembly
        .dofs()
        .free_dofs()
        .iter()
        .map(|&d| gradient[d].abs())
        .fold(0.0, f64::max)
}

/// The force (N) Newton judges the residual against: the per-node loads of the problem
/// (`force_floor`: dead and inertial loads), or, when there are none (a body moved only by
/// its supports), the support reactions in `gradient`; never the first residual, which after
/// an impact predictor can be 1e9 times larger than any force in the solution. Reactions are
/// not used otherwise: they sum the load of many nodes, and on the soft inertial modes of a
/// small step a residual of that size would be a visible error.
fn force_scale(assembly: &Assembly, force_floor: f64, gradient: &[f64]) -> f64 {
    if force_floor > 0.0 {
        return force_floor;
    }
    let dofs = assembly.dofs();
    (0..gradient.len())
        .filter(|&d| dofs.free(d).is_none())
        .map(|d| gradient[d].abs())
        .fold(0.0, f64::max)
}

/// Minimises a quadratic `potential` whose free-system Hessian `hessian` (CSC values of
/// `assembly`'s pattern) does not depend on u: one solve from `u`, then the gradient on the
/// free dofs as g + H Δu and the potential as E + g·Δu + ½ Δuᵀ H Δu, without evaluating the
/// potential again (the constrained dofs' gradient, the reactions, keeps its value at the
/// start). If that does not meet the tolerance — an iterative solver's inexact solve, or a
/// matrix the factorisation refuses — Newton carries on from there ([`minimize`]).
///
/// `factored` says whether `linear` is already prepared for `hessian` (the caller's promise,
/// which spares comparing the values); it is left true when it is afterwards, false when
/// Newton took over.
pub fn minimize_quadratic(
    potential: &mut impl Potential,
    (hessian, factored): (&[f64], &mut bool),
    u: &mut [f64],
    assembly: &Assembly,
    linear: &mut LinearSolver,
    (params, force_floor): (&NewtonParams, f64),
    work: &mut NewtonWorkspace,
) -> Result<NewtonReport, NewtonError> {
    let mut report = NewtonReport::default();
    linear.start_newton_solve();
    // The solver is about to hold the fixed Hessian's factor, not the buffer's.
    work.factor_kept = false;
    let start = Instant::now();
    let energy = potential.gradient(u, &mut work.gradient);
    report.t_assembly = start.elapsed().as_secs_f64();
    let residual = free_max(assembly, &work.gradient);
    if !energy.is_finite() || !residual.is_finite() {
        return Err(NewtonError::NonFinite { iteration: 0 });
    }
    report.force_scale = force_scale(assembly, force_floor, &work.gradient);
    report.roundoff_floor = roundoff_floor(assembly, hessian, u);
    report.residual = residual;
    report.energy = energy;
    let target = (params.tolerance * report.force_scale).max(report.roundoff_floor);
    if residual <= target {
        return Ok(report);
    }
    let prepare = |linear: &mut LinearSolver| match *factored {
        true => Ok(None),
        false => linear.factorize(assembly, hessian),
    };
    let solved = prepare(linear).and_then(|t| {
        for (r, &d) in work.rhs.iter_mut().zip(assembly.dofs().free_dofs()) {
            *r = -work.gradient[d];
        }
        linear.set_forcing(forcing(residual, f64::INFINITY, target));
        Ok((
            t,
            linear.solve(assembly, hessian, &work.rhs, &mut work.direction)?,
        ))
    });
    let Ok((t_factorization, stats)) = solved else {
        *factored = false;
        let rest = minimize(potential, u, assembly, linear, params, force_floor, work)?;
        return Ok(report.then(&rest));
    };
    *factored = true;
    if let Some(t) = t_factorization {
        report.t_factorization += t;
        report.factorizations += 1;
    }
    report.add_solve(&stats);
    report.iterations = 1;
    // H Δu, into the spare free-dof buffer.
    assembly.multiply(hessian, &work.direction, &mut work.landing);
    let mut change = 0.0;
    for (k, &d) in assembly.dofs().free_dofs().iter().enumerate() {
        let dx = work.direction[k];
        change += (work.gradient[d] + 0.5 * work.landing[k]) * dx;
        work.gradient[d] += work.landing[k];
        u[d] += dx;
    }
    report.energy = energy + change;
    report.residual = free_max(assembly, &work.gradient);
    if report.residual <= target {
        return Ok(report);
    }
    *factored = false;
    let rest = minimize(potential, u, assembly, linear, params, force_floor, work)?;
    Ok(report.then(&rest))
}

/// Relative accuracy a linear solve needs at an iterate with max |residual| `residual` (N),
/// `previous` at the iterate before (∞ at the first) and Newton's `target` (N): Eisenstat and
/// Walker's choice 2, 0.9 (residual / previous)² — as accurate as Newton's quadratic
/// convergence can use — but never more accurate than needed to bring the residual to half
/// the target (no oversolving). The first iteration has no rate to go by and asks for the
/// cap, which [`LinearSolver::set_forcing`] applies.
fn forcing(residual: f64, previous: f64, target: f64) -> f64 {
    if !previous.is_finite() {
        return f64::INFINITY;
    }
    let quadratic = 0.9 * (residual / previous).powi(2);
    quadratic.max(0.5 * target / residual)
}

/// Newton iterations during which constraints a step would activate are anticipated (see
/// `Potential::anticipate`). Past them Newton anticipates only after a damped step:
/// anticipation can cycle — a constraint the full step would activate is stiffened, the
/// stiffened step leaves it inactive, the next full step activates it again — and two crack
/// sides of a fractured block at rest against each other kept a step at a 20 N residual for
/// 50 iterations that way; without it, a node that the line search stops at an inactive
/// constraint creeps towards it by ~1e-3 of the step per iteration (a cracked ball of ice in a
/// Gmsh cup: 40 iterations at a 13 N residual, then failure).
const ANTICIPATION_ITERATIONS: usize = 10;

/// The smallest residual (N) double precision can resolve at `u`: forces are stiffness times
/// displacement, and a displacement of magnitude |u| is stored to ε|u|, so the residual cannot
/// be trusted below ε · max diag(K) · max|u|; ten times that is the floor Newton accepts. It
/// matters when the body has moved far (a falling cube: 5 cm of displacement leaves ~5e-8 N of
/// noise on ice) and is negligible for the small displacements of a supported body.
pub fn roundoff_floor(assembly: &Assembly, hessian: &[f64], u: &[f64]) -> f64 {
    let dofs = assembly.dofs();
    let max_diag = (0..dofs.num_free())
        .map(|f| hessian[assembly.diagonal_slot(f)].abs())
        .fold(0.0, f64::max);
    let max_u = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    10.0 * f64::EPSILON * max_diag * max_u
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::assembly::DofMap;
    use crate::mesh::TetMesh;
    use crate::solver::linear::{FactorPrecision, IterativeSettings, LinearSolverKind};
    use crate::solver::ordering::FillOrdering;

    /// ½ |u − c|², whose exact Hessian turns indefinite once a contact is anticipated (as a
    /// compressed corotated element's does) until it is projected.
    struct AnticipatedIndefinite {
        target: Vec<f64>,
        /// Value slot of each free dof's diagonal entry.
        diagonal: Vec<usize>,
        anticipated: bool,
        projected: bool,
    }

    impl Potential for AnticipatedIndefinite {
        fn energy(&mut self, u: &[f64]) -> f64 {
            u.iter()
                .zip(&self.target)
                .map(|(a, c)| 0.5 * (a - c) * (a - c))
                .sum()
        }
        fn evaluate(&mut self, u: &[f64], gradient: &mut [f64], hessian: &mut [f64]) -> f64 {
            let energy = self.gradient(u, gradient);
            hessian.fill(0.0);
            for (k, &slot) in self.diagonal.iter().enumerate() {
                hessian[slot] = if k == 0 && self.anticipated && !self.projected {
                    -1.0
                } else {
                    1.0
                };
            }
            energy
        }
        fn gradient(&mut self, u: &[f64], gradient: &mut [f64]) -> f64 {
            for ((g, a), c) in gradient.iter_mut().zip(u).zip(&self.target) {
                *g = a - c;
            }
            self.energy(u)
        }
        fn project_hessian(&mut self, project: bool) -> bool {
            std::mem::replace(&mut self.projected, project) != project
        }
        fn anticipate(&mut self, _u: &[f64], _trial: &[f64]) -> bool {
            !std::mem::replace(&mut self.anticipated, true)
        }
    }

    #[test]
    fn an_indefinite_hessian_after_anticipation_is_projected_not_fatal() {
        let mesh = TetMesh::from_arrays(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            vec![[0, 1, 2, 3]],
        )
        .unwrap();
        let assembly = Assembly::new(&mesh, DofMap::new(&[false; 12]));
        let settings = IterativeSettings {
            tolerance: 1e-12,
            max_iterations: 100,
            amg_reuse: false,
            factor_reuse: false,
            factor_precision: FactorPrecision::Double,
        };
        let mut linear = LinearSolver::new(
            LinearSolverKind::Cholesky,
            FillOrdering::Auto,
            &assembly,
            &mesh.rest,
            &settings,
        )
        .unwrap();
        let target: Vec<f64> = (0..12).map(|d| 0.1 * d as f64).collect();
        let mut potential = AnticipatedIndefinite {
            target: target.clone(),
            diagonal: (0..12).map(|f| assembly.diagonal_slot(f)).collect(),
            anticipated: false,
            projected: false,
        };
        let mut u = vec![0.0; 12];
        let params = NewtonParams {
            tolerance: 1e-10,
            step_tolerance: 0.0,
            max_iterations: 10,
        };
        let mut work = NewtonWorkspace::new(&assembly);
        minimize(
            &mut potential,
            &mut u,
            &assembly,
            &mut linear,
            &params,
            1.0,
            &mut work,
        )
        .expect("the projected Hessian is positive definite");
        assert!(potential.projected);
        // The minimiser of a quadratic: exact to round-off.
        for (a, c) in u.iter().zip(&target) {
            assert!((a - c).abs() < 1e-12, "{a} vs {c}");
        }
    }
}
