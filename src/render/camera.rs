//! The camera: a view direction, fitted to a box so that the box fills the picture.

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

/// Vertical field of view: narrow enough that boxes keep their shape, wide enough for depth.
const FIELD_OF_VIEW_DEG: f64 = 30.0;
/// Fraction of the picture the fitted box may fill along its tighter axis.
const FILL: f64 = 0.9;

impl Camera {
    /// A camera looking from `view` at the axis-aligned box `[lo, hi]` (m), placed so that the
    /// box's projection fills [`FILL`] of the picture along its tighter axis, centred.
    pub fn fit(view: View, lo: Vector3<f64>, hi: Vector3<f64>, width: u32, height: u32) -> Self {
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
        let centre_box = (lo + hi) / 2.0;
        let radius = ((hi - lo).norm() / 2.0).max(1e-12);
        let half_fov = (FIELD_OF_VIEW_DEG.to_radians()) / 2.0;
        let eye = centre_box + towards_eye * (radius / half_fov.sin());
        let mut camera = Camera {
            eye,
            right,
            up,
            forward,
            focal: 1.0,
            centre: [0.0, 0.0],
        };
        // Fit: the corners' projections at unit focal length give the extent to scale up.
        let corners = (0..8).map(|k| {
            Vector3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            )
        });
        let (mut min, mut max) = ([f64::MAX; 2], [f64::MIN; 2]);
        for c in corners {
            let [x, y, _] = camera.project(c);
            min = [min[0].min(x), min[1].min(y)];
            max = [max[0].max(x), max[1].max(y)];
        }
        let extent = [(max[0] - min[0]).max(1e-12), (max[1] - min[1]).max(1e-12)];
        camera.focal = FILL * (width as f64 / extent[0]).min(height as f64 / extent[1]);
        let mid = [(min[0] + max[0]) / 2.0, (min[1] + max[1]) / 2.0];
        camera.centre = [
            width as f64 / 2.0 - camera.focal * mid[0],
            height as f64 / 2.0 - camera.focal * mid[1],
        ];
        camera
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
    fn fitted_box_fills_the_picture_centred() {
        let (lo, hi) = (Vector3::zeros(), Vector3::new(0.1, 0.2, 0.05));
        for view in ["iso", "front", "side", "top", "120,-40"] {
            let camera = Camera::fit(view.parse().unwrap(), lo, hi, 300, 200);
            let (mut min, mut max) = ([f64::MAX; 2], [f64::MIN; 2]);
            for k in 0..8 {
                let c = Vector3::new(
                    [lo.x, hi.x][k & 1],
                    [lo.y, hi.y][(k >> 1) & 1],
                    [lo.z, hi.z][(k >> 2) & 1],
                );
                let [x, y, depth] = camera.project(c);
                assert!(depth > 0.0, "{view}: corner behind the camera");
                min = [min[0].min(x), min[1].min(y)];
                max = [max[0].max(x), max[1].max(y)];
            }
            // Centred to round-off, and exactly 90 % along the tighter axis.
            assert!(((min[0] + max[0]) / 2.0 - 150.0).abs() < 1e-9, "{view}");
            assert!(((min[1] + max[1]) / 2.0 - 100.0).abs() < 1e-9, "{view}");
            let fill = ((max[0] - min[0]) / 300.0).max((max[1] - min[1]) / 200.0);
            assert!((fill - FILL).abs() < 1e-9, "{view}: fill {fill}");
        }
    }

    #[test]
    fn top_view_keeps_y_up_in_the_picture() {
        let camera = Camera::fit(
            "top".parse().unwrap(),
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
