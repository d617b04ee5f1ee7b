//! `[time]` and `[solver]`: the step size and scheme, the adaptive step control, the Newton
//! and linear-solver settings, checked into [`StepSettings`].

use super::{AdaptiveSection, SceneError, SolverSection, TimeSection, Validator};
use crate::mesh::TetMesh;
use crate::sim::{Analysis, Scheme, StepSettings};
use crate::solver::{FactorPrecision, FillOrdering, LinearSolverKind, NewtonParams};

/// The checked `[time]` and `[solver]` sections.
pub(super) struct Stepping {
    /// Step size, scheme and solver settings.
    pub settings: StepSettings,
    /// End time (s).
    pub end_time: f64,
    /// Steps per output frame.
    pub output_every: u64,
    /// Steps between restart points.
    pub restart_every: u64,
}

/// The checked limits of `[solver]`.
struct SolverLimits {
    /// Newton relative residual tolerance.
    tolerance: f64,
    /// CG relative tolerance.
    cg_tolerance: f64,
    /// Newton iteration cap.
    max_iterations: usize,
    /// CG iteration cap.
    cg_max_iterations: usize,
}

impl Validator<'_> {
    /// The step settings of `time` and `solver` for a body whose bounding box is `mesh`'s (the
    /// whole mesh's, of which `mesh` may be a part).
    pub(super) fn stepping(
        &self,
        time: &TimeSection,
        solver: &SolverSection,
        mesh: &TetMesh,
    ) -> Result<Stepping, SceneError> {
        let dt = self.positive("time.dt", time.dt)?;
        let end_time = self.positive("time.end_time", time.end_time)?;
        let output_every = time.output_every.unwrap_or(1);
        if output_every == 0 {
            return Err(self.invalid("time.output_every", "must be ≥ 1"));
        }
        let restart_every = self.restart_every(time, output_every)?;
        let limits = self.solver_limits(solver)?;
        let (lo, hi) = self.bounding_box(mesh);
        let adaptive = time
            .adaptive
            .as_ref()
            .map(|a| self.adaptive(a, dt, output_every, (hi - lo).norm()))
            .transpose()?;
        let settings = StepSettings {
            adaptive,
            analysis: time.analysis.unwrap_or(Analysis::Dynamic),
            scheme: time.scheme.unwrap_or_default(),
            dt,
            newton: NewtonParams {
                tolerance: limits.tolerance,
                // An update of 1e-15 of the body size is at the round-off of the positions.
                step_tolerance: 1e-15 * (hi - lo).norm(),
                max_iterations: limits.max_iterations,
            },
            linear: solver.linear.unwrap_or(LinearSolverKind::Auto),
            ordering: solver.ordering.unwrap_or(FillOrdering::Auto),
            cg_tolerance: limits.cg_tolerance,
            cg_max_iterations: limits.cg_max_iterations,
            amg_reuse: solver.amg_reuse.unwrap_or(true),
            factor_reuse: solver.reuse_factorization.unwrap_or(false),
            factor_precision: solver.factor_precision.unwrap_or(FactorPrecision::Single),
        };
        Ok(Stepping {
            settings,
            end_time,
            output_every,
            restart_every,
        })
    }

    /// `[time] restart_every` (default 10), with a notice when restart points fall on few of
    /// the frames (neither count divides the other).
    fn restart_every(&self, time: &TimeSection, output_every: u64) -> Result<u64, SceneError> {
        let restart_every = time.restart_every.unwrap_or(10);
        if restart_every == 0 {
            return Err(self.invalid("time.restart_every", "must be ≥ 1"));
        }
        let divides = |a: u64, b: u64| b.is_multiple_of(a);
        if time.adaptive.is_none()
            && !divides(output_every, restart_every)
            && !divides(restart_every, output_every)
        {
            let (mut a, mut b) = (output_every, restart_every);
            while b != 0 {
                (a, b) = (b, a % b);
            }
            let lcm = (output_every / a).saturating_mul(restart_every);
            self.notices.borrow_mut().push(format!(
                "{}: [time] output_every = {output_every} and restart_every = {restart_every}: \
                 --resume can continue only from the frames every {lcm} steps (make one a \
                 multiple of the other for more)",
                self.path.display()
            ));
        }
        Ok(restart_every)
    }

    /// The tolerances and iteration caps of `[solver]`, with their defaults.
    fn solver_limits(&self, solver: &SolverSection) -> Result<SolverLimits, SceneError> {
        let tolerance = solver.tolerance.unwrap_or(1e-9);
        if !(tolerance > 0.0 && tolerance < 1.0) {
            return Err(self.invalid(
                "solver.tolerance",
                format!("must be in (0, 1), got {tolerance}"),
            ));
        }
        let cg_tolerance = solver.cg_tolerance.unwrap_or(1e-12);
        if !(cg_tolerance > 0.0 && cg_tolerance < 1.0) {
            return Err(self.invalid(
                "solver.cg_tolerance",
                format!("must be in (0, 1), got {cg_tolerance}"),
            ));
        }
        let max_iterations = solver.max_iterations.unwrap_or(50);
        if max_iterations == 0 {
            return Err(self.invalid("solver.max_iterations", "must be ≥ 1"));
        }
        let cg_max_iterations = solver.cg_max_iterations.unwrap_or(20_000);
        if cg_max_iterations == 0 {
            return Err(self.invalid("solver.cg_max_iterations", "must be ≥ 1"));
        }
        Ok(SolverLimits {
            tolerance,
            cg_tolerance,
            max_iterations,
            cg_max_iterations,
        })
    }

    /// The adaptive step control of `[time.adaptive]`, for first step `dt` (s), frames every
    /// `output_every` steps and a body of size `size` (m).
    fn adaptive(
        &self,
        a: &AdaptiveSection,
        dt: f64,
        output_every: u64,
        size: f64,
    ) -> Result<crate::sim::Adaptive, SceneError> {
        let relative = a.relative_tolerance.unwrap_or(1e-3);
        if !(relative > 0.0 && relative < 1.0) {
            return Err(self.invalid(
                "time.adaptive.relative_tolerance",
                format!("must be in (0, 1), got {relative}"),
            ));
        }
        let absolute = match a.absolute_tolerance {
            Some(v) => self.positive("time.adaptive.absolute_tolerance", v)?,
            None => relative * 1e-6 * size,
        };
        let dt_min = match a.dt_min {
            Some(v) => self.positive("time.adaptive.dt_min", v)?,
            None => 1e-3 * dt,
        };
        let dt_max = match a.dt_max {
            Some(v) => self.positive("time.adaptive.dt_max", v)?,
            None => output_every as f64 * dt,
        };
        if !(dt_min <= dt && dt <= dt_max) {
            return Err(self.invalid(
                "time.dt",
                format!("the first step of adaptive steps must lie in [dt_min, dt_max] = [{dt_min}, {dt_max}] s, got {dt}"),
            ));
        }
        Ok(crate::sim::Adaptive {
            relative_tolerance: relative,
            absolute_tolerance: absolute,
            dt_min,
            dt_max,
        })
    }

    /// Refuses step controls and schemes the analysis cannot use: adaptive steps and a scheme
    /// other than backward Euler in a static analysis, and Newmark with fracture (`fracture`).
    pub(super) fn check_scheme(
        &self,
        settings: &StepSettings,
        fracture: bool,
    ) -> Result<(), SceneError> {
        if settings.adaptive.is_some() && settings.analysis == Analysis::Static {
            return Err(self.invalid("time.adaptive", "adaptive steps control the time-integration error of a dynamic analysis; a static one has none (remove [time.adaptive] or set analysis = \"dynamic\")".to_string()));
        }
        if settings.scheme != Scheme::BackwardEuler {
            let refuse = |field: &str, why: &str| Err(self.invalid(field, why.to_string()));
            if settings.analysis == Analysis::Static {
                return refuse("time.scheme", "\"newmark\" and \"bdf2\" integrate a dynamic analysis; a static one has no scheme (remove it or set analysis = \"dynamic\")");
            }
            if fracture && settings.scheme == Scheme::Newmark {
                return refuse("time.scheme", "\"newmark\" has no numerical dissipation, and the stress a node split releases would ring undamped (the paper's fracture scene failed the step after its first split): use \"bdf2\" (second order, damps the fastest modes) or \"backward_euler\" with [fracture]");
            }
        }
        Ok(())
    }
}
