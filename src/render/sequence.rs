//! Rendering a list of frames to files: one PNG, a numbered PNG sequence, or an animated GIF.

use super::{save_png, GifWriter, RenderError, RenderOptions, Renderer};
use crate::output::FrameReader;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What [`render_frames`] wrote and where its time went (s, summed over the frames).
#[derive(Clone, Debug, Default)]
pub struct RenderSummary {
    /// Files written (one GIF, or one PNG per frame).
    pub files: Vec<PathBuf>,
    /// Frames drawn.
    pub frames: usize,
    /// Reading frames from the HDF5 file.
    pub t_read: f64,
    /// Drawing (surface extraction, rasterisation, labels).
    pub t_draw: f64,
    /// PNG or GIF encoding and writing.
    pub t_encode: f64,
}

/// `RUN.h5` → `RUN<suffix>` beside it.
pub fn sibling(file: &Path, suffix: &str) -> PathBuf {
    let stem = file.file_stem().unwrap_or_default().to_string_lossy();
    file.with_file_name(format!("{stem}{suffix}"))
}

/// The frames `icefem render` draws from `reader` (whose file is `file`): frame `frame` if
/// given, else the range `frames` (`A:B:S`, see [`super::parse_frame_range`]), else the last
/// complete frame.
pub fn select_frames(
    file: &Path,
    reader: &FrameReader,
    frame: Option<usize>,
    frames: Option<&str>,
) -> Result<Vec<usize>, RenderError> {
    let available = reader.frame_indices();
    Ok(match (frame, frames) {
        (Some(f), _) => vec![f],
        (None, Some(spec)) => {
            super::parse_frame_range(spec, &available).map_err(|message| RenderError::Invalid {
                path: file.to_path_buf(),
                message,
            })?
        }
        (None, None) => vec![available[available.len() - 1]],
    })
}

/// Where `icefem render` writes `frames` of `file` by default: `RUN_NNNNNN.png` beside it for
/// one frame, `RUN.gif` for several.
pub fn default_output(file: &Path, frames: &[usize]) -> PathBuf {
    match frames {
        [one] => sibling(file, &format!("_{one:06}.png")),
        _ => sibling(file, ".gif"),
    }
}

/// The PNG file of frame `index` when a sequence is written to `path`: `stem_NNNNNN.png`.
pub fn numbered_path(path: &Path, index: usize) -> PathBuf {
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    path.with_file_name(format!("{stem}_{index:06}.png"))
}

/// Renders `frames` of `reader` to `path`: an animated GIF at `fps` frames per second if
/// `path` ends in `.gif`, else PNG — `path` itself for one frame, [`numbered_path`] for
/// several. The colour range (when colouring by a field) is fitted over all the frames, so a
/// sequence keeps one scale.
pub fn render_frames(
    reader: &FrameReader,
    frames: &[usize],
    options: RenderOptions,
    path: &Path,
    fps: f64,
) -> Result<RenderSummary, RenderError> {
    let mut summary = RenderSummary::default();
    let mut renderer = Renderer::new(reader, options)?;
    if let (Some(field), None) = (options.color_by, options.range) {
        // A first pass for the range; frames are read again when drawn, so that a long
        // sequence never holds more than one frame.
        let mut extremes = Vec::with_capacity(2 * frames.len());
        for &index in frames {
            let start = Instant::now();
            let frame = reader.read(index)?;
            summary.t_read += start.elapsed().as_secs_f64();
            let values = field.values(&frame, reader)?;
            let finite = values.iter().copied().filter(|v| v.is_finite());
            extremes.push(finite.clone().fold(f64::MAX, f64::min));
            extremes.push(finite.fold(f64::MIN, f64::max));
        }
        renderer.fit_range(extremes.into_iter().filter(|v| v.abs() < f64::MAX));
    }
    let is_gif = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gif"));
    let mut gif = if is_gif {
        summary.files.push(path.into());
        Some(GifWriter::create(path, options.width, options.height, fps)?)
    } else {
        None
    };
    for &index in frames {
        let start = Instant::now();
        let frame = reader.read(index)?;
        let drawn = Instant::now();
        let picture = renderer.render(reader, &frame, true)?;
        let encoded = Instant::now();
        match &mut gif {
            Some(gif) => gif.push(&picture)?,
            None => {
                let file = if frames.len() == 1 {
                    path.to_path_buf()
                } else {
                    numbered_path(path, index)
                };
                save_png(&picture, &file)?;
                summary.files.push(file);
            }
        }
        summary.t_read += (drawn - start).as_secs_f64();
        summary.t_draw += (encoded - drawn).as_secs_f64();
        summary.t_encode += encoded.elapsed().as_secs_f64();
        summary.frames += 1;
    }
    Ok(summary)
}
