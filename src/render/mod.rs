//! Pictures of a run, from its HDF5 file alone: `icefem render` (one frame, a PNG sequence or
//! an animated GIF) and `icefem figure` (the paper's four panels with captions).
//!
//! The ice's outer surface is drawn lit, by default as translucent "glass" so that crack
//! surfaces inside it show (crack faces opaque, red); `solid` draws it opaque. Smooth shading
//! (the default) interpolates normals and colours from the vertices: element fields (stress,
//! plastic strain, freeze state) are averaged to the nodes and coloured through a colour map
//! with a colour bar; flat shading colours each face by its element and lights it by its own
//! normal. Rigid obstacles from the stored scene are drawn as lit glass (translucent, more
//! opaque edge-on) with their outlines, half-spaces as ground planes to the horizon
//! (`scenery`). Text, lines and the
//! colour bar scale with the picture ([`overlay`]). Everything runs on the CPU: a z-buffered
//! rasteriser with 2 × 2 supersampling ([`raster`]), PNG (RGBA when the background is
//! transparent) and GIF encoders.

pub mod camera;
mod clip;
mod draw;
mod encode;
mod figure;
pub mod obstacles;
pub mod overlay;
pub mod raster;
mod scenery;
mod sequence;
mod shading;
pub mod text;

pub use camera::{Camera, Lens, View};
pub use encode::{save_png, GifWriter};
pub use figure::{figure, FigureOptions};
pub use raster::Picture;
pub use sequence::{
    default_output, numbered_path, render_frames, select_frames, sibling, RenderSummary, Target,
};

use crate::output::{FrameMesh, FrameReader, OutputError, StoredFrame, SurfaceExtractor};
use crate::physics::Motion;
use nalgebra::Vector3;
use overlay::Overlay;
use raster::{Canvas, Rgb};
use std::collections::HashMap;
use std::path::PathBuf;
use std::str::FromStr;
use text::Align;

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
    /// Temperature (°C; runs with `[thermal]`), the mean of each element's nodes.
    Temperature,
}

impl FromStr for ColorField {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "freeze" => Ok(ColorField::Freeze),
            "plastic" => Ok(ColorField::Plastic),
            "stress" | "von-mises" => Ok(ColorField::VonMises),
            "principal" => Ok(ColorField::Principal),
            "temperature" => Ok(ColorField::Temperature),
            _ => Err(format!(
                "unknown field {s:?}: expected freeze, plastic, stress (von Mises), principal or temperature"
            )),
        }
    }
}

impl ColorField {
    /// The field's name on its colour bar (the unit goes on a line of its own).
    pub fn title(self) -> &'static str {
        match self {
            ColorField::Freeze => "freeze state",
            ColorField::Plastic => "plastic strain ‖εp‖",
            ColorField::VonMises => "von Mises stress",
            ColorField::Principal => "largest principal stress",
            ColorField::Temperature => "temperature",
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
            ColorField::Plastic => frame.plastic_strain_norm().ok_or_else(|| {
                missing(
                    "plastic_strain",
                    "the scene has neither [plasticity] nor [creep]",
                )
            })?,
            ColorField::VonMises => frame
                .von_mises()
                .ok_or_else(|| missing("stress", "malformed file"))?,
            ColorField::Principal => frame
                .max_principal_stress()
                .ok_or_else(|| missing("stress", "malformed file"))?,
            ColorField::Temperature => {
                let t = frame
                    .node_field("temperature")
                    .filter(|(cols, _)| *cols == 1)
                    .ok_or_else(|| missing("temperature", "the scene has no [thermal]"))?
                    .1;
                frame
                    .state
                    .tets
                    .iter()
                    .map(|tet| {
                        tet.iter()
                            .map(|&i| t.get(i).copied().unwrap_or(f64::NAN))
                            .sum::<f64>()
                            / 4.0
                    })
                    .collect()
            }
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

/// How surfaces are shaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// Normals and colours interpolated from the vertices (fields averaged to the nodes):
    /// the default, for presentation.
    Smooth,
    /// One normal and one colour (its element's) per face: the elements show.
    Flat,
}

impl FromStr for Shading {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "smooth" => Ok(Shading::Smooth),
            "flat" => Ok(Shading::Flat),
            _ => Err(format!("unknown shading {s:?}: expected smooth or flat")),
        }
    }
}

/// What lies behind the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Background {
    /// A pale grey-blue gradient (the default).
    Sky,
    /// One colour (display RGB in [0, 1]).
    Color(Rgb),
    /// Nothing: a PNG with an alpha channel, the scene's translucent ice partly transparent.
    Transparent,
}

impl FromStr for Background {
    type Err = String;
    /// `sky`, `white`, `black`, `transparent` or `#RRGGBB`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let hex = |t: &str| {
            let v = u32::from_str_radix(t, 16).ok()?;
            Some([16, 8, 0].map(|shift| ((v >> shift) & 0xff) as f32 / 255.0))
        };
        match s.trim() {
            "sky" => Ok(Background::Sky),
            "white" => Ok(Background::Color([1.0; 3])),
            "black" => Ok(Background::Color([0.0; 3])),
            "transparent" => Ok(Background::Transparent),
            t => t
                .strip_prefix('#')
                .filter(|h| h.len() == 6)
                .and_then(hex)
                .map(Background::Color)
                .ok_or_else(|| {
                    format!("background {t:?}: expected sky, white, black, transparent or #RRGGBB")
                }),
        }
    }
}

impl Background {
    /// The gradient (top, bottom) behind the scene, or `None` for transparent.
    fn gradient(self) -> Option<(Rgb, Rgb)> {
        match self {
            Background::Sky => Some((SKY_TOP, SKY_BOTTOM)),
            Background::Color(c) => Some((c, c)),
            Background::Transparent => None,
        }
    }

    /// An empty picture of this background.
    fn picture(self, width: usize, height: usize) -> Picture {
        Canvas::new(width, height, self.gradient()).downsample(1)
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
    /// Camera target, distance and field of view.
    pub lens: Lens,
    /// Surface style.
    pub style: Style,
    /// Smooth or flat shading.
    pub shading: Shading,
    /// What lies behind the scene.
    pub background: Background,
    /// Colour the surface by a field, with a colour bar.
    pub color_by: Option<ColorField>,
    /// Colour-bar range (min, max); default: the range over the frames drawn.
    pub range: Option<(f64, f64)>,
    /// Leave out the ice between the camera and a plane.
    pub cut: Option<Cut>,
}

impl RenderOptions {
    /// Sizes of text and marks for the picture.
    pub fn overlay(&self) -> Overlay {
        Overlay::new(self.height, self.background.gradient().map(|g| g.0))
    }

    /// Width of the colour-bar strip: none unless colouring by a field (pixels).
    pub fn bar_strip(&self) -> usize {
        if self.color_by.is_some() {
            self.overlay().strip()
        } else {
            0
        }
    }

    /// Width of the scene area: the picture less the colour-bar strip, if any (pixels).
    fn scene_width(&self) -> usize {
        self.width.saturating_sub(self.bar_strip()).max(1)
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 800,
            height: 600,
            view: View::ISO,
            lens: Lens::default(),
            style: Style::Glass,
            shading: Shading::Smooth,
            background: Background::Sky,
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
/// Strength of the white highlight of smooth-shaded ice (flat shading has none: a highlight
/// per face would flicker from face to face).
const SPECULAR: f32 = 0.25;
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
    /// Outlines of the obstacles other than half-spaces (a ground plane has no edge).
    outlines: Vec<Outline>,
    /// The obstacles' surfaces as drawn.
    scenery: Vec<scenery::Scenery>,
    /// Diagonal of the box the camera is fitted to (m): sets the ground's checker and haze.
    scale: f64,
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
        let stored = obstacles::stored_obstacles(reader, || Ok((ice_lo, ice_hi)))?;
        let outlines = obstacle_outlines(&stored);
        let (lo, hi) = bounds(
            &mut [ice_lo, ice_hi].into_iter().chain(
                outlines
                    .iter()
                    .flat_map(|o| o.segments.iter().flatten().copied()),
            ),
        );
        let scene_width = options.scene_width();
        if options.bar_strip() > 0 && scene_width < MIN_SIZE {
            return Err(invalid(format!(
                "a picture {} pixels wide leaves {scene_width} beside the colour bar's {} (at least {MIN_SIZE} are needed): widen it",
                options.width,
                options.bar_strip()
            )));
        }
        let camera = Camera::fit(
            options.view,
            options.lens,
            lo,
            hi,
            scene_width as u32,
            options.height as u32,
        );
        let surfaces = SurfaceExtractor::new(reader, &first)?;
        let scale = (hi - lo).norm().max(1e-9);
        // A half-space's square only sizes the camera's box: it is drawn as a ground plane.
        let outlines = outlines
            .into_iter()
            .zip(&stored)
            .filter(|(_, o)| o.kind != "halfspace")
            .map(|(outline, _)| outline)
            .collect();
        Ok(Renderer {
            options,
            camera,
            surfaces,
            outlines,
            scenery: stored
                .iter()
                .filter_map(|o| scenery::Scenery::new(o, scale))
                .collect(),
            scale,
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
        let mut picture = self.options.background.picture(width, height);
        picture.blit(&scene, 0, 0);
        let overlay = self.options.overlay();
        if let Some(field) = self.options.color_by {
            self.color_bar(&mut picture, field, scene.width, 0, height);
        }
        if label {
            let t = overlay::clock_time(frame.state.time, 3);
            let text = format!("frame {}   t = {t}", frame.index);
            let m = overlay.margin();
            overlay.text(&mut picture, &text, m, 0.75 * m, Align::Left);
        }
        Ok(picture)
    }

    /// The colour bar of `field` in the strip right of `x`, for a scene area from `top`,
    /// `height` pixels high (its middle two thirds).
    fn color_bar(
        &self,
        picture: &mut Picture,
        field: ColorField,
        x: usize,
        top: usize,
        height: usize,
    ) {
        let range = self.range;
        self.options.overlay().color_bar(
            picture,
            field,
            range,
            [x as f64, (top + height / 6) as f64, (height * 2 / 3) as f64],
            |v| colormap(v, range),
        );
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

/// The scene area of a picture with nothing in it, with the default background: what
/// [`Renderer::draw_scene`] draws where the scene does not cover a pixel.
pub fn background(width: usize, height: usize) -> Picture {
    Canvas::new(
        width * SUPERSAMPLE,
        height * SUPERSAMPLE,
        Background::Sky.gradient(),
    )
    .downsample(SUPERSAMPLE)
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

/// Outline segments of `obstacles`: their surfaces' feature edges and borders (a
/// container's floor, rim and wall edges; a plane's square).
fn obstacle_outlines(obstacles: &[obstacles::StoredObstacle]) -> Vec<Outline> {
    obstacles
        .iter()
        .map(|o| {
            let triangles: Vec<([usize; 3], usize)> =
                o.surface.triangles.iter().map(|&t| (t, 0)).collect();
            Outline {
                segments: feature_edges(&triangles, &o.surface.vertices),
                motion: o.motion.clone(),
            }
        })
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn container_outline_has_floor_rim_and_wall_edges() {
        let container = obstacles::StoredObstacle {
            index: 0,
            kind: "container".into(),
            surface: obstacles::container(Vector3::zeros(), Vector3::repeat(0.1)),
            motion: Motion::default(),
        };
        let outlines = obstacle_outlines(&[container]);
        let segments = &outlines[0].segments;
        assert_eq!(segments.len(), 12);
        let length: f64 = segments.iter().map(|[a, b]| (b - a).norm()).sum();
        assert!((length - 1.2).abs() < 1e-12, "12 edges of 0.1 m");
    }
}
