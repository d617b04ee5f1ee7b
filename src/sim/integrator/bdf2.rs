//! BDF2, second order with some numerical dissipation of the fastest modes.

use super::{largest, BackwardEuler, SchemeState, StepEnd, TimeIntegrator};
use crate::sim::State;

/// Largest ratio of a BDF2 step to the step before it: variable-step BDF2 is zero-stable
/// below 1 + √2; a longer step (the first full step after a chain of halved ones) is a
/// backward-Euler step.
pub const BDF2_MAX_STEP_RATIO: f64 = 2.0;

/// The node fields BDF2 carries: displacement (m) and velocity (m/s) one step back.
const BACK_FIELDS: [&str; 2] = ["back_displacement", "back_velocity"];
/// The scalar BDF2 carries: the length of the step back (s).
const BACK_DT: &str = "back_dt";

/// Variable-step BDF2 with ω = h / (the step before), α₀ = (1 + 2ω)/(1 + ω),
/// α₁ = −(1 + ω), α₂ = ω²/(1 + ω): α₀ yₙ₊₁ + α₁ yₙ + α₂ yₙ₋₁ = h y'ₙ₊₁ (ω = 1: 3/2, −2, 1/2).
/// With equal steps the step minimises Ψ(u) + 9/(8h²) (u − ũ)ᵀM(u − ũ),
/// ũ = (4uₙ − uₙ₋₁)/3 + 2h/9 (4vₙ − vₙ₋₁); then vₙ₊₁ = (3uₙ₊₁ − 4uₙ + uₙ₋₁)/(2h). A step
/// without a step before it (the first, the first after a remesh) or more than
/// [`BDF2_MAX_STEP_RATIO`] times as long is a backward-Euler step.
#[derive(Clone, Copy, Debug, Default)]
pub struct Bdf2;

/// The state one step back.
struct Back<'a> {
    u: &'a [f64],
    v: &'a [f64],
    dt: f64,
}

impl Bdf2 {
    /// The state one step back and the coefficients α₀, α₁, α₂ of a solve of length `h`
    /// from `state`; `None` where the solve is a backward-Euler step.
    fn formula(state: &State, h: f64) -> Option<(Back<'_>, (f64, f64, f64))> {
        let carried = &state.carried;
        let n = state.u.len();
        let back = Back {
            u: carried.field(BACK_FIELDS[0])?,
            v: carried.field(BACK_FIELDS[1])?,
            dt: carried.scalar(BACK_DT)?,
        };
        if !(back.dt > 0.0 && back.u.len() == n && back.v.len() == n) {
            return None;
        }
        let w = h / back.dt;
        (w <= BDF2_MAX_STEP_RATIO).then(|| {
            (
                back,
                ((1.0 + 2.0 * w) / (1.0 + w), -(1.0 + w), w * w / (1.0 + w)),
            )
        })
    }
}

impl TimeIntegrator for Bdf2 {
    fn carried_fields(&self) -> &'static [&'static str] {
        &BACK_FIELDS
    }

    fn carried_scalars(&self) -> &'static [&'static str] {
        &[BACK_DT]
    }

    fn order(&self, state: &State, h: f64) -> u32 {
        match Self::formula(state, h) {
            Some(_) => 2,
            None => BackwardEuler.order(state, h),
        }
    }

    /// α₀²/(2h²) is backward Euler's at h' = h/α₀ (2h/3 at ω = 1).
    fn inertia_step(&self, state: &State, h: f64) -> f64 {
        match Self::formula(state, h) {
            Some((_, (a0, _, _))) => h / a0,
            None => BackwardEuler.inertia_step(state, h),
        }
    }

    /// From M(α₀vₙ₊₁ + α₁vₙ + α₂vₙ₋₁)/h = F(uₙ₊₁) with vₙ₊₁ = (α₀uₙ₊₁ + α₁uₙ + α₂uₙ₋₁)/h:
    /// ũ = −(α₁uₙ + α₂uₙ₋₁)/α₀ − h(α₁vₙ + α₂vₙ₋₁)/α₀².
    fn predict(&self, state: &State, h: f64, predictor: &mut [f64]) {
        let Some((back, (a0, a1, a2))) = Self::formula(state, h) else {
            return BackwardEuler.predict(state, h, predictor);
        };
        let (u, v) = (&state.u, &state.v);
        for (d, p) in predictor.iter_mut().enumerate() {
            *p = -(a1 * u[d] + a2 * back.u[d]) / a0 - h * (a1 * v[d] + a2 * back.v[d]) / (a0 * a0);
        }
    }

    /// h/α₀ and −(α₁uₙ + α₂uₙ₋₁)/α₀.
    fn velocity_form(&self, state: &State, h: f64, predictor: &[f64], origin: &mut [f64]) -> f64 {
        let Some((back, (a0, a1, a2))) = Self::formula(state, h) else {
            return BackwardEuler.velocity_form(state, h, predictor, origin);
        };
        let u = &state.u;
        for (d, p) in origin.iter_mut().enumerate() {
            *p = -(a1 * u[d] + a2 * back.u[d]) / a0;
        }
        h / a0
    }

    /// The velocity, and the state it started from as the step back.
    fn finish(&self, state: &State, h: f64, u: &[f64], predictor: &[f64]) -> StepEnd {
        let velocity = match Self::formula(state, h) {
            Some((back, (a0, a1, a2))) => (0..u.len())
                .map(|d| (a0 * u[d] + a1 * state.u[d] + a2 * back.u[d]) / h)
                .collect(),
            None => BackwardEuler.finish(state, h, u, predictor).velocity,
        };
        let carried = SchemeState {
            fields: vec![
                (BACK_FIELDS[0], state.u.clone()),
                (BACK_FIELDS[1], state.v.clone()),
            ],
            scalars: vec![(BACK_DT, h)],
        };
        StepEnd { velocity, carried }
    }

    /// Milne's device, 8/23 (uₙ₊₁ − uᴾ) with the explicit second-order predictor
    /// uᴾ = uₙ + h vₙ + h²/2 (vₙ − vₙ₋₁)/hₙ₋₁: its error (5/12) h³ u‴ and BDF2's −(2/9) h³ u‴
    /// give BDF2's as (2/9)/(5/12 + 2/9) of their difference (constants of equal steps).
    fn local_error(&self, state: &State, h: f64, u: &[f64], end: &StepEnd, free: &[usize]) -> f64 {
        let Some((back, _)) = Self::formula(state, h) else {
            return BackwardEuler.local_error(state, h, u, end, free);
        };
        largest(free, |d| {
            let slope = (state.v[d] - back.v[d]) / back.dt;
            let explicit = state.u[d] + h * state.v[d] + 0.5 * h * h * slope;
            8.0 / 23.0 * (u[d] - explicit)
        })
    }
}
