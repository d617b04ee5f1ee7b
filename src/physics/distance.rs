//! Distance from a set of surface triangles, measured through the mesh.
//!
//! Each node is given the triangles nearest to it by propagating triangles from node to node
//! along the mesh's edges, Dijkstra-like: a node takes the triangles its neighbours hold (a
//! surface node starts with those it is a corner of), each walked over the surface to the
//! one nearest to the node, keeps those within two of its edges of its least distance (where
//! the nearest face changes, as at a box's edges, a point of its elements may be nearer to
//! another face than the node is), and passes them on; a point's distance is the
//! straight-line distance to the triangles its element's nodes hold. This costs
//! O(n log n) instead of nodes × triangles. When the triangles are the body's whole boundary
//! the result is the distance through the body (a straight segment to a surface point beyond
//! a gap crosses the body's own surface first, which is nearer). When they are only part of
//! it, the distance is still a straight line to the nearest of them, which in a non-convex
//! body may cross a gap.

use crate::mesh::TetMesh;
use crate::physics::obstacle_mesh::closest_on_triangle;
use nalgebra::Vector3;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// The triangle nearest to each node of a mesh, among given surface triangles.
#[derive(Clone, Debug)]
pub struct SurfaceDistance {
    /// The surface triangles (corner positions, m).
    triangles: Vec<[Vector3<f64>; 3]>,
    /// Per node, its nearest triangle and every other within two edges of as near
    /// (empty: the surface does not reach the node).
    candidates: Vec<Vec<u32>>,
    /// The surface triangles as node triples.
    nodes: Vec<[usize; 3]>,
    /// Per node, the triangles that have it as a corner (all at distance 0 from it).
    incident: Vec<Vec<u32>>,
}

/// The surface triangles with what a walk over them needs.
struct Surface<'a> {
    corners: &'a [[Vector3<f64>; 3]],
    triangles: &'a [[usize; 3]],
    incident: &'a [Vec<u32>],
}

impl Surface<'_> {
    /// From triangle `f`, walks to ever nearer triangles sharing a corner with the current one
    /// until none is nearer to `x`: the triangle reached and its distance (m). A triangle a
    /// node's neighbour holds is nearest to that neighbour; the one nearest to the node is
    /// usually a few triangles on.
    fn descend(&self, x: &Vector3<f64>, mut f: u32) -> (u32, f64) {
        let distance = |f: u32| {
            let (q, _) = closest_on_triangle(*x, self.corners[f as usize]);
            (x - q).norm()
        };
        let mut best = distance(f);
        loop {
            let mut next = None;
            for &v in &self.triangles[f as usize] {
                for &g in &self.incident[v] {
                    let d = distance(g);
                    if d < best {
                        best = d;
                        next = Some(g);
                    }
                }
            }
            match next {
                Some(g) => f = g,
                None => return (f, best),
            }
        }
    }
}

/// A node waiting in the queue with a tentative distance.
#[derive(PartialEq)]
struct Queued(f64, usize);

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, other: &Self) -> Ordering {
        // Smallest distance first, ties by node: a deterministic order.
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl SurfaceDistance {
    /// The nearest of `triangles` (node triples of `mesh`) for every node of `mesh`.
    pub fn new(mesh: &TetMesh, triangles: &[[usize; 3]]) -> Self {
        let n = mesh.num_nodes();
        let corners: Vec<[Vector3<f64>; 3]> =
            triangles.iter().map(|t| t.map(|v| mesh.rest[v])).collect();
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); n];
        for tet in &mesh.tets {
            for a in 0..4 {
                for b in 0..4 {
                    if a != b {
                        neighbours[tet[a]].push(tet[b]);
                    }
                }
            }
        }
        for list in &mut neighbours {
            list.sort_unstable();
            list.dedup();
        }
        // A point of an element is at most one edge from each of its nodes, so its nearest
        // triangle is within the node's own distance plus two edges of the node (the
        // distance is 1-Lipschitz): each node keeps every candidate within that slack.
        let slack: Vec<f64> = (0..n)
            .map(|i| {
                let x = mesh.rest[i];
                2.0 * neighbours[i]
                    .iter()
                    .map(|&j| (mesh.rest[j] - x).norm())
                    .fold(0.0, f64::max)
            })
            .collect();
        let mut incident: Vec<Vec<u32>> = vec![Vec::new(); n];
        for (f, t) in triangles.iter().enumerate() {
            for &v in t {
                incident[v].push(f as u32);
            }
        }
        let surface = Surface {
            corners: &corners,
            triangles,
            incident: &incident,
        };
        // Each triangle's corners start at distance 0 with the triangles they are a corner of.
        let mut candidates: Vec<Vec<(u32, f64)>> = incident
            .iter()
            .map(|fs| fs.iter().map(|&f| (f, 0.0)).collect())
            .collect();
        let mut distance: Vec<f64> = incident
            .iter()
            .map(|fs| if fs.is_empty() { f64::INFINITY } else { 0.0 })
            .collect();
        let mut queue: BinaryHeap<Queued> = (0..n)
            .filter(|&v| distance[v] == 0.0)
            .map(|v| Queued(0.0, v))
            .collect();
        let distance_to = |x: &Vector3<f64>, f: u32| {
            let (q, _) = closest_on_triangle(*x, corners[f as usize]);
            (x - q).norm()
        };
        let mut offered: Vec<Vec<u32>> = incident.clone();
        while let Some(Queued(d, i)) = queue.pop() {
            if d > distance[i] {
                continue;
            }
            // The node's candidates came from its neighbours: walk each on to the triangle
            // nearest to this node, and keep those within the slack.
            let x = mesh.rest[i];
            let mut list: Vec<(u32, f64)> = candidates[i]
                .iter()
                .map(|&(f, _)| surface.descend(&x, f))
                .collect();
            list.sort_unstable_by_key(|c| c.0);
            list.dedup_by_key(|c| c.0);
            let least = list.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
            list.retain(|c| c.1 <= least + slack[i]);
            distance[i] = least;
            candidates[i] = list;
            for &j in &neighbours[i] {
                let mut changed = false;
                for k in 0..candidates[i].len() {
                    let f = candidates[i][k].0;
                    let dj = distance_to(&mesh.rest[j], f);
                    // A triangle offered once is not taken again: the node's walk may have
                    // replaced it by a nearer one, and taking it back would cycle.
                    if dj > distance[j] + slack[j] || offered[j].contains(&f) {
                        continue;
                    }
                    offered[j].push(f);
                    candidates[j].push((f, dj));
                    changed = true;
                    if dj < distance[j] {
                        distance[j] = dj;
                        let keep = dj + slack[j];
                        candidates[j].retain(|c| c.1 <= keep);
                    }
                }
                if changed {
                    queue.push(Queued(distance[j], j));
                }
            }
        }
        SurfaceDistance {
            triangles: corners,
            nodes: triangles.to_vec(),
            candidates: candidates
                .into_iter()
                .map(|list| list.into_iter().map(|c| c.0).collect())
                .collect(),
            incident,
        }
    }

    fn surface(&self) -> Surface<'_> {
        Surface {
            corners: &self.triangles,
            triangles: &self.nodes,
            incident: &self.incident,
        }
    }

    /// Distances (m) from `points`, points of the element with the nodes `tet`, to the
    /// surface (∞ where the surface reaches none of those nodes). The nodes' candidates are
    /// first walked to the triangles nearest to the element's centroid (one per basin of the
    /// distance over the surface: a face, or another face across an edge); each point's
    /// distance is the least over those, each walked on to the triangle nearest to the point,
    /// and over the candidates themselves.
    pub fn at_points(&self, tet: &[usize; 4], points: &[Vector3<f64>]) -> Vec<f64> {
        let surface = self.surface();
        let centroid = points.iter().sum::<Vector3<f64>>() / points.len().max(1) as f64;
        let mut candidates: Vec<u32> = tet
            .iter()
            .flat_map(|&v| self.candidates[v].iter().copied())
            .collect();
        candidates.sort_unstable();
        candidates.dedup();
        let mut basins: Vec<u32> = candidates
            .iter()
            .map(|&f| surface.descend(&centroid, f).0)
            .collect();
        basins.sort_unstable();
        basins.dedup();
        let direct = |x: &Vector3<f64>, f: u32| {
            let (q, _) = closest_on_triangle(*x, self.triangles[f as usize]);
            (x - q).norm()
        };
        points
            .iter()
            .map(|x| {
                let walked = basins.iter().map(|&f| surface.descend(x, f).1);
                let held = candidates.iter().map(|&f| direct(x, f));
                walked.chain(held).fold(f64::INFINITY, f64::min)
            })
            .collect()
    }

    /// Distance (m) from `x`, a point of the element with the nodes `tet`, to the surface
    /// (see [`SurfaceDistance::at_points`]).
    pub fn at(&self, x: Vector3<f64>, tet: &[usize; 4]) -> f64 {
        self.at_points(tet, &[x])[0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::box_mesh;

    #[test]
    fn inside_a_box_the_distance_is_to_the_nearest_face() {
        // A 10 × 6 × 4 cm box, all its boundary triangles: at any point the distance is the
        // least of the six face distances, exactly (the box is convex).
        let mesh = box_mesh([0.0; 3], [0.1, 0.06, 0.04], [10, 6, 4], 6).unwrap();
        let faces: Vec<[usize; 3]> = mesh.boundary_faces().iter().map(|f| f.nodes).collect();
        let d = SurfaceDistance::new(&mesh, &faces);
        let size = [0.1, 0.06, 0.04];
        for tet in &mesh.tets {
            let x = tet.iter().map(|&v| mesh.rest[v]).sum::<Vector3<f64>>() / 4.0;
            let exact = (0..3)
                .map(|a| x[a].min(size[a] - x[a]))
                .fold(f64::INFINITY, f64::min);
            assert!(
                (d.at(x, tet) - exact).abs() < 1e-15,
                "at {x}: {} vs {exact}",
                d.at(x, tet)
            );
        }
    }

    #[test]
    fn on_a_distorted_mesh_the_propagated_triangle_is_the_nearest_one() {
        // Interior nodes of a box moved by up to a third of a cell: every element centroid's
        // distance equals the brute-force least distance over all boundary triangles.
        let mut mesh = box_mesh([0.0; 3], [0.1, 0.08, 0.06], [8, 6, 5], 6).unwrap();
        let inside =
            |x: &Vector3<f64>| (0..3).all(|a| x[a] > 1e-9 && x[a] < [0.1, 0.08, 0.06][a] - 1e-9);
        for (k, x) in mesh.rest.iter_mut().enumerate() {
            if inside(x) {
                let s = k as f64;
                *x += Vector3::new((s * 0.7).sin(), (s * 1.3).cos(), (s * 2.1).sin()) * 0.004;
            }
        }
        let faces: Vec<[usize; 3]> = mesh.boundary_faces().iter().map(|f| f.nodes).collect();
        let d = SurfaceDistance::new(&mesh, &faces);
        let mut worst: f64 = 0.0;
        for tet in &mesh.tets {
            let x = tet.iter().map(|&v| mesh.rest[v]).sum::<Vector3<f64>>() / 4.0;
            let brute = faces
                .iter()
                .map(|f| {
                    let (q, _) = closest_on_triangle(x, f.map(|v| mesh.rest[v]));
                    (x - q).norm()
                })
                .fold(f64::INFINITY, f64::min);
            worst = worst.max((d.at(x, tet) - brute).abs());
        }
        assert!(worst < 1e-15, "off by {worst:e} m");
    }
}
