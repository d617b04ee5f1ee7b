//! Inertia and Rayleigh damping as terms of a dynamic step.
//!
//! For a backward-Euler step h from displacements uₙ and velocities vₙ, with û = uₙ + h vₙ
//! and D = α M + β Kₙ, the step minimises
//!
//! ```text
//! E(u) = Σₑ Wₑ(u) − f·u + 1/(2h²) (u − û)ᵀ M (u − û) + 1/(2h) (u − uₙ)ᵀ D (u − uₙ),
//! ```
//!
//! whose stationarity condition is exactly M (vₙ₊₁ − vₙ)/h = f − ∇W(uₙ₊₁) − D vₙ₊₁ with
//! vₙ₊₁ = (uₙ₊₁ − uₙ)/h. Every scheme has this form: its inertia term at its own length h' and
//! predictor, and its velocity vₙ₊₁ = (u − p)/h_d, affine in u, which the damping term
//! 1/(2h_d) (u − p)ᵀ D (u − p) turns into the force D vₙ₊₁ (see `sim::scheme`). The damping
//! stiffness Kₙ is the elastic Hessian at the start of the step, so the damping term is a fixed
//! quadratic and the step stays a minimisation.

use super::term::StepTerm;
use crate::assembly::Assembly;

/// Inertia with mass-proportional damping: 1/(2h²) ‖u − û‖²_M + α/(2h_d) ‖u − p‖²_M.
pub struct Inertia<'a> {
    /// Length h of the inertia term (s): the step for backward Euler.
    pub dt: f64,
    /// Lumped nodal mass (kg), one per node.
    pub mass: &'a [f64],
    /// Predictor û (m), all dofs: uₙ + h vₙ for backward Euler.
    pub predictor: &'a [f64],
    /// The velocity's length h_d (s) and origin p (m, all dofs): vₙ₊₁ = (u − p)/h_d (for
    /// backward Euler h and uₙ).
    pub velocity_form: (f64, &'a [f64]),
    /// Mass-proportional damping α (1/s).
    pub alpha: f64,
    /// Pattern of the free system.
    pub assembly: &'a Assembly,
}

impl StepTerm for Inertia<'_> {
    fn name(&self) -> &'static str {
        "inertia"
    }

    fn add(
        &mut self,
        u: &[f64],
        energy: &mut f64,
        mut gradient: Option<&mut [f64]>,
        mut hessian: Option<&mut [f64]>,
    ) {
        let h = self.dt;
        let (hd, origin) = self.velocity_form;
        let dofs = self.assembly.dofs();
        for d in 0..u.len() {
            let m = self.mass[d / 3];
            let a = u[d] - self.predictor[d];
            let b = u[d] - origin[d];
            *energy += 0.5 * m * a * a / (h * h) + 0.5 * self.alpha * m * b * b / hd;
            if let Some(g) = gradient.as_deref_mut() {
                g[d] += m * a / (h * h) + self.alpha * m * b / hd;
            }
            if let (Some(hs), Some(f)) = (hessian.as_deref_mut(), dofs.free(d)) {
                hs[self.assembly.diagonal_slot(f)] += m / (h * h) + self.alpha * m / hd;
            }
        }
    }
    fn hessian_is_fixed(&self) -> bool {
        true // M/h² + αM/h_d: fixed for a step length
    }
}

/// Stiffness-proportional damping: 1/(2h_d) (u − p)ᵀ β Kₙ (u − p) on the free dofs.
pub struct StiffnessDamping<'a> {
    /// The velocity's length h_d (s) and origin p (m, all dofs): vₙ₊₁ = (u − p)/h_d.
    pub velocity_form: (f64, &'a [f64]),
    /// β Kₙ on the free system (CSC values of `assembly`'s pattern, N s/m); in a distributed
    /// run, this process's share of it by elements (see [`StepTerm::shared_by_elements`]).
    pub beta_stiffness: &'a [f64],
    /// Pattern of the free system.
    pub assembly: &'a Assembly,
    /// Scratch of 2 × free dofs.
    pub scratch: &'a mut [f64],
}

impl StepTerm for StiffnessDamping<'_> {
    fn name(&self) -> &'static str {
        "stiffness damping"
    }

    fn add(
        &mut self,
        u: &[f64],
        energy: &mut f64,
        mut gradient: Option<&mut [f64]>,
        hessian: Option<&mut [f64]>,
    ) {
        let ((h, origin), k) = (self.velocity_form, self.beta_stiffness);
        let dofs = self.assembly.dofs();
        // Δu and βKₙΔu in the two halves of the scratch buffer: no allocation per call.
        let (delta, product) = self.scratch.split_at_mut(dofs.num_free());
        for (x, &d) in delta.iter_mut().zip(dofs.free_dofs()) {
            *x = u[d] - origin[d];
        }
        self.assembly.multiply(k, delta, product);
        for (i, &d) in dofs.free_dofs().iter().enumerate() {
            *energy += 0.5 * delta[i] * product[i] / h;
            if let Some(g) = gradient.as_deref_mut() {
                g[d] += product[i] / h;
            }
        }
        if let Some(hs) = hessian {
            for (v, kv) in hs.iter_mut().zip(k) {
                *v += kv / h;
            }
        }
    }
    fn hessian_is_fixed(&self) -> bool {
        // βKₙ/h: fixed when Kₙ is, i.e. when the elastic term's Hessian is.
        true
    }
    fn shared_by_elements(&self) -> bool {
        // Kₙ is assembled from the elastic energy's elements (and nodal parts), as that is.
        true
    }
}
