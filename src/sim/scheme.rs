//! Time integration of a dynamic step. Every scheme is an incremental potential whose
//! inertia term is backward Euler's 1/(2h'²) (u − ũ)ᵀM(u − ũ) with its own predictor ũ and
//! length h', so Newton, the line search, contact and friction see the same kind of problem;
//! after the solve the scheme turns the solution into the new velocity (and acceleration).
//! Newmark's start acceleration, from the state's forces, is computed here too.

use super::potential::{Share, StepPotential};
use super::{solve_terms, Simulation, State};
use crate::physics::term::Solve;

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
    /// BDF2, second order with some numerical dissipation of the fastest modes: with equal
    /// steps the step minimises Ψ(u) + 9/(8h²) (u − ũ)ᵀM(u − ũ),
    /// ũ = (4uₙ − uₙ₋₁)/3 + 2h/9 (4vₙ − vₙ₋₁); then vₙ₊₁ = (3uₙ₊₁ − 4uₙ + uₙ₋₁)/(2h) (the
    /// variable-step coefficients are in `StepFormula::Bdf2`). A step without a step before it
    /// (the first, the first after a remesh) or more than [`BDF2_MAX_STEP_RATIO`] times as
    /// long is a backward-Euler step.
    Bdf2,
}

/// The state one step back, for BDF2.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StepBack {
    /// Displacement one step back (m, 3 per node).
    pub u: Vec<f64>,
    /// Velocity one step back (m/s, 3 per node).
    pub v: Vec<f64>,
    /// Length of the step from there to the current state (s).
    pub dt: f64,
}

impl StepBack {
    /// Whether there is a step back for a state of `n` dofs.
    pub fn is_for(&self, n: usize) -> bool {
        self.dt > 0.0 && self.u.len() == n && self.v.len() == n
    }
}

/// Largest ratio of a BDF2 step to the step before it: variable-step BDF2 is zero-stable
/// below 1 + √2; a longer step (the first full step after a chain of halved ones) is a
/// backward-Euler step.
pub const BDF2_MAX_STEP_RATIO: f64 = 2.0;

/// The formula one dynamic solve uses: its scheme's, or backward Euler where BDF2 has no step
/// before it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum StepFormula {
    BackwardEuler,
    Newmark,
    /// Variable-step BDF2 with ω = h / (the step before), α₀ = (1 + 2ω)/(1 + ω),
    /// α₁ = −(1 + ω), α₂ = ω²/(1 + ω): α₀ yₙ₊₁ + α₁ yₙ + α₂ yₙ₋₁ = h y'ₙ₊₁ (ω = 1: 3/2, −2, 1/2).
    Bdf2 {
        ratio: f64,
    },
}

impl StepFormula {
    /// The formula of a solve of length `h` of `scheme` from `state`.
    pub(super) fn of(scheme: Scheme, state: &State, h: f64) -> Self {
        match scheme {
            Scheme::BackwardEuler => StepFormula::BackwardEuler,
            Scheme::Newmark => StepFormula::Newmark,
            Scheme::Bdf2 if state.back.is_for(state.u.len()) => {
                let ratio = h / state.back.dt;
                if ratio <= BDF2_MAX_STEP_RATIO {
                    StepFormula::Bdf2 { ratio }
                } else {
                    StepFormula::BackwardEuler
                }
            }
            Scheme::Bdf2 => StepFormula::BackwardEuler,
        }
    }

    /// BDF2's coefficients α₀, α₁, α₂ at step ratio ω.
    fn bdf2_coefficients(ratio: f64) -> (f64, f64, f64) {
        let w = ratio;
        ((1.0 + 2.0 * w) / (1.0 + w), -(1.0 + w), w * w / (1.0 + w))
    }

    /// The length h' of backward Euler's inertia term this formula's equals (s): Newmark's
    /// 1/(2βh²) with β = ¼ at h' = h/2, BDF2's α₀²/(2h²) at h' = h/α₀ (2h/3 at ω = 1).
    pub(super) fn inertia_step(self, h: f64) -> f64 {
        match self {
            StepFormula::BackwardEuler => h,
            StepFormula::Newmark => 0.5 * h,
            StepFormula::Bdf2 { ratio } => h / Self::bdf2_coefficients(ratio).0,
        }
    }

    /// The order of accuracy of the formula.
    pub(super) fn order(self) -> u32 {
        match self {
            StepFormula::BackwardEuler => 1,
            StepFormula::Newmark | StepFormula::Bdf2 { .. } => 2,
        }
    }

    /// The predictor ũ (m, all dofs) of a solve of length `h` from `state`: the solution
    /// minimises Ψ(u) + 1/(2h'²)(u − ũ)ᵀM(u − ũ). BDF2's, from
    /// M(α₀vₙ₊₁ + α₁vₙ + α₂vₙ₋₁)/h = F(uₙ₊₁) with vₙ₊₁ = (α₀uₙ₊₁ + α₁uₙ + α₂uₙ₋₁)/h:
    /// ũ = −(α₁uₙ + α₂uₙ₋₁)/α₀ − h(α₁vₙ + α₂vₙ₋₁)/α₀².
    pub(super) fn predict(self, state: &State, h: f64, predictor: &mut [f64]) {
        let (u, v) = (&state.u, &state.v);
        match self {
            StepFormula::BackwardEuler => {
                for (d, p) in predictor.iter_mut().enumerate() {
                    *p = u[d] + h * v[d];
                }
            }
            StepFormula::Newmark => {
                for (d, p) in predictor.iter_mut().enumerate() {
                    *p = u[d] + h * v[d] + 0.25 * h * h * state.a[d];
                }
            }
            StepFormula::Bdf2 { ratio } => {
                let (a0, a1, a2) = Self::bdf2_coefficients(ratio);
                let back = &state.back;
                for (d, p) in predictor.iter_mut().enumerate() {
                    *p = -(a1 * u[d] + a2 * back.u[d]) / a0
                        - h * (a1 * v[d] + a2 * back.v[d]) / (a0 * a0);
                }
            }
        }
    }

    /// The velocity as an affine function of the solution u, vₙ₊₁ = (u − p)/h_d: returns h_d
    /// (s) and writes the origin p (m, all dofs) of a solve of length `h` from `state` with
    /// `predictor` — what the damping terms need. Backward Euler: h, uₙ. Newmark:
    /// vₙ₊₁ = vₙ + h/2 aₙ + 2(u − ũ)/h, so h/2 and ũ − h/2 (vₙ + h/2 aₙ). BDF2: h/α₀ and
    /// −(α₁uₙ + α₂uₙ₋₁)/α₀.
    pub(super) fn velocity_form(
        self,
        state: &State,
        (h, predictor): (f64, &[f64]),
        origin: &mut [f64],
    ) -> f64 {
        let u = &state.u;
        match self {
            StepFormula::BackwardEuler => {
                origin.copy_from_slice(u);
                h
            }
            StepFormula::Newmark => {
                for (d, p) in origin.iter_mut().enumerate() {
                    *p = predictor[d] - 0.5 * h * (state.v[d] + 0.5 * h * state.a[d]);
                }
                0.5 * h
            }
            StepFormula::Bdf2 { ratio } => {
                let (a0, a1, a2) = Self::bdf2_coefficients(ratio);
                for (d, p) in origin.iter_mut().enumerate() {
                    *p = -(a1 * u[d] + a2 * state.back.u[d]) / a0;
                }
                h / a0
            }
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
            StepFormula::Bdf2 { ratio } => {
                let (a0, a1, a2) = Self::bdf2_coefficients(ratio);
                let back = &state.back.u;
                let v = (0..n)
                    .map(|d| (a0 * u[d] + a1 * state.u[d] + a2 * back[d]) / h)
                    .collect();
                (v, Vec::new())
            }
        }
    }

    /// An estimate of the local (one-step) displacement error of dof `d` (m) of a solve of
    /// length `h` from `state` that reached displacement `u`, velocity `v` and (Newmark)
    /// acceleration `a`:
    /// - backward Euler: h/2 (vₙ₊₁ − vₙ), its difference with the trapezoidal rule's
    ///   uₙ + h/2 (vₙ + vₙ₊₁) from the same velocities (the embedded second-order solution);
    /// - Newmark (β = ¼): (β − 1/6) h² (aₙ₊₁ − aₙ) = h²/12 (aₙ₊₁ − aₙ), its leading error
    ///   term (Zienkiewicz and Xie 1991);
    /// - BDF2: Milne's device, 8/23 (uₙ₊₁ − uᴾ) with the explicit second-order predictor
    ///   uᴾ = uₙ + h vₙ + h²/2 (vₙ − vₙ₋₁)/hₙ₋₁: its error (5/12) h³ u‴ and BDF2's −(2/9) h³ u‴
    ///   give BDF2's as (2/9)/(5/12 + 2/9) of their difference (constants of equal steps).
    pub(super) fn local_error(
        self,
        state: &State,
        (u, v, a): (&[f64], &[f64], &[f64]),
        h: f64,
        d: usize,
    ) -> f64 {
        match self {
            StepFormula::BackwardEuler => 0.5 * h * (v[d] - state.v[d]),
            StepFormula::Newmark => h * h / 12.0 * (a[d] - state.a[d]),
            StepFormula::Bdf2 { .. } => {
                let back = &state.back;
                let slope = (state.v[d] - back.v[d]) / back.dt;
                let explicit = state.u[d] + h * state.v[d] + 0.5 * h * h * slope;
                8.0 / 23.0 * (u[d] - explicit)
            }
        }
    }
}

impl Simulation {
    /// The acceleration of the current state from its forces, a = −M⁻¹ (∇Ψ(u) + D v) on the
    /// free dofs (Ψ: elasticity, dead loads and contact at the state's time; D the Rayleigh
    /// damping), 0 on the supported ones: what the Newmark scheme starts from.
    pub(super) fn acceleration_at_start(&mut self) -> Vec<f64> {
        let t = self.state.time;
        self.model.apply_schedule(t, &mut self.state.history);
        let offsets = self.state.history.offsets();
        let max_speed = self.max_speed();
        let model = &self.model;
        let solve = Solve {
            rest: &model.mesh.rest,
            previous: &self.state.u,
            velocity: &self.state.v,
            max_speed,
            earlier: &self.state.u,
            h: self.settings.dt,
            dynamic: true,
            times: (t, t),
        };
        let subset = self
            .shared
            .as_ref()
            .map(|s| (&s.elements, s.distribution.owned_dofs()));
        let terms = solve_terms(
            model,
            &self.assembly,
            (&self.state.history, &offsets),
            (&mut self.element_energy, subset),
            &solve,
        );
        let mut potential = StepPotential::new(terms);
        // Summed over the processes of a distributed run.
        potential.share = self.shared.as_ref().map(|s| Share {
            collective: s.distribution.collective(),
            owned: s.distribution.owned_dofs(),
            assembly: &self.assembly,
        });
        let mut gradient = vec![0.0; self.state.u.len()];
        crate::solver::Potential::gradient(&mut potential, &self.state.u, &mut gradient);
        drop(potential);
        let damping = model.damping.unwrap_or_default();
        for (d, g) in gradient.iter_mut().enumerate() {
            *g += damping.mass * model.mass[d / 3] * self.state.v[d];
        }
        if damping.stiffness > 0.0 {
            self.previous.copy_from_slice(&self.state.u);
            self.stiffness_at_previous(damping.stiffness);
            let dofs = self.assembly.dofs();
            let v: Vec<f64> = dofs.free_dofs().iter().map(|&d| self.state.v[d]).collect();
            let mut force = vec![0.0; v.len()];
            self.assembly
                .multiply(&self.damping_stiffness, &v, &mut force);
            for (f, &d) in force.iter().zip(dofs.free_dofs()) {
                gradient[d] += f;
            }
        }
        let model = &self.model;
        let dofs = self.assembly.dofs();
        // A process of a distributed run has the masses of its owned nodes (see
        // `Model::restrict`): the others' accelerations come from their owners.
        let mut a: Vec<f64> = (0..gradient.len())
            .map(|d| match dofs.free(d) {
                Some(_) if model.mass[d / 3] > 0.0 => -gradient[d] / model.mass[d / 3],
                _ => 0.0,
            })
            .collect();
        self.exchange_owned(&mut a);
        a
    }
}
