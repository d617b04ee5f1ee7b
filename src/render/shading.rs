//! Smooth shading: normals per triangle corner (averaged over the faces around a vertex that
//! meet it at less than the feature angle, so that creases stay sharp), element fields
//! averaged to the nodes, and the lighting of a surface point.

use super::raster::Rgb;
use nalgebra::Vector3;

/// A unit normal per corner of each triangle of `surface` (node indices into `positions`):
/// the area-weighted mean of the normals of the triangles at that corner's node whose normal
/// is within `feature_deg` of this triangle's. A flat triangle (zero area) gets zeros.
pub fn corner_normals(
    surface: &[([usize; 3], usize)],
    positions: &[Vector3<f64>],
    feature_deg: f64,
) -> Vec<[Vector3<f64>; 3]> {
    // Area-weighted (unnormalised) face normals, and the faces at each node.
    let area_normals: Vec<Vector3<f64>> = surface
        .iter()
        .map(|(n, _)| {
            let x = n.map(|i| positions[i]);
            (x[1] - x[0]).cross(&(x[2] - x[0]))
        })
        .collect();
    let mut faces_at = vec![Vec::new(); positions.len()];
    for (f, (nodes, _)) in surface.iter().enumerate() {
        for &i in nodes {
            faces_at[i].push(f);
        }
    }
    let cos_feature = feature_deg.to_radians().cos();
    surface
        .iter()
        .enumerate()
        .map(|(f, (nodes, _))| {
            let own = area_normals[f].try_normalize(0.0).unwrap_or_default();
            nodes.map(|i| {
                let sum: Vector3<f64> = faces_at[i]
                    .iter()
                    .map(|&g| area_normals[g])
                    .filter(|n| {
                        n.try_normalize(0.0)
                            .is_some_and(|u| u.dot(&own) >= cos_feature)
                    })
                    .sum();
                sum.try_normalize(0.0).unwrap_or(own)
            })
        })
        .collect()
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
        let facing = if normal.dot(&self.half) < 0.0 {
            -normal
        } else {
            normal
        };
        let diffuse = facing.dot(&self.to_light).abs();
        let highlight = self.specular * facing.dot(&self.half).max(0.0).powi(SHININESS);
        color.map(|c| (c * (AMBIENT + (1.0 - AMBIENT) * diffuse) + highlight).min(1.0))
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
