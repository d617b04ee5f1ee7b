//! Newmark's average acceleration (the trapezoidal rule, β = ¼, γ = ½): second order, no
//! numerical dissipation (a linear undamped system keeps its energy).

use super::{largest, SchemeState, StepEnd, TimeIntegrator};
use crate::sim::State;

/// The node field Newmark carries: the acceleration (m/s², 3 per node).
const ACCELERATION: &str = "acceleration";

/// Newmark (β = ¼, γ = ½): the step minimises Ψ(u) + 2/h² (u − ũ)ᵀM(u − ũ),
/// ũ = uₙ + h vₙ + h²/4 aₙ; then aₙ₊₁ = 4 (uₙ₊₁ − ũ)/h², vₙ₊₁ = vₙ + h/2 (aₙ + aₙ₊₁). The
/// first step starts from the state's acceleration from its forces.
#[derive(Clone, Copy, Debug, Default)]
pub struct Newmark;

impl Newmark {
    /// The acceleration aₙ of `state` (its first step has one: see `needs_acceleration`).
    fn acceleration(state: &State) -> &[f64] {
        state.carried.field(ACCELERATION).unwrap_or_default()
    }
}

impl TimeIntegrator for Newmark {
    fn carried_fields(&self) -> &'static [&'static str] {
        &[ACCELERATION]
    }

    fn needs_acceleration(&self, state: &State) -> bool {
        state.carried.field(ACCELERATION).map_or(0, <[f64]>::len) != state.u.len()
    }

    fn start_from_acceleration(&self, carried: &mut SchemeState, acceleration: Vec<f64>) {
        *carried = SchemeState {
            fields: vec![(ACCELERATION, acceleration)],
            scalars: Vec::new(),
        };
    }

    fn order(&self, _state: &State, _h: f64) -> u32 {
        2
    }

    /// 1/(2βh²) with β = ¼ is backward Euler's at h' = h/2.
    fn inertia_step(&self, _state: &State, h: f64) -> f64 {
        0.5 * h
    }

    fn predict(&self, state: &State, h: f64, predictor: &mut [f64]) {
        let (u, v, a) = (&state.u, &state.v, Self::acceleration(state));
        for (d, p) in predictor.iter_mut().enumerate() {
            *p = u[d] + h * v[d] + 0.25 * h * h * a[d];
        }
    }

    /// vₙ₊₁ = vₙ + h/2 aₙ + 2(u − ũ)/h, so h/2 and ũ − h/2 (vₙ + h/2 aₙ).
    fn velocity_form(&self, state: &State, h: f64, predictor: &[f64], origin: &mut [f64]) -> f64 {
        let a = Self::acceleration(state);
        for (d, p) in origin.iter_mut().enumerate() {
            *p = predictor[d] - 0.5 * h * (state.v[d] + 0.5 * h * a[d]);
        }
        0.5 * h
    }

    fn finish(&self, state: &State, h: f64, u: &[f64], predictor: &[f64]) -> StepEnd {
        let n = u.len();
        let a0 = Self::acceleration(state);
        let a: Vec<f64> = (0..n)
            .map(|d| 4.0 * (u[d] - predictor[d]) / (h * h))
            .collect();
        let velocity = (0..n)
            .map(|d| state.v[d] + 0.5 * h * (a0[d] + a[d]))
            .collect();
        let mut carried = SchemeState::default();
        self.start_from_acceleration(&mut carried, a);
        StepEnd { velocity, carried }
    }

    /// (β − 1/6) h² (aₙ₊₁ − aₙ) = h²/12 (aₙ₊₁ − aₙ), its leading error term (Zienkiewicz and
    /// Xie 1991).
    fn local_error(&self, state: &State, h: f64, _u: &[f64], end: &StepEnd, free: &[usize]) -> f64 {
        let (a0, a) = (Self::acceleration(state), Self::acceleration_of(end));
        largest(free, |d| h * h / 12.0 * (a[d] - a0[d]))
    }
}

impl Newmark {
    /// The acceleration aₙ₊₁ a solve reached.
    fn acceleration_of(end: &StepEnd) -> &[f64] {
        end.carried.field(ACCELERATION).unwrap_or_default()
    }
}
