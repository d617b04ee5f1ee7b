//! Time integration of a dynamic step. Every scheme is an incremental potential whose
//! inertia term is backward Euler's 1/(2h'²) (u − ũ)ᵀM(u − ũ) with its own predictor ũ and
//! length h', so Newton, the line search, contact and friction see the same kind of problem;
//! after the solve the scheme turns the solution into the new velocity (and acceleration).

use super::State;

/// How a dynamic step integrates in time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Backward Euler: first order; dissipates ½ ΔvᵀMΔv per step, which damps the motion.
    #[default]
    BackwardEuler,
    /// Newmark's average acceleration (the trapezoidal rule, β = ¼, γ = ½): second order, no
    /// numerical dissipation (a linear undamped system keeps its energy). The step minimises
    /// Ψ(u) + 2/h² (u − ũ)ᵀM(u − ũ), ũ = uₙ + h vₙ + h²/4 aₙ; then aₙ₊₁ = 4 (uₙ₊₁ − ũ)/h²,
    /// vₙ₊₁ = vₙ + h/2 (aₙ + aₙ₊₁).
    Newmark,
    /// BDF2, second order with some numerical dissipation of the fastest modes: the step
    /// minimises Ψ(u) + 9/(8h²) (u − ũ)ᵀM(u − ũ), ũ = (4uₙ − uₙ₋₁)/3 + 2h/9 (4vₙ − vₙ₋₁);
    /// then vₙ₊₁ = (3uₙ₊₁ − 4uₙ + uₙ₋₁)/(2h). A step without a full step before it (the
    /// first, a halved one, the first after a remesh) is a backward-Euler step.
    Bdf2,
}

/// The formula one dynamic solve uses: its scheme's, or backward Euler where BDF2 has no full
/// step before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum StepFormula {
    BackwardEuler,
    Newmark,
    Bdf2,
}

impl StepFormula {
    /// The formula of a solve of length `h` of `scheme` (full step `dt`) from `state`.
    pub(super) fn of(scheme: Scheme, state: &State, h: f64, dt: f64) -> Self {
        match scheme {
            Scheme::BackwardEuler => StepFormula::BackwardEuler,
            Scheme::Newmark => StepFormula::Newmark,
            Scheme::Bdf2 if h == dt && state.back.0.len() == state.u.len() => StepFormula::Bdf2,
            Scheme::Bdf2 => StepFormula::BackwardEuler,
        }
    }

    /// The length h' of backward Euler's inertia term this formula's equals (s): Newmark's
    /// 1/(2βh²) with β = ¼ at h' = h/2, BDF2's 9/(8h²) at h' = 2h/3.
    pub(super) fn inertia_step(self, h: f64) -> f64 {
        match self {
            StepFormula::BackwardEuler => h,
            StepFormula::Newmark => 0.5 * h,
            StepFormula::Bdf2 => 2.0 * h / 3.0,
        }
    }

    /// The predictor ũ (m, all dofs) of a solve of length `h` from `state`.
    pub(super) fn predict(self, state: &State, h: f64, predictor: &mut [f64]) {
        let (u, v) = (&state.u, &state.v);
        for (d, p) in predictor.iter_mut().enumerate() {
            *p = match self {
                StepFormula::BackwardEuler => u[d] + h * v[d],
                StepFormula::Newmark => u[d] + h * v[d] + 0.25 * h * h * state.a[d],
                StepFormula::Bdf2 => {
                    let (back_u, back_v) = &state.back;
                    (4.0 * u[d] - back_u[d]) / 3.0 + 2.0 * h / 9.0 * (4.0 * v[d] - back_v[d])
                }
            };
        }
    }

    /// The velocity (m/s) and, for Newmark, the acceleration (m/s²; empty otherwise) at the
    /// solution `u` of a solve of length `h` from `state` with `predictor`.
    pub(super) fn velocity(
        self,
        state: &State,
        (u, predictor): (&[f64], &[f64]),
        h: f64,
    ) -> (Vec<f64>, Vec<f64>) {
        let n = u.len();
        match self {
            StepFormula::BackwardEuler => (
                (0..n).map(|d| (u[d] - state.u[d]) / h).collect(),
                Vec::new(),
            ),
            StepFormula::Newmark => {
                let a: Vec<f64> = (0..n)
                    .map(|d| 4.0 * (u[d] - predictor[d]) / (h * h))
                    .collect();
                let v = (0..n)
                    .map(|d| state.v[d] + 0.5 * h * (state.a[d] + a[d]))
                    .collect();
                (v, a)
            }
            StepFormula::Bdf2 => {
                let back = &state.back.0;
                let v = (0..n)
                    .map(|d| (3.0 * u[d] - 4.0 * state.u[d] + back[d]) / (2.0 * h))
                    .collect();
                (v, Vec::new())
            }
        }
    }
}
