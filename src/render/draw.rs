//! The 3-D scene of a frame on a supersampled canvas: crack faces (opaque, flat), the ice's
//! outer surface (glass or solid, smooth or flat, coloured by a field or by the freeze state),
//! its feature edges and the obstacles' outlines.

use super::raster::{Canvas, Rgb};
use super::shading::{self, Light};
use super::{
    colormap, feature_edges, Camera, Picture, RenderError, Renderer, Shading, Style, CRACK, EDGE,
    FEATURE_ANGLE_DEG, GLASS_ALPHA, ICE, OBSTACLE, SPECULAR, SUPERSAMPLE, WATER,
};
use crate::output::{FrameReader, StoredFrame};
use nalgebra::Vector3;

/// The supersampled camera of a picture and its lights.
struct Stage {
    camera: Camera,
    /// Lights the ice (with a highlight when smooth-shaded).
    light: Light,
    /// Lights the cracks: no highlight (each is a plane within its element).
    crack_light: Light,
}

impl Stage {
    /// The stage of `camera` scaled to the supersampled canvas, the light above the eye and
    /// to its left; a highlight on the ice when `smooth`.
    fn new(camera: &Camera, smooth: bool) -> Self {
        let camera = camera.scaled(SUPERSAMPLE as f64);
        let (right, up) = camera.right_up();
        let to_light = -camera.forward() + 0.5 * up - 0.3 * right;
        let light = Light::new(
            to_light,
            -camera.forward(),
            if smooth { SPECULAR } else { 0.0 },
        );
        let crack_light = Light::new(to_light, -camera.forward(), 0.0);
        Stage {
            camera,
            light,
            crack_light,
        }
    }

    /// Where `x` (m) lands on the canvas.
    fn project(&self, x: Vector3<f64>) -> [f64; 3] {
        self.camera.project(x)
    }
}

/// The ice surface to draw: its triangles (nodes, element) and the nodes' positions (m).
struct IceSurface {
    triangles: Vec<([usize; 3], usize)>,
    positions: Vec<Vector3<f64>>,
}

/// The colour and normal at each corner of a triangle.
type Corners = [(Rgb, Vector3<f32>); 3];

/// The unit normal of the triangle `x` (zero for a flat one).
fn face_normal(x: [Vector3<f64>; 3]) -> Vector3<f32> {
    let n = (x[1] - x[0]).cross(&(x[2] - x[0]));
    n.try_normalize(0.0).unwrap_or_default().cast()
}

impl Renderer {
    /// Only the 3-D scene of `frame`, in the scene area of the picture (the full width when
    /// no colour bar is drawn).
    pub fn draw_scene(
        &self,
        reader: &FrameReader,
        frame: &StoredFrame,
    ) -> Result<Picture, RenderError> {
        let state = &frame.state;
        let mesh = self.surfaces.mesh(reader.path(), frame)?;
        let values = match self.options.color_by {
            Some(field) => Some(field.values(frame, reader)?),
            None => None,
        };
        let freeze = frame.element_field("freeze_state").map(|(_, s)| s);
        let ice = IceSurface {
            triangles: self.surface(&mesh),
            positions: state.positions.iter().map(|p| Vector3::from(*p)).collect(),
        };
        let stage = Stage::new(&self.camera, self.options.shading == Shading::Smooth);
        let scene_width = self.options.scene_width();
        let (w, h) = (scene_width * SUPERSAMPLE, self.options.height * SUPERSAMPLE);
        let mut canvas = Canvas::new(w, h, self.options.background.gradient());
        // Cracks first, so that glass blends over them.
        self.draw_cracks(&mut canvas, &stage, frame);
        // The colour of the ice: a field through the colour map, else water → ice by the
        // freeze state.
        let element_values: Option<&[f64]> = values.as_deref().or(freeze);
        let corners = self.corners(&ice, element_values, values.is_some(), &state.tets);
        self.draw_ice(&mut canvas, &stage, &ice, &corners);
        self.draw_lines(&mut canvas, &stage, &ice, state.time);
        Ok(canvas.downsample(SUPERSAMPLE))
    }

    /// The crack faces of `frame` off the cut: opaque, flat.
    fn draw_cracks(&self, canvas: &mut Canvas, stage: &Stage, frame: &StoredFrame) {
        let crack_triangles: Vec<[Vector3<f64>; 3]> = frame
            .crack_triangles
            .iter()
            .map(|(x, _)| x.map(Vector3::from))
            .filter(|x| !self.is_cut_away(&((x[0] + x[1] + x[2]) / 3.0)))
            .collect();
        for &x in &crack_triangles {
            let colour = stage.crack_light.shade(CRACK, face_normal(x));
            canvas.fill(x.map(|p| stage.project(p)), colour);
        }
    }

    /// The colour of element value `v`: through the colour map when colouring `by_field`,
    /// else water → ice by a freeze state (ice without one).
    fn paint(&self, by_field: bool, v: Option<f64>) -> Rgb {
        match (by_field, v) {
            (true, Some(v)) => colormap(v, self.range),
            (_, v) => {
                let s = v.map_or(1.0, |s| s.clamp(0.0, 1.0)) as f32;
                std::array::from_fn(|k| WATER[k] + (ICE[k] - WATER[k]) * s)
            }
        }
    }

    /// Per triangle of `ice`: its corners' colours from the elements' `values` (coloured
    /// `by_field` or as freeze states) and normals, per element (flat shading) or averaged to
    /// the nodes of `tets` (smooth).
    fn corners(
        &self,
        ice: &IceSurface,
        values: Option<&[f64]>,
        by_field: bool,
        tets: &[[usize; 4]],
    ) -> Vec<Corners> {
        let positions = &ice.positions;
        let smooth = self.options.shading == Shading::Smooth;
        let nodal = values
            .filter(|_| smooth)
            .map(|v| shading::nodal_values(v, tets, positions));
        let normals = if smooth {
            shading::corner_normals(&ice.triangles, positions, FEATURE_ANGLE_DEG)
        } else {
            ice.triangles
                .iter()
                .map(|(n, _)| [face_normal(n.map(|i| positions[i])).cast(); 3])
                .collect()
        };
        ice.triangles
            .iter()
            .zip(&normals)
            .map(|((nodes, element), n)| {
                std::array::from_fn(|k| {
                    let v = match &nodal {
                        Some(nodal) => Some(nodal[nodes[k]]),
                        None => values.map(|v| v[*element]),
                    };
                    (self.paint(by_field, v), n[k].cast::<f32>())
                })
            })
            .collect()
    }

    /// The ice surface, its triangles shaded from their `corners`: opaque (solid) or blended
    /// back to front (glass).
    fn draw_ice(&self, canvas: &mut Canvas, stage: &Stage, ice: &IceSurface, corners: &[Corners]) {
        let light = &stage.light;
        let shade_at = |c: Corners| {
            move |w: [f32; 3]| -> Rgb {
                let color =
                    std::array::from_fn(|k| w[0] * c[0].0[k] + w[1] * c[1].0[k] + w[2] * c[2].0[k]);
                let n = c[0].1 * w[0] + c[1].1 * w[1] + c[2].1 * w[2];
                light.shade(color, n.try_normalize(0.0).unwrap_or(c[0].1))
            }
        };
        let (surface, positions) = (&ice.triangles, &ice.positions);
        match self.options.style {
            Style::Solid => {
                for ((nodes, _), c) in surface.iter().zip(corners) {
                    let x = nodes.map(|i| stage.project(positions[i]));
                    canvas.fill_with(x, shade_at(*c));
                }
            }
            Style::Glass => {
                // Back to front, so that each blend lands on what lies behind it.
                let mut order: Vec<(f64, usize)> = surface
                    .iter()
                    .enumerate()
                    .map(|(k, (nodes, _))| {
                        let c = nodes.iter().map(|&i| positions[i]).sum::<Vector3<f64>>() / 3.0;
                        (stage.project(c)[2], k)
                    })
                    .collect();
                order.sort_by(|a, b| b.0.total_cmp(&a.0));
                for (_, k) in order {
                    let x = surface[k].0.map(|i| stage.project(positions[i]));
                    canvas.blend_with(x, GLASS_ALPHA, shade_at(corners[k]));
                }
            }
        }
    }

    /// The ice's feature edges and the obstacles' outlines where they are at `time` (s).
    fn draw_lines(&self, canvas: &mut Canvas, stage: &Stage, ice: &IceSurface, time: f64) {
        let project = |x: Vector3<f64>| stage.project(x);
        let line_width = self.options.overlay().line_width() * SUPERSAMPLE as f64;
        for [a, b] in feature_edges(&ice.triangles, &ice.positions) {
            canvas.line(project(a), project(b), EDGE, line_width, true);
        }
        for outline in &self.outlines {
            let place = |x: &Vector3<f64>| outline.motion.position(time, x);
            for [a, b] in &outline.segments {
                canvas.line(
                    project(place(a)),
                    project(place(b)),
                    OBSTACLE,
                    1.5 * line_width,
                    true,
                );
            }
        }
    }
}
