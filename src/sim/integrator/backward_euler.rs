//! Backward Euler: first order; dissipates ½ ΔvᵀMΔv per step, which damps the motion.

use super::{largest, StepEnd, TimeIntegrator};
use crate::sim::State;

/// Backward Euler: ũ = uₙ + h vₙ, vₙ₊₁ = (uₙ₊₁ − uₙ)/h.
#[derive(Clone, Copy, Debug, Default)]
pub struct BackwardEuler;

impl TimeIntegrator for BackwardEuler {
    fn order(&self, _state: &State, _h: f64) -> u32 {
        1
    }

    fn inertia_step(&self, _state: &State, h: f64) -> f64 {
        h
    }

    fn predict(&self, state: &State, h: f64, predictor: &mut [f64]) {
        let (u, v) = (&state.u, &state.v);
        for (d, p) in predictor.iter_mut().enumerate() {
            *p = u[d] + h * v[d];
        }
    }

    /// h and uₙ.
    fn velocity_form(&self, state: &State, h: f64, _predictor: &[f64], origin: &mut [f64]) -> f64 {
        origin.copy_from_slice(&state.u);
        h
    }

    fn finish(&self, state: &State, h: f64, u: &[f64], _predictor: &[f64]) -> StepEnd {
        StepEnd {
            velocity: (0..u.len()).map(|d| (u[d] - state.u[d]) / h).collect(),
            carried: Default::default(),
        }
    }

    /// h/2 (vₙ₊₁ − vₙ): its difference with the trapezoidal rule's uₙ + h/2 (vₙ + vₙ₊₁) from
    /// the same velocities (the embedded second-order solution).
    fn local_error(&self, state: &State, h: f64, _u: &[f64], end: &StepEnd, free: &[usize]) -> f64 {
        let v = &end.velocity;
        largest(free, |d| 0.5 * h * (v[d] - state.v[d]))
    }
}
