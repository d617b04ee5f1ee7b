//! Penalty contact between separate pieces of ice (bodies of a multi-part mesh, fragments
//! after fracture): a boundary node of one part against a boundary triangle of another.
//!
//! For node p and triangle (a, b, c) with unit normal n (outward of its part) and foot point
//! q = βₐa + β_b b + β_c c of p on the triangle's plane, the gap is g = (p − q)·n. While
//! −depth < g < 0 and β is inside the triangle, the node has penetrated the other part and
//! stores ½ k Aₚ g² (Aₚ: the node's rest boundary-area share). The gap's gradient is exactly
//! ∇g = (n, −βₐ n, −β_b n, −β_c n) (moving the triangle moves its plane affinely; its rotation
//! changes g only at second order because p − q ∥ n), so the force couples all four nodes and
//! the 12 × 12 Jacobian k Aₚ ∇g ∇gᵀ is exact up to the O(g) curvature of the normal.
//!
//! Friction between the pieces is the smoothed Coulomb potential of the obstacles (see
//! `contact`), on the slip of the node relative to the foot point, y = T (Δuₚ − Σ βᵢ Δuᵢ), with
//! the normal n, the weights β and the normal force λ frozen per step (re-lagged to the end of
//! the step like the obstacles'): its 12-dof gradient and Hessian follow from y being linear in u.
//!
//! The broad phase runs once per step: triangle boxes, grown by a margin covering the step's
//! motion, go into a uniform grid, and each boundary node of another part is looked up in it.
//! The candidate (node, triangle) pairs are fixed for the step.

use super::grid::BoxGrid;
use crate::mesh::TetMesh;
use nalgebra::Vector3;

/// The ice–ice contact term of a mesh with several parts.
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
}

/// A (node, triangle) pair that may touch during a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// The node (global index).
    pub node: usize,
    /// Its rest area share (m²).
    pub area: f64,
    /// The triangle's nodes (global indices).
    pub face: [usize; 3],
}

/// Connected components of the mesh (nodes joined by tets): part index per node and count.
pub fn parts(mesh: &TetMesh) -> (Vec<u32>, usize) {
    let n = mesh.num_nodes();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for tet in &mesh.tets {
        for &v in &tet[1..] {
            let (a, b) = (find(&mut parent, tet[0]), find(&mut parent, v));
            if a != b {
                parent[a.max(b)] = a.min(b);
            }
        }
    }
    let mut label = vec![u32::MAX; n];
    let mut part = vec![0u32; n];
    let mut count = 0;
    for (i, p) in part.iter_mut().enumerate() {
        let r = find(&mut parent, i);
        if label[r] == u32::MAX {
            label[r] = count;
            count += 1;
        }
        *p = label[r];
    }
    (part, count as usize)
}

fn position(rest: &[Vector3<f64>], u: &[f64], i: usize) -> Vector3<f64> {
    rest[i] + Vector3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2])
}

impl IceContact {
    /// The term for `mesh`, or `None` if the mesh is one part (then nothing is paid).
    pub fn new(
        mesh: &TetMesh,
        stiffness: f64,
        friction: f64,
        smoothing_velocity: f64,
    ) -> Option<Self> {
        let (part, parts) = parts(mesh);
        if parts < 2 {
            return None;
        }
        let boundary = mesh.boundary_faces();
        let mut area = vec![0.0; mesh.num_nodes()];
        let mut edge = 0.0;
        for f in &boundary {
            let [a, b, c] = f.nodes.map(|i| mesh.rest[i]);
            let share = 0.5 * (b - a).cross(&(c - a)).norm() / 3.0;
            for &v in &f.nodes {
                area[v] += share;
            }
            edge += ((b - a).norm() + (c - b).norm() + (a - c).norm()) / 3.0;
        }
        let edge = edge / boundary.len() as f64;
        let nodes = (0..mesh.num_nodes())
            .filter(|&i| area[i] > 0.0)
            .map(|i| (i, area[i]))
            .collect();
        let faces = boundary.iter().map(|f| f.nodes).collect();
        Some(IceContact {
            part,
            parts,
            stiffness,
            friction,
            smoothing_velocity,
            nodes,
            faces,
            edge,
        })
    }

    /// Candidate pairs for a step from displacement `u` with velocities `v` over `h` seconds:
    /// node and triangle of different parts whose boxes, grown by the motion of the step plus
    /// half an edge, overlap.
    pub fn candidates(
        &self,
        rest: &[Vector3<f64>],
        u: &[f64],
        v: &[f64],
        h: f64,
    ) -> Vec<Candidate> {
        let vmax = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let margin = 2.0 * vmax * h + 0.5 * self.edge;
        let mut grid = BoxGrid::new(self.edge.max(margin));
        for (f, face) in self.faces.iter().enumerate() {
            let pts = face.map(|i| position(rest, u, i));
            let lo = pts[0].inf(&pts[1]).inf(&pts[2]).add_scalar(-margin);
            let hi = pts[0].sup(&pts[1]).sup(&pts[2]).add_scalar(margin);
            grid.insert(&lo, &hi, f as u32);
        }
        let mut out = Vec::new();
        for &(node, area) in &self.nodes {
            let p = position(rest, u, node);
            for &f in grid.at(&p) {
                let face = self.faces[f as usize];
                if self.part[face[0]] == self.part[node] {
                    continue;
                }
                let pts = face.map(|i| position(rest, u, i));
                let lo = pts[0].inf(&pts[1]).inf(&pts[2]).add_scalar(-margin);
                let hi = pts[0].sup(&pts[1]).sup(&pts[2]).add_scalar(margin);
                if (0..3).all(|a| p[a] >= lo[a] && p[a] <= hi[a]) {
                    out.push(Candidate { node, area, face });
                }
            }
        }
        out
    }

    /// Gap g (m) and its gradient ∇g over the 12 dofs (node, a, b, c) of one pair at `u`, or
    /// `None` when the node's foot point is outside the triangle or the node is deeper than an
    /// edge length behind it (then it is not touching this face).
    pub fn gap(&self, rest: &[Vector3<f64>], u: &[f64], c: &Candidate) -> Option<(f64, [f64; 12])> {
        let p = position(rest, u, c.node);
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
    /// is inside. Calls `f(index into candidates, gap, ∇g)` for each chosen pair.
    pub fn for_each_closest(
        &self,
        rest: &[Vector3<f64>],
        u: &[f64],
        candidates: &[Candidate],
        mut f: impl FnMut(usize, f64, &[f64; 12]),
    ) {
        let mut start = 0;
        while start < candidates.len() {
            let key = (candidates[start].node, self.part[candidates[start].face[0]]);
            let mut end = start + 1;
            while end < candidates.len()
                && (candidates[end].node, self.part[candidates[end].face[0]]) == key
            {
                end += 1;
            }
            let best = (start..end)
                .filter_map(|m| self.gap(rest, u, &candidates[m]).map(|(g, dg)| (m, g, dg)))
                .min_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
            if let Some((m, g, dg)) = best {
                f(m, g, &dg);
            }
            start = end;
        }
    }

    /// The four nodes of a pair, in gradient order.
    pub fn pair_nodes(c: &Candidate) -> [usize; 4] {
        [c.node, c.face[0], c.face[1], c.face[2]]
    }
}
