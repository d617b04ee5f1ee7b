//! Adaptive time steps: each step's local error estimate (see `TimeIntegrator::local_error`)
//! against a tolerance chooses the next step's length, between limits; a step whose error is
//! above the tolerance is taken again, shorter. Steps end exactly at the limits the caller
//! sets (frame times).

use super::{SimError, Simulation, StepReport};

/// Adaptive step control of a dynamic analysis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    /// Local error allowed per step, relative to the largest displacement (dimensionless).
    pub relative_tolerance: f64,
    /// Local error allowed per step when nothing has moved (m), added to the relative part.
    pub absolute_tolerance: f64,
    /// Shortest step (s): a step this short is accepted whatever its error.
    pub dt_min: f64,
    /// Longest step (s).
    pub dt_max: f64,
}

/// Fraction of the step length the error estimate asks for that the control takes: the
/// usual safety factor, so that the next step is accepted the first time.
pub const SAFETY: f64 = 0.9;

/// The most a step may grow from one step to the next: a longer step than the last by more
/// than this would leave BDF2's step ratio (see `integrator::BDF2_MAX_STEP_RATIO`) and outrun
/// the estimate's validity.
pub const MAX_GROWTH: f64 = 2.0;

/// The most a rejected or accepted step shrinks the next in one go.
pub const MAX_SHRINK: f64 = 0.2;

impl Adaptive {
    /// The error measure of a step: its local error estimate `error` (m) over the tolerance at
    /// displacement magnitude `scale` (m); the step is acceptable at ≤ 1.
    pub fn ratio(&self, error: f64, scale: f64) -> f64 {
        error / (self.relative_tolerance * scale + self.absolute_tolerance)
    }

    /// The step length (s) to try after a step of length `h` (s) with error measure `ratio`,
    /// taken with a formula of order `order`: the local error scales as h^(order + 1), so the
    /// length that would meet the tolerance is h · ratio^(−1/(order + 1)); a safety factor
    /// below it, within [`MAX_SHRINK`] and [`MAX_GROWTH`] of h and within the limits.
    pub fn next_step(&self, h: f64, ratio: f64, order: u32) -> f64 {
        let factor = if ratio > 0.0 {
            SAFETY * ratio.powf(-1.0 / f64::from(order + 1))
        } else {
            MAX_GROWTH
        };
        (h * factor.clamp(MAX_SHRINK, MAX_GROWTH)).clamp(self.dt_min, self.dt_max)
    }
}

/// The length of the next step towards `remaining` (s) when the control asks for `wanted`:
/// the remaining time split into equal steps no longer than `wanted`, so that the last step
/// before a frame is not a sliver.
pub fn fit_to(remaining: f64, wanted: f64) -> f64 {
    if wanted >= remaining {
        return remaining;
    }
    // A step within 1e-9 of dividing the remaining time evenly is not split one more time.
    let steps = (remaining / wanted - 1e-9).ceil();
    remaining / steps
}

impl Simulation {
    /// Advances one step of adaptive length ending no later than `limit` (s; later than the
    /// current time): the length the control proposed (the scene's `dt` at first), fitted to
    /// the time left to `limit`; a step whose error measure is above 1 is undone and taken
    /// again shorter (counted in the report's `rejected`), unless it is at `dt_min` already. A
    /// step that fails (Newton, after its halvings) is taken again at a quarter of its length
    /// while that is above `dt_min`. Leaves `settings.dt` at the length of the step taken
    /// (what fracture's retake uses) and the next proposal in the state. Without adaptive
    /// settings it is [`Simulation::step`].
    pub fn step_adaptive(&mut self, limit: f64) -> Result<StepReport, SimError> {
        let Some(control) = self.settings.adaptive else {
            return self.step();
        };
        let mut wanted = if self.state.next_dt > 0.0 {
            self.state.next_dt
        } else {
            self.settings.dt.clamp(control.dt_min, control.dt_max)
        };
        let at_least = |h: f64| h <= control.dt_min * (1.0 + 1e-9);
        let clock = std::time::Instant::now();
        let mut rejected = 0;
        loop {
            let h = fit_to(limit - self.state.time, wanted);
            self.settings.dt = h;
            let mut report = match self.step() {
                Ok(report) => report,
                Err(_) if !at_least(h) => {
                    rejected += 1;
                    wanted = (0.25 * h).max(control.dt_min);
                    continue;
                }
                Err(e) => return Err(e),
            };
            let ratio = control.ratio(report.local_error, report.displacement_scale);
            if ratio > 1.0 && !at_least(h) {
                self.undo_step();
                rejected += 1;
                wanted = control.next_step(h, ratio, report.order).min(h * SAFETY);
                continue;
            }
            self.state.next_dt = control.next_step(h, ratio, report.order);
            report.rejected = rejected;
            report.error_ratio = ratio;
            // The rejected and failed tries included.
            report.t_step = clock.elapsed().as_secs_f64();
            return Ok(report);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CONTROL: Adaptive = Adaptive {
        relative_tolerance: 1e-3,
        absolute_tolerance: 1e-9,
        dt_min: 1e-6,
        dt_max: 1e-2,
    };

    #[test]
    fn the_next_step_meets_the_tolerance_for_the_formula_order() {
        // Second order: error ∝ h³; at ratio 8 the step that meets it is h/2, times the
        // safety factor.
        let h = 1e-3;
        assert!((CONTROL.next_step(h, 8.0, 2) - SAFETY * h / 2.0).abs() < 1e-15);
        // First order: error ∝ h²; ratio 1/4 allows 2h, and growth stops at MAX_GROWTH.
        assert!((CONTROL.next_step(h, 0.25, 1) - SAFETY * 2.0 * h).abs() < 1e-15);
        assert_eq!(CONTROL.next_step(h, 1e-12, 2), MAX_GROWTH * h);
        assert_eq!(CONTROL.next_step(h, 0.0, 2), MAX_GROWTH * h);
        // Shrinking is bounded, and the limits hold.
        assert_eq!(CONTROL.next_step(h, 1e9, 1), MAX_SHRINK * h);
        assert_eq!(CONTROL.next_step(9e-3, 1e-6, 2), CONTROL.dt_max);
        assert_eq!(CONTROL.next_step(2e-6, 1e9, 2), CONTROL.dt_min);
    }

    #[test]
    fn the_error_measure_is_relative_with_an_absolute_floor() {
        // 1e-6 m of error at 1 mm of displacement: 1e-6 / (1e-6 + 1e-9).
        assert!((CONTROL.ratio(1e-6, 1e-3) - 1.0 / 1.001).abs() < 1e-12);
        // At rest only the absolute tolerance counts.
        assert!((CONTROL.ratio(2e-9, 0.0) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn steps_divide_the_time_to_a_frame_evenly() {
        assert_eq!(fit_to(0.1, 0.5), 0.1);
        assert_eq!(fit_to(0.1, 0.1), 0.1);
        // 0.1 / 0.03 = 3.33: four steps of 0.025, not three of 0.03 and a sliver.
        assert!((fit_to(0.1, 0.03) - 0.025).abs() < 1e-15);
        // Round-off above an even division does not add a step.
        assert!((fit_to(0.1, 0.05 * (1.0 - 1e-12)) - 0.05).abs() < 1e-15);
    }
}
