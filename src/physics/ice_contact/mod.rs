//! Penalty contact between separate pieces of ice (bodies of a multi-part mesh, fragments
//! after fracture): a boundary node of one part against a boundary triangle of another.
//!
//! For node p and triangle (a, b, c) with unit normal n (outward of its part) and foot point
//! q = βₐa + β_b b + β_c c of p on the triangle's plane, the gap is g = (p − q)·n. While
//! −depth < g < δ and β is inside the triangle, the node touches the other part and stores
//! k Aₚ φ(g) (Aₚ: the node's rest boundary-area share; φ the C² penalty of
//! [`IceContact::penalty`], ½ g² shifted by the small onset δ). The gap's gradient is exactly
//! ∇g = (n, −βₐ n, −β_b n, −β_c n) (moving the triangle moves its plane affinely; its rotation
//! changes g only at second order because p − q ∥ n), so the force couples all four nodes and
//! the 12 × 12 Jacobian k Aₚ φ″ ∇g ∇gᵀ is exact up to the O(g) curvature of the normal.
//!
//! Friction between the pieces is the smoothed Coulomb potential of the obstacles (see
//! `contact`), on the slip of the node relative to the foot point, y = T (Δuₚ − Σ βᵢ Δuᵢ), with
//! the normal n, the weights β and the normal force λ frozen per step (re-lagged to the end of
//! the step like the obstacles'): its 12-dof gradient and Hessian follow from y being linear in u.
//!
//! The two sides of a crack that has not (yet) cut a piece off belong to one part; they must
//! still not pass through each other. They touch where they were split apart: every copy of a
//! split node is paired with its other copies (same rest position; `crack_sides`), and the
//! pair's gap g = g₀ + ((p − q) − (p₀ − q₀))·m moves with the copies along m, the unit normal
//! from q's side of the crack to p's frozen for the step, from g₀, the gap the pair carries
//! from step to step. Such a pair is a candidate like a node–triangle pair whose triangle is
//! the point q (β = (1, 0, 0)).
//!
//! The same holds for the two sides of a crack that has cut a piece off: crack
//! nodes are never paired with crack faces node-to-triangle. That would not do: a copy sits
//! exactly on a vertex of the other side's faces, and which face is nearest flips with
//! round-off where the crack bends, making the energy jump. Copies that have slid apart by more
//! than an edge length (tangentially) no longer face each other and are not paired.
//!
//! A node is paired only with triangles that face it: its outward normal (the area-weighted
//! mean of its boundary faces', at the start of the step) within 60° of the reversed
//! triangle's. Otherwise a node on the top of one piece, next to another piece's side face,
//! lies behind that face's plane and would be pushed as if it had gone in.
//!
//! Nor is a node paired with a triangle whose plane it is already behind, at the start of the
//! step, by more than 1 % of an edge: contact starts from outside, and a node that far behind
//! a face's plane is beside the other piece's edge, not in it — paired, it would jump into a
//! deep "penetration" the moment its foot point slid onto the face (a jump of 5e4 J in the
//! energy, which stalls the line search).
//!
//! The broad phase runs once per step: triangle boxes, grown by a margin covering the step's
//! motion, go into a uniform grid, and each boundary node of another part is looked up in it.
//! The candidate (node, triangle) pairs are fixed for the step.

use super::crack_sides::{position, CopyFrame, CrackSides};
use super::grid::BoxGrid;
use super::term::NodeRestriction;
use crate::mesh::{BoundaryFace, TetMesh};
use nalgebra::Vector3;

mod step;
mod term;
pub use step::{FrictionFrame, IceFriction, IceStep};
pub use term::{renumbered_gaps, IceContactTerm, CRACK_GAPS};

/// The ice–ice contact term of a mesh with several parts or with cracks.
#[derive(Clone, Debug)]
pub struct IceContact {
    /// Part (connected component) of every node.
    pub part: Vec<u32>,
    /// Number of parts.
    pub parts: usize,
    /// Penalty stiffness k (N/m³).
    pub stiffness: f64,
    /// Coulomb friction coefficient between pieces of ice.
    pub friction: f64,
    /// Friction smoothing velocity ε_v (m/s), as for obstacles.
    pub smoothing_velocity: f64,
    /// Boundary nodes and their rest area shares (m²).
    nodes: Vec<(usize, f64)>,
    /// Boundary triangles (outward), global node indices.
    faces: Vec<[usize; 3]>,
    /// Mean boundary edge length (m): grid cell size and largest penetration counted.
    edge: f64,
    /// Gap (m) below which the penalty starts: ONSET × the mean edge.
    onset: f64,
    /// Copies of split nodes on cracks, paired (see the module docs).
    copies: CrackSides,
    /// Per boundary face, whether it is a crack face.
    crack_face: Vec<bool>,
    /// Per node, whether it lies on a crack face.
    on_crack: Vec<bool>,
    /// Per node, whether this process owns it: every node on one process, the owned nodes on
    /// a process's part (see [`IceContact::restricted`]).
    owned: Vec<bool>,
}

/// Largest cos of the angle between a node's outward normal and the reversed outward normal of
/// a face it may touch (60°; a box corner's normal is 55° from each of its faces').
const OPPOSED: f64 = 0.5;

/// Gap at which the penalty starts, as a fraction of the mean edge (see [`IceContact::penalty`]).
const ONSET: f64 = 1e-4;

/// Depth behind a face's plane, as a fraction of the mean edge, beyond which a node at the
/// start of a step is taken to be beside the other piece rather than in it. A real penetration
/// is the penalty depth, pressure / stiffness: ~1e-5 m at 1e9 Pa, far below 1 % of an edge.
const GATE: f64 = 1e-2;

/// A (node, triangle) pair that may touch during a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// The node (global index).
    pub node: usize,
    /// Its rest area share (m²).
    pub area: f64,
    /// The triangle's nodes (global indices); all three the same node for a pair of copies
    /// of a split node.
    pub face: [usize; 3],
    /// For a pair of copies: the unit normal m from the other copy's side to the node's
    /// (frozen for the step); zero otherwise.
    pub normal: Vector3<f64>,
    /// For a pair of copies: g₀ − (p₀ − q₀)·m, the carried gap at the step's start less the
    /// part the positions give there (m); zero otherwise.
    pub offset: f64,
}

impl Candidate {
    /// Whether this pairs two copies of a split node (the "triangle" is a point).
    pub fn is_copy_pair(&self) -> bool {
        self.face[0] == self.face[1]
    }
}

/// A boundary surface an ice–ice contact term reads, as one process of a distributed run
/// gathers it: its faces and, at each of its nodes, what the whole mesh gives there. Nodes
/// are numbered as the positions the term reads.
#[derive(Clone, Debug, Default)]
pub struct ContactSurface {
    /// Faces (outward; in the order `TetMesh::boundary_faces` gives the whole mesh's).
    pub faces: Vec<[usize; 3]>,
    /// Per face, whether it is a crack face.
    pub crack_face: Vec<bool>,
    /// Per node, its rest boundary-area share on the whole mesh (m²; 0 off the surface).
    pub area: Vec<f64>,
    /// Per node, the connected piece of the whole mesh it is in.
    pub piece: Vec<u32>,
    /// Per node, whether it lies on a crack face.
    pub on_crack: Vec<bool>,
    /// Per node, whether this process owns it.
    pub owned: Vec<bool>,
    /// Number of pieces of the whole mesh.
    pub pieces: usize,
}

impl IceContact {
    /// The term on `surface`, the whole mesh's boundary faces having `perimeters` (m, in
    /// `TetMesh::boundary_faces` order: the mean edge scales the penalty's onset and the
    /// broad phase), with penalty `stiffness` (N/m³) and Coulomb `friction` smoothed over a
    /// velocity (m/s), pairing the copies of split nodes `copies`.
    pub fn on_surface(
        (surface, copies): (ContactSurface, CrackSides),
        perimeters: &[f64],
        stiffness: f64,
        (friction, smoothing_velocity): (f64, f64),
    ) -> Self {
        let edge = perimeters.iter().map(|p| p / 3.0).sum::<f64>() / perimeters.len() as f64;
        IceContact {
            nodes: (surface.area.iter().enumerate())
                .filter(|(_, &a)| a > 0.0)
                .map(|(i, &a)| (i, a))
                .collect(),
            part: surface.piece,
            parts: surface.pieces,
            stiffness,
            friction,
            smoothing_velocity,
            faces: surface.faces,
            edge,
            onset: ONSET * edge,
            copies,
            crack_face: surface.crack_face,
            on_crack: surface.on_crack,
            owned: surface.owned,
        }
    }

    /// The term for `mesh` with the given crack faces (node triples, any order), or `None` if
    /// the mesh is one part without cracks (then nothing is paid, not even `stiffness`, asked
    /// for only when the term is on: a default stiffness takes a pass over the boundary).
    pub fn new(
        mesh: &TetMesh,
        stiffness: impl FnOnce() -> f64,
        friction: f64,
        smoothing_velocity: f64,
        cracks: &[[usize; 3]],
    ) -> Option<Self> {
        let (part, parts) = crate::mesh::parts(mesh);
        if parts < 2 && cracks.is_empty() {
            return None;
        }
        let boundary = mesh.boundary_faces();
        let perimeters = mesh.perimeters(&boundary);
        let friction = (friction, smoothing_velocity);
        Some(Self::on_boundary(
            (mesh, &boundary, &perimeters),
            (part, parts),
            stiffness(),
            friction,
            cracks,
        ))
    }

    /// The term on `mesh` (the whole mesh, or a process's part of it) with its faces
    /// `boundary` on the whole mesh's boundary, `perimeters` those of the whole boundary's
    /// faces (m, whose mean edge scales the penalty's onset and the broad phase), each node
    /// in the piece `part.0[i]` of `part.1`, penalty `stiffness` (N/m³), Coulomb `friction`
    /// smoothed over a velocity (m/s), and the crack faces `cracks`.
    pub fn on_boundary(
        (mesh, boundary, perimeters): (&TetMesh, &[BoundaryFace], &[f64]),
        (part, parts): (Vec<u32>, usize),
        stiffness: f64,
        (friction, smoothing_velocity): (f64, f64),
        cracks: &[[usize; 3]],
    ) -> Self {
        let area = mesh.area_shares(boundary);
        let faces: Vec<[usize; 3]> = boundary.iter().map(|f| f.nodes).collect();
        let sorted = |f: &[usize; 3]| {
            let mut k = *f;
            k.sort_unstable();
            k
        };
        let crack_keys: std::collections::HashSet<[usize; 3]> = cracks.iter().map(sorted).collect();
        let crack_face: Vec<bool> = faces
            .iter()
            .map(|f| crack_keys.contains(&sorted(f)))
            .collect();
        let mut on_crack = vec![false; mesh.num_nodes()];
        for f in cracks {
            for &i in f {
                on_crack[i] = true;
            }
        }
        let surface = ContactSurface {
            faces,
            crack_face,
            area,
            piece: part,
            on_crack,
            owned: vec![true; mesh.num_nodes()],
            pieces: parts,
        };
        let copies = CrackSides::new(mesh, cracks);
        let friction = (friction, smoothing_velocity);
        Self::on_surface((surface, copies), perimeters, stiffness, friction)
    }

    /// The term on a process's part of a distributed run: numbered as the part's mesh, which
    /// holds every boundary face and node a pair with an owned node meets (the elements of
    /// its ghost surface, see `distributed::surface_hold`), and evaluating only the pairs with
    /// a node the process owns among their four, whose forces and stiffness the process keeps
    /// on its owned nodes; the energy of a pair counts on the owner of its node. An owned node
    /// then gets the contributions of its pairs in the order one process adds them: the same
    /// bits. The process finds every candidate pair with an owned node, as on the whole
    /// boundary, so its sparsity pattern couples every pair its rows take part in. A face or
    /// node the part does not hold is left out.
    pub fn restricted(&self, part: &NodeRestriction) -> IceContact {
        let n = part.num_nodes();
        let mut component = vec![u32::MAX; n];
        let (mut on_crack, mut owned) = (vec![false; n], vec![false; n]);
        for i in 0..self.part.len() {
            if let Some(k) = part.held(i) {
                component[k] = self.part[i];
                on_crack[k] = self.on_crack[i];
                owned[k] = self.owned[i] && part.kept(i).is_some();
            }
        }
        let held_face = |f: &[usize; 3]| f.iter().all(|&i| part.held(i).is_some());
        let (faces, crack_face) = (self.faces.iter().zip(&self.crack_face))
            .filter(|(f, _)| held_face(f))
            .map(|(f, &c)| (f.map(|i| part.local(i)), c))
            .unzip();
        IceContact {
            part: component,
            nodes: (self.nodes.iter())
                .filter_map(|&(i, area)| part.held(i).map(|k| (k, area)))
                .collect(),
            faces,
            crack_face,
            on_crack,
            owned,
            copies: self.copies.renumbered(|i| part.held(i)),
            ..*self
        }
    }

    /// The mean boundary edge (m).
    pub fn edge(&self) -> f64 {
        self.edge
    }

    /// How far (m) the broad phase of a step of `h` seconds with `vmax` the largest velocity
    /// component (m/s) grows each box: twice the motion bound plus half an edge.
    pub fn margin(&self, vmax: f64, h: f64) -> f64 {
        2.0 * vmax * h + 0.5 * self.edge
    }

    /// How far (m) from a process's owned boundary nodes the boundary faces it must hold
    /// reach, for such a step from the current positions (see
    /// `distributed::ghost_surface`): twice the broad phase's margin plus two edges, so that
    /// it holds every face a pair with an owned node meets, every face of such a pair's node
    /// and every face its closest-face choice weighs.
    pub fn ghost_reach(&self, vmax: f64, h: f64) -> f64 {
        Self::reach_for(self.edge, vmax, h)
    }

    /// [`IceContact::ghost_reach`] of a contact whose mean boundary edge is `edge` (m).
    pub fn reach_for(edge: f64, vmax: f64, h: f64) -> f64 {
        2.0 * (2.0 * vmax * h + 0.5 * edge) + 2.0 * edge
    }

    /// Candidate pairs for a step from displacement `u` over `h` seconds with `vmax` the
    /// largest velocity component (m/s, over the whole mesh): node and triangle of different
    /// parts, or across a crack (see the module docs), whose boxes, grown by the motion of the
    /// step plus half an edge, overlap. The pairs of copies get their normal and offset from
    /// `frames` ([`CrackSides::frames`]).
    pub fn candidates(
        &self,
        rest: &[Vector3<f64>],
        (u, vmax): (&[f64], f64),
        h: f64,
        frames: &[CopyFrame],
    ) -> Vec<Candidate> {
        let margin = self.margin(vmax, h);
        let mut grid = BoxGrid::new(self.edge.max(margin));
        // Unit normals of the faces and (area-weighted mean) of the boundary nodes, now.
        let mut face_normal = Vec::with_capacity(self.faces.len());
        let mut node_normal = vec![Vector3::zeros(); self.part.len()];
        for (f, face) in self.faces.iter().enumerate() {
            let pts = face.map(|i| position(rest, u, i));
            let lo = pts[0].inf(&pts[1]).inf(&pts[2]).add_scalar(-margin);
            let hi = pts[0].sup(&pts[1]).sup(&pts[2]).add_scalar(margin);
            grid.insert(&lo, &hi, f as u32);
            let cross = (pts[1] - pts[0]).cross(&(pts[2] - pts[0]));
            for &i in face {
                node_normal[i] += cross;
            }
            face_normal.push(cross.try_normalize(0.0).unwrap_or_default());
        }
        let mut out = Vec::new();
        for &(node, area) in &self.nodes {
            let p = position(rest, u, node);
            for &f in grid.at(&p) {
                let face = self.faces[f as usize];
                // Crack against crack is the copies' business (see the module docs); a node
                // only meets faces that face it.
                if self.part[face[0]] == self.part[node]
                    || (self.on_crack[node] && self.crack_face[f as usize])
                    || node_normal[node].normalize().dot(&face_normal[f as usize]) > -OPPOSED
                {
                    continue;
                }
                let pts = face.map(|i| position(rest, u, i));
                let lo = pts[0].inf(&pts[1]).inf(&pts[2]).add_scalar(-margin);
                let hi = pts[0].sup(&pts[1]).sup(&pts[2]).add_scalar(margin);
                // A node already well behind the face's plane now is not touching that face
                // but beside the other piece's edge (see the module docs).
                let behind = (p - pts[0]).dot(&face_normal[f as usize]) < -GATE * self.edge;
                if !behind && (0..3).all(|a| p[a] >= lo[a] && p[a] <= hi[a]) {
                    out.push(Candidate {
                        node,
                        area,
                        face,
                        normal: Vector3::zeros(),
                        offset: 0.0,
                    });
                }
            }
        }
        // Copies of split nodes, after the node–triangle pairs (which come in runs by node).
        for (pair, frame) in self.copies.pairs().iter().zip(frames) {
            // Copies that slid apart by more than an edge no longer face each other.
            let d = self.copies.separation(rest, u, pair);
            if let Some((normal, offset)) =
                frame.filter(|(m, _)| (d - d.dot(m) * m).norm() < self.edge)
            {
                out.push(Candidate {
                    node: pair.p,
                    area: pair.area,
                    face: [pair.q; 3],
                    normal,
                    offset,
                });
            }
        }
        out
    }

    /// The penalty per unit k Aₚ at gap g (m): its value (m²), slope (m) and curvature, or
    /// `None` where it is zero (g ≥ δ). With δ = 1e-4 × the mean edge,
    ///
    /// ```text
    /// φ(g) = (δ − g)³ / (6δ)             0 ≤ g < δ
    /// φ(g) = g²/2 − δ g/2 + δ²/6         g < 0
    /// ```
    ///
    /// twice differentiable: the plain ½ min(g, 0)² jumps in curvature at contact, and two
    /// sides of a crack resting at g ≈ 0 then make Newton's active set flip between iterations
    /// (the Hessian with the pair stiffness, the energy without), which stalled it at a
    /// convergence rate of 0.99 per iteration in the freezing container. The shift of the
    /// contact by up to δ (µm at cm elements) is far below the penalty depth at 1e9 Pa.
    pub fn penalty(&self, g: f64) -> Option<(f64, f64, f64)> {
        debug_assert!(self.onset > 0.0);
        let d = self.onset;
        if g >= d {
            None
        } else if g >= 0.0 {
            let r = d - g;
            Some((r * r * r / (6.0 * d), -r * r / (2.0 * d), r / d))
        } else {
            Some((0.5 * g * g - 0.5 * d * g + d * d / 6.0, g - 0.5 * d, 1.0))
        }
    }

    /// The pairs of copies of split nodes (the crack sides' contact).
    pub fn crack_sides(&self) -> &CrackSides {
        &self.copies
    }

    /// The gap δ (m) at which the penalty starts.
    pub fn onset(&self) -> f64 {
        self.onset
    }

    /// Gap g (m) and its gradient ∇g over the 12 dofs (node, a, b, c) of one pair at `u`, or
    /// `None` when the node's foot point is outside the triangle or the node is deeper than an
    /// edge length behind it (then it is not touching this face).
    pub fn gap(&self, rest: &[Vector3<f64>], u: &[f64], c: &Candidate) -> Option<(f64, [f64; 12])> {
        let p = position(rest, u, c.node);
        if c.is_copy_pair() {
            let g = (p - position(rest, u, c.face[0])).dot(&c.normal) + c.offset;
            let mut grad_g = [0.0; 12];
            for k in 0..3 {
                grad_g[k] = c.normal[k];
                grad_g[3 + k] = -c.normal[k];
            }
            return Some((g, grad_g));
        }
        let [a, b, cc] = c.face.map(|i| position(rest, u, i));
        let cross = (b - a).cross(&(cc - a));
        let area2 = cross.norm();
        if area2 == 0.0 {
            return None;
        }
        let n = cross / area2;
        let g = (p - a).dot(&n);
        if g <= -self.edge {
            return None;
        }
        let q = p - g * n;
        let beta_b = (q - a).cross(&(cc - a)).dot(&n) / area2;
        let beta_c = (b - a).cross(&(q - a)).dot(&n) / area2;
        let beta_a = 1.0 - beta_b - beta_c;
        if beta_a < 0.0 || beta_b < 0.0 || beta_c < 0.0 {
            return None;
        }
        let mut grad_g = [0.0; 12];
        for (slot, w) in [(0, 1.0), (1, -beta_a), (2, -beta_b), (3, -beta_c)] {
            for k in 0..3 {
                grad_g[3 * slot + k] = w * n[k];
            }
        }
        Some((g, grad_g))
    }

    /// Splits `candidates` (ordered by node, as [`IceContact::candidates`] makes them) into
    /// runs of one node against one other part, and in each run picks the face the node is
    /// closest to (smallest |g| among faces it projects into): a node near an edge of the other
    /// body also lies "behind" the side face there, and only the nearest face tells whether it
    /// is inside. Pairs of copies of a split node each count on their own. Calls `f(index into
    /// candidates, gap, ∇g)` for each chosen pair with a node this process owns.
    pub fn for_each_closest(
        &self,
        rest: &[Vector3<f64>],
        u: &[f64],
        candidates: &[Candidate],
        mut f: impl FnMut(usize, f64, &[f64; 12]),
    ) {
        let mut start = 0;
        while start < candidates.len() {
            if candidates[start].is_copy_pair() {
                let mine = self.touches_owned(&candidates[start]);
                if let Some((g, dg)) = mine
                    .then(|| self.gap(rest, u, &candidates[start]))
                    .flatten()
                {
                    f(start, g, &dg);
                }
                start += 1;
                continue;
            }
            let key = (candidates[start].node, self.part[candidates[start].face[0]]);
            let mut end = start + 1;
            while end < candidates.len()
                && (candidates[end].node, self.part[candidates[end].face[0]]) == key
            {
                end += 1;
            }
            // The nearest face is chosen among all the run's, as on one process.
            let mine = (start..end).any(|m| self.touches_owned(&candidates[m]));
            let best = (start..end)
                .filter(|_| mine)
                .filter_map(|m| self.gap(rest, u, &candidates[m]).map(|(g, dg)| (m, g, dg)))
                .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
            if let Some((m, g, dg)) = best.filter(|b| self.touches_owned(&candidates[b.0])) {
                f(m, g, &dg);
            }
            start = end;
        }
    }

    /// Whether a node of the pair `c` is one this process owns.
    fn touches_owned(&self, c: &Candidate) -> bool {
        IceContact::pair_nodes(c).iter().any(|&i| self.owned[i])
    }

    /// Whether this process counts the energy of the pair `c`: it owns the pair's node.
    pub fn counts_energy(&self, c: &Candidate) -> bool {
        self.owned[c.node]
    }

    /// The four nodes of a pair, in gradient order.
    pub fn pair_nodes(c: &Candidate) -> [usize; 4] {
        [c.node, c.face[0], c.face[1], c.face[2]]
    }
}
