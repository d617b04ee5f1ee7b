//! The ice–ice contact of one step: its candidates' energy, gradient and Hessian, friction
//! frozen for the step, and the pairs anticipated before they touch.

use super::{Candidate, IceContact};
use crate::physics::contact::friction_terms;
use crate::physics::contact_forces::{ContactForces, SolveContact};
use crate::physics::term::{LagChange, StepTerm};
use nalgebra::{Matrix3, Vector3};

/// The ice–ice contact candidates of a step and where their 12 × 12 blocks go.
pub struct IceStep<'a> {
    /// The term.
    pub term: &'a IceContact,
    /// Rest positions (m).
    pub rest: &'a [Vector3<f64>],
    /// Candidate pairs.
    pub candidates: &'a [Candidate],
    /// For each candidate, the CSC value index of each entry of its 12 × 12 block (row-major),
    /// `u32::MAX` where a dof is constrained.
    pub slots: &'a [Vec<u32>],
    /// Candidates whose stiffness enters the Hessian before they penetrate (see
    /// `ContactStep::anticipate`).
    pub anticipated: Vec<bool>,
    /// Friction of the step (dynamic steps with ice friction only).
    pub friction: Option<IceFriction<'a>>,
}

/// A normal (unit), the foot-point weights (βₐ, β_b, β_c) and the normal force λ (N) of a
/// penetrating ice–ice pair, frozen for friction.
pub type FrictionFrame = (Vector3<f64>, [f64; 3], f64);

/// Ice–ice friction data frozen for a step.
pub struct IceFriction<'a> {
    /// Time step (s).
    pub dt: f64,
    /// Displacement at the start of the step (m).
    pub previous: &'a [f64],
    /// Per candidate, its frame if it penetrates.
    pub frames: Vec<Option<FrictionFrame>>,
}

impl<'a> IceStep<'a> {
    /// Friction frames of the pairs penetrating at `u`.
    pub fn friction_frames(&self, rest: &[Vector3<f64>], u: &[f64]) -> Vec<Option<FrictionFrame>> {
        let mut frames = vec![None; self.candidates.len()];
        self.term
            .for_each_closest(rest, u, self.candidates, |m, g, dg| {
                if let Some((_, slope, _)) = self.term.penalty(g) {
                    let n = Vector3::new(dg[0], dg[1], dg[2]);
                    let beta = [1, 2, 3]
                        .map(|k| -n.dot(&Vector3::new(dg[3 * k], dg[3 * k + 1], dg[3 * k + 2])));
                    let normal_force = -self.term.stiffness * self.candidates[m].area * slope;
                    frames[m] = Some((n, beta, normal_force));
                }
            });
        frames
    }

    /// Friction frames at `previous` (the start of the step) with each normal force
    /// extrapolated linearly in time from `earlier` (one step before, m): λ = max(0, 2 λ(uₙ) −
    /// λ(uₙ₋₁)), as [`crate::physics::contact::ContactStep::extrapolate_lagged`] does for obstacles.
    pub fn extrapolated_friction_frames(
        &self,
        rest: &[Vector3<f64>],
        previous: &[f64],
        earlier: &[f64],
    ) -> Vec<Option<FrictionFrame>> {
        let mut frames = self.friction_frames(rest, previous);
        let before = self.friction_frames(rest, earlier);
        for (frame, b) in frames.iter_mut().zip(&before) {
            if let Some(frame) = frame {
                frame.2 = (2.0 * frame.2 - b.map_or(0.0, |b| b.2)).max(0.0);
            }
        }
        frames
    }

    /// Re-lags the friction frames to `u`; returns the largest change of a normal force and
    /// the largest normal force (N; 0 without friction).
    pub fn relag_friction(&mut self, u: &[f64]) -> LagChange {
        if self.friction.is_none() {
            return LagChange::default();
        }
        let new = self.friction_frames(self.rest, u);
        let lam = |f: &Option<FrictionFrame>| f.map_or(0.0, |x| x.2);
        let scale = new.iter().map(lam).fold(0.0f64, f64::max);
        let Some(fr) = self.friction.as_mut() else {
            return LagChange::default();
        };
        let change = new
            .iter()
            .zip(&fr.frames)
            .map(|(a, b)| (lam(a) - lam(b)).abs())
            .fold(0.0f64, f64::max);
        fr.frames = new;
        LagChange { change, scale }
    }

    /// Friction energy (J), adding gradient, Hessian and forces.
    fn add_friction(
        &self,
        u: &[f64],
        mut gradient: Option<&mut [f64]>,
        mut hessian: Option<&mut [f64]>,
        mut forces: Option<&mut [f64]>,
    ) -> f64 {
        let Some(fr) = &self.friction else { return 0.0 };
        let mut energy = 0.0;
        let eps = self.term.smoothing_velocity * fr.dt;
        for (m, frame) in fr.frames.iter().enumerate() {
            let Some((n, beta, lambda)) = frame else {
                continue;
            };
            let nodes = IceContact::pair_nodes(&self.candidates[m]);
            let w = [1.0, -beta[0], -beta[1], -beta[2]];
            let rel: Vector3<f64> = (0..4)
                .map(|k| {
                    let i = nodes[k];
                    w[k] * Vector3::from_fn(|a, _| u[3 * i + a] - fr.previous[3 * i + a])
                })
                .sum();
            let tangent = Matrix3::identity() - n * n.transpose();
            let y = tangent * rel;
            let (f0, g_y, h_y) = friction_terms(self.term.friction * lambda, &y, &tangent, eps);
            if self.term.counts_energy(&self.candidates[m]) {
                energy += f0;
            }
            for k in 0..4 {
                for a in 0..3 {
                    let d = 3 * nodes[k] + a;
                    if let Some(g) = gradient.as_deref_mut() {
                        g[d] += w[k] * g_y[a];
                    }
                    if let Some(f) = forces.as_deref_mut() {
                        f[d] -= w[k] * g_y[a];
                    }
                }
            }
            if let (Some(hs), Some(slots)) = (hessian.as_deref_mut(), self.slots.get(m)) {
                for r in 0..12 {
                    for col in 0..12 {
                        let slot = slots[12 * r + col];
                        if slot != u32::MAX {
                            hs[slot as usize] += w[r / 3] * w[col / 3] * h_y[(r % 3, col % 3)];
                        }
                    }
                }
            }
        }
        energy
    }

    /// Marks candidates that do not penetrate at `u` but would at `trial`; returns whether any
    /// was newly marked.
    pub fn anticipate_pairs(&mut self, u: &[f64], trial: &[f64]) -> bool {
        let rest = self.rest;
        if self.anticipated.is_empty() {
            self.anticipated = vec![false; self.candidates.len()];
        }
        let mut now = vec![false; self.candidates.len()];
        let term = self.term;
        term.for_each_closest(rest, u, self.candidates, |m, g, _| {
            now[m] = term.penalty(g).is_some()
        });
        let mut changed = false;
        let anticipated = &mut self.anticipated;
        term.for_each_closest(rest, trial, self.candidates, |m, g, _| {
            if term.penalty(g).is_some() && !now[m] && !anticipated[m] {
                anticipated[m] = true;
                changed = true;
            }
        });
        changed
    }

    /// Adds k Aₚ (g − δ) ∇g for the anticipated pairs still short of the penalty's onset δ at
    /// `u` (see `Potential::add_anticipated_gradient`); returns whether there was any.
    pub fn add_anticipated_pair_gradient(&self, u: &[f64], gradient: &mut [f64]) -> bool {
        if !self.anticipated.contains(&true) {
            return false;
        }
        let rest = self.rest;
        let mut any = false;
        self.term
            .for_each_closest(rest, u, self.candidates, |m, gap, dg| {
                if self.term.penalty(gap).is_none() && self.anticipated[m] {
                    let c = &self.candidates[m];
                    let ka = self.term.stiffness * c.area;
                    let nodes = IceContact::pair_nodes(c);
                    let beyond = gap - self.term.onset();
                    for (k, dgk) in dg.iter().enumerate() {
                        gradient[3 * nodes[k / 3] + k % 3] += ka * beyond * dgk;
                    }
                    any = true;
                }
            });
        any
    }

    /// Contact energy (J) at `u`, adding gradient, Hessian and, if asked, the forces on the ice.
    pub fn evaluate(
        &self,
        u: &[f64],
        mut gradient: Option<&mut [f64]>,
        mut hessian: Option<&mut [f64]>,
        mut forces: Option<&mut ContactForces>,
    ) -> f64 {
        let rest = self.rest;
        let mut energy = 0.0;
        let anticipated = &self.anticipated;
        self.term
            .for_each_closest(rest, u, self.candidates, |m, gap, dg| {
                let c = &self.candidates[m];
                let ka = self.term.stiffness * c.area;
                let nodes = IceContact::pair_nodes(c);
                let penalty = self.term.penalty(gap);
                if let Some((phi, slope, _)) = penalty {
                    if self.term.counts_energy(c) {
                        energy += ka * phi;
                    }
                    for (k, dgk) in dg.iter().enumerate() {
                        let d = 3 * nodes[k / 3] + k % 3;
                        if let Some(gr) = gradient.as_deref_mut() {
                            gr[d] += ka * slope * dgk;
                        }
                        if let Some(f) = forces.as_deref_mut() {
                            f.normal[d] -= ka * slope * dgk;
                        }
                    }
                }
                // Anticipated pairs take the full stiffness (they are about to be pressed).
                let curvature = match penalty {
                    Some((_, _, c2)) if !anticipated.get(m).is_some_and(|a| *a) => c2,
                    None if !anticipated.get(m).is_some_and(|a| *a) => 0.0,
                    _ => 1.0,
                };
                if let (Some(hs), Some(slots), true) =
                    (hessian.as_deref_mut(), self.slots.get(m), curvature > 0.0)
                {
                    for r in 0..12 {
                        for col in 0..12 {
                            let s = slots[12 * r + col];
                            if s != u32::MAX {
                                hs[s as usize] += ka * curvature * dg[r] * dg[col];
                            }
                        }
                    }
                }
            });
        energy + self.add_friction(u, gradient, hessian, forces.map(|f| &mut f.friction[..]))
    }
}

impl StepTerm for IceStep<'_> {
    fn name(&self) -> &'static str {
        "ice–ice contact"
    }

    fn add(
        &mut self,
        u: &[f64],
        energy: &mut f64,
        gradient: Option<&mut [f64]>,
        hessian: Option<&mut [f64]>,
    ) {
        *energy += self.evaluate(u, gradient, hessian, None);
    }
    fn anticipate(&mut self, u: &[f64], trial: &[f64]) -> bool {
        self.anticipate_pairs(u, trial)
    }
    fn forget_anticipated(&mut self) {
        self.anticipated.clear();
    }
    fn add_anticipated_gradient(&self, u: &[f64], gradient: &mut [f64]) -> bool {
        self.add_anticipated_pair_gradient(u, gradient)
    }
    fn relag(&mut self, u: &[f64]) -> LagChange {
        self.relag_friction(u)
    }
    fn as_contact(&self) -> Option<&dyn SolveContact> {
        Some(self)
    }
}

impl SolveContact for IceStep<'_> {
    fn add_contact_forces(&self, u: &[f64], forces: &mut ContactForces) {
        self.evaluate(u, None, None, Some(forces));
    }
}
