//! Rigid triangle-mesh obstacles: closest-feature queries with pseudo-normals.
//!
//! A node near the obstacle surface gets, once per step, the plane through the closest point q
//! of the surface: for a point on a face, the face's plane; for a point on an edge or vertex,
//! the plane through q normal to the node's offset x − q (the tangent plane of the rounded
//! edge or corner). Whether the node is inside is the sign of (x − q) against the feature's
//! angle-weighted pseudo-normal (Bærentzen & Aanæs 2005), which is exact for closed, outward
//! oriented surfaces and gives the outward side of an open one (a terrain, a bowl). The plane
//! is then frozen for the step, so the penalty keeps the exact gradient and Hessian of a plane
//! (see `contact`); the contact re-picks planes at the end of the step until they settle.
//!
//! Triangles go once into a uniform grid (body frame): a query visits only the cells within
//! the search radius.

use super::grid::BoxGrid;
use crate::mesh::orientation::winding_number;
use crate::mesh::surface::TriSurface;
use nalgebra::Vector3;
use std::collections::HashMap;

/// A triangle surface prepared for closest-point queries.
#[derive(Clone, Debug)]
pub struct ObstacleSurface {
    /// Vertices at t = 0 (m).
    pub vertices: Vec<Vector3<f64>>,
    /// Triangles, outward by the right-hand rule.
    pub triangles: Vec<[usize; 3]>,
    /// Unit normal of each triangle.
    face_normals: Vec<Vector3<f64>>,
    /// Angle-weighted pseudo-normal of each vertex (unit).
    vertex_normals: Vec<Vector3<f64>>,
    /// Pseudo-normal (sum of the adjacent face normals, unit) of each edge, keyed (min, max).
    edge_normals: HashMap<(usize, usize), Vector3<f64>>,
    /// Triangles by grid cell (cell size: the mean triangle edge).
    grid: BoxGrid,
    /// Whether every edge is shared by exactly two triangles.
    closed: bool,
    /// Bounding box of the vertices (m).
    bounds: (Vector3<f64>, Vector3<f64>),
}

impl PartialEq for ObstacleSurface {
    fn eq(&self, other: &Self) -> bool {
        self.vertices == other.vertices && self.triangles == other.triangles
    }
}

/// The feature of a triangle that holds the closest point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Feature {
    Face,
    Edge(usize, usize),
    Vertex(usize),
}

/// Closest point to `p` on triangle (a, b, c) and the feature it lies on (local indices 0–2),
/// by Voronoi regions of the vertices, edges and face.
pub(crate) fn closest_on_triangle(
    p: Vector3<f64>,
    [a, b, c]: [Vector3<f64>; 3],
) -> (Vector3<f64>, Feature) {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Feature::Vertex(0));
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (a + ab * (d1 / (d1 - d3)), Feature::Edge(0, 1));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (a + ac * (d2 / (d2 - d6)), Feature::Edge(0, 2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Feature::Edge(1, 2));
    }
    let denom = 1.0 / (va + vb + vc);
    (a + ab * (vb * denom) + ac * (vc * denom), Feature::Face)
}

/// The plane a node gets from an obstacle surface: through `point` with outward unit
/// `normal`; `gap` = (x − point)·normal (m), negative inside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPlane {
    /// Closest surface point (m, body frame).
    pub point: Vector3<f64>,
    /// Outward unit normal.
    pub normal: Vector3<f64>,
    /// Signed distance (m).
    pub gap: f64,
}

impl ObstacleSurface {
    /// Prepares `surface` (checked by its reader) for queries.
    pub fn new(surface: &TriSurface) -> Self {
        let vertices = surface.vertices.clone();
        let triangles = surface.triangles.clone();
        let mut face_normals = Vec::with_capacity(triangles.len());
        let mut vertex_normals = vec![Vector3::zeros(); vertices.len()];
        let mut edge_normals: HashMap<(usize, usize), Vector3<f64>> = HashMap::new();
        let mut edge_uses: HashMap<(usize, usize), u32> = HashMap::new();
        let mut edge_sum = 0.0;
        for t in &triangles {
            let p = t.map(|i| vertices[i]);
            let n = (p[1] - p[0]).cross(&(p[2] - p[0])).normalize();
            face_normals.push(n);
            for k in 0..3 {
                let (e1, e2) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                let angle = e1.normalize().dot(&e2.normalize()).clamp(-1.0, 1.0).acos();
                vertex_normals[t[k]] += angle * n;
                let (i, j) = (t[k], t[(k + 1) % 3]);
                *edge_normals.entry((i.min(j), i.max(j))).or_default() += n;
                *edge_uses.entry((i.min(j), i.max(j))).or_default() += 1;
                edge_sum += e1.norm();
            }
        }
        for n in vertex_normals.iter_mut().chain(edge_normals.values_mut()) {
            *n = n.try_normalize(0.0).unwrap_or_else(Vector3::z);
        }
        let mut grid = BoxGrid::new(edge_sum / (3.0 * triangles.len().max(1) as f64));
        for (f, t) in triangles.iter().enumerate() {
            let p = t.map(|i| vertices[i]);
            grid.insert(
                &p[0].inf(&p[1]).inf(&p[2]),
                &p[0].sup(&p[1]).sup(&p[2]),
                f as u32,
            );
        }
        let bounds = vertices.iter().fold(
            (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), v| (lo.inf(v), hi.sup(v)),
        );
        ObstacleSurface {
            closed: !edge_uses.is_empty() && edge_uses.values().all(|&k| k == 2),
            vertices,
            triangles,
            face_normals,
            vertex_normals,
            edge_normals,
            grid,
            bounds,
        }
    }

    /// The bounding box of its vertices at t = 0 (min, max; m).
    pub fn bounds(&self) -> (Vector3<f64>, Vector3<f64>) {
        self.bounds
    }

    /// Whether the surface is closed (every edge shared by exactly two triangles), so that
    /// it has an inside.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Signed distance from `x` (body frame, m) to the surface, however far: negative inside.
    /// For a closed surface inside is told by the winding number (whatever the triangles'
    /// orientation); for an open one it is the side its normals point away from. Visits every
    /// triangle of a far point's reach (and every triangle for the winding number).
    pub fn signed_distance(&self, x: Vector3<f64>) -> f64 {
        let (lo, hi) = self.bounds;
        // The farthest corner of the bounding box bounds the distance to every vertex.
        let reach = (x - lo).abs().sup(&(x - hi).abs()).norm() * (1.0 + 1e-12);
        let gap = self.closest(x, reach).map_or(f64::INFINITY, |c| c.gap);
        if !self.closed {
            return gap;
        }
        let inside = winding_number(&self.vertices, &self.triangles, &x).abs() > 0.5;
        if inside {
            -gap.abs()
        } else {
            gap.abs()
        }
    }

    /// The plane of the surface point closest to `x` (body frame, m), if one lies within
    /// `radius` (m).
    pub fn closest(&self, x: Vector3<f64>, radius: f64) -> Option<ClosestPlane> {
        let mut best: Option<(f64, usize, Vector3<f64>, Feature)> = None;
        let (lo, hi) = (x.add_scalar(-radius), x.add_scalar(radius));
        self.grid.overlapping(&lo, &hi, |f| {
            let f = f as usize;
            let t = self.triangles[f].map(|i| self.vertices[i]);
            let (q, feature) = closest_on_triangle(x, t);
            let d = (x - q).norm_squared();
            // Ties go to the lower triangle index, whatever order the grid yields them in.
            // Strictly closer only: ties go to the first triangle in the grid's (fixed) order.
            if d <= radius * radius && best.is_none_or(|b| d < b.0) {
                best = Some((d, f, q, feature));
            }
        });
        let (_, f, q, feature) = best?;
        let t = self.triangles[f];
        let pseudo = match feature {
            Feature::Face => {
                let n = self.face_normals[f];
                return Some(ClosestPlane {
                    point: q,
                    normal: n,
                    gap: (x - q).dot(&n),
                });
            }
            Feature::Edge(i, j) => self.edge_normals[&(t[i].min(t[j]), t[i].max(t[j]))],
            Feature::Vertex(i) => self.vertex_normals[t[i]],
        };
        let d = x - q;
        let side = if d.dot(&pseudo) < 0.0 { -1.0 } else { 1.0 };
        let normal = (side * d).try_normalize(1e-14 * radius).unwrap_or(pseudo);
        Some(ClosestPlane {
            point: q,
            normal,
            gap: d.dot(&normal),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> ObstacleSurface {
        // Unit cube [0, 1]³, two outward triangles per face.
        let (vertices, triangles) = crate::mesh::surface::box_surface(0.0, 1.0, 0);
        ObstacleSurface::new(&TriSurface {
            vertices,
            triangles,
        })
    }

    #[test]
    fn face_edge_and_vertex_regions_give_signed_distances() {
        let c = cube();
        // Above the top face, and 0.1 inside under it.
        let p = c.closest(Vector3::new(0.3, 0.6, 1.2), 1.0).unwrap();
        assert!((p.gap - 0.2).abs() < 1e-15 && (p.normal - Vector3::z()).norm() < 1e-15);
        let p = c.closest(Vector3::new(0.3, 0.6, 0.9), 1.0).unwrap();
        assert!((p.gap + 0.1).abs() < 1e-15 && (p.normal - Vector3::z()).norm() < 1e-15);
        // Beyond the edge x = 1, z = 1: distance √(0.1² + 0.2²), normal along the offset.
        let x = Vector3::new(1.1, 0.5, 1.2);
        let p = c.closest(x, 1.0).unwrap();
        assert!((p.gap - 0.05f64.sqrt()).abs() < 1e-15);
        assert!((p.normal - Vector3::new(0.1, 0.0, 0.2).normalize()).norm() < 1e-14);
        // Beyond the corner (1, 1, 1).
        let p = c.closest(Vector3::new(1.1, 1.1, 1.1), 1.0).unwrap();
        assert!((p.gap - 0.03f64.sqrt()).abs() < 1e-15);
        // Out of reach.
        assert!(c.closest(Vector3::new(3.0, 3.0, 3.0), 0.5).is_none());
    }

    #[test]
    fn signed_distance_reaches_deep_inside_and_far_outside_a_closed_surface() {
        let c = cube();
        assert!(c.is_closed());
        // The centre is 0.5 inside; a point 10 away from the face x = 1.
        assert!((c.signed_distance(Vector3::new(0.5, 0.5, 0.5)) + 0.5).abs() < 1e-15);
        assert!((c.signed_distance(Vector3::new(11.0, 0.5, 0.5)) - 10.0).abs() < 1e-12);
        // One face of it alone is open.
        let mut open = TriSurface {
            vertices: c.vertices.clone(),
            triangles: c.triangles.clone(),
        };
        open.triangles.truncate(2);
        assert!(!ObstacleSurface::new(&open).is_closed());
    }

    #[test]
    fn closest_point_matches_brute_force_sampling() {
        // The Voronoi-region answer is never farther than any sampled point of the triangle.
        let t = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.2, 0.1),
            Vector3::new(0.3, 0.9, -0.2),
        ];
        for k in 0..200 {
            let s = k as f64;
            let p = Vector3::new(
                (s * 0.37).sin() * 2.0,
                (s * 0.71).cos() * 2.0,
                (s * 0.13).sin(),
            );
            let (q, _) = closest_on_triangle(p, t);
            let d = (p - q).norm();
            for i in 0..=20 {
                for j in 0..=(20 - i) {
                    let (u, v) = (i as f64 / 20.0, j as f64 / 20.0);
                    let sample = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                    assert!(d <= (p - sample).norm() + 1e-12);
                }
            }
        }
    }
}
