//! `icefem export`: a run's frames as surfaces for other programs — a USD stage (Blender,
//! Houdini), OBJ, PLY or VTU files (ParaView).
//!
//! Every format gets the same objects per frame ([`ExportFrame`], `frame.rs`): the ice's
//! outer surface and the crack surfaces, with per-point freeze state, ‖ε_p‖, von Mises stress,
//! temperature and velocity where the format holds attributes, and the rigid obstacles where
//! they are at the frame's time. Metres, z up. One file per format
//! (`usd.rs`, `obj.rs`, `ply.rs`, `vtu.rs`), all written by hand: the formats are small, and
//! the crates for them are old, heavy or need a newer compiler (each file says which and why).
//! `target.rs` says where the files go and when existing ones are replaced.

mod frame;
mod obj;
mod ply;
mod target;
mod usd;
mod vtu;

pub use frame::{
    ExportFrame, PointScalar, SurfaceMesh, FREEZE_STATE, PLASTIC_STRAIN, TEMPERATURE, VELOCITY,
    VON_MISES,
};

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::output::{parse_frame_range, FrameReader, OutputError, SurfaceExtractor};
use crate::render::obstacles::{stored_obstacles, StoredObstacle};
use nalgebra::Vector3;
use target::Target;

/// An export format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportFormat {
    /// One USD text stage (`.usda`), time-sampled.
    Usd,
    /// One Wavefront OBJ per frame (geometry only).
    Obj,
    /// Binary PLY per frame and object, with the attributes as vertex properties.
    Ply,
    /// VTK XML unstructured grid per frame and object, and a `.pvd` collection.
    Vtu,
}

impl ExportFormat {
    /// The files' extension.
    pub fn extension(self) -> &'static str {
        match self {
            ExportFormat::Usd => "usda",
            ExportFormat::Obj => "obj",
            ExportFormat::Ply => "ply",
            ExportFormat::Vtu => "vtu",
        }
    }
}

/// What to export and where.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportOptions {
    /// The format.
    pub format: ExportFormat,
    /// Frames `FIRST:LAST[:STEP]` ([`parse_frame_range`]); `None`: every complete frame.
    pub frames: Option<String>,
    /// The `.usda` file (USD) or the folder (OBJ, PLY, VTU); default `RUN.usda` or
    /// `RUN_export/` beside the run.
    pub output: Option<PathBuf>,
    /// Replace an earlier export's files.
    pub force: bool,
    /// USD: the animation's frames per second, the stage's `framesPerSecond` and
    /// `timeCodesPerSecond` ([`DEFAULT_FPS`] from the command line).
    pub fps: f64,
    /// USD: simulated seconds per second of animation — 1 plays the run in real time, 600 a
    /// six-hour freezing run in 36 s. A frame at simulated time t is at time code
    /// (t − t₀) × fps / speed, t₀ the first exported frame's time.
    pub speed: f64,
}

/// An animation's frames per second unless `--fps` says otherwise.
pub const DEFAULT_FPS: f64 = 30.0;

/// Largest `fps` accepted: beyond any player's rate.
pub const MAX_FPS: f64 = 1000.0;

/// What an export wrote and where its time went (s, summed over the frames).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExportSummary {
    /// Frames exported.
    pub frames: usize,
    /// The stage or the folder.
    pub output: PathBuf,
    /// Every file written.
    pub files: Vec<PathBuf>,
    /// Reading frames from the HDF5 file.
    pub t_read: f64,
    /// Building the surfaces and their attributes.
    pub t_build: f64,
    /// Formatting and writing the files.
    pub t_write: f64,
}

/// Failures of an export. Each names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// Reading the run failed, or it is not icefem output.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// Writing failed.
    #[error("{}: {context}: {source}", path.display())]
    Io {
        /// File concerned.
        path: PathBuf,
        /// What was being done.
        context: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// An earlier export's file is in the way.
    #[error("{} exists: pass --force to replace it", path.display())]
    Exists {
        /// The (first) file in the way.
        path: PathBuf,
    },
    /// The output path holds something an export never replaces.
    #[error("{}: refusing to write the export over it: {reason}", path.display())]
    Foreign {
        /// Path concerned.
        path: PathBuf,
        /// What it holds.
        reason: String,
    },
    /// An option does not fit the file.
    #[error("{}: {message}", path.display())]
    Invalid {
        /// File concerned.
        path: PathBuf,
        /// What is wrong, naming the option.
        message: String,
    },
}

/// A format's writer: frames in order, then [`Sink::finish`].
trait Sink {
    /// Writes (or, for one file over all frames, keeps) `frame`.
    fn frame(&mut self, frame: &ExportFrame) -> Result<(), ExportError>;
    /// Writes what is left; every file the export wrote.
    fn finish(self: Box<Self>) -> Result<Vec<PathBuf>, ExportError>;
}

/// Exports frames of `reader` as `options` say.
pub fn export(reader: &FrameReader, options: &ExportOptions) -> Result<ExportSummary, ExportError> {
    let path = reader.path();
    let invalid = |message: String| ExportError::Invalid {
        path: path.to_path_buf(),
        message,
    };
    let available = reader.frame_indices();
    let frames = match &options.frames {
        Some(spec) => parse_frame_range(spec, &available).map_err(invalid)?,
        None => available,
    };
    if let (ExportFormat::Usd, Some(file)) = (options.format, &options.output) {
        if file.extension().is_none_or(|e| e != "usda") {
            return Err(invalid(format!(
                "--output {}: a USD text stage's name ends in .usda",
                file.display()
            )));
        }
    }
    if !(options.fps > 0.0 && options.fps <= MAX_FPS) {
        return Err(invalid(format!(
            "--fps {}: an animation's frames per second must be in (0, {MAX_FPS}]",
            options.fps
        )));
    }
    if !(options.speed.is_finite() && options.speed > 0.0) {
        return Err(invalid(format!(
            "--speed {}: simulated seconds per second of animation must be a number > 0",
            options.speed
        )));
    }
    let obstacles = run_obstacles(reader)?;
    let target = Target::new(path, options.format, options.output.as_deref());
    target.prepare(
        &planned_files(&target, options.format, frames.len(), !obstacles.is_empty()),
        options.force,
    )?;

    let mut summary = ExportSummary {
        frames: frames.len(),
        output: target.output(),
        ..Default::default()
    };
    let mut sink: Box<dyn Sink> = match options.format {
        ExportFormat::Usd => Box::new(usd::UsdSink::new(&target, path, options.fps, options.speed)),
        ExportFormat::Obj => Box::new(obj::ObjSink::new(&target, path)),
        ExportFormat::Ply => Box::new(ply::PlySink::new(&target, path)),
        ExportFormat::Vtu => Box::new(vtu::VtuSink::new(&target)),
    };
    let mut extractor = None;
    for (number, &index) in frames.iter().enumerate() {
        let start = Instant::now();
        let stored = reader.read(index)?;
        let read = Instant::now();
        let extractor = match &mut extractor {
            Some(e) => e,
            None => extractor.insert(SurfaceExtractor::new(reader, &stored)?),
        };
        let frame = ExportFrame::new(extractor, path, &stored, number, &obstacles)?;
        let built = Instant::now();
        sink.frame(&frame)?;
        summary.t_read += (read - start).as_secs_f64();
        summary.t_build += (built - read).as_secs_f64();
        summary.t_write += built.elapsed().as_secs_f64();
    }
    let start = Instant::now();
    summary.files = sink.finish()?;
    summary.t_write += start.elapsed().as_secs_f64();
    Ok(summary)
}

/// Every file an export of `frames` frames to `target` writes (with the obstacles' where
/// `obstacles`).
fn planned_files(
    target: &Target,
    format: ExportFormat,
    frames: usize,
    obstacles: bool,
) -> Vec<PathBuf> {
    let objects = &OBJECTS[..if obstacles { 3 } else { 2 }];
    match format {
        ExportFormat::Usd => vec![target.usd_file()],
        ExportFormat::Obj => (0..frames).map(|k| target.frame_file(None, k)).collect(),
        ExportFormat::Ply | ExportFormat::Vtu => {
            let mut files: Vec<PathBuf> = (0..frames)
                .flat_map(|k| objects.iter().map(move |o| target.frame_file(Some(o), k)))
                .collect();
            if format == ExportFormat::Vtu {
                files.push(vtu::collection_file(target));
            }
            files
        }
    }
}

/// The objects' names, as the files and prims are named: the ice's outer surface, the crack
/// surfaces and the rigid obstacles.
const OBJECTS: [&str; 3] = ["ice", "cracks", "obstacles"];

/// The objects of `frame`, in the order of [`OBJECTS`] (obstacles where the run had them).
fn objects(frame: &ExportFrame) -> Vec<(&'static str, &SurfaceMesh)> {
    let mut objects = vec![(OBJECTS[0], &frame.ice), (OBJECTS[1], &frame.cracks)];
    if let Some(obstacles) = &frame.obstacles {
        objects.push((OBJECTS[2], obstacles));
    }
    objects
}

/// The rigid obstacles of `reader`'s run, planes sized to the ice's box in its first frame
/// (as `icefem render` draws them; that frame is read only for a scene with a plane).
fn run_obstacles(reader: &FrameReader) -> Result<Vec<StoredObstacle>, ExportError> {
    Ok(stored_obstacles(reader, || {
        let first = reader.read(reader.frame_indices()[0])?;
        Ok(first.state.positions.iter().fold(
            (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN)),
            |(lo, hi), p| (lo.inf(&Vector3::from(*p)), hi.sup(&Vector3::from(*p))),
        ))
    })?)
}

/// Writes `bytes` to `path` (created or truncated).
fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(bytes))
        .map_err(|source| ExportError::Io {
            path: path.to_path_buf(),
            context: "writing".into(),
            source,
        })
}

/// The run's file name, for the files' comments.
fn run_name(run: &Path) -> String {
    run.file_name()
        .unwrap_or_default()
        .to_string_lossy()
        .into_owned()
}
