//! Rendering a list of frames to files: one PNG, a numbered PNG sequence, an animated GIF, or
//! an MP4 video (through `ffmpeg`).

use super::{save_png, Background, GifWriter, RenderError, RenderOptions, Renderer};
use crate::output::{parse_frame_range, FrameReader};
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
/// given, else the range `frames` (`A:B:S`, see [`parse_frame_range`]), else the last
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
            parse_frame_range(spec, &available).map_err(|message| RenderError::Invalid {
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

/// The `k`-th PNG (0, 1, 2, … whatever the frames' indices, as video encoders expect) when a
/// sequence is written to `path`: `stem_NNNNNN.png`.
pub fn numbered_path(path: &Path, k: usize) -> PathBuf {
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    path.with_file_name(format!("{stem}_{k:06}.png"))
}

/// What kind of file `icefem render` writes, from the output's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// `.png`: one picture, or a numbered sequence.
    Png,
    /// `.gif`: an animation.
    Gif,
    /// `.mp4`: an H.264 video, encoded by `ffmpeg` from a PNG sequence.
    Mp4,
}

impl Target {
    /// The target of `path`; an error names any other extension.
    pub fn of(path: &Path) -> Result<Self, RenderError> {
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match extension.as_deref() {
            Some("png") => Ok(Target::Png),
            Some("gif") => Ok(Target::Gif),
            Some("mp4") => Ok(Target::Mp4),
            other => Err(RenderError::Invalid {
                path: path.to_path_buf(),
                message: format!(
                    "cannot write {}: the output must end in .png (one frame, or a sequence numbered _000000, _000001, …), .gif or .mp4",
                    other.map_or_else(|| "a file without extension".to_string(), |e| format!(".{e} files"))
                ),
            }),
        }
    }
}

/// Checks that `ffmpeg` runs, for an `.mp4` output to `path`.
fn check_ffmpeg(path: &Path) -> Result<(), RenderError> {
    match std::process::Command::new("ffmpeg")
        .arg("-version")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
    {
        Ok(status) if status.success() => Ok(()),
        _ => Err(RenderError::Invalid {
            path: path.to_path_buf(),
            message: "writing .mp4 needs ffmpeg on the PATH, and it is not there: install it (Debian: apt-get install ffmpeg), or write a .gif or a .png sequence".into(),
        }),
    }
}

/// Encodes the PNG sequence `first` (numbered by [`numbered_path`]) at `fps` into the H.264
/// video `path` with `ffmpeg` (even sizes padded, as the codec needs; yuv420p, which players
/// expect).
fn encode_mp4(first: &Path, fps: f64, path: &Path) -> Result<(), RenderError> {
    let stem = first.file_stem().unwrap_or_default().to_string_lossy();
    let pattern = first.with_file_name(format!("{stem}_%06d.png"));
    let out = std::process::Command::new("ffmpeg")
        .args([
            "-y",
            "-loglevel",
            "error",
            "-framerate",
            &fps.to_string(),
            "-i",
        ])
        .arg(&pattern)
        .args([
            "-vf",
            "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            "-c:v",
            "libx264",
            "-pix_fmt",
            "yuv420p",
        ])
        .arg(path)
        .output();
    match out {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => Err(RenderError::Invalid {
            path: path.to_path_buf(),
            message: format!(
                "ffmpeg failed: {}",
                String::from_utf8_lossy(&o.stderr).trim()
            ),
        }),
        Err(e) => Err(RenderError::Invalid {
            path: path.to_path_buf(),
            message: format!("cannot run ffmpeg: {e}"),
        }),
    }
}

/// Renders `frames` of `reader` to `path` by its extension ([`Target`]): an animated GIF or
/// an MP4 video at `fps` frames per second, or PNG — `path` itself for one frame, the
/// [`numbered_path`]s for several. The colour range (when colouring by a field) is fitted over
/// all the frames, so a sequence keeps one scale.
pub fn render_frames(
    reader: &FrameReader,
    frames: &[usize],
    options: RenderOptions,
    path: &Path,
    fps: f64,
) -> Result<RenderSummary, RenderError> {
    let target = Target::of(path)?;
    if target != Target::Png && options.background == Background::Transparent {
        return Err(RenderError::Invalid {
            path: path.into(),
            message: "a transparent background needs PNG output: GIF and MP4 frames are opaque (write a .png sequence, or choose another --background)".into(),
        });
    }
    if target == Target::Mp4 {
        check_ffmpeg(path)?;
    }
    // A video is encoded from a PNG sequence in a folder beside it, removed afterwards.
    let frames_dir = sibling(path, ".frames");
    let png_path = match target {
        Target::Mp4 => {
            std::fs::create_dir_all(&frames_dir).map_err(|source| RenderError::Io {
                path: frames_dir.clone(),
                source,
            })?;
            frames_dir.join("frame.png")
        }
        _ => path.to_path_buf(),
    };
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
    let mut gif = if target == Target::Gif {
        summary.files.push(path.into());
        Some(GifWriter::create(path, options.width, options.height, fps)?)
    } else {
        None
    };
    let mut pngs = Vec::new();
    for (k, &index) in frames.iter().enumerate() {
        let start = Instant::now();
        let frame = reader.read(index)?;
        let drawn = Instant::now();
        let picture = renderer.render(reader, &frame, true)?;
        let encoded = Instant::now();
        match &mut gif {
            Some(gif) => gif.push(&picture)?,
            None => {
                let file = if frames.len() == 1 && target == Target::Png {
                    png_path.clone()
                } else {
                    numbered_path(&png_path, k)
                };
                save_png(&picture, &file)?;
                pngs.push(file);
            }
        }
        summary.t_read += (drawn - start).as_secs_f64();
        summary.t_draw += (encoded - drawn).as_secs_f64();
        summary.t_encode += encoded.elapsed().as_secs_f64();
        summary.frames += 1;
    }
    if target == Target::Mp4 {
        let start = Instant::now();
        let encoded = encode_mp4(&png_path, fps, path);
        // The PNGs were only the video's input.
        let _ = std::fs::remove_dir_all(&frames_dir);
        encoded?;
        summary.t_encode += start.elapsed().as_secs_f64();
        summary.files.push(path.to_path_buf());
    } else {
        summary.files.extend(pngs);
    }
    Ok(summary)
}
