//! Time integration of a dynamic step, one file per scheme behind [`TimeIntegrator`].
//!
//! Every scheme is an incremental potential whose inertia term is backward Euler's
//! 1/(2h'²) (u − ũ)ᵀM(u − ũ) with its own predictor ũ and length h', so Newton, the line
//! search, contact and friction see the same kind of problem; after the solve the scheme turns
//! the solution into the new velocity and whatever it carries to the next step
//! ([`SchemeState`]). A new scheme is one file implementing [`TimeIntegrator`] and its name in
//! [`Scheme`], which the scene reads.

mod backward_euler;
mod bdf2;
mod newmark;

pub use backward_euler::BackwardEuler;
pub use bdf2::{Bdf2, BDF2_MAX_STEP_RATIO};
pub use newmark::Newmark;

use super::State;

/// How a dynamic step integrates in time (the scene's `[time] scheme`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Backward Euler ([`BackwardEuler`]).
    #[default]
    BackwardEuler,
    /// Newmark's average acceleration ([`Newmark`]).
    Newmark,
    /// Variable-step BDF2 ([`Bdf2`]).
    Bdf2,
}

impl Scheme {
    /// The integrator of this scheme.
    pub fn integrator(self) -> Box<dyn TimeIntegrator> {
        match self {
            Scheme::BackwardEuler => Box::new(BackwardEuler),
            Scheme::Newmark => Box::new(Newmark),
            Scheme::Bdf2 => Box::new(Bdf2),
        }
    }
}

/// What a time scheme carries from one step to the next besides displacement and velocity
/// (Newmark's acceleration, BDF2's step back): node fields (3 per node) and scalars, by name,
/// in the order its [`TimeIntegrator`] declares them — the names frames store them under, so
/// that a resumed run continues from them. Empty before a scheme's first step and after a
/// remesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SchemeState {
    /// Node fields (3 per node; their units are the scheme's).
    pub fields: Vec<(&'static str, Vec<f64>)>,
    /// Scalars (their units are the scheme's).
    pub scalars: Vec<(&'static str, f64)>,
}

impl SchemeState {
    /// The node field `name`, if carried.
    pub fn field(&self, name: &str) -> Option<&[f64]> {
        self.fields
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| &v[..])
    }

    /// The scalar `name`, if carried.
    pub fn scalar(&self, name: &str) -> Option<f64> {
        self.scalars
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| *v)
    }

    /// The state `integrator` carries, read by name with `field` (node fields of 3 per node
    /// of the right length) and `scalar`; empty unless every field and scalar it declares is
    /// there (then its next step starts as its first does).
    pub fn read(
        integrator: &dyn TimeIntegrator,
        field: impl Fn(&str) -> Option<Vec<f64>>,
        scalar: impl Fn(&str) -> Option<f64>,
    ) -> SchemeState {
        let fields: Option<Vec<_>> = integrator
            .carried_fields()
            .iter()
            .map(|&name| field(name).map(|v| (name, v)))
            .collect();
        let scalars: Option<Vec<_>> = integrator
            .carried_scalars()
            .iter()
            .map(|&name| scalar(name).map(|v| (name, v)))
            .collect();
        match (fields, scalars) {
            (Some(fields), Some(scalars)) if !(fields.is_empty() && scalars.is_empty()) => {
                SchemeState { fields, scalars }
            }
            _ => SchemeState::default(),
        }
    }
}

/// The end of a dynamic solve: the new velocity and what the scheme carries on.
#[derive(Clone, Debug, Default)]
pub struct StepEnd {
    /// Velocity at the solution (m/s, 3 per node).
    pub velocity: Vec<f64>,
    /// What the scheme carries to the next step.
    pub carried: SchemeState,
}

/// A time-integration scheme of a dynamic step. Each method is given the state at the start of
/// the solve (whose [`State::carried`] is this scheme's) and the solve's length h (s).
pub trait TimeIntegrator: Send + Sync + std::fmt::Debug {
    /// Names of the node fields (3 per node) the scheme carries, in the order it stores them.
    fn carried_fields(&self) -> &'static [&'static str] {
        &[]
    }
    /// Names of the scalars the scheme carries.
    fn carried_scalars(&self) -> &'static [&'static str] {
        &[]
    }
    /// Whether a solve from `state` first needs the state's acceleration from its forces
    /// (a scheme that carries an acceleration, before its first step): the simulation then
    /// computes it and gives it to [`TimeIntegrator::start_from_acceleration`].
    fn needs_acceleration(&self, _state: &State) -> bool {
        false
    }
    /// Takes the state's acceleration (m/s², 3 per node) into what the scheme carries.
    fn start_from_acceleration(&self, _carried: &mut SchemeState, _acceleration: Vec<f64>) {}
    /// The order of accuracy of a solve from `state`.
    fn order(&self, state: &State, h: f64) -> u32;
    /// The length h' of backward Euler's inertia term the scheme's equals (s).
    fn inertia_step(&self, state: &State, h: f64) -> f64;
    /// Writes the predictor ũ (m, all dofs): the solution minimises
    /// Ψ(u) + 1/(2h'²)(u − ũ)ᵀM(u − ũ).
    fn predict(&self, state: &State, h: f64, predictor: &mut [f64]);
    /// The velocity as an affine function of the solution u, vₙ₊₁ = (u − p)/h_d: returns h_d
    /// (s) and writes the origin p (m, all dofs) — what the damping terms need.
    fn velocity_form(&self, state: &State, h: f64, predictor: &[f64], origin: &mut [f64]) -> f64;
    /// The velocity at the solution `u` and what the scheme carries on.
    fn finish(&self, state: &State, h: f64, u: &[f64], predictor: &[f64]) -> StepEnd;
    /// An estimate of the local (one-step) displacement error (m): the largest over the dofs
    /// `free` of a solve that reached `u` and `end`.
    fn local_error(&self, state: &State, h: f64, u: &[f64], end: &StepEnd, free: &[usize]) -> f64;
}

/// The largest |`error(d)`| over the dofs `free`.
fn largest(free: &[usize], error: impl Fn(usize) -> f64) -> f64 {
    free.iter().map(|&d| error(d).abs()).fold(0.0, f64::max)
}
