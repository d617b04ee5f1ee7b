//! Penalty contact of the ice with rigid obstacles, with smoothed Coulomb friction.
//!
//! Against a plane with point p and unit normal n (pointing out of the obstacle), a boundary
//! node i has the gap g = (xᵢ − p)·n and, when penetrating, stores the energy ½ k Aᵢ g²: a
//! contact pressure k·depth (k in N/m³) on the node's area share Aᵢ — a third of each boundary
//! triangle around it, projected on the plane and counted only where the triangle faces it, so
//! that a flat face resting on a plane carries exactly its area and side faces carry nothing.
//! The areas are those of the rest configuration (obstacles translate, so they are constants):
//! the penalty is then a fixed conservative energy with exact gradient k Aᵢ g n and Hessian
//! k Aᵢ n nᵀ, and a stiff penalty stays stable at large steps. (A fragment that tips over keeps
//! its rest areas; fine for the small rotations of ice in a container.)
//!
//! Friction (dynamic steps only) is the smoothed Coulomb potential of incremental potential
//! contact (Li et al. 2020): with the tangential slip of the step y = (I − n nᵀ)(Δuᵢ − v_obs h),
//! D = α λ f₀(|y|), whose force has magnitude α λ f₁(|y|) ≤ α λ — exactly α λ once the slip
//! exceeds ε = ε_v h, growing smoothly from zero below (stick, with creep slower than ε_v). The
//! normal force λ = k Aᵢ max(0, −g) is lagged: the step is solved with λ from the start of the
//! step, then re-solved with λ from its end until λ settles (a few rounds at most), so friction
//! acts with the normal force of the end of the step while each solve stays a minimisation.

use super::Region;
use crate::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

/// Shape of a rigid obstacle at t = 0 (it moves rigidly with its velocity).
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// The solid half-space behind the plane through `point` with outward unit `normal`.
    HalfSpace {
        point: Vector3<f64>,
        normal: Vector3<f64>,
    },
    /// An open-top box container whose inner space is `inner`: a floor at `inner.min.z` and
    /// four walls; the ice lives inside. The top (`inner.max.z`) is open.
    Container { inner: Region },
}

/// One obstacle with its contact parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Obstacle {
    /// Geometry at t = 0.
    pub shape: Shape,
    /// Rigid velocity (m/s).
    pub velocity: Vector3<f64>,
    /// Penalty stiffness k (N/m³: contact pressure per metre of penetration).
    pub stiffness: f64,
    /// Coulomb friction coefficient α.
    pub friction: f64,
}

/// One contact plane of an obstacle at a given time.
#[derive(Clone, Copy, Debug)]
pub struct Plane {
    /// A point on the plane at t = 0 (m).
    pub point: Vector3<f64>,
    /// How far the plane has moved along its normal since t = 0 (m).
    pub offset: f64,
    /// Unit normal pointing out of the obstacle.
    pub normal: Vector3<f64>,
    /// Penalty stiffness (N/m³).
    pub stiffness: f64,
    /// Friction coefficient.
    pub friction: f64,
    /// Obstacle velocity (m/s).
    pub velocity: Vector3<f64>,
}

impl Obstacle {
    /// Appends the obstacle's contact planes at time `t` (s).
    pub fn planes_into(&self, t: f64, out: &mut Vec<Plane>) {
        let plane = |point: Vector3<f64>, normal: Vector3<f64>| Plane {
            point,
            offset: t * self.velocity.dot(&normal),
            normal,
            stiffness: self.stiffness,
            friction: self.friction,
            velocity: self.velocity,
        };
        match &self.shape {
            Shape::HalfSpace { point, normal } => out.push(plane(*point, *normal)),
            Shape::Container { inner } => {
                out.push(plane(inner.min, Vector3::z()));
                for a in 0..2 {
                    let e = Vector3::ith(a, 1.0);
                    out.push(plane(inner.min, e));
                    out.push(plane(inner.max, -e));
                }
            }
        }
    }

    /// Number of contact planes.
    pub fn num_planes(&self) -> usize {
        match self.shape {
            Shape::HalfSpace { .. } => 1,
            Shape::Container { .. } => 5,
        }
    }
}

/// The contact term: obstacles, the boundary nodes that can touch them and their areas.
#[derive(Clone, Debug)]
pub struct Contact {
    /// Obstacles.
    pub obstacles: Vec<Obstacle>,
    /// Boundary nodes.
    pub nodes: Vec<usize>,
    /// Rest area share of each boundary node (m²), all faces around it.
    pub area: Vec<f64>,
    /// Boundary triangles (outward), as indices into `nodes`.
    pub faces: Vec<[usize; 3]>,
    /// Area share per (boundary node, plane) (m²), see [`Contact::facing_areas`].
    pub areas: Vec<f64>,
    /// Friction smoothing velocity ε_v (m/s): below it the friction force ramps up from zero.
    pub smoothing_velocity: f64,
}

/// Default penalty stiffness (N/m³): 10 E / h, with h the mean edge length of the boundary
/// triangles. A node's elastic stiffness is about E h and its penalty stiffness k A ≈ k h²/3
/// (A its area share), so the penalty is a few times stiffer than the ice under it:
/// penetration stays below the elastic deformation the contact causes (and far below a
/// micrometre for ice under its own weight), while Newton still converges in a few iterations
/// when contacts open and close.
pub fn default_stiffness(mesh: &TetMesh, young: f64) -> f64 {
    let faces = mesh.boundary_faces();
    let mut sum = 0.0;
    for f in &faces {
        let [a, b, c] = f.nodes.map(|i| mesh.rest[i]);
        sum += (b - a).norm() + (c - b).norm() + (a - c).norm();
    }
    let h = sum / (3.0 * faces.len().max(1) as f64);
    10.0 * young / h
}

impl Contact {
    /// Contact of `mesh`'s boundary with `obstacles`.
    pub fn new(mesh: &TetMesh, obstacles: Vec<Obstacle>, smoothing_velocity: f64) -> Self {
        let mut area = vec![0.0; mesh.num_nodes()];
        for f in mesh.boundary_faces() {
            let [a, b, c] = f.nodes.map(|i| mesh.rest[i]);
            let share = 0.5 * (b - a).cross(&(c - a)).norm() / 3.0;
            for &v in &f.nodes {
                area[v] += share;
            }
        }
        let nodes: Vec<usize> = (0..mesh.num_nodes()).filter(|&i| area[i] > 0.0).collect();
        let mut index = vec![usize::MAX; mesh.num_nodes()];
        for (k, &i) in nodes.iter().enumerate() {
            index[i] = k;
        }
        let faces = mesh
            .boundary_faces()
            .iter()
            .map(|f| f.nodes.map(|i| index[i]))
            .collect();
        let area = nodes.iter().map(|&i| area[i]).collect();
        let mut contact = Contact {
            obstacles,
            nodes,
            area,
            faces,
            areas: Vec::new(),
            smoothing_velocity,
        };
        contact.areas = contact.facing_areas(
            &mesh.rest,
            &vec![0.0; 3 * mesh.num_nodes()],
            &contact.planes(0.0),
        );
        contact
    }

    /// All contact planes at time `t` (s).
    pub fn planes(&self, t: f64) -> Vec<Plane> {
        let mut planes = Vec::with_capacity(self.obstacles.iter().map(Obstacle::num_planes).sum());
        for o in &self.obstacles {
            o.planes_into(t, &mut planes);
        }
        planes
    }

    /// Area share (m²) of every (boundary node, plane) pair at displacements `u`: a third of
    /// each adjacent boundary triangle's area, times the cosine between its inward normal and
    /// the plane normal where positive (the triangle faces the plane), else nothing.
    pub fn facing_areas(&self, rest: &[Vector3<f64>], u: &[f64], planes: &[Plane]) -> Vec<f64> {
        let np = planes.len();
        let mut areas = vec![0.0; self.nodes.len() * np];
        for f in &self.faces {
            let [a, b, c] = f.map(|k| rest[self.nodes[k]] + displacement(u, self.nodes[k]));
            let area_normal = 0.5 * (b - a).cross(&(c - a)); // outward, |.| = area
            for (j, p) in planes.iter().enumerate() {
                let facing = -area_normal.dot(&p.normal);
                if facing > 0.0 {
                    for &k in f {
                        areas[k * np + j] += facing / 3.0;
                    }
                }
            }
        }
        areas
    }
}

fn displacement(u: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2])
}

impl Plane {
    /// Gap of node `i` (m, negative when penetrating): (Xᵢ − p₀)·n + uᵢ·n − offset. Splitting
    /// off the rest part keeps the gap accurate to round-off of the displacement rather than
    /// of the position; with k Aᵢ ~ 1e10 N/m, 1e-17 m of position round-off would already be
    /// a 1e-7 N force error.
    fn gap(&self, rest: &[Vector3<f64>], u: &[f64], i: usize) -> f64 {
        (rest[i] - self.point).dot(&self.normal)
            + (displacement(u, i).dot(&self.normal) - self.offset)
    }
}

/// Smoothed friction profile: f₀ (potential), f₁ = f₀′ (force fraction) and f₁′, for slip s ≥ 0
/// and smoothing length ε.
pub(crate) fn friction_profile(s: f64, eps: f64) -> (f64, f64, f64) {
    if s < eps {
        let r = s / eps;
        (
            eps * (-r * r * r / 3.0 + r * r + 1.0 / 3.0),
            -r * r + 2.0 * r,
            (2.0 - 2.0 * r) / eps,
        )
    } else {
        (s, 1.0, 0.0)
    }
}

/// Receives a node's 3 × 3 Hessian block: `(node, block)`.
pub type BlockSink<'a> = &'a mut dyn FnMut(usize, &Matrix3<f64>);

/// The contact data fixed during one step.
pub struct ContactStep<'a> {
    /// The term.
    pub contact: &'a Contact,
    /// Rest positions (m).
    pub rest: &'a [Vector3<f64>],
    /// Planes at the end of the step.
    pub planes: Vec<Plane>,
    /// Time step (s) — friction acts only in dynamic steps.
    pub dt: Option<f64>,
    /// Displacement at the start of the step (m).
    pub previous: &'a [f64],
    /// Lagged normal force per (boundary node, plane) (N), for friction.
    pub lagged: Vec<f64>,
    /// (Boundary node, plane) pairs whose penalty stiffness enters the Hessian although they
    /// do not penetrate yet, because a Newton step was about to push them through (see
    /// [`ContactStep::anticipate`]). Empty until then.
    pub anticipated: Vec<bool>,
}

/// Per-node contact forces on the ice (N), for output.
#[derive(Clone, Debug, Default)]
pub struct ContactForces {
    /// Normal (penalty) force per node, 3 per node.
    pub normal: Vec<f64>,
    /// Friction force per node, 3 per node.
    pub friction: Vec<f64>,
}

impl<'a> ContactStep<'a> {
    /// The contact of a step from `t_start` to `t_end` (s) starting at displacement `previous`
    /// (m), with the friction normal force taken there; `dt` is `None` for a static step (no
    /// friction).
    pub fn new(
        contact: &'a Contact,
        rest: &'a [Vector3<f64>],
        previous: &'a [f64],
        t_start: f64,
        t_end: f64,
        dt: Option<f64>,
    ) -> Self {
        let mut step = ContactStep {
            contact,
            rest,
            planes: contact.planes(t_start),
            dt,
            previous,
            lagged: Vec::new(),
            anticipated: Vec::new(),
        };
        step.lagged = step.normal_forces(previous);
        step.planes = contact.planes(t_end);
        step
    }

    /// Normal force magnitude k Aᵢ max(0, −g) (N) of every (boundary node, plane) pair at `u`.
    pub fn normal_forces(&self, u: &[f64]) -> Vec<f64> {
        let np = self.planes.len();
        let mut out = Vec::with_capacity(self.contact.nodes.len() * np);
        for (k, &i) in self.contact.nodes.iter().enumerate() {
            for (j, p) in self.planes.iter().enumerate() {
                let g = p.gap(self.rest, u, i);
                out.push(if g < 0.0 {
                    -p.stiffness * self.contact.areas[k * np + j] * g
                } else {
                    0.0
                });
            }
        }
        out
    }

    /// Whether any obstacle has friction (then the lagged normal force matters).
    pub fn has_friction(&self) -> bool {
        self.dt.is_some() && self.planes.iter().any(|p| p.friction > 0.0)
    }

    /// Marks the pairs that do not penetrate at `u` but would at `trial` (the full Newton
    /// step), so that the next Hessian holds their penalty stiffness: without it Newton sees a
    /// node resting at zero gap, or falling towards the floor, as free, steps it centimetres
    /// into the obstacle, and the line search must cut the step by the stiffness ratio (1e-8).
    /// Returns whether any pair was newly marked.
    pub fn anticipate(&mut self, u: &[f64], trial: &[f64]) -> bool {
        let np = self.planes.len();
        if self.anticipated.is_empty() {
            self.anticipated = vec![false; self.contact.nodes.len() * np];
        }
        let mut changed = false;
        for (k, &i) in self.contact.nodes.iter().enumerate() {
            for (j, p) in self.planes.iter().enumerate() {
                let marked = &mut self.anticipated[k * np + j];
                if !*marked && p.gap(self.rest, trial, i) < 0.0 && p.gap(self.rest, u, i) >= 0.0 {
                    *marked = true;
                    changed = true;
                }
            }
        }
        changed
    }

    /// Contact energy (J) at `u`; adds its gradient and, through `add_block(node, 3×3)`, its
    /// Hessian blocks.
    pub fn evaluate(
        &self,
        u: &[f64],
        mut gradient: Option<&mut [f64]>,
        mut add_block: Option<BlockSink<'_>>,
        mut forces: Option<&mut ContactForces>,
    ) -> f64 {
        let c = self.contact;
        let np = self.planes.len();
        let mut energy = 0.0;
        for (k, &i) in c.nodes.iter().enumerate() {
            let mut g_node = Vector3::zeros();
            let mut h_node = Matrix3::zeros();
            for (j, p) in self.planes.iter().enumerate() {
                let gap = p.gap(self.rest, u, i);
                let ka = p.stiffness * c.areas[k * np + j];
                if gap < 0.0 || self.anticipated.get(k * np + j).is_some_and(|a| *a) {
                    h_node += ka * p.normal * p.normal.transpose();
                }
                if gap < 0.0 {
                    energy += 0.5 * ka * gap * gap;
                    g_node += ka * gap * p.normal;
                    if let Some(f) = forces.as_deref_mut() {
                        for a in 0..3 {
                            f.normal[3 * i + a] -= ka * gap * p.normal[a];
                        }
                    }
                }
                let Some(h) = self.dt else { continue };
                let lambda = self.lagged[k * np + j];
                if lambda <= 0.0 || p.friction <= 0.0 {
                    continue;
                }
                let tangent = Matrix3::identity() - p.normal * p.normal.transpose();
                let du = displacement(u, i) - displacement(self.previous, i);
                let y = tangent * (du - p.velocity * h);
                let s = y.norm();
                let eps = c.smoothing_velocity * h;
                let (f0, f1, f1_prime) = friction_profile(s, eps);
                let scale = p.friction * lambda;
                energy += scale * f0;
                // f₁(s)/s → 2/ε as s → 0.
                let f1_over_s = if s > 1e-14 * eps { f1 / s } else { 2.0 / eps };
                let g_fric = scale * f1_over_s * y;
                g_node += g_fric;
                if let Some(f) = forces.as_deref_mut() {
                    for a in 0..3 {
                        f.friction[3 * i + a] -= g_fric[a];
                    }
                }
                let mut h_fric = scale * f1_over_s * tangent;
                if s > 1e-14 * eps {
                    let yhat = y / s;
                    h_fric += scale * (f1_prime - f1_over_s) * yhat * yhat.transpose();
                }
                h_node += h_fric;
            }
            if let Some(g) = gradient.as_deref_mut() {
                for a in 0..3 {
                    g[3 * i + a] += g_node[a];
                }
            }
            if let Some(add) = add_block.as_deref_mut() {
                if h_node != Matrix3::zeros() {
                    add(i, &h_node);
                }
            }
        }
        energy
    }
}
