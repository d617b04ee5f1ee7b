//! The paper's figure: four frames side by side with captions (frame, time, element and
//! crack-polygon counts) and, when colouring by a field, one shared colour bar.

use super::text::Align;
use super::{Picture, RenderError, RenderOptions, Renderer};
use crate::fracture::cracks::{count_polygons, OriginalBoundary};
use crate::mesh::TetMesh;
use crate::output::{FrameReader, StoredFrame};
use std::collections::HashSet;
use std::path::Path;

/// The paper's figure shows its animation frames 1200, 1600, 2000 and 2400: time steps of
/// 1/30 s, so the frames written at these steps (whatever the run's output cadence).
pub const PAPER_STEPS: [u64; 4] = [1200, 1600, 2000, 2400];

/// What a figure shows.
#[derive(Clone, Debug, PartialEq)]
pub struct FigureOptions {
    /// Frame indices, one panel each; empty: the frames written at `PAPER_STEPS` if the
    /// file has them all, else four frames evenly spaced up to its last (a cut-off run).
    pub frames: Vec<usize>,
    /// View, style and colouring of each panel, and, without `size`, its size
    /// (`width × height` is one panel's scene).
    pub panel: RenderOptions,
    /// The whole figure's size, width × height in pixels: the panels are sized to fill it
    /// (title, captions, margins and colour bar included). `None`: the panels are
    /// `panel.width × panel.height`.
    pub size: Option<(usize, usize)>,
}

/// Margins, title and caption rows and the colour-bar strip of a figure with panels `panel`
/// (pixels), and the figure's width and height for `n` panels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Layout {
    margin: usize,
    title_row: usize,
    caption_row: usize,
    strip: usize,
    width: usize,
    height: usize,
}

impl Layout {
    fn of(panel: &RenderOptions, n: usize) -> Layout {
        let overlay = panel.overlay();
        // Margins, title and caption rows at 10, 26 and 40 pixels for scale 1.
        let scaled = |v: f64| (v * overlay.scale).round() as usize;
        let (margin, title_row, caption_row) = (scaled(10.0), scaled(26.0), scaled(40.0));
        let strip = panel.bar_strip();
        Layout {
            margin,
            title_row,
            caption_row,
            strip,
            width: margin + n * (panel.width + margin) + strip,
            height: title_row + panel.height + caption_row + margin,
        }
    }
}

/// Smallest panel side a figure accepts (pixels): a picture's smallest.
const MIN_PANEL: usize = super::MIN_SIZE;

/// `panel` resized so that `n` panels with their title, captions, margins and colour bar fit
/// in `width × height` as fully as whole pixels allow; `None` when the panels would be
/// smaller than [`MIN_PANEL`]. The text scale follows the panel height, and the rows follow
/// the scale, so the height is found by a few fixed-point passes and then stepped down until
/// the figure fits.
fn fit_panels(
    panel: &RenderOptions,
    n: usize,
    width: usize,
    height: usize,
) -> Option<RenderOptions> {
    let n = n.max(1);
    let resized = |panel_height: usize| {
        let tall = RenderOptions {
            height: panel_height,
            ..*panel
        };
        let l = Layout::of(&tall, n);
        let free = width.checked_sub(l.margin + n * l.margin + l.strip)?;
        Some(RenderOptions {
            width: free / n,
            ..tall
        })
    };
    let mut panel_height = height;
    for _ in 0..8 {
        let l = Layout::of(
            &RenderOptions {
                height: panel_height,
                ..*panel
            },
            n,
        );
        panel_height = height.saturating_sub(l.title_row + l.caption_row + l.margin);
    }
    while panel_height >= MIN_PANEL {
        if let Some(p) = resized(panel_height) {
            let l = Layout::of(&p, n);
            if p.width >= MIN_PANEL && l.width <= width && l.height <= height {
                return Some(p);
            }
        }
        panel_height -= 1;
    }
    None
}

/// One panel's caption data.
#[derive(Clone, Debug, PartialEq)]
pub struct Panel {
    /// Frame index.
    pub frame: usize,
    /// Time step the frame was written at (the paper's "frame": steps are 1/30 s).
    pub step: u64,
    /// Simulated time (s).
    pub time: f64,
    /// Tetrahedra in the frame.
    pub elements: usize,
    /// Crack polygons: planar crack pieces per scene element, counted once for both sides
    /// (`fracture::cracks::crack_polygons`).
    pub crack_polygons: usize,
    /// Crack triangles, both sides of each crack.
    pub crack_triangles: usize,
    /// Connected crack surfaces.
    pub cracks: usize,
}

impl Panel {
    /// The captions of `frame` of a run whose scene mesh has the boundary `original` (none:
    /// no crack polygons counted).
    fn of(frame: &StoredFrame, original: Option<&OriginalBoundary>) -> Panel {
        let origin: Option<Vec<usize>> = frame
            .element_field("origin")
            .map(|(_, data)| data.iter().map(|&o| o.max(0.0) as usize).collect());
        let crack_polygons = match (original, origin) {
            (Some(original), Some(origin)) => count_polygons(
                original,
                &frame.state.rest_positions,
                &frame.state.tets,
                &origin,
            ),
            _ => 0,
        };
        Panel {
            frame: frame.index,
            step: frame.state.step,
            time: frame.state.time,
            elements: frame.state.tets.len(),
            crack_polygons,
            crack_triangles: frame.crack_triangles.len(),
            cracks: frame
                .crack_triangles
                .iter()
                .map(|(_, c)| c)
                .collect::<HashSet<_>>()
                .len(),
        }
    }
}

/// The frames a figure shows by default (see [`FigureOptions::frames`]), from the complete
/// frames' indices and the steps they were written at.
pub fn default_frames(indices: &[usize], steps: &[u64]) -> Vec<usize> {
    let at_paper_steps: Vec<usize> = PAPER_STEPS
        .iter()
        .filter_map(|s| steps.iter().position(|t| t == s).map(|k| indices[k]))
        .collect();
    if at_paper_steps.len() == PAPER_STEPS.len() {
        return at_paper_steps;
    }
    let count = indices.len();
    let mut frames: Vec<usize> = (1..=4)
        .map(|k| indices[(count * k / 4).max(1) - 1])
        .collect();
    frames.dedup();
    frames
}

/// Composes the figure of `reader`'s run; returns it with each panel's caption data.
pub fn figure(
    reader: &FrameReader,
    options: &FigureOptions,
) -> Result<(Picture, Vec<Panel>), RenderError> {
    let indices = if options.frames.is_empty() {
        default_frames(&reader.frame_indices(), reader.frame_steps())
    } else {
        options.frames.clone()
    };
    let frames = indices
        .iter()
        .map(|&i| reader.read(i))
        .collect::<Result<Vec<_>, _>>()?;
    let n = frames.len();
    let panel = match options.size {
        None => options.panel,
        Some((width, height)) => {
            fit_panels(&options.panel, n, width, height).ok_or_else(|| RenderError::Invalid {
                path: reader.path().to_path_buf(),
                message: format!(
                    "a figure of {width}x{height} pixels has no room for {n} panels of at least \
                     {MIN_PANEL}x{MIN_PANEL} with their captions: give a larger --size"
                ),
            })?
        }
    };
    // The renderer leaves a colour-bar strip beside its scene; widen it by the strip so each
    // panel's scene is `panel.width` wide, and draw one shared bar instead.
    let overlay = panel.overlay();
    let Layout {
        margin,
        title_row,
        caption_row,
        strip,
        width,
        height,
    } = Layout::of(&panel, n);
    let mut renderer = Renderer::new(
        reader,
        RenderOptions {
            width: panel.width + strip,
            ..panel
        },
    )?;
    if let Some(field) = panel.color_by {
        let values = frames
            .iter()
            .map(|f| field.values(f, reader))
            .collect::<Result<Vec<_>, _>>()?;
        renderer.fit_range(values.into_iter().flatten());
    }

    let mut picture = panel.background.picture(width, height);
    let file = reader
        .path()
        .file_name()
        .unwrap_or_default()
        .to_string_lossy();
    let scene = Path::new(reader.scene_path())
        .file_name()
        .unwrap_or_default()
        .to_string_lossy();
    let title = format!("icefem: {scene} ({file})");
    overlay.text(
        &mut picture,
        &title,
        margin as f64,
        0.2 * title_row as f64,
        Align::Left,
    );
    let (rest, tets) = reader.initial_mesh()?;
    let original = TetMesh::from_arrays(&rest, tets)
        .ok()
        .map(|mesh| OriginalBoundary::new(&mesh));
    let mut panels = Vec::with_capacity(n);
    for (k, frame) in frames.iter().enumerate() {
        let x = margin + k * (panel.width + margin);
        picture.blit(&renderer.draw_scene(reader, frame)?, x, title_row);
        let p = Panel::of(frame, original.as_ref());
        let centre = (x + panel.width / 2) as f64;
        let below = (title_row + panel.height) as f64;
        let letter = (b'a' + (k % 26) as u8) as char;
        let t = super::overlay::clock_time(p.time, 1);
        let line1 = format!("({letter}) step {}, t = {t}", p.step);
        let line2 = format!(
            "{} elements, {} crack polygons",
            p.elements, p.crack_polygons
        );
        let row = caption_row as f64 / 2.0;
        overlay.text(
            &mut picture,
            &line1,
            centre,
            below + 0.1 * row,
            Align::Centre,
        );
        overlay.text(
            &mut picture,
            &line2,
            centre,
            below + 0.9 * row,
            Align::Centre,
        );
        panels.push(p);
    }
    if let Some(field) = panel.color_by {
        renderer.color_bar(&mut picture, field, width - strip, title_row, panel.height);
    }
    if let Some((full_width, full_height)) = options.size {
        // Whole pixels leave up to n − 1 columns (and a row or so) over: centred.
        let mut full = panel.background.picture(full_width, full_height);
        full.blit(
            &picture,
            (full_width - width) / 2,
            (full_height - height) / 2,
        );
        picture = full;
    }
    Ok((picture, panels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_steps_when_present_else_four_spread_over_the_run() {
        // Every 10th step written: the paper's steps are frames 120 … 240.
        let indices: Vec<usize> = (0..=240).collect();
        let steps: Vec<u64> = (0..=240).map(|f| 10 * f).collect();
        assert_eq!(default_frames(&indices, &steps), vec![120, 160, 200, 240]);
        // Cut off at step 999: a quarter of the frames each.
        let indices: Vec<usize> = (0..1000).collect();
        let steps: Vec<u64> = (0..1000).collect();
        assert_eq!(default_frames(&indices, &steps), vec![249, 499, 749, 999]);
        assert_eq!(default_frames(&[0], &[0]), vec![0]);
    }
}
