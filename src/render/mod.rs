//! Pictures of a run, from its HDF5 file alone: `icefem render` (one frame, a PNG sequence or
//! an animated GIF) and `icefem figure` (the paper's four panels with captions).
//!
//! The ice's outer surface is drawn shaded, by default as translucent "glass" so that crack
//! surfaces inside it show (crack faces opaque, red); `solid` draws it opaque. Surface
//! triangles take the colour of their element: ice white-blue, water darker blue, or a field
//! (stress, plastic strain, freeze state) through a colour map with a colour bar. Rigid
//! obstacles from the stored scene are drawn as outlines. Everything runs on the CPU: a
//! z-buffered rasteriser with 2 × 2 supersampling ([`raster`]), PNG and GIF encoders.

pub mod camera;
mod encode;
mod figure;
pub mod raster;
mod sequence;

pub use camera::{Camera, View};
pub use encode::{save_png, GifWriter};
pub use figure::{figure, FigureOptions};
pub use raster::Picture;
pub use sequence::{
    default_output, numbered_path, render_frames, select_frames, sibling, RenderSummary, Target,
};

use crate::mesh::surface::TriSurface;
use crate::output::{
    FrameMesh, FrameReader, ObstacleMesh, OutputError, StoredFrame, SurfaceExtractor,
};
use crate::physics::contact::Shape;
use crate::physics::{Amplitude, Motion, Region};
use crate::scene::{ObstacleSection, SceneFile};
use embedded_graphics::mono_font::{ascii::FONT_7X13, MonoTextStyle};
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::{Point, Primitive};
use embedded_graphics::primitives::{PrimitiveStyle, Rectangle};
use embedded_graphics::text::{Alignment, Baseline, Text, TextStyleBuilder};
use embedded_graphics::Drawable;
use nalgebra::Vector3;
use raster::{Canvas, Rgb};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// Failures of rendering. Each names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// Reading the HDF5 file failed, or it is not icefem output, or lacks the frame.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// Writing a picture failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// File concerned.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The encoder refused the picture.
    #[error("{}: could not encode the picture: {message}", path.display())]
    Encode {
        /// File concerned.
        path: PathBuf,
        /// The encoder's message.
        message: String,
    },
    /// The request does not fit the file (a field it lacks, a malformed mesh).
    #[error("{}: {message}", path.display())]
    Invalid {
        /// File concerned.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// A per-element quantity to colour the surface by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColorField {
    /// Freeze state, 0 (water) … 1 (ice).
    Freeze,
    /// Frobenius norm of the plastic strain ‖ε_p‖.
    Plastic,
    /// Von Mises stress (Pa).
    VonMises,
    /// Largest principal stress (Pa; positive is tension).
    Principal,
}

impl FromStr for ColorField {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "freeze" => Ok(ColorField::Freeze),
            "plastic" => Ok(ColorField::Plastic),
            "stress" | "von-mises" => Ok(ColorField::VonMises),
            "principal" => Ok(ColorField::Principal),
            _ => Err(format!(
                "unknown field {s:?}: expected freeze, plastic, stress (von Mises) or principal"
            )),
        }
    }
}

impl ColorField {
    /// Label of the colour bar (ASCII: the bitmap font has no other glyphs).
    pub fn label(self) -> &'static str {
        match self {
            ColorField::Freeze => "freeze state",
            ColorField::Plastic => "plastic strain",
            ColorField::VonMises => "von Mises (Pa)",
            ColorField::Principal => "max principal (Pa)",
        }
    }

    /// The value of every element of `frame`.
    pub fn values(
        self,
        frame: &StoredFrame,
        reader: &FrameReader,
    ) -> Result<Vec<f64>, RenderError> {
        let missing = |what: &str, why: &str| RenderError::Invalid {
            path: reader.path().into(),
            message: format!("frame {} has no {what} ({why})", frame.index),
        };
        Ok(match self {
            ColorField::Freeze => frame
                .freeze_state()
                .ok_or_else(|| missing("freeze_state", "the scene has no [freezing]"))?
                .to_vec(),
            ColorField::Plastic => frame
                .plastic_strain_norm()
                .ok_or_else(|| missing("plastic_strain", "the scene has no [plasticity]"))?,
            ColorField::VonMises => frame
                .von_mises()
                .ok_or_else(|| missing("stress", "malformed file"))?,
            ColorField::Principal => frame
                .max_principal_stress()
                .ok_or_else(|| missing("stress", "malformed file"))?,
        })
    }
}

/// How the ice's outer surface is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// Translucent, so that cracks inside show (the default).
    Glass,
    /// Opaque: only what faces the camera shows.
    Solid,
}

impl FromStr for Style {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "glass" => Ok(Style::Glass),
            "solid" => Ok(Style::Solid),
            _ => Err(format!("unknown style {s:?}: expected glass or solid")),
        }
    }
}

/// A cut through the ice to show its inside: the elements whose rest centroid lies on the
/// camera's side of the plane `x[axis] = value` are left out (and crack triangles on that
/// side), so the faces along the cut show the interior's colours.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cut {
    /// 0, 1, 2 for x, y, z.
    pub axis: usize,
    /// Position of the plane (m).
    pub value: f64,
}

impl FromStr for Cut {
    type Err = String;
    /// `x=0.05`, `y=…` or `z=…` (m).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = || format!("cut {s:?}: expected x=VALUE, y=VALUE or z=VALUE (m)");
        let (axis, value) = s.split_once('=').ok_or_else(bad)?;
        let axis = ["x", "y", "z"]
            .iter()
            .position(|a| *a == axis.trim())
            .ok_or_else(bad)?;
        let value = value
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(bad)?;
        Ok(Cut { axis, value })
    }
}

/// What a picture shows and how.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Picture width (pixels).
    pub width: usize,
    /// Picture height (pixels).
    pub height: usize,
    /// Camera direction (the camera is fitted to the initial mesh and the obstacles, and kept
    /// for every frame so that a sequence does not jump).
    pub view: View,
    /// Surface style.
    pub style: Style,
    /// Colour the surface by a field, with a colour bar.
    pub color_by: Option<ColorField>,
    /// Colour-bar range (min, max); default: the range over the frames drawn.
    pub range: Option<(f64, f64)>,
    /// Leave out the ice between the camera and a plane.
    pub cut: Option<Cut>,
}

impl RenderOptions {
    /// Width of the scene area: the picture less the colour-bar strip, if any (pixels).
    fn scene_width(&self) -> usize {
        self.width
            - if self.color_by.is_some() {
                BAR_STRIP
            } else {
                0
            }
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 800,
            height: 600,
            view: View::ISO,
            style: Style::Glass,
            color_by: None,
            range: None,
            cut: None,
        }
    }
}

/// Smallest picture side (pixels): below it the labels do not fit.
pub const MIN_SIZE: usize = 64;
/// Largest picture side (pixels): the 2 × 2 supersampled canvas holds 16 bytes per sample,
/// 1.1 GB at 4096 × 4096.
pub const MAX_SIZE: usize = 4096;
/// Supersampling factor per direction (anti-aliasing).
const SUPERSAMPLE: usize = 2;
/// Width of the colour-bar strip at the picture's right (pixels).
const BAR_STRIP: usize = 140;

/// Ice, water, cracks and outlines (display RGB).
const ICE: Rgb = [0.84, 0.92, 1.0];
const WATER: Rgb = [0.20, 0.42, 0.80];
/// The crack colour: a red that no surface colour (blues, viridis) comes near.
pub const CRACK: Rgb = [0.86, 0.12, 0.10];
const OBSTACLE: Rgb = [0.25, 0.25, 0.28];
const EDGE: Rgb = [0.35, 0.50, 0.68];
const SKY_TOP: Rgb = [1.0, 1.0, 1.0];
const SKY_BOTTOM: Rgb = [0.86, 0.88, 0.91];
/// Opacity of glass-style surfaces.
const GLASS_ALPHA: f32 = 0.3;
/// Surface edges sharper than this (degrees between face normals) are drawn as lines.
const FEATURE_ANGLE_DEG: f64 = 30.0;

/// Rigid-obstacle outline segments at t = 0 (m) and the obstacle's motion.
struct Outline {
    segments: Vec<[Vector3<f64>; 2]>,
    motion: Motion,
}

/// Draws frames of one file with one camera.
pub struct Renderer {
    options: RenderOptions,
    camera: Camera,
    /// Tells crack faces from outer faces (fracture runs).
    surfaces: SurfaceExtractor,
    outlines: Vec<Outline>,
    range: (f64, f64),
}

impl Renderer {
    /// Prepares pictures of `reader`'s frames: the camera is fitted to the first frame's
    /// positions and the outlines of the stored scene's obstacles.
    pub fn new(reader: &FrameReader, options: RenderOptions) -> Result<Self, RenderError> {
        let invalid = |message: String| RenderError::Invalid {
            path: reader.path().into(),
            message,
        };
        for (what, v) in [("width", options.width), ("height", options.height)] {
            if !(MIN_SIZE..=MAX_SIZE).contains(&v) {
                return Err(invalid(format!(
                    "picture {what} {v} is outside {MIN_SIZE} … {MAX_SIZE} pixels"
                )));
            }
        }
        let first = reader.read(reader.frame_indices()[0])?;
        let bounds = |points: &mut dyn Iterator<Item = Vector3<f64>>| {
            points.fold(
                (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN)),
                |(lo, hi), x| (lo.inf(&x), hi.sup(&x)),
            )
        };
        let (ice_lo, ice_hi) = bounds(&mut first.state.positions.iter().map(|p| Vector3::from(*p)));
        let surfaces = ObstacleSurfaces {
            stored: reader.obstacle_meshes()?,
            scene_dirs: scene_dirs(reader),
        };
        let outlines = obstacle_outlines(reader.scene_text(), &surfaces, ice_lo, ice_hi);
        let (lo, hi) = bounds(
            &mut [ice_lo, ice_hi].into_iter().chain(
                outlines
                    .iter()
                    .flat_map(|o| o.segments.iter().flatten().copied()),
            ),
        );
        let scene_width = options.scene_width();
        let camera = Camera::fit(
            options.view,
            lo,
            hi,
            scene_width as u32,
            options.height as u32,
        );
        let surfaces = SurfaceExtractor::new(reader, &first)?;
        Ok(Renderer {
            options,
            camera,
            surfaces,
            outlines,
            range: options.range.unwrap_or((0.0, 1.0)),
        })
    }

    /// The camera (for the scene area of the picture).
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Sets the colour-bar range to that of `values` (unless the options fix it); a constant
    /// field gets a range around its value. Only the extremes matter, so callers may pass
    /// each frame's minimum and maximum instead of every value.
    pub fn fit_range(&mut self, values: impl IntoIterator<Item = f64>) {
        if self.options.range.is_some() {
            return;
        }
        let (mut min, mut max) = (f64::MAX, f64::MIN);
        for v in values.into_iter().filter(|v| v.is_finite()) {
            min = min.min(v);
            max = max.max(v);
        }
        if min > max {
            (min, max) = (0.0, 1.0);
        } else if max - min <= 1e-12 * max.abs().max(min.abs()) {
            let pad = 0.5 * max.abs().max(1e-12);
            (min, max) = (min - pad, max + pad);
        }
        self.range = (min, max);
    }

    /// The colour-bar range in use.
    pub fn range(&self) -> (f64, f64) {
        self.range
    }

    /// The picture of `frame`: the scene, a label with frame and time when `label`, and the
    /// colour bar when colouring by a field.
    pub fn render(
        &self,
        reader: &FrameReader,
        frame: &StoredFrame,
        label: bool,
    ) -> Result<Picture, RenderError> {
        let RenderOptions { width, height, .. } = self.options;
        let scene = self.draw_scene(reader, frame)?;
        let mut picture = Picture::filled(width, height, to_u8(SKY_TOP));
        picture.blit(&scene, 0, 0);
        if let Some(field) = self.options.color_by {
            let x = scene.width + 12;
            color_bar(
                &mut picture,
                field,
                self.range,
                x,
                height / 6,
                height * 2 / 3,
            );
        }
        if label {
            let text = format!("frame {}   t = {:.3} s", frame.index, frame.state.time);
            draw_text(&mut picture, &text, 8, 6, Alignment::Left);
        }
        Ok(picture)
    }

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
        let positions: Vec<Vector3<f64>> =
            state.positions.iter().map(|p| Vector3::from(*p)).collect();

        let surface = self.surface(&mesh);
        let crack_triangles: Vec<[Vector3<f64>; 3]> = frame
            .crack_triangles
            .iter()
            .map(|(x, _)| x.map(Vector3::from))
            .filter(|x| !self.is_cut_away(&((x[0] + x[1] + x[2]) / 3.0)))
            .collect();

        let camera = self.camera.scaled(SUPERSAMPLE as f64);
        let scene_width = self.options.scene_width();
        let (w, h) = (scene_width * SUPERSAMPLE, self.options.height * SUPERSAMPLE);
        let mut canvas = sky(w, h);
        let (right, up) = camera.right_up();
        let light = (-camera.forward() + 0.5 * up - 0.3 * right).normalize();
        let shade = |x: [Vector3<f64>; 3], color: Rgb| -> Rgb {
            let n = (x[1] - x[0]).cross(&(x[2] - x[0]));
            let lambert = if n.norm() > 0.0 {
                n.normalize().dot(&light).abs()
            } else {
                0.0
            };
            color.map(|c| c * (0.45 + 0.55 * lambert as f32))
        };
        let project = |x: Vector3<f64>| camera.project(x);

        // Cracks: opaque, first, so that glass blends over them.
        for &x in &crack_triangles {
            canvas.fill(x.map(project), shade(x, CRACK));
        }
        let color_of = |element: usize| -> Rgb {
            match &values {
                Some(v) => colormap(v[element], self.range),
                None => {
                    let s = freeze.map_or(1.0, |s| s[element].clamp(0.0, 1.0)) as f32;
                    std::array::from_fn(|k| WATER[k] + (ICE[k] - WATER[k]) * s)
                }
            }
        };
        match self.options.style {
            Style::Solid => {
                for (nodes, element) in &surface {
                    let x = nodes.map(|i| positions[i]);
                    canvas.fill(x.map(project), shade(x, color_of(*element)));
                }
            }
            Style::Glass => {
                // Back to front, so that each blend lands on what lies behind it.
                let mut order: Vec<(f64, usize)> = surface
                    .iter()
                    .enumerate()
                    .map(|(k, (nodes, _))| {
                        let c = nodes.iter().map(|&i| positions[i]).sum::<Vector3<f64>>() / 3.0;
                        (project(c)[2], k)
                    })
                    .collect();
                order.sort_by(|a, b| b.0.total_cmp(&a.0));
                for (_, k) in order {
                    let (nodes, element) = surface[k];
                    let x = nodes.map(|i| positions[i]);
                    canvas.blend(x.map(project), shade(x, color_of(element)), GLASS_ALPHA);
                }
            }
        }
        let line_width = 1.2 * SUPERSAMPLE as f64;
        for [a, b] in feature_edges(&surface, &positions) {
            canvas.line(project(a), project(b), EDGE, line_width, true);
        }
        for outline in &self.outlines {
            let place = |x: &Vector3<f64>| outline.motion.position(state.time, x);
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
        Ok(canvas.downsample(SUPERSAMPLE))
    }
}

impl Renderer {
    /// The ice surface to draw: the outer faces of the (cut) mesh, each with its element; the
    /// faces along a cut are drawn.
    fn surface(&self, mesh: &FrameMesh) -> Vec<([usize; 3], usize)> {
        let rest = &mesh.rest;
        let keep: Option<Vec<bool>> = self.options.cut.map(|_| {
            rest.tets
                .iter()
                .map(|t| {
                    let centroid = t.iter().map(|&i| rest.rest[i]).sum::<Vector3<f64>>() / 4.0;
                    !self.is_cut_away(&centroid)
                })
                .collect()
        });
        mesh.outer_faces(keep.as_deref())
            .into_iter()
            .map(|f| (f.nodes, f.tet))
            .collect()
    }

    /// Whether the point `x` (m) is on the camera's side of the cut plane.
    fn is_cut_away(&self, x: &Vector3<f64>) -> bool {
        self.options.cut.is_some_and(|cut| {
            let towards_eye = -self.camera.forward()[cut.axis];
            (x[cut.axis] - cut.value) * towards_eye > 0.0
        })
    }
}

/// The backdrop of the scene area, at `SUPERSAMPLE` × the size.
fn sky(width: usize, height: usize) -> Canvas {
    Canvas::new(width, height, SKY_TOP, SKY_BOTTOM)
}

/// The scene area of a picture with nothing in it: what [`Renderer::draw_scene`] draws where
/// the scene does not cover a pixel.
pub fn background(width: usize, height: usize) -> Picture {
    sky(width * SUPERSAMPLE, height * SUPERSAMPLE).downsample(SUPERSAMPLE)
}

/// Edges of a triangle surface where it bends by more than [`FEATURE_ANGLE_DEG`], or that
/// bound it (a crack's mouth), at `positions`.
fn feature_edges(
    surface: &[([usize; 3], usize)],
    positions: &[Vector3<f64>],
) -> Vec<[Vector3<f64>; 2]> {
    let mut normals: HashMap<(usize, usize), Vec<Vector3<f64>>> = HashMap::new();
    for (nodes, _) in surface {
        let x = nodes.map(|i| positions[i]);
        let n = (x[1] - x[0]).cross(&(x[2] - x[0]));
        let n = if n.norm() > 0.0 { n.normalize() } else { n };
        for j in 0..3 {
            let (a, b) = (nodes[j], nodes[(j + 1) % 3]);
            normals.entry((a.min(b), a.max(b))).or_default().push(n);
        }
    }
    let cos_feature = FEATURE_ANGLE_DEG.to_radians().cos();
    let mut edges: Vec<_> = normals
        .into_iter()
        .filter(|(_, n)| n.len() != 2 || n[0].dot(&n[1]) < cos_feature)
        .map(|((a, b), _)| (a, b))
        .collect();
    edges.sort_unstable(); // deterministic drawing order
    edges
        .into_iter()
        .map(|(a, b)| [positions[a], positions[b]])
        .collect()
}

/// Where the triangle surfaces of a file's mesh obstacles come from.
struct ObstacleSurfaces {
    /// The surfaces stored in the file (`/obstacles`), as the run placed them.
    stored: Vec<ObstacleMesh>,
    /// Folders to look for a surface file in, for a file that stores none (written before
    /// they were stored): the scene's folder, and for a scene path relative to where that run
    /// was started, that folder from the HDF5 file's.
    scene_dirs: Vec<PathBuf>,
}

impl ObstacleSurfaces {
    /// The surface of obstacle `index` at t = 0 (m): the stored one, or the scene's `file`
    /// (times `scale`, moved by `translate`) where it is found.
    fn surface(&self, index: usize, o: &ObstacleSection) -> Option<TriSurface> {
        if let Some(m) = self.stored.iter().find(|m| m.index == index) {
            return Some(TriSurface {
                vertices: m.vertices.iter().map(|&v| Vector3::from(v)).collect(),
                triangles: m.triangles.clone(),
            });
        }
        let file = o.file.as_ref()?;
        let mut surface = self
            .scene_dirs
            .iter()
            .find_map(|dir| TriSurface::read(&dir.join(file), o.scale.unwrap_or(1.0)).ok())?;
        let shift = o.translate.map(Vector3::from).unwrap_or_default();
        for v in &mut surface.vertices {
            *v += shift;
        }
        Some(surface)
    }
}

/// The folders a file's scene may be in (see [`ObstacleSurfaces::scene_dirs`]).
fn scene_dirs(reader: &FrameReader) -> Vec<PathBuf> {
    let scene = Path::new(reader.scene_path());
    let Some(dir) = scene.parent() else {
        return Vec::new();
    };
    let mut dirs = vec![dir.to_path_buf()];
    if scene.is_relative() {
        if let Some(h5_dir) = reader.path().parent() {
            dirs.push(h5_dir.join(dir));
        }
    }
    dirs
}

/// Outline segments of the scene's rigid obstacles: containers' floor, rim and wall edges;
/// half-spaces as a square on the plane around the ice's box `[lo, hi]`; triangle meshes by
/// their feature edges, from the surface the file stores (or, in a file that stores none, the
/// surface file where the scene names it).
fn obstacle_outlines(
    scene_text: &str,
    surfaces: &ObstacleSurfaces,
    lo: Vector3<f64>,
    hi: Vector3<f64>,
) -> Vec<Outline> {
    // The scene was validated when the run started; a text that no longer parses (another
    // version) just draws no obstacles.
    let Ok(scene) = toml::from_str::<SceneFile>(scene_text) else {
        return Vec::new();
    };
    scene
        .obstacle
        .iter()
        .enumerate()
        .filter_map(|(index, o)| {
            let v3 = |v: Option<[f64; 3]>| v.map(Vector3::from);
            let segments = match o.kind.as_str() {
                "container" => shape_outline(
                    &Shape::Container {
                        inner: Region {
                            min: v3(o.min)?,
                            max: v3(o.max)?,
                        },
                    },
                    lo,
                    hi,
                ),
                "halfspace" => shape_outline(
                    &Shape::HalfSpace {
                        point: v3(o.point)?,
                        normal: v3(o.normal)?.try_normalize(0.0)?,
                    },
                    lo,
                    hi,
                ),
                "mesh" => {
                    let surface = surfaces.surface(index, o)?;
                    let triangles: Vec<([usize; 3], usize)> =
                        surface.triangles.iter().map(|&t| (t, 0)).collect();
                    feature_edges(&triangles, &surface.vertices)
                }
                _ => return None,
            };
            Some(Outline {
                segments,
                motion: Motion {
                    velocity: v3(o.velocity).unwrap_or_default(),
                    angular_velocity: v3(o.angular_velocity).unwrap_or_default(),
                    centre: v3(o.centre).unwrap_or_default(),
                    amplitude: o
                        .amplitude
                        .as_ref()
                        .and_then(|p| Amplitude::new(p.iter().map(|&[t, a]| (t, a)).collect()).ok())
                        .unwrap_or_default(),
                },
            })
        })
        .collect()
}

fn shape_outline(shape: &Shape, lo: Vector3<f64>, hi: Vector3<f64>) -> Vec<[Vector3<f64>; 2]> {
    match shape {
        Shape::Container { inner } => {
            let (a, b) = (inner.min, inner.max);
            let corner = |i: usize, z: f64| {
                let (x, y) = [(a.x, a.y), (b.x, a.y), (b.x, b.y), (a.x, b.y)][i % 4];
                Vector3::new(x, y, z)
            };
            (0..4)
                .flat_map(|i| {
                    [
                        [corner(i, a.z), corner(i + 1, a.z)], // floor
                        [corner(i, b.z), corner(i + 1, b.z)], // rim
                        [corner(i, a.z), corner(i, b.z)],     // wall edge
                    ]
                })
                .collect()
        }
        Shape::HalfSpace { point, normal } => {
            let centre = (lo + hi) / 2.0;
            let c = centre - normal * (centre - point).dot(normal);
            let t = normal.cross(&if normal.x.abs() < 0.9 {
                Vector3::x()
            } else {
                Vector3::y()
            });
            let (t, s) = (t.normalize(), normal.cross(&t).normalize());
            let r = 0.75 * (hi - lo).norm().max(1e-9);
            let corner = |i: usize| {
                c + t * r * [1.0, -1.0, -1.0, 1.0][i % 4] + s * r * [1.0, 1.0, -1.0, -1.0][i % 4]
            };
            (0..4).map(|i| [corner(i), corner(i + 1)]).collect()
        }
        Shape::Mesh { .. } => Vec::new(), // drawn from its file (see `obstacle_outlines`)
    }
}

/// Viridis colour of `v` in `range` (clamped).
fn colormap(v: f64, (min, max): (f64, f64)) -> Rgb {
    let t = if v.is_finite() {
        ((v - min) / (max - min)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let c = colorous::VIRIDIS.eval_continuous(t);
    [c.r, c.g, c.b].map(|k| k as f32 / 255.0)
}

fn to_u8(c: Rgb) -> [u8; 3] {
    c.map(|k| (k * 255.0).round().clamp(0.0, 255.0) as u8)
}

/// Draws one line of black text with its top at `y`, aligned at `x`.
fn draw_text(picture: &mut Picture, text: &str, x: usize, y: usize, alignment: Alignment) {
    let style = MonoTextStyle::new(&FONT_7X13, Rgb888::new(20, 20, 24));
    let layout = TextStyleBuilder::new()
        .alignment(alignment)
        .baseline(Baseline::Top)
        .build();
    // Drawing on a `Picture` cannot fail (its error type is `Infallible`).
    let _ =
        Text::with_text_style(text, Point::new(x as i32, y as i32), style, layout).draw(picture);
}

/// A vertical colour bar at (x, top) of `height` pixels, labelled with the field and range.
fn color_bar(
    picture: &mut Picture,
    field: ColorField,
    (min, max): (f64, f64),
    x: usize,
    top: usize,
    height: usize,
) {
    const BAR_WIDTH: usize = 16;
    let height = height.max(2);
    for row in 0..height {
        let t = 1.0 - row as f64 / (height - 1) as f64;
        let c = to_u8(colormap(min + t * (max - min), (min, max)));
        for col in 0..BAR_WIDTH {
            picture.set((x + col) as i64, (top + row) as i64, c);
        }
    }
    let frame = Rectangle::new(
        Point::new(x as i32, top as i32),
        embedded_graphics::prelude::Size::new(BAR_WIDTH as u32, height as u32),
    );
    let _ = frame
        .into_styled(PrimitiveStyle::with_stroke(Rgb888::new(60, 60, 60), 1))
        .draw(picture);
    draw_text(
        picture,
        &format!("{max:.2e}"),
        x + BAR_WIDTH + 4,
        top,
        Alignment::Left,
    );
    draw_text(
        picture,
        &format!("{min:.2e}"),
        x + BAR_WIDTH + 4,
        top + height - 13,
        Alignment::Left,
    );
    draw_text(
        picture,
        field.label(),
        x,
        top.saturating_sub(20),
        Alignment::Left,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn container_outline_has_floor_rim_and_wall_edges() {
        let inner = Region {
            min: Vector3::zeros(),
            max: Vector3::repeat(0.1),
        };
        let segments = shape_outline(
            &Shape::Container { inner },
            Vector3::zeros(),
            Vector3::repeat(0.1),
        );
        assert_eq!(segments.len(), 12);
        let length: f64 = segments.iter().map(|[a, b]| (b - a).norm()).sum();
        assert!((length - 1.2).abs() < 1e-12, "12 edges of 0.1 m");
    }
}
