//! Smooth shading: normals per triangle corner (averaged over the smooth region around a
//! vertex, so that creases stay sharp and smooth regions show no seams), element fields
//! averaged to the nodes, and the lighting of a surface point.

use super::raster::Rgb;
use nalgebra::Vector3;
use petgraph::unionfind::UnionFind;
use std::collections::HashMap;

/// A unit normal per corner of each triangle of `surface` (node indices into `positions`).
///
/// An edge shared by exactly two triangles whose normals differ by less than `feature_deg`
/// (degrees) is smooth; any other edge (sharper, a border, more than two triangles) is a
/// crease. The corners at a node that are joined through smooth edges form one smooth fan,
/// and every corner of a fan gets the same normal: the mean of the fan's face normals, each
/// weighted by the triangle's angle at the node. Deciding per edge, not per triangle, is what
/// keeps two triangles meeting at a smooth vertex from averaging different sets of faces
/// (which shows as light and dark bands on a coarse curved surface). A flat triangle (zero
/// area) keeps a zero normal.
pub fn corner_normals(
    surface: &[([usize; 3], usize)],
    positions: &[Vector3<f64>],
    feature_deg: f64,
) -> Vec<[Vector3<f64>; 3]> {
    let unit: Vec<Vector3<f64>> = surface
        .iter()
        .map(|(n, _)| {
            let x = n.map(|i| positions[i]);
            (x[1] - x[0])
                .cross(&(x[2] - x[0]))
                .try_normalize(0.0)
                .unwrap_or_default()
        })
        .collect();
    // Corner 3 f + k is corner k of triangle f; corners of one fan end up in one set.
    let mut fans = UnionFind::<usize>::new(3 * surface.len());
    let cos_feature = feature_deg.to_radians().cos();
    for sides in edge_sides(surface).values() {
        let &[(f, fa, fb), (g, ga, gb)] = sides.as_slice() else {
            continue; // a border or a non-manifold edge: a crease
        };
        let (u, v) = (unit[f], unit[g]);
        if u != Vector3::zeros() && v != Vector3::zeros() && u.dot(&v) >= cos_feature {
            fans.union(3 * f + fa, 3 * g + ga);
            fans.union(3 * f + fb, 3 * g + gb);
        }
    }
    // Σ angle × unit normal per fan: angle weights do not depend on how a region is split
    // into triangles, so a vertex's normal does not lean towards its many thin triangles.
    let mut sums = vec![Vector3::zeros(); 3 * surface.len()];
    for (f, (nodes, _)) in surface.iter().enumerate() {
        let x = nodes.map(|i| positions[i]);
        for k in 0..3 {
            let (a, b) = (x[(k + 1) % 3] - x[k], x[(k + 2) % 3] - x[k]);
            let angle = if a.norm() > 0.0 && b.norm() > 0.0 {
                a.angle(&b)
            } else {
                0.0
            };
            sums[fans.find_mut(3 * f + k)] += angle * unit[f];
        }
    }
    (0..surface.len())
        .map(|f| {
            std::array::from_fn(|k| {
                sums[fans.find_mut(3 * f + k)]
                    .try_normalize(0.0)
                    .unwrap_or(unit[f])
            })
        })
        .collect()
}

/// Per edge (its nodes, smaller first): (triangle, corner of the smaller node, corner of the
/// larger node) of each triangle along it.
type EdgeSides = HashMap<(usize, usize), Vec<(usize, usize, usize)>>;

/// The triangles along each edge of `surface` (see [`EdgeSides`]).
fn edge_sides(surface: &[([usize; 3], usize)]) -> EdgeSides {
    let mut sides = EdgeSides::new();
    for (f, (nodes, _)) in surface.iter().enumerate() {
        for k in 0..3 {
            let j = (k + 1) % 3;
            let (lo, hi) = if nodes[k] < nodes[j] { (k, j) } else { (j, k) };
            sides
                .entry((nodes[lo], nodes[hi]))
                .or_default()
                .push((f, lo, hi));
        }
    }
    sides
}

/// Element values averaged to the nodes, each element weighted by its volume at `positions`
/// (m³): the smooth field a P1 interpolant of the elements' values would show. Nodes in no
/// element get 0.
pub fn nodal_values(values: &[f64], tets: &[[usize; 4]], positions: &[Vector3<f64>]) -> Vec<f64> {
    let mut sum = vec![0.0; positions.len()];
    let mut weight = vec![0.0; positions.len()];
    for (t, v) in tets.iter().zip(values) {
        let x = t.map(|i| positions[i]);
        let volume = ((x[1] - x[0]).cross(&(x[2] - x[0])))
            .dot(&(x[3] - x[0]))
            .abs()
            / 6.0;
        // A crushed element still counts a little, so every node of the mesh gets a value.
        let w = volume.max(f64::MIN_POSITIVE);
        for &i in t {
            sum[i] += w * v;
            weight[i] += w;
        }
    }
    sum.iter()
        .zip(&weight)
        .map(|(s, w)| if *w > 0.0 { s / w } else { 0.0 })
        .collect()
}

/// A light at infinity and the viewer's direction, for two-sided Blinn–Phong shading.
#[derive(Clone, Copy, Debug)]
pub struct Light {
    /// Unit direction towards the light.
    to_light: Vector3<f32>,
    /// Unit half vector between the light and the eye.
    half: Vector3<f32>,
    /// Strength of the white highlight (0: matte).
    specular: f32,
}

/// Share of light every surface gets whatever its orientation.
const AMBIENT: f32 = 0.45;
/// Sharpness of the highlight (Blinn–Phong exponent).
const SHININESS: i32 = 32;

impl Light {
    /// A light from `to_light` seen from `to_eye` (both pointing away from the surface).
    pub fn new(to_light: Vector3<f64>, to_eye: Vector3<f64>, specular: f32) -> Self {
        let to_light = to_light.normalize().cast::<f32>();
        let half = (to_light + to_eye.normalize().cast::<f32>()).normalize();
        Light {
            to_light,
            half,
            specular,
        }
    }

    /// The colour of a surface of colour `color` with unit normal `normal` (either side
    /// faces the viewer: crack faces and cut faces are seen from both).
    pub fn shade(&self, color: Rgb, normal: Vector3<f32>) -> Rgb {
        let diffuse = self.facing(normal).dot(&self.to_light).abs();
        let highlight = self.highlight(normal);
        color.map(|c| (c * (AMBIENT + (1.0 - AMBIENT) * diffuse) + highlight).min(1.0))
    }

    /// The white highlight's strength on a surface with unit normal `normal` (0 … the
    /// light's specular strength), which [`Light::shade`] adds to the colour.
    pub fn highlight(&self, normal: Vector3<f32>) -> f32 {
        self.specular * self.facing(normal).dot(&self.half).max(0.0).powi(SHININESS)
    }

    /// `normal` or its opposite, whichever faces the viewer's side.
    fn facing(&self, normal: Vector3<f32>) -> Vector3<f32> {
        if normal.dot(&self.half) < 0.0 {
            -normal
        } else {
            normal
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Surface = Vec<([usize; 3], usize)>;

    /// A unit cube's surface, two triangles per face, outward.
    fn cube() -> (Surface, Vec<Vector3<f64>>) {
        let (x, triangles) = crate::mesh::surface::box_surface(0.0, 1.0, 0);
        (triangles.into_iter().map(|t| (t, 0)).collect(), x)
    }

    #[test]
    fn creases_stay_sharp_and_smooth_surfaces_average() {
        let (tris, x) = cube();
        // 30°: each corner keeps its face's normal (faces meet at 90°).
        for (t, n) in tris.iter().zip(corner_normals(&tris, &x, 30.0)) {
            let face = (x[t.0[1]] - x[t.0[0]])
                .cross(&(x[t.0[2]] - x[t.0[0]]))
                .normalize();
            for c in n {
                assert!((c - face).norm() < 1e-12);
            }
        }
        // 100°: every corner of the cube averages its three faces: the diagonal direction
        // (area weights: the corner's node has one or two triangles of each face, so test
        // only the direction's octant and unit length).
        for n in corner_normals(&tris, &x, 100.0).iter().flatten() {
            assert!((n.norm() - 1.0).abs() < 1e-12);
            assert!(
                n.iter().all(|c| c.abs() > 0.2),
                "{n:?} is not a corner normal"
            );
        }
    }

    /// A coarse open tube: a cylinder of radius 1 from z = 0 to 1 (16 sides, 22.5° apart)
    /// and a cone on it whose side is tilted 25° inwards, each ring of quads split into
    /// triangles, outward.
    fn cylinder_and_cone() -> (Surface, Vec<Vector3<f64>>) {
        const SIDES: usize = 16;
        let tilt = 25f64.to_radians();
        let rings = [
            (1.0, 0.0),
            (1.0, 1.0),
            (1.0 - 0.5 * tilt.sin(), 1.0 + 0.5 * tilt.cos()),
        ];
        let mut x = Vec::new();
        for (r, z) in rings {
            for k in 0..SIDES {
                let a = std::f64::consts::TAU * k as f64 / SIDES as f64;
                x.push(Vector3::new(r * a.cos(), r * a.sin(), z));
            }
        }
        let mut tris = Vec::new();
        for ring in 0..2 {
            for k in 0..SIDES {
                let at = |ring: usize, k: usize| ring * SIDES + k % SIDES;
                let (a, b) = (at(ring, k), at(ring, k + 1));
                let (c, d) = (at(ring + 1, k + 1), at(ring + 1, k));
                tris.push(([a, b, c], 0));
                tris.push(([a, c, d], 0));
            }
        }
        (tris, x)
    }

    #[test]
    fn a_smooth_vertex_has_one_normal_across_a_gentle_shoulder() {
        let (tris, x) = cylinder_and_cone();
        let normals = corner_normals(&tris, &x, 30.0);
        let face = |t: &[usize; 3]| (x[t[1]] - x[t[0]]).cross(&(x[t[2]] - x[t[0]])).normalize();
        let mut at_node: Vec<Vec<(Vector3<f64>, Vector3<f64>)>> = vec![Vec::new(); x.len()];
        for ((t, _), n) in tris.iter().zip(&normals) {
            for k in 0..3 {
                at_node[t[k]].push((n[k], face(t)));
            }
        }
        let cos30 = 30f64.to_radians().cos();
        // Every edge bends by less than 30° (22.5° round, 25° at the shoulder), but faces at a
        // shoulder vertex differ by more (both at once): a per-triangle choice of neighbours
        // within 30° averages different faces at each corner there.
        let shoulder = &at_node[16];
        assert!(shoulder
            .iter()
            .any(|(_, f)| shoulder.iter().any(|(_, g)| f.dot(g) < cos30)));
        // Yet all corners at each vertex share one normal, tilted between cylinder and cone.
        for corners in &at_node {
            for (n, _) in corners {
                assert!((n - corners[0].0).norm() < 1e-12, "{n} vs {}", corners[0].0);
            }
        }
        let n = shoulder[0].0;
        let radial = Vector3::new(1.0, 0.0, 0.0);
        assert!(n.z > 0.05 && n.dot(&radial) > 0.9, "{n}");
    }

    #[test]
    fn nodal_values_are_volume_weighted_means() {
        // Two tets sharing face (1, 2, 3); the second twice the volume of the first.
        let x: Vec<Vector3<f64>> = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(2.0, 2.0, 2.0),
        ];
        let tets = [[0, 1, 2, 3], [4, 1, 2, 3]];
        let v0 = 1.0 / 6.0;
        let v1: f64 = ((x[1] - x[4]).cross(&(x[2] - x[4])))
            .dot(&(x[3] - x[4]))
            .abs()
            / 6.0;
        let nodal = nodal_values(&[1.0, 4.0], &tets, &x);
        assert_eq!(nodal[0], 1.0);
        assert_eq!(nodal[4], 4.0);
        let shared = (v0 * 1.0 + v1 * 4.0) / (v0 + v1);
        assert!(
            (nodal[1] - shared).abs() < 1e-12,
            "{} vs {shared}",
            nodal[1]
        );
    }

    #[test]
    fn lighting_is_two_sided_with_a_highlight_towards_the_half_vector() {
        let light = Light::new(Vector3::z(), Vector3::z(), 0.25);
        let white = [0.5; 3];
        let up = light.shade(white, Vector3::z());
        let down = light.shade(white, -Vector3::z());
        assert_eq!(up, down);
        assert!(
            (up[0] - (0.5 + 0.25)).abs() < 1e-6,
            "full diffuse and highlight: {up:?}"
        );
        let grazing = light.shade(white, Vector3::x());
        assert!(
            (grazing[0] - 0.5 * AMBIENT).abs() < 1e-6,
            "ambient only: {grazing:?}"
        );
    }
}
