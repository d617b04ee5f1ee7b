//! When a kept preconditioner is rebuilt: the rules that decide whether a Cholesky factor kept
//! across Hessian refreshes ([`FactorReuse`]) or a multigrid hierarchy kept across them
//! ([`HierarchyReuse`]) still serves the current matrix, how many CG iterations a solve with it
//! may take, and what a solve's outcome says about the next refresh. The methods that own the
//! factor or the hierarchy ask these rules and do the factorisations and set-ups.

use super::settings::IterativeSettings;

/// A reused Cholesky factor is refreshed on the next Hessian refresh once a CG solve
/// preconditioned by it needed more than this many iterations per decade of residual
/// reduction (see [`reuse_iteration_budget`]): each costs one pair of triangular solves and a
/// product with the matrix, a fresh factorisation about as much as 25–30 of them on the 1e5-tet
/// freezing container (single precision: 0.8 s against 0.028 s with the tree-parallel solves),
/// and a step makes a few solves with the same factor. There a factor from the step before
/// reaches Newton's first forcing ([`FORCING_MAX`], 3 decades) in 1–13 iterations, typically 5.
/// Steps 91–102 of that scene (resumed from step 90, two runs each): 14.1 s with 5, 14.2–15.0 s
/// with 7, 14.8–16.2 s with 10 iterations per decade.
pub const FACTOR_REUSE_ITERATIONS_PER_DECADE: f64 = 5.0;

/// CG iterations a reused factor may take to reach the relative residual `forcing` before it
/// is refreshed: [`FACTOR_REUSE_ITERATIONS_PER_DECADE`] per decade (15 at 1e-3, 60 at 1e-12).
pub fn reuse_iteration_budget(forcing: f64) -> usize {
    let decades = -forcing.log10();
    (FACTOR_REUSE_ITERATIONS_PER_DECADE * decades)
        .ceil()
        .max(2.0) as usize
}

/// A solve preconditioned by a stale factor or hierarchy stops after this many times the
/// iterations that trigger a refresh (the factor's cap, or the hierarchy's first count) and
/// refreshes at once: after a large change of the matrix (contacts switching on) the old
/// preconditioner can need hundreds of iterations.
pub const STALE_ITERATION_CAP: usize = 3;

/// The first solve of a Newton solve, preconditioned by a reused factor, needs a relative
/// residual of at most this: the Newton direction far from the solution need not be exact
/// (the nonlinear error dominates), and nearer the solution
/// [`LinearSolver::set_forcing`](super::LinearSolver::set_forcing) asks for what Newton's
/// convergence can use. Measured on the 1e5-tet freezing container: the first Newton step of a
/// frame leaves a relative residual of ~4e-4 whether its linear solve reached 1e-4 or 1e-12,
/// and steps 62–75 took 1.00 s on average at 1e-3 against 1.20 s at 1e-4 (same Newton
/// iterations).
pub const FORCING_MAX: f64 = 1e-3;

/// Loosest relative residual a later solve of a Newton solve may stop at (Eisenstat and
/// Walker's safeguard η_max, smaller than their 0.9: a direction good to 10 % keeps Newton's
/// step count).
pub const FORCING_LATER_MAX: f64 = 0.1;

/// After a reused factor had to be abandoned (or converged too slowly) at some age — Newton
/// solves since it was computed, see
/// [`LinearSolver::start_newton_solve`](super::LinearSolver::start_newton_solve) — a factor
/// reaching that age is replaced at the first Hessian refresh, without the doomed attempt. It
/// is tried again (a probe) after 1 such replacement, then after 2, 4, … up to
/// `STALE_PROBE_PERIOD` as long as the probes fail. (Within one Newton solve an earlier
/// iterate's factor is a good preconditioner; across the steps of a freezing run it is not: a
/// band of elements changes stiffness every step. A failed probe costs a few CG iterations, a
/// needless factorisation 10–20 of them.)
pub const STALE_PROBE_PERIOD: usize = 8;

/// A multigrid-preconditioned CG solve is re-set-up on the next Newton refresh when it needed
/// more than `REFRESH_GROWTH` × (iterations of the first solve after the last set-up) +
/// [`REFRESH_SLACK`] iterations.
pub const REFRESH_GROWTH: f64 = 1.5;
/// Absolute slack of the refresh test, so that a change of one or two iterations at small
/// counts does not trigger a set-up.
pub const REFRESH_SLACK: usize = 2;

/// The reuse state of a Cholesky factor kept as CG's preconditioner: whether it is of the
/// current matrix, how accurately the next solves must converge, and the record of factors
/// that had to be abandoned.
pub struct FactorReuse {
    /// CG's own tolerance (the tightest forcing).
    tolerance: f64,
    /// CG's iteration cap.
    max_iterations: usize,
    /// The matrix changed since the factorisation.
    stale: bool,
    /// A factorisation is due at the next refresh.
    refresh_due: bool,
    /// Relative residual the next solves need (see [`FactorReuse::set_forcing`]).
    forcing: f64,
    /// Newton solves begun since the current factor was computed.
    age: usize,
    /// Smallest age at which a factor had to be abandoned, if it has not done since.
    failed_age: Option<usize>,
    /// Factorisations made early because of `failed_age` since the last probe.
    skipped_attempts: usize,
    /// Early factorisations before the next probe (1, 2, 4, … [`STALE_PROBE_PERIOD`]).
    probe_period: usize,
}

/// How far a CG solve preconditioned by a kept factor may go.
#[derive(Clone, Copy, Debug)]
pub struct FactorSolveLimits {
    /// Relative residual to reach.
    pub forcing: f64,
    /// Iterations beyond which the factor is refreshed ([`reuse_iteration_budget`]).
    pub budget: usize,
    /// Iterations after which the solve is abandoned: beyond them a fresh factorisation is
    /// cheaper than going on.
    pub cap: usize,
    /// Give up unless the relative residual after this many iterations is below this: a good
    /// factor reaches half the digits in a few iterations.
    pub checkpoint: (usize, f64),
}

impl FactorReuse {
    /// No factor yet; solves at CG's tolerance until the first forcing.
    pub fn new(settings: &IterativeSettings) -> Self {
        FactorReuse {
            tolerance: settings.tolerance,
            max_iterations: settings.max_iterations,
            stale: false,
            refresh_due: false,
            forcing: settings.tolerance,
            age: 0,
            failed_age: None,
            skipped_attempts: 0,
            probe_period: 1,
        }
    }

    /// Whether the matrix changed since the factorisation.
    pub fn is_stale(&self) -> bool {
        self.stale
    }

    /// The matrix values changed in place since the factorisation.
    pub fn matrix_changed(&mut self) {
        self.stale = true;
    }

    /// A new Newton solve begins: the factor is one solve older.
    pub fn start_newton_solve(&mut self) {
        self.age += 1;
    }

    /// Sets the relative residual the next solves need from Newton's forcing term `eta`:
    /// clamped to [CG's tolerance, [`FORCING_MAX`]] for a first solve (η = ∞) and to
    /// [CG's tolerance, [`FORCING_LATER_MAX`]] after.
    pub fn set_forcing(&mut self, eta: f64) {
        // The first solve (η = ∞) has no rate to go by.
        let cap = if eta == f64::INFINITY {
            FORCING_MAX
        } else {
            FORCING_LATER_MAX
        };
        // max/min rather than clamp: a NaN request falls back to CG's own tolerance.
        self.forcing = eta.max(self.tolerance).min(cap.max(self.tolerance));
    }

    /// A refresh brings a new matrix: `same` when its values are bit for bit the factored
    /// ones, `factored` when there is a factor at all. Whether the kept factor serves the
    /// new matrix (no factorisation now).
    pub fn keeps_factor(&mut self, same: bool, factored: bool) -> bool {
        self.stale = !same;
        if !same && factored && !self.replace_before_use() {
            return true;
        }
        same
    }

    /// Whether the factor, about to be kept through one more refresh, should rather be
    /// replaced now: it is due, or factors of that age have been failing.
    fn replace_before_use(&mut self) -> bool {
        if self.refresh_due {
            return true;
        }
        if self.failed_age.is_some_and(|a| self.age >= a) {
            if self.skipped_attempts < self.probe_period {
                self.skipped_attempts += 1;
                return true;
            }
            self.skipped_attempts = 0;
        }
        false
    }

    /// The limits of the next CG solve with the factor.
    pub fn limits(&self) -> FactorSolveLimits {
        let budget = reuse_iteration_budget(self.forcing);
        FactorSolveLimits {
            forcing: self.forcing,
            budget,
            cap: self.max_iterations.min(STALE_ITERATION_CAP * budget),
            checkpoint: (budget / 2, self.forcing.sqrt()),
        }
    }

    /// CG preconditioned by the factor converged in `iterations` within `limits`. Returns
    /// whether a fresh factor was this slow: then it is short of precision, not of freshness,
    /// and the caller replaces it by a double-precision one. A stale one this slow is replaced
    /// at the next refresh.
    pub fn converged(&mut self, iterations: usize, limits: &FactorSolveLimits) -> bool {
        let fresh = !self.stale;
        if iterations > limits.budget && fresh {
            return true;
        }
        if iterations > limits.budget {
            // Too slow: replace it, and do not keep one this long again.
            self.refresh_due = true;
            self.note_failure();
        } else if !fresh && self.failed_age.is_some_and(|a| self.age >= a) {
            self.failed_age = None;
        }
        false
    }

    /// CG preconditioned by the factor failed; the caller factorises the current matrix.
    /// Returns whether the factor was fresh: then it is short of precision (the caller
    /// switches to double precision), else of freshness.
    pub fn failed(&mut self) -> bool {
        let fresh = !self.stale;
        if !fresh {
            self.note_failure();
        }
        fresh
    }

    /// The factor had to be abandoned, or converged too slowly, at its current age. Only
    /// factors from earlier Newton solves are remembered: within a solve a failure is rare
    /// (contacts switching on) and says nothing about the next refresh.
    fn note_failure(&mut self) {
        if self.age > 0 {
            self.probe_period = match self.failed_age {
                // A probe failed: wait longer before the next.
                Some(a) if self.age >= a => (2 * self.probe_period).min(STALE_PROBE_PERIOD),
                _ => 1,
            };
            self.failed_age = Some(self.failed_age.map_or(self.age, |a| a.min(self.age)));
            self.skipped_attempts = 0;
        }
    }

    /// A fresh factor of the current matrix.
    pub fn renewed(&mut self) {
        self.stale = false;
        self.refresh_due = false;
        self.age = 0;
    }
}

/// The reuse state of a multigrid hierarchy kept across Newton iterations and steps: it is
/// rebuilt on the next refresh once a solve needed more than [`REFRESH_GROWTH`] times the
/// iterations of the first solve after the last set-up (plus [`REFRESH_SLACK`]).
pub struct HierarchyReuse {
    /// Keep the hierarchy between refreshes (false: set up at every refresh).
    reuse: bool,
    /// Iterations of the first solve after the last set-up.
    baseline: Option<usize>,
    /// A set-up is due at the next refresh.
    refresh_due: bool,
    /// The matrix changed since the last set-up.
    stale: bool,
}

impl HierarchyReuse {
    /// Before the first set-up; `reuse`: keep hierarchies between refreshes.
    pub fn new(reuse: bool) -> Self {
        HierarchyReuse {
            reuse,
            baseline: None,
            refresh_due: false,
            stale: false,
        }
    }

    /// Whether hierarchies are kept between refreshes.
    pub fn reuses(&self) -> bool {
        self.reuse
    }

    /// Whether the matrix changed since the last set-up.
    pub fn is_stale(&self) -> bool {
        self.stale
    }

    /// The matrix values changed in place since the last set-up.
    pub fn matrix_changed(&mut self) {
        self.stale = true;
    }

    /// A refresh brings a new matrix; `built` when there is a hierarchy. Whether it serves
    /// the new matrix (no set-up now).
    pub fn keeps_hierarchy(&mut self, built: bool) -> bool {
        if built && self.reuse && !self.refresh_due {
            self.stale = true;
            return true;
        }
        false
    }

    /// A set-up for the current matrix was made.
    pub fn set_up(&mut self) {
        self.baseline = None;
        self.refresh_due = false;
        self.stale = false;
    }

    /// The iteration cap of a solve with a stale hierarchy that has a first count, capped by
    /// `max_iterations` (`None`: a fresh hierarchy, or no count yet).
    pub fn stale_cap(&self, max_iterations: usize) -> Option<usize> {
        match (self.stale, self.baseline) {
            (true, Some(base)) => {
                Some(max_iterations.min(STALE_ITERATION_CAP * base + 10 * REFRESH_SLACK))
            }
            _ => None,
        }
    }

    /// A stale hierarchy should reach half the digits of `tolerance` within the first solve's
    /// count: the checkpoint of CG (`None` for a fresh hierarchy).
    pub fn checkpoint(&self, tolerance: f64) -> Option<(usize, f64)> {
        match (self.stale, self.baseline) {
            (true, Some(base)) => Some((base.max(1), tolerance.sqrt())),
            _ => None,
        }
    }

    /// A solve converged in `iterations`: the first count after a set-up, or a test of it.
    pub fn converged(&mut self, iterations: usize) {
        match self.baseline {
            None => self.baseline = Some(iterations),
            Some(base) => {
                if iterations as f64 > REFRESH_GROWTH * base as f64 + REFRESH_SLACK as f64 {
                    self.refresh_due = true;
                }
            }
        }
    }
}
