//! Clipping to the camera's view before projection: a surface that reaches behind the eye
//! (a ground plane under it) or far past the picture's edges would otherwise project to
//! points at infinity, or wrap around through the eye. Triangles and segments are cut to the
//! part in front of a near plane and within a guard band around the picture, so that every
//! point left projects to finite coordinates the rasteriser accepts.

use super::Camera;
use nalgebra::Vector3;

/// A surface point being clipped: position (m) and normal (unit, or zero for none); clipping
/// interpolates both linearly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vertex {
    /// Position (m).
    pub x: Vector3<f64>,
    /// Normal (unit or zero).
    pub n: Vector3<f64>,
}

impl Vertex {
    /// The point `t` of the way from `self` to `other` (t in [0, 1]).
    fn lerp(&self, other: &Vertex, t: f64) -> Vertex {
        Vertex {
            x: self.x + (other.x - self.x) * t,
            n: self.n + (other.n - self.n) * t,
        }
    }
}

/// A triangle with a normal at each corner.
pub type Facet = [Vertex; 3];

/// What a camera can draw: the points past a near plane that project within a guard band
/// around the picture, as the intersection of five half-spaces a·x + b ≥ 0 (x in m), and of
/// any further bounds (a cut).
#[derive(Clone)]
pub struct Frustum {
    planes: Vec<(Vector3<f64>, f64)>,
}

impl Frustum {
    /// The view of `camera`, from `near` (m) in front of the eye, the guard band as wide as
    /// the picture's larger side (so that projected points stay within three picture sides
    /// of its corner, far inside what the rasteriser takes).
    pub fn new(camera: &Camera, near: f64) -> Self {
        let (width, height) = camera.picture_size();
        Frustum {
            planes: camera.view_planes(near, width.max(height)).to_vec(),
        }
    }

    /// This view with the half-space `a·x + b ≥ 0` (x in m) as a further bound.
    pub fn bounded_by(&self, a: Vector3<f64>, b: f64) -> Self {
        let mut planes = self.planes.clone();
        planes.push((a, b));
        Frustum { planes }
    }

    /// The part of `triangle` inside the view, as triangles (none when it is all outside).
    pub fn clip_triangle(&self, triangle: Facet) -> Vec<Facet> {
        let mut polygon = triangle.to_vec();
        for (a, b) in &self.planes {
            if polygon.is_empty() {
                break;
            }
            let side = |v: &Vertex| a.dot(&v.x) + b;
            if polygon.iter().all(|v| side(v) >= 0.0) {
                continue;
            }
            let mut kept = Vec::with_capacity(polygon.len() + 1);
            for (k, v) in polygon.iter().enumerate() {
                let next = &polygon[(k + 1) % polygon.len()];
                let (sv, sn) = (side(v), side(next));
                if sv >= 0.0 {
                    kept.push(*v);
                }
                if (sv >= 0.0) != (sn >= 0.0) {
                    kept.push(crossing((v, sv), (next, sn)));
                }
            }
            polygon = kept;
        }
        // A convex polygon: a fan from its first corner.
        (1..polygon.len().saturating_sub(1))
            .map(|k| [polygon[0], polygon[k], polygon[k + 1]])
            .collect()
    }

    /// The part of the segment `[a, b]` (m) inside the view, if any.
    pub fn clip_segment(&self, a: Vector3<f64>, b: Vector3<f64>) -> Option<[Vector3<f64>; 2]> {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (normal, offset) in &self.planes {
            let (sa, sb) = (normal.dot(&a) + offset, normal.dot(&b) + offset);
            match (sa >= 0.0, sb >= 0.0) {
                (false, false) => return None,
                (false, true) => t0 = t0.max(sa / (sa - sb)),
                (true, false) => t1 = t1.min(sa / (sa - sb)),
                (true, true) => {}
            }
        }
        (t0 <= t1).then(|| [a + (b - a) * t0, a + (b - a) * t1])
    }
}

/// Where the edge between two vertices with signed distances `s` crosses the plane. Always
/// interpolated from the inside vertex, so that the two triangles sharing an edge cut it at
/// bit-identical points (no seam in a translucent surface).
fn crossing((u, su): (&Vertex, f64), (v, sv): (&Vertex, f64)) -> Vertex {
    let ((inside, si), (outside, so)) = if su >= 0.0 {
        ((u, su), (v, sv))
    } else {
        ((v, sv), (u, su))
    };
    inside.lerp(outside, si / (si - so))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{Lens, View};

    /// A camera 1 m from the origin, looking down at it from 30° elevation, for a picture of
    /// 200 × 100 pixels.
    fn camera() -> Camera {
        Camera::fit(
            View::ISO,
            Lens {
                target: Some(Vector3::zeros()),
                distance: Some(1.0),
                ..Lens::default()
            },
            -Vector3::repeat(0.1),
            Vector3::repeat(0.1),
            200,
            100,
        )
    }

    fn vertex(x: Vector3<f64>) -> Vertex {
        Vertex { x, n: Vector3::z() }
    }

    #[test]
    fn a_plane_reaching_behind_the_eye_projects_to_finite_points() {
        let camera = camera();
        let frustum = Frustum::new(&camera, 1e-3);
        let r = 1e4;
        let ground = [
            vertex(Vector3::new(-r, -r, 0.0)),
            vertex(Vector3::new(r, -r, 0.0)),
            vertex(Vector3::new(r, r, 0.0)),
        ];
        let pieces = frustum.clip_triangle(ground);
        assert!(!pieces.is_empty(), "the ground is in view");
        for v in pieces.iter().flatten() {
            let [x, y, depth] = camera.project(v.x);
            assert!(
                depth >= 1e-3 * (1.0 - 1e-9),
                "behind the near plane: {depth}"
            );
            assert!((-201.0..=401.0).contains(&x) && (-201.0..=301.0).contains(&y));
            assert!(
                v.x.z.abs() < 1e-9 && v.n == Vector3::z(),
                "still on the plane"
            );
        }
        // A triangle wholly behind the eye is dropped; one wholly inside is kept as it is.
        let behind = ground.map(|v| vertex(v.x * 1e-4 + camera.eye() * 2.0));
        assert!(frustum.clip_triangle(behind).is_empty());
        let small = ground.map(|v| vertex(v.x * 1e-6));
        assert_eq!(frustum.clip_triangle(small), vec![small]);
    }

    #[test]
    fn segments_are_cut_at_the_near_plane() {
        let camera = camera();
        let frustum = Frustum::new(&camera, 0.01);
        let eye = camera.eye();
        let through = frustum.clip_segment(eye - camera.forward(), eye + camera.forward());
        let [a, b] = through.expect("crosses the view");
        assert!(((a - eye).dot(&camera.forward()) - 0.01).abs() < 1e-12);
        assert!((b - (eye + camera.forward())).norm() < 1e-12);
        assert!(frustum
            .clip_segment(eye - camera.forward(), eye - 2.0 * camera.forward())
            .is_none());
    }
}
