//! The obstacles as pictures draw them (exports keep [`super::obstacles`]' finite surfaces):
//! containers and mesh obstacles as translucent, glass-like surfaces, more opaque where seen
//! edge-on, so that the ice inside shows; half-spaces as opaque ground planes reaching the
//! horizon, with a faint checker that fades with distance.

use super::clip::{Facet, Vertex};
use super::obstacles::StoredObstacle;
use super::raster::Rgb;
use super::shading::{self, Light};
use super::FEATURE_ANGLE_DEG;
use crate::physics::Motion;
use nalgebra::Vector3;

/// Glass tint (display RGB): a faint cool grey, so that glass reads over white ice too.
const GLASS_TINT: Rgb = [0.62, 0.72, 0.76];
/// Opacity of glass seen face-on …
const GLASS_FACING: f32 = 0.10;
/// … and edge-on (a Fresnel-like rise, so that walls seen at a slant and silhouettes show).
const GLASS_GRAZING: f32 = 0.55;
/// The ground's two checker colours (display RGB).
const GROUND: [Rgb; 2] = [[0.74, 0.74, 0.72], [0.69, 0.69, 0.67]];
/// Distance over which the ground fades to the horizon's colour, in scene sizes (the
/// diagonal of the box around the first frame and the obstacles).
const HAZE_SCENES: f64 = 30.0;
/// Half-side of the drawn ground square, in scene sizes (or in eye heights above the
/// ground, if more): far enough that its end is within a few pixels of the horizon, where
/// the haze has made it the horizon's colour; near enough that positions interpolated in
/// single precision stay within a thousandth of a checker cell near the eye.
const GROUND_REACH: f64 = 1000.0;
/// Most triangles a glass obstacle is split into (see [`glass_facets`]).
const MAX_GLASS_FACETS: usize = 20_000;

/// One obstacle as drawn.
pub enum Scenery {
    /// A translucent surface: its facets at t = 0 and its motion.
    Glass(Vec<Facet>, Motion),
    /// An infinite plane.
    Ground(Ground),
}

impl Scenery {
    /// How `obstacle` is drawn in a scene `scale` m across: a half-space as a ground plane,
    /// anything else as glass.
    pub fn new(obstacle: &StoredObstacle, scale: f64) -> Option<Self> {
        let surface = &obstacle.surface;
        if obstacle.kind == "halfspace" {
            // Its stored surface is a square on the plane facing out of the solid.
            let x = surface.triangles.first()?.map(|i| surface.vertices[i]);
            let normal = (x[1] - x[0]).cross(&(x[2] - x[0])).try_normalize(0.0)?;
            return Some(Scenery::Ground(Ground {
                point: x[0],
                normal,
                motion: obstacle.motion.clone(),
                cell: checker_cell(scale),
                haze: HAZE_SCENES * scale,
                scale,
            }));
        }
        let triangles: Vec<([usize; 3], usize)> =
            surface.triangles.iter().map(|&t| (t, 0)).collect();
        let normals = shading::corner_normals(&triangles, &surface.vertices, FEATURE_ANGLE_DEG);
        let facets: Vec<Facet> = triangles
            .iter()
            .zip(normals)
            .map(|((t, _), n)| {
                std::array::from_fn(|k| Vertex {
                    x: surface.vertices[t[k]],
                    n: n[k],
                })
            })
            .collect();
        Some(Scenery::Glass(
            glass_facets(&facets, scale),
            obstacle.motion.clone(),
        ))
    }
}

/// `facets` split evenly into n × n triangles each, n such that no edge is longer than an
/// eighth of `scale` (m), within [`MAX_GLASS_FACETS`] in all. Glass is blended back to
/// front by each triangle's centre: a container's wall as two triangles would sort as a
/// whole before or after all of the ice, small pieces sort among the ice's triangles where
/// they are. One n for the whole surface keeps it without T-junctions (which would show as
/// seams in a translucent surface).
fn glass_facets(facets: &[Facet], scale: f64) -> Vec<Facet> {
    let longest = facets
        .iter()
        .flat_map(|f| (0..3).map(|k| (f[(k + 1) % 3].x - f[k].x).norm()))
        .fold(0.0, f64::max);
    let wanted = (8.0 * longest / scale).ceil().max(1.0) as usize;
    let most = ((MAX_GLASS_FACETS / facets.len().max(1)) as f64).sqrt() as usize;
    let n = wanted.min(most).max(1);
    facets.iter().flat_map(|f| subdivide(f, n)).collect()
}

/// `facet` as n² triangles of the same orientation, positions and normals interpolated.
fn subdivide(facet: &Facet, n: usize) -> Vec<Facet> {
    let at = |i: usize, j: usize| {
        let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
        interpolate(facet, [1.0 - s - t, s, t])
    };
    let mut out = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n - i {
            out.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
            if i + j + 1 < n {
                out.push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
    }
    out
}

/// The point of `facet` with barycentric weights `w`.
pub fn interpolate(facet: &Facet, w: [f64; 3]) -> Vertex {
    Vertex {
        x: facet[0].x * w[0] + facet[1].x * w[1] + facet[2].x * w[2],
        n: facet[0].n * w[0] + facet[1].n * w[1] + facet[2].n * w[2],
    }
}

/// `facet` moved as `motion` takes it at time `t` (s): positions placed, normals turned.
pub fn moved(facet: &Facet, motion: &Motion, t: f64) -> Facet {
    facet.map(|v| {
        let x = motion.position(t, &v.x);
        // The motion is rigid (affine), so the image of a point one normal away gives the
        // turned normal.
        Vertex {
            x,
            n: motion.position(t, &(v.x + v.n)) - x,
        }
    })
}

/// The colour and opacity of glass at each corner of `facet`, seen from `eye` (m), lit by
/// `light`: faintly tinted, more opaque edge-on and under the highlight. Evaluated at the
/// corners and interpolated across (the facets are small, see [`glass_facets`]): per pixel
/// it would double the time to draw a container.
pub fn glass_corners(facet: &Facet, eye: Vector3<f64>, light: &Light) -> [(Rgb, f32); 3] {
    let face = (facet[1].x - facet[0].x).cross(&(facet[2].x - facet[0].x));
    facet.map(|v| {
        let n =
            v.n.try_normalize(0.0)
                .or(face.try_normalize(0.0))
                .unwrap_or_default();
        let cos = (eye - v.x)
            .try_normalize(0.0)
            .map_or(1.0, |d| n.dot(&d).abs()) as f32;
        // Schlick's (1 − cos θ)⁵ rises too late for a picture: a cube keeps more of the rim.
        let rim = (1.0 - cos).powi(3);
        let n = n.cast::<f32>();
        // The highlight makes the glass a little more opaque too: a reflection hides what is
        // behind it.
        let alpha = GLASS_FACING + (GLASS_GRAZING - GLASS_FACING) * rim + 0.5 * light.highlight(n);
        (light.shade(GLASS_TINT, n), alpha.min(1.0))
    })
}

/// A half-space's plane as a ground.
pub struct Ground {
    /// A point of the plane at t = 0 (m).
    point: Vector3<f64>,
    /// Its unit normal at t = 0, out of the solid side.
    normal: Vector3<f64>,
    motion: Motion,
    /// Side of a checker cell (m).
    cell: f64,
    /// Distance over which the ground fades into the horizon's colour (m).
    haze: f64,
    /// Size of the scene (m).
    scale: f64,
}

impl Ground {
    /// The ground where its motion has it at time `t` (s).
    pub fn at(&self, t: f64) -> PlacedGround {
        let origin = self.motion.position(t, &self.point);
        // The motion is rigid: the images of points one unit away give the turned axes.
        let turned =
            |d: Vector3<f64>| (self.motion.position(t, &(self.point + d)) - origin).normalize();
        let (u, v) = plane_axes(self.normal);
        PlacedGround {
            origin,
            normal: turned(self.normal),
            u: turned(u),
            v: turned(v),
            cell: self.cell,
            haze: self.haze,
            scale: self.scale,
        }
    }
}

/// Two unit vectors that make a right-handed frame (u, v, normal) with the unit `normal`.
fn plane_axes(normal: Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = normal.cross(&helper).normalize();
    (u, normal.cross(&u))
}

/// A ground at one time: the plane with its checker's axes.
pub struct PlacedGround {
    /// Corner of a checker cell, on the plane (m).
    origin: Vector3<f64>,
    /// Unit normal, out of the solid side.
    normal: Vector3<f64>,
    /// The checker's unit axes in the plane.
    u: Vector3<f64>,
    v: Vector3<f64>,
    /// Side of a checker cell (m).
    cell: f64,
    /// Distance over which the ground fades into the horizon's colour (m).
    haze: f64,
    /// Size of the scene (m).
    scale: f64,
}

impl PlacedGround {
    /// Whether `eye` (m) is on the open side of the plane: the ground is then seen from above
    /// and drawn opaque; seen from the solid side it would hide the whole scene.
    pub fn seen_from_above(&self, eye: Vector3<f64>) -> bool {
        (eye - self.origin).dot(&self.normal) > 0.0
    }

    /// The ground as two triangles: a square of [`GROUND_REACH`] around the foot of `eye`
    /// (m), to be clipped to the view.
    pub fn facets(&self, eye: Vector3<f64>) -> [Facet; 2] {
        let height = (eye - self.origin).dot(&self.normal);
        let foot = eye - self.normal * height;
        let r = GROUND_REACH * self.scale.max(height.abs());
        let corner = |a: f64, b: f64| Vertex {
            x: foot + self.u * (r * a) + self.v * (r * b),
            n: self.normal,
        };
        let c = [
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
        ];
        // (u, v, normal) is right-handed, so corners in this order turn about the normal.
        [[c[0], c[1], c[2]], [c[0], c[2], c[3]]]
    }

    /// The ground's colour at `x` (m), seen from `eye` (m) through a camera of focal length
    /// `focal` (pixels), lit by `light`, fading into `horizon` with distance.
    pub fn shade(
        &self,
        x: Vector3<f64>,
        eye: Vector3<f64>,
        focal: f64,
        light: &Light,
        horizon: Rgb,
    ) -> Rgb {
        let d = x - self.origin;
        let cell = |along: f64| (along / self.cell).floor() as i64;
        let odd = (cell(d.dot(&self.u)) + cell(d.dot(&self.v))).rem_euclid(2) == 1;
        // A cell's size in pixels across its foreshortened side: below a few pixels the
        // checker would alias into moiré, so its contrast fades out before.
        let distance = (eye - x).norm().max(1e-12);
        let slant = (eye - x).dot(&self.normal).abs() / distance;
        let footprint = self.cell * focal * slant / distance;
        let contrast = ((footprint - 3.0) / 9.0).clamp(0.0, 1.0) as f32;
        let base: Rgb = std::array::from_fn(|k| {
            let mean = 0.5 * (GROUND[0][k] + GROUND[1][k]);
            let half = 0.5 * (GROUND[1][k] - GROUND[0][k]) * contrast;
            if odd {
                mean + half
            } else {
                mean - half
            }
        });
        let lit = light.shade(base, self.normal.cast());
        let fog = (1.0 - (-distance / self.haze).exp()) as f32;
        std::array::from_fn(|k| lit[k] + (horizon[k] - lit[k]) * fog)
    }
}

/// A round checker cell (1, 2 or 5 × 10ⁿ m) of about a fifth of `scale` (m).
fn checker_cell(scale: f64) -> f64 {
    let target = scale.max(1e-9) / 5.0;
    let decade = 10f64.powf(target.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&c| c <= target)
        .unwrap_or(decade)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit right triangle at the origin in the xy plane, with corner normals `n`.
    fn unit_facet(n: [Vector3<f64>; 3]) -> Facet {
        let x = [Vector3::zeros(), Vector3::x(), Vector3::y()];
        std::array::from_fn(|k| Vertex { x: x[k], n: n[k] })
    }

    #[test]
    fn subdivision_keeps_area_orientation_and_normals() {
        let f = unit_facet([Vector3::z(), Vector3::x(), Vector3::y()]);
        let area = |f: &Facet| (f[1].x - f[0].x).cross(&(f[2].x - f[0].x)) / 2.0;
        for n in [1, 2, 5] {
            let pieces = subdivide(&f, n);
            assert_eq!(pieces.len(), n * n);
            let total: Vector3<f64> = pieces.iter().map(area).sum();
            assert!((total - area(&f)).norm() < 1e-12, "{n}: {total}");
            assert!(pieces.iter().all(|p| area(p).z > 0.0));
        }
        // Normals interpolate: the middle of the long edge gets the mean of its ends.
        let mid = interpolate(&f, [0.0, 0.5, 0.5]);
        assert!((mid.n - Vector3::new(0.5, 0.5, 0.0)).norm() < 1e-15);
    }

    #[test]
    fn glass_is_more_opaque_edge_on() {
        let light = Light::new(Vector3::new(0.3, 0.2, 1.0), Vector3::z(), 0.0);
        let f = unit_facet([Vector3::z(); 3]);
        let (_, face_on) = glass_corners(&f, Vector3::new(0.0, 0.0, 5.0), &light)[0];
        let (_, edge_on) = glass_corners(&f, Vector3::new(5.0, 0.0, 0.1), &light)[0];
        assert!((face_on - GLASS_FACING).abs() < 1e-3, "{face_on}");
        assert!(edge_on > 0.45, "{edge_on}");
    }

    #[test]
    fn checker_cells_are_round() {
        for (scale, cell) in [(0.35, 0.05), (1.0, 0.2), (3.0, 0.5), (40.0, 5.0)] {
            assert!((checker_cell(scale) - cell).abs() < 1e-12 * cell, "{scale}");
        }
    }
}
