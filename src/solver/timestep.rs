//! The potentials Newton minimises in one step: the backward-Euler incremental potential and
//! the static total potential energy.
//!
//! Backward Euler, for displacements u and velocities v at step n and a step h:
//!
//! ```text
//! E(u) = Σₑ Wₑ(u) − f·u + 1/(2h²) (u − û)ᵀ M (u − û) + 1/(2h) (u − uₙ)ᵀ D (u − uₙ),
//! û = uₙ + h vₙ,   D = α M + β Kₙ,   vₙ₊₁ = (uₙ₊₁ − uₙ)/h,
//! ```
//!
//! whose stationarity condition is exactly M (vₙ₊₁ − vₙ)/h = f − ∇W(uₙ₊₁) − D vₙ₊₁. The damping
//! stiffness Kₙ is the elastic Hessian at the start of the step, so the damping term is a fixed
//! quadratic and the step stays a minimisation.

use super::newton::Potential;
use crate::assembly::Assembly;
use crate::physics::contact::{friction_terms, ContactForces, ContactStep};
use crate::physics::ice_contact::{Candidate, IceContact};
use crate::physics::Model;
use nalgebra::{Matrix3, Vector3};

/// Inertia and damping data of a dynamic step.
pub struct Inertia<'a> {
    /// Time step h (s).
    pub dt: f64,
    /// Predictor û = uₙ + h vₙ (m), all dofs.
    pub predictor: &'a [f64],
    /// Displacement uₙ at the start of the step (m), all dofs.
    pub previous: &'a [f64],
    /// Mass-proportional damping α (1/s).
    pub alpha: f64,
    /// β Kₙ on the free system (CSC values), if stiffness damping is on.
    pub beta_stiffness: Option<&'a [f64]>,
}

/// The potential of one step; static when `inertia` is `None`.
pub struct StepPotential<'a> {
    /// The mechanics.
    pub model: &'a Model,
    /// Pattern of the free system.
    pub assembly: &'a Assembly,
    /// Dynamic terms.
    pub inertia: Option<Inertia<'a>>,
    /// Per-element energy buffer (J), length = number of elements.
    pub element_energy: &'a mut Vec<f64>,
    /// Scratch for the damping product, length = 2 × free dofs.
    pub scratch: &'a mut [f64],
    /// Contact for this step, if the model has obstacles.
    pub contact: Option<ContactStep<'a>>,
    /// CSC value indices of each node's 3 × 3 block (for contact), indexed by node.
    pub block_slots: &'a [[u32; 9]],
    /// Whether element stiffnesses are projected to be positive semi-definite.
    pub project: bool,
    /// Ice–ice contact pairs of this step, if the mesh has several parts.
    pub ice: Option<IceStep<'a>>,
    /// Wall time spent evaluating contact (obstacles and ice–ice narrow phase) (s).
    pub t_contact: f64,
    /// The obstacle contact's 3 × 3 Hessian blocks (node, block) in the last assembled Hessian,
    /// for [`Potential::update_contact_hessian`].
    pub contact_blocks: Vec<(usize, Matrix3<f64>)>,
}

/// The ice–ice contact candidates of a step and where their 12 × 12 blocks go.
pub struct IceStep<'a> {
    /// The term.
    pub term: &'a IceContact,
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

impl IceStep<'_> {
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
    /// λ(uₙ₋₁)), as [`ContactStep::extrapolate_lagged`] does for obstacles.
    pub fn extrapolated_friction_frames(
        &self,
        rest: &[Vector3<f64>],
        previous: &[f64],
        earlier: &[f64],
    ) -> Vec<Option<FrictionFrame>> {
        let mut frames = self.friction_frames(rest, previous);
        let before = self.friction_frames(rest, earlier);
        for (frame, b) in frames.iter_mut().flatten().zip(&before) {
            frame.2 = (2.0 * frame.2 - b.map_or(0.0, |b| b.2)).max(0.0);
        }
        frames
    }

    /// Re-lags the friction frames to `u`; returns the largest change of a normal force relative
    /// to the largest normal force (0 without friction).
    pub fn relag(&mut self, rest: &[Vector3<f64>], u: &[f64]) -> f64 {
        if self.friction.is_none() {
            return 0.0;
        }
        let new = self.friction_frames(rest, u);
        let lam = |f: &Option<FrictionFrame>| f.map_or(0.0, |x| x.2);
        let scale = new.iter().map(lam).fold(0.0f64, f64::max);
        let Some(fr) = self.friction.as_mut() else {
            return 0.0;
        };
        let change = new
            .iter()
            .zip(&fr.frames)
            .map(|(a, b)| (lam(a) - lam(b)).abs())
            .fold(0.0f64, f64::max);
        fr.frames = new;
        if scale > 0.0 {
            change / scale
        } else {
            0.0
        }
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
            energy += f0;
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
    pub fn anticipate(
        &mut self,
        rest: &[nalgebra::Vector3<f64>],
        u: &[f64],
        trial: &[f64],
    ) -> bool {
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
    pub fn add_anticipated_gradient(
        &self,
        rest: &[nalgebra::Vector3<f64>],
        u: &[f64],
        gradient: &mut [f64],
    ) -> bool {
        if !self.anticipated.contains(&true) {
            return false;
        }
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
    pub fn add(
        &self,
        rest: &[nalgebra::Vector3<f64>],
        u: &[f64],
        mut gradient: Option<&mut [f64]>,
        mut hessian: Option<&mut [f64]>,
        mut forces: Option<&mut ContactForces>,
    ) -> f64 {
        let mut energy = 0.0;
        let anticipated = &self.anticipated;
        self.term
            .for_each_closest(rest, u, self.candidates, |m, gap, dg| {
                let c = &self.candidates[m];
                let ka = self.term.stiffness * c.area;
                let nodes = IceContact::pair_nodes(c);
                let penalty = self.term.penalty(gap);
                if let Some((phi, slope, _)) = penalty {
                    energy += ka * phi;
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

impl StepPotential<'_> {
    /// Energy of the non-elastic terms, adding their gradient and Hessian if given.
    fn add_other_terms(
        &mut self,
        u: &[f64],
        mut gradient: Option<&mut [f64]>,
        mut hessian: Option<&mut [f64]>,
    ) -> f64 {
        let model = self.model;
        let mut energy = 0.0;
        for (d, (ud, f)) in u.iter().zip(&model.external_force).enumerate() {
            energy -= f * ud;
            if let Some(g) = gradient.as_deref_mut() {
                g[d] -= f;
            }
        }
        let contact_start = std::time::Instant::now();
        if let Some(contact) = &self.contact {
            let slots = self.block_slots;
            energy += match hessian.as_deref_mut() {
                Some(hs) => {
                    let blocks = &mut self.contact_blocks;
                    blocks.clear();
                    let mut add = |node: usize, block: &Matrix3<f64>| {
                        add_block(hs, &slots[node], block, 1.0);
                        blocks.push((node, *block));
                    };
                    contact.evaluate(u, gradient.as_deref_mut(), Some(&mut add), None)
                }
                None => contact.evaluate(u, gradient.as_deref_mut(), None, None),
            };
        }
        if let Some(ice) = &self.ice {
            energy += ice.add(
                &model.mesh.rest,
                u,
                gradient.as_deref_mut(),
                hessian.as_deref_mut(),
                None,
            );
        }
        if self.contact.is_some() || self.ice.is_some() {
            self.t_contact += contact_start.elapsed().as_secs_f64();
        }
        let Some(inertia) = &self.inertia else {
            return energy;
        };
        let h = inertia.dt;
        let dofs = self.assembly.dofs();
        for d in 0..u.len() {
            let m = model.mass[d / 3];
            let a = u[d] - inertia.predictor[d];
            let b = u[d] - inertia.previous[d];
            energy += 0.5 * m * a * a / (h * h) + 0.5 * inertia.alpha * m * b * b / h;
            if let Some(g) = gradient.as_deref_mut() {
                g[d] += m * a / (h * h) + inertia.alpha * m * b / h;
            }
            if let (Some(hs), Some(f)) = (hessian.as_deref_mut(), dofs.free(d)) {
                hs[self.assembly.diagonal_slot(f)] += m / (h * h) + inertia.alpha * m / h;
            }
        }
        if let Some(k) = inertia.beta_stiffness {
            // Δu and βKₙΔu in the two halves of the scratch buffer: no allocation per call.
            let (delta, product) = self.scratch.split_at_mut(dofs.num_free());
            for (x, &d) in delta.iter_mut().zip(dofs.free_dofs()) {
                *x = u[d] - inertia.previous[d];
            }
            self.assembly.multiply(k, delta, product);
            for (i, &d) in dofs.free_dofs().iter().enumerate() {
                energy += 0.5 * delta[i] * product[i] / h;
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
        energy
    }

    /// Potential at `u`; overwrites `gradient` and adds the Hessian into `hessian` if given.
    fn assemble_all(
        &mut self,
        u: &[f64],
        gradient: &mut [f64],
        mut hessian: Option<&mut [f64]>,
    ) -> f64 {
        gradient.fill(0.0);
        let project = self.project;
        let el = &self.model.elasticity;
        let tets = &self.model.mesh.tets;
        self.assembly.assemble(
            |e, with_h, out| el.element_with(tets, u, e, with_h, project, out),
            self.element_energy,
            gradient,
            hessian.as_deref_mut(),
        );
        let elastic: f64 = self.element_energy.iter().sum();
        elastic + self.add_other_terms(u, Some(gradient), hessian)
    }

    /// Elastic energy Σ Wₑ (J) at `u`.
    pub fn elastic_energy(&mut self, u: &[f64]) -> f64 {
        let el = &self.model.elasticity;
        let tets = &self.model.mesh.tets;
        self.assembly.energies(
            |e, out| el.element(tets, u, e, false, out),
            self.element_energy,
        );
        // Summed in order so the result does not depend on thread scheduling.
        self.element_energy.iter().sum()
    }
}

/// Adds `sign` × a node's 3 × 3 `block` into the CSC values `hessian` at the node's `slots`.
fn add_block(hessian: &mut [f64], slots: &[u32; 9], block: &Matrix3<f64>, sign: f64) {
    for (k, s) in slots.iter().enumerate() {
        if *s != u32::MAX {
            hessian[*s as usize] += sign * block[(k / 3, k % 3)];
        }
    }
}

impl Potential for StepPotential<'_> {
    fn update_contact_hessian(&mut self, u: &[f64], hessian: &mut [f64]) -> bool {
        let Some(contact) = &self.contact else {
            return false;
        };
        let start = std::time::Instant::now();
        let mut blocks = Vec::with_capacity(self.contact_blocks.len());
        contact.evaluate(u, None, Some(&mut |node, b| blocks.push((node, *b))), None);
        let changed = blocks != self.contact_blocks;
        if changed {
            let slots = self.block_slots;
            for (node, block) in &self.contact_blocks {
                add_block(hessian, &slots[*node], block, -1.0);
            }
            for (node, block) in &blocks {
                add_block(hessian, &slots[*node], block, 1.0);
            }
            self.contact_blocks = blocks;
        }
        self.t_contact += start.elapsed().as_secs_f64();
        changed
    }

    fn anticipate(&mut self, u: &[f64], trial: &[f64]) -> bool {
        let obstacles = self
            .contact
            .as_mut()
            .is_some_and(|c| c.anticipate(u, trial));
        let rest = &self.model.mesh.rest;
        let ice = self
            .ice
            .as_mut()
            .is_some_and(|ice| ice.anticipate(rest, u, trial));
        obstacles || ice
    }

    fn add_anticipated_gradient(&self, u: &[f64], gradient: &mut [f64]) -> bool {
        let rest = &self.model.mesh.rest;
        let obstacles = self
            .contact
            .as_ref()
            .is_some_and(|c| c.add_anticipated_gradient(u, gradient));
        let ice = self
            .ice
            .as_ref()
            .is_some_and(|ice| ice.add_anticipated_gradient(rest, u, gradient));
        obstacles || ice
    }

    fn forget_anticipated(&mut self) {
        if let Some(c) = self.contact.as_mut() {
            c.anticipated.clear();
        }
        if let Some(ice) = self.ice.as_mut() {
            ice.anticipated.clear();
        }
    }

    fn project_hessian(&mut self) -> bool {
        !std::mem::replace(&mut self.project, true)
    }

    fn energy(&mut self, u: &[f64]) -> f64 {
        self.elastic_energy(u) + self.add_other_terms(u, None, None)
    }

    fn evaluate(&mut self, u: &[f64], gradient: &mut [f64], hessian: &mut [f64]) -> f64 {
        hessian.fill(0.0);
        self.assemble_all(u, gradient, Some(hessian))
    }

    fn gradient(&mut self, u: &[f64], gradient: &mut [f64]) -> f64 {
        self.assemble_all(u, gradient, None)
    }
}
