//! The camera: a view direction, a target and a distance (fitted to a box unless given), and a
//! field of view.

use nalgebra::Vector3;
use std::str::FromStr;

/// Where the camera looks from: angles of the direction from the scene's centre to the eye.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// Azimuth (degrees) in the xy plane, from +x towards +y.
    pub azimuth: f64,
    /// Elevation (degrees) above the xy plane (z is up), in [−90, 90].
    pub elevation: f64,
}

impl View {
    /// Three-quarter view from the front right and above, the default.
    pub const ISO: View = View {
        azimuth: -60.0,
        elevation: 30.0,
    };
}

impl FromStr for View {
    type Err = String;

    /// `iso`, `front` (from −y), `side` (from +x), `top`, or `AZIMUTH,ELEVATION` in degrees.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let view = |azimuth, elevation| View { azimuth, elevation };
        match s.trim() {
            "iso" => Ok(View::ISO),
            "front" => Ok(view(-90.0, 0.0)),
            "side" => Ok(view(0.0, 0.0)),
            "top" => Ok(view(-90.0, 90.0)),
            other => {
                let parts: Vec<&str> = other.split(',').collect();
                let [az, el] = parts.as_slice() else {
                    return Err(format!(
                        "view {other:?}: expected iso, front, side, top or AZIMUTH,ELEVATION in degrees"
                    ));
                };
                let number = |t: &str| t.trim().parse::<f64>().ok().filter(|v| v.is_finite());
                match (number(az), number(el)) {
                    (Some(a), Some(e)) if (-90.0..=90.0).contains(&e) => Ok(view(a, e)),
                    _ => Err(format!(
                        "view {other:?}: azimuth and elevation must be numbers (degrees), elevation in [-90, 90]"
                    )),
                }
            }
        }
    }
}

/// Where the camera stands besides its direction: what it looks at, from how far, and how wide.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lens {
    /// The point looked at, at the picture's centre (m); default: the centre of the fitted box.
    pub target: Option<Vector3<f64>>,
    /// Distance from the eye to the target (m); default: the distance at which the fitted box
    /// fills [`FILL`] of the picture along its tighter axis.
    pub distance: Option<f64>,
    /// Vertical field of view (degrees, in (0, 170)).
    pub fov: f64,
}

impl Default for Lens {
    fn default() -> Self {
        Lens {
            target: None,
            distance: None,
            fov: FIELD_OF_VIEW_DEG,
        }
    }
}

/// A perspective camera for a picture of `width × height` pixels.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    eye: Vector3<f64>,
    right: Vector3<f64>,
    up: Vector3<f64>,
    forward: Vector3<f64>,
    /// Focal length (pixels).
    focal: f64,
    /// Pixel position of the optical axis.
    centre: [f64; 2],
}

/// Default vertical field of view (degrees): narrow enough that boxes keep their shape, wide
/// enough for depth.
pub const FIELD_OF_VIEW_DEG: f64 = 30.0;
/// Fraction of the picture the fitted box may fill along its tighter axis.
pub const FILL: f64 = 0.9;

impl Camera {
    /// A camera looking from `view` at the axis-aligned box `[lo, hi]` (m) through `lens`:
    /// at the lens's target (default: the box's centre) from its distance (default: the
    /// distance at which the box's projection reaches [`FILL`] of the picture's half-width or
    /// half-height around the target, whichever is tighter).
    pub fn fit(
        view: View,
        lens: Lens,
        lo: Vector3<f64>,
        hi: Vector3<f64>,
        width: u32,
        height: u32,
    ) -> Self {
        let (az, el) = (view.azimuth.to_radians(), view.elevation.to_radians());
        let towards_eye = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
        let forward = -towards_eye;
        // z is up, unless the camera looks (almost) along z: then the picture's up is the
        // horizontal direction the azimuth names.
        let up_hint = if el.cos() < 1e-3 {
            Vector3::new(-az.cos(), -az.sin(), 0.0) * el.sin().signum()
        } else {
            Vector3::z()
        };
        let right = forward.cross(&up_hint).normalize();
        let up = right.cross(&forward);
        let target = lens.target.unwrap_or((lo + hi) / 2.0);
        let half_fov = lens.fov.to_radians() / 2.0;
        let at = |distance: f64| Camera {
            eye: target + towards_eye * distance,
            right,
            up,
            forward,
            focal: height as f64 / 2.0 / half_fov.tan(),
            centre: [width as f64 / 2.0, height as f64 / 2.0],
        };
        let distance = match lens.distance {
            Some(d) => d,
            None => {
                // How far past FILL the farthest corner projects from the centre (< 1: inside);
                // infinite when a corner is not in front of the eye. It falls as the eye
                // backs away, so bisect on it.
                let corners: Vec<Vector3<f64>> = (0..8)
                    .map(|k| {
                        Vector3::new(
                            if k & 1 == 0 { lo.x } else { hi.x },
                            if k & 2 == 0 { lo.y } else { hi.y },
                            if k & 4 == 0 { lo.z } else { hi.z },
                        )
                    })
                    .collect();
                let reach = |distance: f64| {
                    let camera = at(distance);
                    corners.iter().fold(0.0f64, |r, &c| {
                        let [x, y, depth] = camera.project(c);
                        if depth <= 0.0 {
                            return f64::INFINITY;
                        }
                        r.max((x - camera.centre[0]).abs() / (FILL * width as f64 / 2.0))
                            .max((y - camera.centre[1]).abs() / (FILL * height as f64 / 2.0))
                    })
                };
                let size = (hi - lo).norm().max(1e-12) + (target - (lo + hi) / 2.0).norm();
                let (mut near, mut far) = (0.0, size);
                while reach(far) > 1.0 && far < 1e12 * size {
                    (near, far) = (far, 2.0 * far);
                }
                for _ in 0..100 {
                    let mid = 0.5 * (near + far);
                    if reach(mid) > 1.0 {
                        near = mid;
                    } else {
                        far = mid;
                    }
                }
                far
            }
        };
        at(distance)
    }

    /// The picture position (pixels, x right, y down; continuous, pixel centres at k + ½) and
    /// the depth along the view direction (m) of point `x`.
    pub fn project(&self, x: Vector3<f64>) -> [f64; 3] {
        let d = x - self.eye;
        let depth = d.dot(&self.forward);
        [
            self.centre[0] + self.focal * d.dot(&self.right) / depth,
            self.centre[1] - self.focal * d.dot(&self.up) / depth,
            depth,
        ]
    }

    /// The eye's position (m).
    pub fn eye(&self) -> Vector3<f64> {
        self.eye
    }

    /// The focal length (pixels): the size in pixels of 1 m seen face-on from 1 m away.
    pub fn focal(&self) -> f64 {
        self.focal
    }

    /// The picture's width and height (pixels).
    pub fn picture_size(&self) -> (f64, f64) {
        (2.0 * self.centre[0], 2.0 * self.centre[1])
    }

    /// The half-spaces a·x + b ≥ 0 (x in m) whose intersection is what the picture shows:
    /// the points at least `near` (m) in front of the eye that project within `guard` pixels
    /// outside the picture's edges. Each side plane goes through the eye (projection is
    /// x = centre + focal · lateral / depth, so "x ≥ −guard" is linear in the point once its
    /// depth is positive), in the order near, left, right, top, bottom.
    pub fn view_planes(&self, near: f64, guard: f64) -> [(Vector3<f64>, f64); 5] {
        let (width, height) = self.picture_size();
        let [cx, cy] = self.centre;
        let (f, r, u) = (self.forward, self.right * self.focal, self.up * self.focal);
        let through_eye = |a: Vector3<f64>| (a, -a.dot(&self.eye));
        [
            (f, -f.dot(&self.eye) - near),
            through_eye(r + f * (cx + guard)),
            through_eye(f * (width + guard - cx) - r),
            through_eye(f * (cy + guard) - u),
            through_eye(u + f * (height + guard - cy)),
        ]
    }

    /// The camera's viewing direction (unit).
    pub fn forward(&self) -> Vector3<f64> {
        self.forward
    }

    /// Unit vectors of the picture's right and up directions in the world.
    pub fn right_up(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.right, self.up)
    }

    /// The same camera for a picture `factor` times larger in each direction.
    pub fn scaled(&self, factor: f64) -> Camera {
        Camera {
            focal: self.focal * factor,
            centre: self.centre.map(|c| c * factor),
            ..*self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_parse_and_bad_ones_are_errors() {
        assert_eq!("iso".parse::<View>(), Ok(View::ISO));
        assert_eq!(
            "30, -10".parse::<View>(),
            Ok(View {
                azimuth: 30.0,
                elevation: -10.0
            })
        );
        assert!("30".parse::<View>().unwrap_err().contains("AZIMUTH"));
        assert!("0,95".parse::<View>().unwrap_err().contains("[-90, 90]"));
        assert!("nan,0".parse::<View>().is_err());
    }

    #[test]
    fn fitted_box_fills_the_picture_around_its_centre() {
        let (lo, hi) = (Vector3::zeros(), Vector3::new(0.1, 0.2, 0.05));
        for view in ["iso", "front", "side", "top", "120,-40"] {
            for fov in [10.0, 30.0, 60.0] {
                let lens = Lens {
                    fov,
                    ..Lens::default()
                };
                let camera = Camera::fit(view.parse().unwrap(), lens, lo, hi, 300, 200);
                let mut reach = 0.0f64;
                for k in 0..8 {
                    let c = Vector3::new(
                        [lo.x, hi.x][k & 1],
                        [lo.y, hi.y][(k >> 1) & 1],
                        [lo.z, hi.z][(k >> 2) & 1],
                    );
                    let [x, y, depth] = camera.project(c);
                    assert!(depth > 0.0, "{view}: corner behind the camera");
                    reach = reach
                        .max((x - 150.0).abs() / 150.0)
                        .max((y - 100.0).abs() / 100.0);
                }
                // The box's centre at the picture's centre; its farthest corner at 90 % of
                // the half-width or half-height (bisection to round-off).
                let [x, y, _] = camera.project((lo + hi) / 2.0);
                assert!(
                    (x - 150.0).abs() < 1e-9 && (y - 100.0).abs() < 1e-9,
                    "{view}"
                );
                assert!(
                    (reach - FILL).abs() < 1e-9,
                    "{view} fov {fov}: reach {reach}"
                );
                // The field of view is the one asked for.
                let top = camera.project(
                    camera.eye + camera.forward + camera.up * (fov.to_radians() / 2.0).tan(),
                );
                assert!(
                    top[1].abs() < 1e-9,
                    "{view} fov {fov}: top edge at {}",
                    top[1]
                );
            }
        }
    }

    #[test]
    fn a_given_target_and_distance_place_the_eye() {
        let lens = Lens {
            target: Some(Vector3::new(1.0, 2.0, 3.0)),
            distance: Some(5.0),
            fov: 40.0,
        };
        let camera = Camera::fit(
            View::ISO,
            lens,
            Vector3::zeros(),
            Vector3::repeat(1.0),
            400,
            300,
        );
        assert!(((camera.eye - lens.target.unwrap()).norm() - 5.0).abs() < 1e-12);
        let [x, y, depth] = camera.project(lens.target.unwrap());
        assert!(
            (x - 200.0).abs() < 1e-9 && (y - 150.0).abs() < 1e-9,
            "({x}, {y})"
        );
        assert!((depth - 5.0).abs() < 1e-12);
    }

    #[test]
    fn top_view_keeps_y_up_in_the_picture() {
        let camera = Camera::fit(
            "top".parse().unwrap(),
            Lens::default(),
            Vector3::zeros(),
            Vector3::repeat(1.0),
            100,
            100,
        );
        let a = camera.project(Vector3::new(0.5, 0.0, 1.0));
        let b = camera.project(Vector3::new(0.5, 1.0, 1.0));
        assert!(b[1] < a[1], "+y must point up in a top view");
        let c = camera.project(Vector3::new(1.0, 0.5, 1.0));
        assert!(c[0] > a[0], "+x must point right in a top view");
    }
}
