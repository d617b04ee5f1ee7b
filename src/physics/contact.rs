//! Penalty contact of the ice with rigid obstacles, with smoothed Coulomb friction.
//!
//! Against a plane with point p and unit normal n (pointing out of the obstacle), a boundary
//! node i has the gap g = (xᵢ − p)·n and, when penetrating, stores the energy ½ k Aᵢ g²: a
//! contact pressure k·depth (k in N/m³) on the node's area share Aᵢ — a third of each boundary
//! triangle's rest area around it, projected on the plane and counted only where the triangle
//! faces it, so that a flat face resting on a plane carries exactly its area and side faces
//! carry nothing. Which way a triangle faces is taken at the start of each step (a tumbling
//! body lands on the faces that are down, not on those that were down at rest), and the areas
//! are then held through the step: each solve minimises a fixed conservative energy with exact
//! gradient k Aᵢ g n and Hessian k Aᵢ n nᵀ, and a stiff penalty stays stable at large steps.
//!
//! Obstacles move rigidly ([`Motion`]): a plane keeps its point and normal on the obstacle and
//! is carried to each time; a turning obstacle's planes turn with it.
//!
//! Friction (dynamic steps only) is the smoothed Coulomb potential of incremental potential
//! contact (Li et al. 2020): with the tangential slip of the step y = (I − n nᵀ)(Δuᵢ − v_obs h),
//! D = α λ f₀(|y|), whose force has magnitude α λ f₁(|y|) ≤ α λ — exactly α λ once the slip
//! exceeds ε = ε_v h, growing smoothly from zero below (stick, with creep slower than ε_v). The
//! normal force λ = k Aᵢ max(0, −g) is lagged: the step is solved with λ extrapolated linearly
//! from the start of the step and the step before it, then re-solved with λ from its end until
//! λ settles (a few rounds at most), so friction acts with the normal force of the end of the
//! step while each solve stays a minimisation.

pub use super::contact_forces::ContactForces;
use super::contact_forces::{SceneContact, SolveContact};
use super::motion::Motion;
use super::obstacle_mesh::ObstacleSurface;
use super::term::{LagChange, NodeRestriction, Remesh, Solve, StepTerm, Term};
use super::Region;
use crate::assembly::Assembly;
use crate::mesh::{BoundaryFace, TetMesh};
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;
use std::time::Instant;

/// Two planes of a mesh obstacle with the same normal whose offsets differ by at most this
/// (m) are the same plane: round-off of the closest-point projection is ~1e-17 m, penetration
/// depths are 1e-7 m and more.
const SAME_PLANE_OFFSET: f64 = 1e-12;

/// Shape of a rigid obstacle at t = 0 (it moves rigidly, see [`Motion`]).
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
    /// A rigid triangle surface (closed and outward oriented, or open with the ice on the side
    /// its normals point to). Each boundary node within reach gets its own plane, through the
    /// closest surface point, per step (see `obstacle_mesh`).
    Mesh { surface: Arc<ObstacleSurface> },
}

/// One obstacle with its contact parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Obstacle {
    /// Geometry at t = 0.
    pub shape: Shape,
    /// Its rigid motion.
    pub motion: Motion,
    /// Penalty stiffness k (N/m³: contact pressure per metre of penetration).
    pub stiffness: f64,
    /// Coulomb friction coefficient α.
    pub friction: f64,
}

/// One contact plane of an obstacle at a given time.
#[derive(Clone, Copy, Debug)]
pub struct Plane {
    /// A point on the plane (m): at t = 0 for an obstacle that only translates, at the
    /// plane's time for one that turns.
    pub point: Vector3<f64>,
    /// How far the plane has moved along its normal since `point` (m).
    pub offset: f64,
    /// Unit normal pointing out of the obstacle.
    pub normal: Vector3<f64>,
    /// Penalty stiffness (N/m³).
    pub stiffness: f64,
    /// Friction coefficient.
    pub friction: f64,
    /// Velocity of the obstacle's centre of rotation (m/s); of all its points if it does not
    /// turn.
    pub velocity: Vector3<f64>,
    /// Angular velocity of the obstacle (rad/s): its point at x moves at `velocity` + `spin`
    /// × (x − `centre`).
    pub spin: Vector3<f64>,
    /// The obstacle's centre of rotation at the plane's time (m).
    pub centre: Vector3<f64>,
    /// The plane on the obstacle at t = 0: a point and the normal.
    origin: (Vector3<f64>, Vector3<f64>),
}

impl Plane {
    /// Velocity (m/s) of the obstacle's point at `x` (m).
    pub fn velocity_at(&self, x: &Vector3<f64>) -> Vector3<f64> {
        if self.spin == Vector3::zeros() {
            self.velocity
        } else {
            self.velocity + self.spin.cross(&(x - self.centre))
        }
    }
}

impl Obstacle {
    /// The plane through `point` with `normal` on this obstacle at t = 0, where the motion
    /// has carried it at time `t` (s).
    fn plane_at(&self, t: f64, point: Vector3<f64>, normal: Vector3<f64>) -> Plane {
        let m = &self.motion;
        let (rotation, centre) = m.placement(t);
        let (point_t, offset, normal_t) = if m.rotates() {
            (m.position(t, &point), 0.0, rotation * normal)
        } else {
            (
                point,
                m.amplitude.integral(t) * m.velocity.dot(&normal),
                normal,
            )
        };
        let a = m.amplitude.at(t);
        Plane {
            point: point_t,
            offset,
            normal: normal_t,
            stiffness: self.stiffness,
            friction: self.friction,
            velocity: a * m.velocity,
            spin: a * m.angular_velocity,
            centre,
            origin: (point, normal),
        }
    }

    /// Appends the obstacle's contact planes at time `t` (s).
    pub fn planes_into(&self, t: f64, out: &mut Vec<Plane>) {
        let plane = |point: Vector3<f64>, normal: Vector3<f64>| self.plane_at(t, point, normal);
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
            Shape::Mesh { .. } => {}
        }
    }

    /// Number of contact planes shared by all nodes (a mesh obstacle has one per node instead).
    pub fn num_planes(&self) -> usize {
        match self.shape {
            Shape::HalfSpace { .. } => 1,
            Shape::Container { .. } => 5,
            Shape::Mesh { .. } => 0,
        }
    }

    /// The surface of a mesh obstacle.
    pub fn surface(&self) -> Option<&ObstacleSurface> {
        match &self.shape {
            Shape::Mesh { surface } => Some(surface),
            _ => None,
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
    /// The boundary triangles (outward node order).
    faces: Vec<[usize; 3]>,
    /// Rest area of each boundary triangle (m²).
    face_areas: Vec<f64>,
    /// Boundary triangles around each boundary node (indices into `faces`).
    node_faces: Vec<Vec<u32>>,
    /// Mean boundary edge length (m): how far from a mesh obstacle a resting node is looked
    /// for, besides the motion of the step.
    pub edge: f64,
    /// Friction smoothing velocity ε_v (m/s): below it the friction force ramps up from zero.
    pub smoothing_velocity: f64,
    /// The largest speed of a mesh obstacle's points near the ice (m/s), bounded over the
    /// ice's rest bounding box: a step's reach includes how far the obstacle moves.
    pub obstacle_speed: f64,
}

/// Default penalty stiffness (N/m³): 10 E / h, with h the mean edge length of the boundary
/// triangles. A node's elastic stiffness is about E h and its penalty stiffness k A ≈ k h²/3
/// (A its area share), so the penalty is a few times stiffer than the ice under it:
/// penetration stays below the elastic deformation the contact causes (and far below a
/// micrometre for ice under its own weight), while Newton still converges in a few iterations
/// when contacts open and close.
pub fn default_stiffness(mesh: &TetMesh, young: f64) -> f64 {
    stiffness_for_edge(mesh.mean_boundary_edge(), young)
}

/// [`default_stiffness`] for the mean boundary edge `edge` (m).
pub fn stiffness_for_edge(edge: f64, young: f64) -> f64 {
    10.0 * young / edge
}

/// What contact needs of the whole boundary that a part of the mesh cannot tell alone.
#[derive(Clone, Copy, Debug)]
pub struct WholeBoundary {
    /// The mean of the boundary triangles' mean edges (m): Σ (perimeter / 3) / faces.
    pub edge: f64,
    /// The mesh's rest bounding box (m).
    pub bounds: (Vector3<f64>, Vector3<f64>),
}

impl WholeBoundary {
    /// The whole boundary of triangles of `perimeters` (m, in the order of
    /// `TetMesh::boundary_faces`) in the bounding box `bounds`.
    pub fn new(perimeters: &[f64], bounds: (Vector3<f64>, Vector3<f64>)) -> Self {
        let edge = perimeters.iter().map(|p| p / 3.0).sum::<f64>() / perimeters.len().max(1) as f64;
        WholeBoundary { edge, bounds }
    }
}

impl Contact {
    /// The contact of the nodes `part` keeps, numbered as in its mesh (a process's share of
    /// a distributed run). Areas, faces and the mean edge stay those of the whole boundary:
    /// a kept node's faces are all in the part's mesh.
    pub fn restricted(&self, part: &NodeRestriction) -> Contact {
        let mut kept = Contact {
            obstacles: self.obstacles.clone(),
            nodes: Vec::new(),
            area: Vec::new(),
            faces: Vec::new(),
            face_areas: Vec::new(),
            node_faces: Vec::new(),
            ..*self
        };
        let mut face_index = vec![u32::MAX; self.faces.len()];
        for (k, &i) in self.nodes.iter().enumerate() {
            let Some(local) = part.kept(i) else { continue };
            kept.nodes.push(local);
            kept.area.push(self.area[k]);
            let faces = self.node_faces[k].iter().map(|&f| {
                let f = f as usize;
                if face_index[f] == u32::MAX {
                    face_index[f] = kept.faces.len() as u32;
                    kept.faces.push(self.faces[f].map(|n| part.local(n)));
                    kept.face_areas.push(self.face_areas[f]);
                }
                face_index[f]
            });
            kept.node_faces.push(faces.collect());
        }
        kept
    }

    /// Contact of `mesh`'s boundary with `obstacles`.
    pub fn new(mesh: &TetMesh, obstacles: Vec<Obstacle>, smoothing_velocity: f64) -> Self {
        let boundary = mesh.boundary_faces();
        let whole = WholeBoundary::new(&mesh.perimeters(&boundary), mesh.bounding_box());
        Contact::on_boundary((mesh, &boundary), whole, obstacles, smoothing_velocity)
    }

    /// Contact of the faces `boundary` of `mesh` (on the whole mesh's boundary, of which
    /// `mesh` may be a process's part: `whole`) with `obstacles`.
    pub fn on_boundary(
        (mesh, boundary): (&TetMesh, &[BoundaryFace]),
        whole: WholeBoundary,
        obstacles: Vec<Obstacle>,
        smoothing_velocity: f64,
    ) -> Self {
        let mut index = vec![usize::MAX; mesh.num_nodes()];
        let mut nodes = Vec::new();
        for f in boundary {
            for &i in &f.nodes {
                if index[i] == usize::MAX {
                    index[i] = 0;
                    nodes.push(i);
                }
            }
        }
        nodes.sort_unstable();
        for (k, &i) in nodes.iter().enumerate() {
            index[i] = k;
        }
        let mut area = vec![0.0; nodes.len()];
        let mut node_faces = vec![Vec::new(); nodes.len()];
        let mut face_areas = Vec::with_capacity(boundary.len());
        for (f, face) in boundary.iter().enumerate() {
            let [a, b, c] = face.nodes.map(|i| mesh.rest[i]);
            let face_area = 0.5 * (b - a).cross(&(c - a)).norm();
            face_areas.push(face_area);
            for &i in &face.nodes {
                area[index[i]] += face_area / 3.0;
                node_faces[index[i]].push(f as u32);
            }
        }
        let mut contact = Contact {
            obstacles,
            nodes,
            area,
            faces: boundary.iter().map(|f| f.nodes).collect(),
            face_areas,
            node_faces,
            edge: whole.edge,
            smoothing_velocity,
            obstacle_speed: 0.0,
        };
        let (lo, hi) = whole.bounds;
        contact.obstacle_speed = contact
            .obstacles
            .iter()
            .filter(|o| o.surface().is_some())
            .map(|o| {
                let c = o.motion.centre;
                let radius = (c - lo).abs().sup(&(c - hi).abs()).norm();
                o.motion.speed_bound(radius)
            })
            .fold(0.0, f64::max);
        contact
    }

    /// Each boundary triangle's rest area along its outward unit normal at displacement `u`
    /// (m²): the area that faces a plane, see [`Contact::facing_area`].
    fn face_vectors(&self, rest: &[Vector3<f64>], u: &[f64]) -> Vec<Vector3<f64>> {
        self.faces
            .iter()
            .zip(&self.face_areas)
            .map(|(face, &area)| {
                let [a, b, c] = face.map(|i| rest[i] + displacement(u, i));
                // A triangle crushed flat faces nothing.
                (b - a)
                    .cross(&(c - a))
                    .try_normalize(0.0)
                    .map_or(Vector3::zeros(), |n| n * area)
            })
            .collect()
    }

    /// All contact planes at time `t` (s).
    pub fn planes(&self, t: f64) -> Vec<Plane> {
        let mut planes = Vec::with_capacity(self.obstacles.iter().map(Obstacle::num_planes).sum());
        for o in &self.obstacles {
            o.planes_into(t, &mut planes);
        }
        planes
    }

    /// Rest area share (m²) of boundary node `k` facing a plane with normal `normal`: a third
    /// of each adjacent boundary triangle's rest area, times the cosine between its inward
    /// normal (of `faces`, from [`Contact::face_vectors`]) and the plane normal where positive
    /// (the triangle faces the plane), else nothing.
    fn facing_area(&self, k: usize, normal: &Vector3<f64>, faces: &[Vector3<f64>]) -> f64 {
        self.node_faces[k]
            .iter()
            .map(|&f| (-faces[f as usize].dot(normal)).max(0.0) / 3.0)
            .sum()
    }

    /// The facing area of every (boundary node, plane) pair, node by node.
    fn facing_areas(&self, planes: &[Plane], faces: &[Vector3<f64>]) -> Vec<f64> {
        (0..self.nodes.len())
            .flat_map(|k| {
                planes
                    .iter()
                    .map(move |p| self.facing_area(k, &p.normal, faces))
            })
            .collect()
    }

    /// Number of mesh obstacles.
    fn num_mesh_obstacles(&self) -> usize {
        self.obstacles
            .iter()
            .filter(|o| o.surface().is_some())
            .count()
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

/// Energy (J), gradient (N) and Hessian (N/m) of the smoothed friction potential α λ f₀(|y|)
/// for the tangential slip `y` (m) with tangential projector `tangent`, `scale` = α λ (N) and
/// smoothing length `eps` = ε_v h (m). The Hessian is positive semi-definite.
pub(crate) fn friction_terms(
    scale: f64,
    y: &Vector3<f64>,
    tangent: &Matrix3<f64>,
    eps: f64,
) -> (f64, Vector3<f64>, Matrix3<f64>) {
    let s = y.norm();
    let (f0, f1, f1_prime) = friction_profile(s, eps);
    // f₁(s)/s → 2/ε as s → 0.
    let f1_over_s = if s > 1e-14 * eps { f1 / s } else { 2.0 / eps };
    let mut hessian = scale * f1_over_s * tangent;
    if s > 1e-14 * eps {
        let yhat = y / s;
        hessian += scale * (f1_prime - f1_over_s) * yhat * yhat.transpose();
    }
    (scale * f0, scale * f1_over_s * y, hessian)
}

/// Receives a node's 3 × 3 Hessian block: `(node, block)`.
pub type BlockSink<'a> = &'a mut dyn FnMut(usize, &Matrix3<f64>);

/// The contact data fixed during one step.
///
/// Every boundary node k has contact pairs numbered k·stride + j: first the planes shared by
/// all nodes (half-spaces, container walls), then one plane per mesh obstacle, chosen per node.
pub struct ContactStep<'a> {
    /// The term.
    pub contact: &'a Contact,
    /// Rest positions (m).
    pub rest: &'a [Vector3<f64>],
    /// Shared planes at the end of the step.
    pub planes: Vec<Plane>,
    /// Per (boundary node, mesh obstacle): the node's plane and its facing area share (m²),
    /// `None` when the obstacle is out of reach.
    pub node_planes: Vec<Option<(Plane, f64)>>,
    /// The boundary triangles' rest areas along their normals at the start of the step (m²).
    faces: Vec<Vector3<f64>>,
    /// Facing area share per (boundary node, shared plane) (m²).
    areas: Vec<f64>,
    /// Time at the end of the step (s).
    time: f64,
    /// How far from a mesh obstacle nodes are given a plane (m).
    reach: f64,
    /// Time step (s) — friction acts only in dynamic steps.
    pub dt: Option<f64>,
    /// Displacement at the start of the step (m).
    pub previous: &'a [f64],
    /// Lagged normal force per contact pair (N), for friction.
    pub lagged: Vec<f64>,
    /// Contact pairs whose penalty stiffness enters the Hessian although they do not penetrate
    /// yet, because a Newton step was about to push them through (see
    /// [`ContactStep::anticipate`]). Empty until then.
    pub anticipated: Vec<bool>,
}

impl<'a> ContactStep<'a> {
    /// The contact of a step from `t_start` to `t_end` (s) starting at displacement `previous`
    /// (m), with the friction normal force taken there; `dt` is `None` for a static step (no
    /// friction). Mesh obstacles give a plane to every node within `reach` (m) of them: the
    /// caller passes the distance a node can travel in the step plus a margin.
    pub fn new(
        contact: &'a Contact,
        rest: &'a [Vector3<f64>],
        previous: &'a [f64],
        (t_start, t_end): (f64, f64),
        dt: Option<f64>,
        reach: f64,
    ) -> Self {
        let mut step = ContactStep {
            contact,
            rest,
            planes: contact.planes(t_start),
            node_planes: Vec::new(),
            faces: contact.face_vectors(rest, previous),
            areas: Vec::new(),
            time: t_start,
            reach,
            dt,
            previous,
            lagged: Vec::new(),
            anticipated: Vec::new(),
        };
        step.areas = contact.facing_areas(&step.planes, &step.faces);
        step.node_planes = step.select_node_planes(previous);
        step.lagged = step.normal_forces(previous);
        step.set_time(t_end);
        step
    }

    /// Moves the obstacles' planes (shared and per node) to time `t` (s); a turning
    /// obstacle's planes turn, and their facing areas with them.
    fn set_time(&mut self, t: f64) {
        let c = self.contact;
        self.planes = c.planes(t);
        self.time = t;
        if c.obstacles
            .iter()
            .any(|o| o.num_planes() > 0 && o.motion.rotates())
        {
            self.areas = c.facing_areas(&self.planes, &self.faces);
        }
        let mesh_obstacles: Vec<&Obstacle> = c
            .obstacles
            .iter()
            .filter(|o| o.surface().is_some())
            .collect();
        let nm = mesh_obstacles.len();
        for (n, entry) in self.node_planes.iter_mut().enumerate() {
            if let Some((plane, area)) = entry {
                let o = mesh_obstacles[n % nm];
                *plane = o.plane_at(t, plane.origin.0, plane.origin.1);
                if o.motion.rotates() {
                    *area = c.facing_area(n / nm, &plane.normal, &self.faces);
                }
            }
        }
    }

    /// Starts the friction normal force of a dynamic step from its linear extrapolation in
    /// time, λ = max(0, 2 λ(uₙ) − λ(uₙ₋₁)), instead of λ(uₙ): `earlier` is the displacement
    /// one step before the start (m), uₙ − h vₙ, against the obstacles where they were then.
    ///
    /// Where the normal force grows steadily — ice expanding against the walls as it freezes —
    /// λ(uₙ) lags the end of the step by a whole step's growth (20–30 % of the largest force
    /// per step at the onset of freezing), and the re-lag, which contracts by only ≈ α per
    /// re-solve, needed all its re-solves every step; extrapolated, the first solve is usually
    /// within the tolerance.
    pub fn extrapolate_lagged(&mut self, earlier: &[f64]) {
        let Some(h) = self.dt.filter(|_| self.has_friction()) else {
            return;
        };
        let end = self.time;
        self.set_time(end - 2.0 * h);
        let before = self.normal_forces(earlier);
        self.set_time(end);
        for (lambda, b) in self.lagged.iter_mut().zip(&before) {
            *lambda = (2.0 * *lambda - b).max(0.0);
        }
    }

    /// Pairs per boundary node.
    fn stride(&self) -> usize {
        self.planes.len() + self.contact.num_mesh_obstacles()
    }

    /// Calls `f(pair, plane, area)` for each plane of boundary node `k`.
    fn for_each_plane(&self, k: usize, mut f: impl FnMut(usize, &Plane, f64)) {
        let (np, stride) = (self.planes.len(), self.stride());
        for (j, p) in self.planes.iter().enumerate() {
            f(k * stride + j, p, self.areas[k * np + j]);
        }
        let nm = stride - np;
        for m in 0..nm {
            if let Some((p, area)) = &self.node_planes[k * nm + m] {
                f(k * stride + np + m, p, *area);
            }
        }
    }

    /// Each boundary node's plane from each mesh obstacle at displacement `u` and the current
    /// time: through the closest surface point within reach, with its facing area.
    fn select_node_planes(&self, u: &[f64]) -> Vec<Option<(Plane, f64)>> {
        let c = self.contact;
        let mut out = Vec::with_capacity(c.nodes.len() * c.num_mesh_obstacles());
        for (k, &i) in c.nodes.iter().enumerate() {
            let x = self.rest[i] + displacement(u, i);
            for o in &c.obstacles {
                let Some(surface) = o.surface() else { continue };
                // Query in the surface's frame at t = 0.
                let m = &o.motion;
                let x0 = if m.rotates() {
                    m.origin_of(self.time, &x)
                } else {
                    x - m.amplitude.integral(self.time) * m.velocity
                };
                let found = surface.closest(x0, self.reach);
                out.push(found.map(|q| {
                    let plane = o.plane_at(self.time, q.point, q.normal);
                    (plane, c.facing_area(k, &plane.normal, &self.faces))
                }));
            }
        }
        out
    }

    /// Re-picks the mesh-obstacle planes at `u` (the end of a solved step); returns whether a
    /// plane changed for a node that penetrates at `u` with either plane, so that the step must
    /// be solved again.
    pub fn reselect_node_planes(&mut self, u: &[f64]) -> bool {
        if self.node_planes.is_empty() {
            return false;
        }
        let new = self.select_node_planes(u);
        let nm = self.contact.num_mesh_obstacles();
        let penetrates = |entry: &Option<(Plane, f64)>, i: usize| {
            entry.is_some_and(|(p, a)| a > 0.0 && p.gap(self.rest, u, i) < 0.0)
        };
        let changed = new
            .iter()
            .zip(&self.node_planes)
            .enumerate()
            .any(|(n, (a, b))| {
                let i = self.contact.nodes[n / nm];
                // The same plane: the same normal, through the same point up to round-off (a
                // node sliding over one face keeps its plane while its closest point moves).
                let same = match (a, b) {
                    (Some((pa, _)), Some((pb, _))) => {
                        pa.normal == pb.normal
                            && (pa.point - pb.point).dot(&pa.normal).abs() <= SAME_PLANE_OFFSET
                    }
                    (None, None) => true,
                    _ => false,
                };
                !same && (penetrates(a, i) || penetrates(b, i))
            });
        self.node_planes = new;
        changed
    }

    /// Normal force magnitude k Aᵢ max(0, −g) (N) of every contact pair at `u`.
    pub fn normal_forces(&self, u: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.contact.nodes.len() * self.stride()];
        for (k, &i) in self.contact.nodes.iter().enumerate() {
            self.for_each_plane(k, |pair, p, area| {
                let g = p.gap(self.rest, u, i);
                if g < 0.0 {
                    out[pair] = -p.stiffness * area * g;
                }
            });
        }
        out
    }

    /// Tangential slip y = (I − n nᵀ)(Δuᵢ − v_obs h) (m) of node `i` against plane `p` over a
    /// step of `h` (s) ending at `u`, and the tangential projector I − n nᵀ.
    fn slip(&self, p: &Plane, u: &[f64], i: usize, h: f64) -> (Vector3<f64>, Matrix3<f64>) {
        let tangent = Matrix3::identity() - p.normal * p.normal.transpose();
        let du = displacement(u, i) - displacement(self.previous, i);
        // The obstacle's velocity where the node starts the step: a constant of the solve, so
        // the slip stays linear in u and the friction potential exact.
        let v = p.velocity_at(&(self.rest[i] + displacement(self.previous, i)));
        (tangent * (du - v * h), tangent)
    }

    /// Re-lags friction's normal forces to `u` (the solution of the last solve); returns how
    /// far that moves friction: the largest change of a pair's friction force at `u`,
    /// α |Δλ| f₁(|y|) (N), and the largest α λ (N) it is relative to (0 without friction). This is the residual
    /// a re-solve starts from. A sliding pair (f₁ = 1) feels the whole change of λ; a sticking
    /// one (slip below ε = ε_v h) only in proportion to f₁ < 1, since inside the cone its
    /// force is set by equilibrium and λ only bounds it.
    pub fn relag(&mut self, u: &[f64]) -> LagChange {
        let Some(h) = self.dt.filter(|_| self.has_friction()) else {
            return LagChange::default();
        };
        let updated = self.normal_forces(u);
        let eps = self.contact.smoothing_velocity * h;
        let (mut change, mut scale) = (0.0f64, 0.0f64);
        for k in 0..self.contact.nodes.len() {
            let i = self.contact.nodes[k];
            self.for_each_plane(k, |pair, p, _| {
                let slip = self.slip(p, u, i, h).0.norm();
                let weight = friction_profile(slip, eps).1;
                let delta = (updated[pair] - self.lagged[pair]).abs();
                change = change.max(p.friction * delta * weight);
                scale = scale.max(p.friction * updated[pair]);
            });
        }
        self.lagged = updated;
        LagChange { change, scale }
    }

    /// Whether any obstacle has friction (then the lagged normal force matters).
    pub fn has_friction(&self) -> bool {
        self.dt.is_some() && self.contact.obstacles.iter().any(|o| o.friction > 0.0)
    }

    /// Marks the pairs that do not penetrate at `u` but would at `trial` (the full Newton
    /// step), so that the next Hessian holds their penalty stiffness: without it Newton sees a
    /// node resting at zero gap, or falling towards the floor, as free, steps it centimetres
    /// into the obstacle, and the line search must cut the step by the stiffness ratio (1e-8).
    /// Returns whether any pair was newly marked.
    pub fn anticipate(&mut self, u: &[f64], trial: &[f64]) -> bool {
        let mut marked = std::mem::take(&mut self.anticipated);
        marked.resize(self.contact.nodes.len() * self.stride(), false);
        let mut changed = false;
        for (k, &i) in self.contact.nodes.iter().enumerate() {
            self.for_each_plane(k, |pair, p, _| {
                if !marked[pair]
                    && p.gap(self.rest, trial, i) < 0.0
                    && p.gap(self.rest, u, i) >= 0.0
                {
                    marked[pair] = true;
                    changed = true;
                }
            });
        }
        self.anticipated = marked;
        changed
    }

    /// Adds k Aᵢ g n for the anticipated pairs at a positive gap g at `u` (see
    /// `Potential::add_anticipated_gradient`); returns whether there was any.
    pub fn add_anticipated_gradient(&self, u: &[f64], gradient: &mut [f64]) -> bool {
        if !self.anticipated.contains(&true) {
            return false;
        }
        let mut any = false;
        for (k, &i) in self.contact.nodes.iter().enumerate() {
            self.for_each_plane(k, |pair, p, area| {
                let gap = p.gap(self.rest, u, i);
                if gap >= 0.0 && self.anticipated[pair] {
                    for a in 0..3 {
                        gradient[3 * i + a] += p.stiffness * area * gap * p.normal[a];
                    }
                    any = true;
                }
            });
        }
        any
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
        let mut energy = 0.0;
        for (k, &i) in c.nodes.iter().enumerate() {
            let mut g_node = Vector3::zeros();
            let mut h_node = Matrix3::zeros();
            self.for_each_plane(k, |pair, p, area| {
                let gap = p.gap(self.rest, u, i);
                let ka = p.stiffness * area;
                if gap < 0.0 || self.anticipated.get(pair).is_some_and(|a| *a) {
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
                let Some(h) = self.dt else { return };
                let lambda = self.lagged.get(pair).copied().unwrap_or(0.0);
                if lambda <= 0.0 || p.friction <= 0.0 {
                    return;
                }
                let (y, tangent) = self.slip(p, u, i, h);
                let eps = c.smoothing_velocity * h;
                let scale = p.friction * lambda;
                let (f0, g_fric, h_fric) = friction_terms(scale, &y, &tangent, eps);
                energy += f0;
                g_node += g_fric;
                if let Some(f) = forces.as_deref_mut() {
                    for a in 0..3 {
                        f.friction[3 * i + a] -= g_fric[a];
                    }
                }
                h_node += h_fric;
            });
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

/// Adds `sign` × a node's 3 × 3 `block` into the CSC values `hessian` at the node's `slots`.
fn add_block(hessian: &mut [f64], slots: &[u32; 9], block: &Matrix3<f64>, sign: f64) {
    for (k, s) in slots.iter().enumerate() {
        if *s != u32::MAX {
            hessian[*s as usize] += sign * block[(k / 3, k % 3)];
        }
    }
}

/// Contact with rigid obstacles as a term of the incremental potential (`[[obstacle]]`).
#[derive(Clone, Debug)]
pub struct ObstacleContact {
    /// The obstacles and the boundary nodes that can touch them.
    pub contact: Contact,
    /// Number of mesh nodes.
    num_nodes: usize,
    /// Per node, the CSC value indices of its 3 × 3 block in the current pattern.
    block_slots: Vec<[u32; 9]>,
}

impl ObstacleContact {
    /// The term for `contact` on a mesh of `num_nodes` nodes.
    pub fn new(contact: Contact, num_nodes: usize) -> Self {
        ObstacleContact {
            contact,
            num_nodes,
            block_slots: Vec::new(),
        }
    }
}

impl Term for ObstacleContact {
    fn name(&self) -> &'static str {
        "obstacle contact"
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
    fn clone_box(&self) -> Box<dyn Term> {
        Box::new(self.clone())
    }
    fn pattern_ready(&mut self, assembly: &Assembly, changed: bool) {
        if changed {
            self.block_slots = (0..self.num_nodes)
                .map(|i| assembly.node_block_slots(i))
                .collect();
        }
    }
    fn begin_solve<'a>(&'a self, solve: &Solve<'a>) -> Option<Box<dyn StepTerm + 'a>> {
        let selection = Instant::now();
        let h = solve.h;
        // Mesh obstacles look for nodes as far as the step can carry them, and an edge.
        let vmax = solve.max_speed;
        let reach = self.contact.edge
            + 2.0 * h * vmax * 3f64.sqrt()
            + 2.0 * h * self.contact.obstacle_speed;
        let mut step = ContactStep::new(
            &self.contact,
            solve.rest,
            solve.previous,
            solve.times,
            solve.dynamic.then_some(h),
            reach,
        );
        // Friction's normal force starts extrapolated from the step before, uₙ − h vₙ.
        step.extrapolate_lagged(solve.earlier);
        Some(Box::new(ObstacleStep {
            step,
            slots: &self.block_slots,
            blocks: Vec::new(),
            t_broad: selection.elapsed().as_secs_f64(),
        }))
    }
    fn stored_energy(&self, rest: &[Vector3<f64>], u: &[f64], t: f64) -> f64 {
        let c = &self.contact;
        ContactStep::new(c, rest, u, (t, t), None, c.edge).evaluate(u, None, None, None)
    }
    fn as_contact(&self) -> Option<&dyn SceneContact> {
        Some(self)
    }
    fn remeshed(&self, remesh: &Remesh) -> Box<dyn Term> {
        let c = &self.contact;
        let w = remesh.whole;
        let contact = Contact::on_boundary(
            (remesh.mesh, w.boundary),
            WholeBoundary::new(w.perimeters, w.bounds),
            c.obstacles.clone(),
            c.smoothing_velocity,
        );
        Box::new(ObstacleContact::new(contact, remesh.mesh.num_nodes()))
    }
    fn restricted(&self, part: &NodeRestriction) -> Box<dyn Term> {
        let contact = self.contact.restricted(part);
        Box::new(ObstacleContact::new(contact, part.num_nodes()))
    }
}

/// Obstacle contact during one solve.
struct ObstacleStep<'a> {
    step: ContactStep<'a>,
    /// CSC value indices of each node's 3 × 3 block, indexed by node.
    slots: &'a [[u32; 9]],
    /// The 3 × 3 Hessian blocks (node, block) in the last assembled or refreshed Hessian.
    blocks: Vec<(usize, Matrix3<f64>)>,
    /// Time spent choosing mesh-obstacle planes (s).
    t_broad: f64,
}

impl SceneContact for ObstacleContact {
    fn exerts_forces(&self) -> bool {
        true
    }
    fn bookkeeping_len(&self) -> usize {
        self.block_slots.len()
    }
}

impl StepTerm for ObstacleStep<'_> {
    fn name(&self) -> &'static str {
        "obstacle contact"
    }

    fn add(
        &mut self,
        u: &[f64],
        energy: &mut f64,
        gradient: Option<&mut [f64]>,
        hessian: Option<&mut [f64]>,
    ) {
        let slots = self.slots;
        *energy += match hessian {
            Some(hs) => {
                let blocks = &mut self.blocks;
                blocks.clear();
                let mut add = |node: usize, block: &Matrix3<f64>| {
                    add_block(hs, &slots[node], block, 1.0);
                    blocks.push((node, *block));
                };
                self.step.evaluate(u, gradient, Some(&mut add), None)
            }
            None => self.step.evaluate(u, gradient, None, None),
        };
    }
    fn anticipate(&mut self, u: &[f64], trial: &[f64]) -> bool {
        self.step.anticipate(u, trial)
    }
    fn forget_anticipated(&mut self) {
        self.step.anticipated.clear();
    }
    fn add_anticipated_gradient(&self, u: &[f64], gradient: &mut [f64]) -> bool {
        self.step.add_anticipated_gradient(u, gradient)
    }
    fn refresh_hessian(&mut self, u: &[f64], hessian: &mut [f64]) -> bool {
        let mut blocks = Vec::with_capacity(self.blocks.len());
        self.step
            .evaluate(u, None, Some(&mut |node, b| blocks.push((node, *b))), None);
        let changed = blocks != self.blocks;
        if changed {
            for (node, block) in &self.blocks {
                add_block(hessian, &self.slots[*node], block, -1.0);
            }
            for (node, block) in &blocks {
                add_block(hessian, &self.slots[*node], block, 1.0);
            }
            self.blocks = blocks;
        }
        changed
    }
    fn relag(&mut self, u: &[f64]) -> LagChange {
        let reselection = Instant::now();
        let replaned = self.step.reselect_node_planes(u);
        self.t_broad += reselection.elapsed().as_secs_f64();
        let change = self.step.relag(u);
        if replaned {
            LagChange {
                change: f64::INFINITY,
                ..change
            }
        } else {
            change
        }
    }
    fn as_contact(&self) -> Option<&dyn SolveContact> {
        Some(self)
    }
}

impl SolveContact for ObstacleStep<'_> {
    fn add_contact_forces(&self, u: &[f64], forces: &mut ContactForces) {
        self.step.evaluate(u, None, None, Some(forces));
    }
    fn broad_phase_time(&self) -> f64 {
        self.t_broad
    }
}
