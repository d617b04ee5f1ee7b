//! The 3-D scene of a frame on a supersampled canvas: the ground under the scene (opaque,
//! to the horizon), crack faces (opaque, flat), the ice's outer surface (glass or solid,
//! smooth or flat, coloured by a field or by the freeze state), the glass-like obstacles
//! (blended back to front together with glass ice), the ice's feature edges and the
//! obstacles' outlines.

use super::clip::{Facet, Frustum};
use super::raster::{Canvas, Rgb};
use super::scenery::{self, Scenery};
use super::shading::{self, Light};
use super::{
    colormap, feature_edges, Camera, Cut, Picture, RenderError, Renderer, Shading, Style, CRACK,
    EDGE, FEATURE_ANGLE_DEG, GLASS_ALPHA, ICE, OBSTACLE, SKY_BOTTOM, SPECULAR, SUPERSAMPLE, WATER,
};
use crate::output::{FrameReader, StoredFrame};
use nalgebra::Vector3;

/// Strength of the highlight on glass obstacles: glass is shiny whatever the ice's shading.
const GLASS_SPECULAR: f32 = 0.4;
/// Distance of the near clipping plane in front of the eye, in scene sizes.
const NEAR: f64 = 1e-3;

/// The supersampled camera of a picture, its lights and its view.
struct Stage {
    camera: Camera,
    /// Lights the ice (with a highlight when smooth-shaded).
    light: Light,
    /// Lights the cracks and the ground: no highlight (a crack is a plane within its element,
    /// a highlight on the ground would draw the eye away from the ice).
    matte_light: Light,
    /// Lights glass obstacles.
    glass_light: Light,
    /// What the camera can draw (for obstacles, which may reach behind the eye).
    frustum: Frustum,
    /// What is drawn of glass obstacles: the view, and the far side of the cut if there is one
    /// (a cut opens the container as it opens the ice).
    glass_view: Frustum,
    /// The colour the ground fades into far away.
    horizon: Rgb,
}

impl Stage {
    /// The stage of `camera` scaled to the supersampled canvas, the light above the eye and
    /// to its left; a highlight on the ice when `smooth`. `scale` (m) is the scene's size and
    /// `horizon` the background's colour there.
    fn new(camera: &Camera, smooth: bool, (scale, cut): (f64, Option<Cut>), horizon: Rgb) -> Self {
        let camera = camera.scaled(SUPERSAMPLE as f64);
        let frustum = Frustum::new(&camera, NEAR * scale);
        // The cut keeps the points x with (x[axis] − value) · (eye's side) ≤ 0.
        let glass_view = match cut {
            Some(cut) => {
                let towards_eye = -camera.forward()[cut.axis];
                let mut a = Vector3::zeros();
                a[cut.axis] = -towards_eye;
                frustum.bounded_by(a, towards_eye * cut.value)
            }
            None => frustum.clone(),
        };
        let (right, up) = camera.right_up();
        let to_light = -camera.forward() + 0.5 * up - 0.3 * right;
        let light_with = |specular| Light::new(to_light, -camera.forward(), specular);
        Stage {
            light: light_with(if smooth { SPECULAR } else { 0.0 }),
            matte_light: light_with(0.0),
            glass_light: light_with(GLASS_SPECULAR),
            frustum,
            glass_view,
            camera,
            horizon,
        }
    }

    /// Where `x` (m) lands on the canvas.
    fn project(&self, x: Vector3<f64>) -> [f64; 3] {
        self.camera.project(x)
    }
}

/// A translucent triangle to blend: one of the ice's (by index) or a piece of glass.
enum Layer {
    Ice(usize),
    Glass(Facet),
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

/// The shading of an ice triangle with `corners` lit by `light`, at the weights `w` of its
/// corners: colours and normals interpolated.
fn ice_shade(light: &Light, c: Corners) -> impl Fn([f32; 3]) -> Rgb + '_ {
    move |w: [f32; 3]| -> Rgb {
        let color = std::array::from_fn(|k| w[0] * c[0].0[k] + w[1] * c[1].0[k] + w[2] * c[2].0[k]);
        let n = c[0].1 * w[0] + c[1].1 * w[1] + c[2].1 * w[2];
        light.shade(color, n.try_normalize(0.0).unwrap_or(c[0].1))
    }
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
        let horizon = match self.options.background.gradient() {
            Some((top, bottom)) => std::array::from_fn(|k| 0.5 * (top[k] + bottom[k])),
            None => SKY_BOTTOM,
        };
        let smooth = self.options.shading == Shading::Smooth;
        let stage = Stage::new(
            &self.camera,
            smooth,
            (self.scale, self.options.cut),
            horizon,
        );
        let scene_width = self.options.scene_width();
        let (w, h) = (scene_width * SUPERSAMPLE, self.options.height * SUPERSAMPLE);
        let mut canvas = Canvas::new(w, h, self.options.background.gradient());
        // Opaque surfaces first (ground, cracks, solid ice), so that glass blends over them.
        self.draw_ground(&mut canvas, &stage, state.time);
        self.draw_cracks(&mut canvas, &stage, frame);
        // The colour of the ice: a field through the colour map, else water → ice by the
        // freeze state.
        let element_values: Option<&[f64]> = values.as_deref().or(freeze);
        let corners = self.corners(&ice, element_values, values.is_some(), &state.tets);
        let glass_ice = match self.options.style {
            Style::Solid => {
                for ((nodes, _), c) in ice.triangles.iter().zip(&corners) {
                    let x = nodes.map(|i| stage.project(ice.positions[i]));
                    canvas.fill_with(x, ice_shade(&stage.light, *c));
                }
                None
            }
            Style::Glass => Some((&ice, corners.as_slice())),
        };
        self.draw_translucent(&mut canvas, &stage, glass_ice, state.time);
        self.draw_lines(&mut canvas, &stage, &ice, state.time);
        Ok(canvas.downsample(SUPERSAMPLE))
    }

    /// The ground planes seen from above at `time` (s), opaque, clipped to the view.
    fn draw_ground(&self, canvas: &mut Canvas, stage: &Stage, time: f64) {
        let (eye, focal) = (stage.camera.eye(), stage.camera.focal());
        for scenery in &self.scenery {
            let Scenery::Ground(ground) = scenery else {
                continue;
            };
            let ground = ground.at(time);
            if !ground.seen_from_above(eye) {
                continue;
            }
            for facet in ground.facets(eye) {
                for piece in stage.frustum.clip_triangle(facet) {
                    canvas.fill_with(piece.map(|v| stage.project(v.x)), |w| {
                        let x = scenery::interpolate(&piece, w.map(f64::from)).x;
                        ground.shade(x, eye, focal, &stage.matte_light, stage.horizon)
                    });
                }
            }
        }
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
            let colour = stage.matte_light.shade(CRACK, face_normal(x));
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

    /// The translucent surfaces at `time` (s), blended back to front by their centres' depth:
    /// the glass obstacles, the ice when it is drawn as glass (`ice`, with its triangles'
    /// corners), and ground planes seen from below (last: the eye is below them, everything
    /// else above).
    fn draw_translucent(
        &self,
        canvas: &mut Canvas,
        stage: &Stage,
        ice: Option<(&IceSurface, &[Corners])>,
        time: f64,
    ) {
        let eye = stage.camera.eye();
        let depth = |x: [Vector3<f64>; 3]| stage.project((x[0] + x[1] + x[2]) / 3.0)[2];
        let mut layers: Vec<(f64, Layer)> = Vec::new();
        let mut add_clipped = |view: &Frustum, facet: Facet, key: Option<f64>| {
            for piece in view.clip_triangle(facet) {
                let d = key.unwrap_or_else(|| depth(piece.map(|v| v.x)));
                layers.push((d, Layer::Glass(piece)));
            }
        };
        for scenery in &self.scenery {
            match scenery {
                Scenery::Glass(facets, motion) => {
                    for facet in facets {
                        let facet = scenery::moved(facet, motion, time);
                        add_clipped(&stage.glass_view, facet, None);
                    }
                }
                Scenery::Ground(ground) => {
                    let ground = ground.at(time);
                    if !ground.seen_from_above(eye) {
                        for facet in ground.facets(eye) {
                            add_clipped(&stage.frustum, facet, Some(f64::NEG_INFINITY));
                        }
                    }
                }
            }
        }
        if let Some((ice, _)) = ice {
            layers.extend(
                ice.triangles
                    .iter()
                    .enumerate()
                    .map(|(k, (nodes, _))| (depth(nodes.map(|i| ice.positions[i])), Layer::Ice(k))),
            );
        }
        layers.sort_by(|a, b| b.0.total_cmp(&a.0));
        for (_, layer) in layers {
            match layer {
                Layer::Ice(k) => {
                    let Some((ice, corners)) = ice else { continue };
                    let x = ice.triangles[k].0.map(|i| stage.project(ice.positions[i]));
                    canvas.blend_with(x, GLASS_ALPHA, ice_shade(&stage.light, corners[k]));
                }
                Layer::Glass(f) => {
                    let x = f.map(|v| stage.project(v.x));
                    let c = scenery::glass_corners(&f, eye, &stage.glass_light);
                    canvas.blend_varying(x, |w| {
                        let color = std::array::from_fn(|k| {
                            w[0] * c[0].0[k] + w[1] * c[1].0[k] + w[2] * c[2].0[k]
                        });
                        (color, w[0] * c[0].1 + w[1] * c[1].1 + w[2] * c[2].1)
                    });
                }
            }
        }
    }

    /// The ice's feature edges and the obstacles' outlines where they are at `time` (s).
    fn draw_lines(&self, canvas: &mut Canvas, stage: &Stage, ice: &IceSurface, time: f64) {
        let line_width = self.options.overlay().line_width() * SUPERSAMPLE as f64;
        let mut line = |view: &Frustum, [a, b]: [Vector3<f64>; 2], color: Rgb| {
            if let Some([a, b]) = view.clip_segment(a, b) {
                canvas.line(stage.project(a), stage.project(b), color, line_width, true);
            }
        };
        for edge in feature_edges(&ice.triangles, &ice.positions) {
            line(&stage.frustum, edge, EDGE);
        }
        for outline in &self.outlines {
            let place = |x: &Vector3<f64>| outline.motion.position(time, x);
            for [a, b] in &outline.segments {
                line(&stage.glass_view, [place(a), place(b)], OBSTACLE);
            }
        }
    }
}
