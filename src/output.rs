//! HDF5 output of an icefem run, plus its XDMF sidecar for ParaView / meshio.
//!
//! # File layout
//!
//! ```text
//! /                      attrs: scene (TOML text), scene_path, icefem_version, format_version (u32)
//! /mesh/rest_positions   f64 [n, 3]  reference configuration (m)
//! /mesh/tets             i64 [m, 4]  0-based node indices of each linear tetrahedron
//! /frames/NNNNNN         one group per output frame, NNNNNN = 0-based frame index (6+ digits)
//!     attrs: step (u64), time (f64, s), complete (u8, = 1, written last)
//!     positions          f64 [n, 3]  (m)
//!     velocities         f64 [n, 3]  (m/s)
//!     rest_positions     f64 [n, 3]  (m)   hard link to the previous frame's when topology is unchanged
//!     tets               i64 [m, 4]        hard link to the previous frame's when topology is unchanged
//!     stress             f64 [m, 6]  Cauchy stress, Voigt order xx yy zz yz xz xy (Pa)
//!     <field>            f64 [rows] if cols == 1, else [rows, cols]; attr center = "Cell" | "Node"
//!     cracks/            fracture runs only: the crack faces as separate triangles
//!         vertices       f64 [3t, 3] (m), drawn with the rendering gap where a crack is closed
//!         triangles      i64 [t, 3]  indices into vertices
//!         crack          i64 [t]     which crack (connected crack surface) each belongs to
//! /stats/<column>        one resizable chunked 1-D dataset per `StepStats` field, one row per step
//! ```
//!
//! Tetrahedra are stored as signed 64-bit integers rather than `u64` because
//! the XDMF 3 library shipped with ParaView has no 64-bit unsigned type.
//!
//! # Crash safety
//!
//! Frames are committed in batches: a file flush, then the `complete` attribute
//! on every frame written since the last commit, then a second flush. A commit
//! happens after the first frame, whenever [`COMMIT_INTERVAL`] has passed since
//! the last one, and when the writer finishes or is dropped — so a run writing a
//! frame every few milliseconds does not spend its time flushing, and a killed
//! run loses at most the last interval. Between commits the file on disk does not
//! change under what it already holds: HDF5's metadata cache writes only when
//! flushed, and freed space is never reused (see `crash_safe_options`). A process
//! killed between commits therefore leaves a readable file in which every frame
//! carrying `complete = 1` is fully on disk; [`OutputWriter::resume`] discards
//! whatever came after it. (A kill during a commit's own flushes, a few
//! milliseconds per interval, could still leave the groups half updated. H5Fflush
//! hands the data to the OS; it does not fsync, so this protects against a killed
//! process, not against a power loss.) The file has superblock version 2 (the
//! HDF5 1.8 format, which the file-space setting needs), not version 3, whose
//! "open for writing" flag would make a killed run's file unopenable without
//! `h5clear`.

use std::fmt::Write as _;
use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use hdf5::types::{FloatSize, IntSize, TypeDescriptor, VarLenAscii, VarLenUnicode};
use hdf5::{Dataset, File, Group, H5Type};
use ndarray::{ArrayView1, ArrayView2};

use crate::fracture::cracks::CrackSurface;

/// Version of the on-disk layout described in the module docs, stored as
/// root attribute `format_version`. Bump when the layout changes incompatibly.
pub const FORMAT_VERSION: u32 = 1;

/// Marks the file's descriptor close-on-exec. HDF5 opens files without `O_CLOEXEC`, so a
/// child process started while a file is open inherits the descriptor and keeps the file's lock
/// after we close it: our own next open of that file then fails with "unable to lock file"
/// (seen in the test suite, which writes files while it runs `icefem` processes). Best effort:
/// on failure the descriptor simply stays inheritable.
fn close_on_exec(file: &File) {
    hdf5::sync::sync(|| {
        let mut handle: *mut std::ffi::c_void = std::ptr::null_mut();
        // SAFETY: `file` is an open file id; with the default (sec2) driver the VFD handle
        // points to the POSIX descriptor, an `int`. The HDF5 call runs under hdf5's lock.
        unsafe {
            let status = hdf5_sys::h5f::H5Fget_vfd_handle(
                file.id(),
                hdf5_sys::h5p::H5P_DEFAULT,
                &mut handle,
            );
            if status >= 0 && !handle.is_null() {
                let fd = *(handle as *const libc::c_int);
                libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC);
            }
        }
    });
}

/// Dataset names inside a frame group that are not user fields.
const RESERVED_FRAME_NAMES: [&str; 5] = [
    "positions",
    "velocities",
    "rest_positions",
    "tets",
    "stress",
];

/// Rows appended to `/stats` per chunk; 4096 rows × 8 B = 32 KiB chunks keep
/// small runs small and long runs from having millions of chunks.
const STATS_CHUNK_ROWS: usize = 4096;

/// Pending stats rows are written out once this many accumulate, so memory
/// stays bounded even if frames are rare.
const STATS_MAX_PENDING: usize = 1024;

/// Target number of values per chunk of a frame dataset (64 Ki × 8 B = 512 KiB),
/// below HDF5's default 1 MiB chunk cache.
const FRAME_CHUNK_VALUES: usize = 65536;

/// One per-element or per-node field stored in a frame, row-major (rows × cols).
///
/// `rows` is implied: the element count for element fields, the node count for
/// node fields; `data.len()` must equal `rows * cols`. Units are the caller's
/// (document them in the field name's meaning, e.g. strain is dimensionless).
pub struct Field<'a> {
    /// Dataset name inside the frame group; must not contain `/`, be `.`, or
    /// collide with a built-in dataset (`positions`, `velocities`,
    /// `rest_positions`, `tets`, `stress`).
    pub name: &'a str,
    /// Number of components per row (≥ 1). Fields with one column are stored
    /// as 1-D datasets.
    pub cols: usize,
    /// Row-major values, `rows * cols` long.
    pub data: &'a [f64],
}

/// What is written once when a run starts.
pub struct RunHeader<'a> {
    /// The TOML scene, stored as root attribute `scene`.
    pub scene_text: &'a str,
    /// Where the scene was read from, root attribute `scene_path`.
    pub scene_path: &'a str,
    /// icefem version that wrote the file, root attribute `icefem_version`.
    pub version: &'a str,
    /// Initial reference node positions (m), `/mesh/rest_positions` [n, 3].
    pub rest_positions: &'a [[f64; 3]],
    /// Initial tetrahedra, 0-based node indices, `/mesh/tets` [m, 4] (i64).
    pub tets: &'a [[usize; 4]],
}

/// One output frame.
pub struct Frame<'a> {
    /// Solver time step index, attribute `step`.
    pub step: u64,
    /// Simulated time (s), attribute `time`.
    pub time: f64,
    /// Current node positions (m), dataset `positions` [n, 3].
    pub positions: &'a [[f64; 3]],
    /// Node velocities (m/s), dataset `velocities` [n, 3].
    pub velocities: &'a [[f64; 3]],
    /// Reference node positions (m), dataset `rest_positions` [n, 3]. Only
    /// written when `topology_changed`; otherwise hard-linked to the previous
    /// frame's (or `/mesh`'s) and this slice is only length-checked.
    pub rest_positions: &'a [[f64; 3]],
    /// Tetrahedra (0-based node indices), dataset `tets` [m, 4]. Same linking
    /// rule as `rest_positions`.
    pub tets: &'a [[usize; 4]],
    /// `true` → write `rest_positions` and `tets` anew in this frame; `false`
    /// → hard-link them to the previous frame's (node and element counts must
    /// then be unchanged).
    pub topology_changed: bool,
    /// Per-element Cauchy stress (Pa), Voigt order xx yy zz yz xz xy, dataset
    /// `stress` [m, 6].
    pub stress: &'a [[f64; 6]],
    /// Extra per-element state (e.g. `eigenstrain` m×1, `plastic_strain` m×6).
    pub element_fields: &'a [Field<'a>],
    /// Extra per-node state (e.g. `temperature` n×1).
    pub node_fields: &'a [Field<'a>],
    /// Crack surfaces (fracture runs), group `cracks`: `vertices` f64 [k, 3] (m),
    /// `triangles` i64 [t, 3] (indices into `vertices`), `crack` i64 [t] (which crack).
    pub cracks: Option<&'a CrackSurface>,
}

/// One row of `/stats` per time step. Times in seconds, energies in joules.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepStats {
    /// Time step index.
    pub step: u64,
    /// Simulated time at the end of the step (s).
    pub time: f64,
    /// Step size (s).
    pub dt: f64,
    /// Newton iterations taken by the step.
    pub newton_iterations: u32,
    /// Newton solves the step took: one per substep, plus one per re-solve after friction's
    /// normal force was re-lagged or a mesh obstacle's planes were re-picked.
    pub newton_solves: u32,
    /// Linear-solver iterations summed over the step (one per Newton iteration for Cholesky).
    pub linear_iterations: u32,
    /// Numeric factorisations or multigrid set-ups in the step (Hessian refreshes, and those a
    /// solve did itself when a reused preconditioner was too stale).
    pub factorizations: u32,
    /// Solves the step took (1, or more when Newton failed and the step was halved).
    pub substeps: u32,
    /// Final Newton residual, max |free-dof force imbalance| (N).
    pub residual: f64,
    /// Total energy (J).
    pub energy: f64,
    /// Kinetic energy (J).
    pub kinetic_energy: f64,
    /// Elastic strain energy (J).
    pub elastic_energy: f64,
    /// Potential (gravity / external) energy (J).
    pub potential_energy: f64,
    /// Penalty energy stored in contact (J).
    pub contact_energy: f64,
    /// Wall-clock time spent assembling (s).
    pub t_assembly: f64,
    /// Wall-clock time spent factorizing (s).
    pub t_factorization: f64,
    /// Wall-clock time spent in triangular / iterative solves (s).
    pub t_solve: f64,
    /// Wall-clock time of the whole step (s).
    pub t_step: f64,
    /// Elements after the step (fracture adds some).
    pub elements: u64,
    /// Crack faces after the step (both sides of every crack; 0 without fracture).
    pub crack_faces: u64,
    /// Node splits made after the step.
    pub fracture_events: u32,
    /// Largest separation stress v⁺ / A(n) after the step, before any split (Pa; 0 without
    /// fracture).
    pub separation_stress: f64,
    /// Wall-clock time of the fracture check and splits after the step (s).
    pub t_fracture: f64,
    /// Wall-clock time of rebuilding the simulation on a split mesh (s).
    pub t_remesh: f64,
    /// Wall-clock time of taking the step again on the split meshes (s).
    pub t_resolve: f64,
}

/// How one `/stats` column is extracted from a [`StepStats`] row.
#[derive(Clone, Copy)]
enum StatsColumn {
    U64(fn(&StepStats) -> u64),
    U32(fn(&StepStats) -> u32),
    F64(fn(&StepStats) -> f64),
}

/// The `/stats` columns, named exactly as the `StepStats` fields. `step` must
/// stay first: `resume` reads it to decide where to truncate.
const STATS_COLUMNS: [(&str, StatsColumn); 25] = [
    ("step", StatsColumn::U64(|s| s.step)),
    ("time", StatsColumn::F64(|s| s.time)),
    ("dt", StatsColumn::F64(|s| s.dt)),
    (
        "newton_iterations",
        StatsColumn::U32(|s| s.newton_iterations),
    ),
    ("newton_solves", StatsColumn::U32(|s| s.newton_solves)),
    (
        "linear_iterations",
        StatsColumn::U32(|s| s.linear_iterations),
    ),
    ("factorizations", StatsColumn::U32(|s| s.factorizations)),
    ("substeps", StatsColumn::U32(|s| s.substeps)),
    ("residual", StatsColumn::F64(|s| s.residual)),
    ("energy", StatsColumn::F64(|s| s.energy)),
    ("kinetic_energy", StatsColumn::F64(|s| s.kinetic_energy)),
    ("elastic_energy", StatsColumn::F64(|s| s.elastic_energy)),
    ("potential_energy", StatsColumn::F64(|s| s.potential_energy)),
    ("contact_energy", StatsColumn::F64(|s| s.contact_energy)),
    ("t_assembly", StatsColumn::F64(|s| s.t_assembly)),
    ("t_factorization", StatsColumn::F64(|s| s.t_factorization)),
    ("t_solve", StatsColumn::F64(|s| s.t_solve)),
    ("t_step", StatsColumn::F64(|s| s.t_step)),
    ("elements", StatsColumn::U64(|s| s.elements)),
    ("crack_faces", StatsColumn::U64(|s| s.crack_faces)),
    ("fracture_events", StatsColumn::U32(|s| s.fracture_events)),
    (
        "separation_stress",
        StatsColumn::F64(|s| s.separation_stress),
    ),
    ("t_fracture", StatsColumn::F64(|s| s.t_fracture)),
    ("t_remesh", StatsColumn::F64(|s| s.t_remesh)),
    ("t_resolve", StatsColumn::F64(|s| s.t_resolve)),
];

/// Everything read back from the last complete frame (owned), to restart a run.
#[derive(Debug, Clone, PartialEq)]
pub struct ResumeFrame {
    /// Step index of the frame.
    pub step: u64,
    /// Simulated time of the frame (s).
    pub time: f64,
    /// The TOML scene stored at run start.
    pub scene_text: String,
    /// Node positions (m).
    pub positions: Vec<[f64; 3]>,
    /// Node velocities (m/s).
    pub velocities: Vec<[f64; 3]>,
    /// Reference node positions (m).
    pub rest_positions: Vec<[f64; 3]>,
    /// Tetrahedra, 0-based node indices (all checked to be < node count).
    pub tets: Vec<[usize; 4]>,
    /// `(name, cols, row-major data)` of every per-element field, sorted by name.
    /// Does not include `stress`; read it with the hdf5 crate if needed.
    pub element_fields: Vec<(String, usize, Vec<f64>)>,
    /// `(name, cols, row-major data)` of every per-node field, sorted by name.
    pub node_fields: Vec<(String, usize, Vec<f64>)>,
}

/// Errors of the output module. Every variant names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The HDF5 library reported an error.
    #[error("{}: HDF5 error while {context}: {source}", path.display())]
    Hdf5 {
        /// File concerned.
        path: PathBuf,
        /// What was being done, e.g. "writing /frames/000003/positions [n, 3]".
        context: String,
        /// The library's error (includes its error stack message).
        #[source]
        source: hdf5::Error,
    },
    /// An operating-system I/O error (missing file, permissions, …).
    #[error("{}: I/O error while {context}: {source}", path.display())]
    Io {
        /// File concerned.
        path: PathBuf,
        /// What was being done.
        context: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The file exists but carries no HDF5 signature.
    #[error("{}: not an HDF5 file (no HDF5 signature found)", path.display())]
    NotHdf5 {
        /// File concerned.
        path: PathBuf,
    },
    /// The file is HDF5 but lacks the icefem layout.
    #[error("{}: HDF5 file is not icefem output: {reason}", path.display())]
    NotIcefem {
        /// File concerned.
        path: PathBuf,
        /// What is missing.
        reason: String,
    },
    /// The file holds no frame with `complete = 1` (nothing to resume from or to show).
    #[error("{}: no complete frame (the run wrote none before it ended)", path.display())]
    NoCompleteFrame {
        /// File concerned.
        path: PathBuf,
    },
    /// A frame index that is not a complete frame of the file.
    #[error("{}: no complete frame {index} (the file has {available})", path.display())]
    NoSuchFrame {
        /// File concerned.
        path: PathBuf,
        /// The index asked for.
        index: usize,
        /// What the file has, e.g. "2401 complete frames, 0 … 2400".
        available: String,
    },
    /// The file has the icefem layout but some content is malformed.
    #[error("{}: malformed icefem file: {reason}", path.display())]
    Corrupt {
        /// File concerned.
        path: PathBuf,
        /// What is malformed, naming the HDF5 object.
        reason: String,
    },
    /// The caller passed inconsistent data; nothing of the offending frame was written.
    #[error("{}: invalid output data: {reason}", path.display())]
    InvalidInput {
        /// File concerned.
        path: PathBuf,
        /// What is inconsistent.
        reason: String,
    },
}

/// Attaches the file path and a description of the failed operation to HDF5 errors.
trait Hdf5Context<T> {
    fn ctx(self, path: &Path, context: impl FnOnce() -> String) -> Result<T, OutputError>;
}

impl<T> Hdf5Context<T> for hdf5::Result<T> {
    fn ctx(self, path: &Path, context: impl FnOnce() -> String) -> Result<T, OutputError> {
        self.map_err(|source| OutputError::Hdf5 {
            path: path.to_path_buf(),
            context: context(),
            source,
        })
    }
}

fn corrupt(path: &Path, reason: impl Into<String>) -> OutputError {
    OutputError::Corrupt {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

fn invalid(path: &Path, reason: impl Into<String>) -> OutputError {
    OutputError::InvalidInput {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// Group name of frame `index`: at least 6 digits so that names sort in
/// frame order in tools that list members alphabetically (h5ls, HDFView).
fn frame_name(index: usize) -> String {
    format!("{index:06}")
}

/// Writes one run's frames and per-step statistics to an HDF5 file.
///
/// Dropping a writer without [`finish`](Self::finish) still writes buffered
/// stats rows (best effort) but produces no XDMF sidecar.
pub struct OutputWriter {
    path: PathBuf,
    /// `None` only after `finish` took it, so `Drop` knows there is nothing to do.
    file: Option<File>,
    /// Index of the next frame group to create.
    next_frame: usize,
    /// Absolute HDF5 paths that a frame with unchanged topology hard-links to.
    topology_rest_path: String,
    topology_tets_path: String,
    /// Node / element counts of the current topology, to reject a frame that
    /// claims unchanged topology but has different sizes.
    n_nodes: usize,
    n_elems: usize,
    /// Rows already in `/stats`.
    stats_rows: usize,
    /// Rows not yet written to `/stats`.
    pending_stats: Vec<StepStats>,
    /// Frames written but not yet marked complete.
    uncommitted: Vec<String>,
    /// When the last commit happened (`None`: never).
    last_commit: Option<std::time::Instant>,
}

/// How a run's file is created and reopened for writing, so that between commits nothing the
/// file on disk refers to changes (see the module docs): the metadata cache never writes an
/// entry out on its own (evictions off, so the cache grows as needed — about 10 kB a frame,
/// measured: 47 MB more peak memory over 5 000 frames of a 60-tet bar — and only a flush
/// writes), and freed file space is never reused (file-space
/// strategy "none": a group's heap that grows moves to the end of the file, and its old block
/// stays as it was, as the on-disk group still points to it until the next flush). With HDF5's
/// defaults, a process killed between commits left files whose `/frames` could not be listed
/// ("bad heap free list", "addr overflow") in 3 of 4 kills of a fast run.
fn crash_safe_options() -> hdf5::file::FileBuilder {
    use hdf5::plist::file_access::{
        CacheDecreaseMode, CacheIncreaseMode, FlashIncreaseMode, MetadataCacheConfig,
    };
    use hdf5::plist::file_create::FileSpaceStrategy;
    let cache = MetadataCacheConfig {
        evictions_enabled: false,
        incr_mode: CacheIncreaseMode::Off,
        flash_incr_mode: FlashIncreaseMode::Off,
        decr_mode: CacheDecreaseMode::Off,
        ..Default::default()
    };
    let mut builder = File::with_options();
    builder
        .with_fapl(|fapl| fapl.mdc_config(&cache))
        .with_fcpl(|fcpl| fcpl.file_space_strategy(FileSpaceStrategy::None));
    builder
}

/// Longest wall time between two commits of written frames (see the module docs).
pub const COMMIT_INTERVAL: std::time::Duration = std::time::Duration::from_millis(500);

impl OutputWriter {
    /// Creates (truncating) the file at `path` and writes the run header:
    /// root attributes, `/mesh`, empty `/frames` and empty `/stats` columns.
    pub fn create(path: &Path, header: &RunHeader) -> Result<Self, OutputError> {
        check_tets(path, "mesh", header.tets, header.rest_positions.len())?;
        let scene = vlen_str(path, "scene", header.scene_text)?;
        let scene_path = vlen_str(path, "scene_path", header.scene_path)?;
        let version = vlen_str(path, "icefem_version", header.version)?;

        let file = crash_safe_options()
            .create(path)
            .ctx(path, || "creating the file".into())?;
        close_on_exec(&file);
        let root: &Group = &file;
        write_attr(path, root, "scene", &scene)?;
        write_attr(path, root, "scene_path", &scene_path)?;
        write_attr(path, root, "icefem_version", &version)?;
        write_attr(path, root, "format_version", &FORMAT_VERSION)?;

        let mesh = file
            .create_group("mesh")
            .ctx(path, || "creating /mesh".into())?;
        write_vec3(path, &mesh, "rest_positions", header.rest_positions)?;
        write_tets(path, &mesh, "tets", header.tets)?;
        file.create_group("frames")
            .ctx(path, || "creating /frames".into())?;
        let stats = file
            .create_group("stats")
            .ctx(path, || "creating /stats".into())?;
        for (name, col) in STATS_COLUMNS {
            create_stats_column(path, &stats, name, col)?;
        }
        file.flush().ctx(path, || "flushing the header".into())?;

        Ok(Self {
            path: path.to_path_buf(),
            file: Some(file),
            next_frame: 0,
            topology_rest_path: "/mesh/rest_positions".into(),
            topology_tets_path: "/mesh/tets".into(),
            n_nodes: header.rest_positions.len(),
            n_elems: header.tets.len(),
            stats_rows: 0,
            pending_stats: Vec::new(),
            uncommitted: Vec::new(),
            last_commit: None,
        })
    }

    /// Number of frames in the file (the index the next frame will get).
    pub fn frame_count(&self) -> usize {
        self.next_frame
    }

    /// Path of the HDF5 file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn file(&self) -> Result<&File, OutputError> {
        // Only reachable if a method were called after `finish`, which takes `self`.
        self.file
            .as_ref()
            .ok_or_else(|| invalid(&self.path, "writer already finished"))
    }

    /// Appends one frame as group `/frames/NNNNNN` and writes pending stats; the
    /// frame is marked `complete = 1` at the next commit (see the module docs).
    ///
    /// All inputs are validated before anything is written, so an
    /// `InvalidInput` error leaves the file untouched.
    pub fn write_frame(&mut self, frame: &Frame) -> Result<(), OutputError> {
        self.validate_frame(frame)?;
        let name = frame_name(self.next_frame);
        let file = self.file()?.clone();
        let frames = file
            .group("frames")
            .ctx(&self.path, || "opening /frames".into())?;
        if frames.link_exists(&name) {
            return Err(corrupt(
                &self.path,
                format!("/frames/{name} already exists"),
            ));
        }
        let result = self.write_frame_group(frame, &file, &frames, &name);
        if result.is_err() {
            // Remove the partial group (best effort) so that a retry can reuse
            // the name; if this fails too, `resume` would discard it anyway
            // since it never got `complete`.
            let _ = frames.unlink(&name);
        }
        result
    }

    fn write_frame_group(
        &mut self,
        frame: &Frame,
        file: &File,
        frames: &Group,
        name: &str,
    ) -> Result<(), OutputError> {
        let path = self.path.clone();
        let g = frames
            .create_group(name)
            .ctx(&path, || format!("creating /frames/{name}"))?;
        write_attr(&path, &g, "step", &frame.step)?;
        write_attr(&path, &g, "time", &frame.time)?;
        write_vec3(&path, &g, "positions", frame.positions)?;
        write_vec3(&path, &g, "velocities", frame.velocities)?;
        if frame.topology_changed {
            write_vec3(&path, &g, "rest_positions", frame.rest_positions)?;
            write_tets(&path, &g, "tets", frame.tets)?;
        } else {
            // Hard links cost a few bytes and keep every frame self-contained
            // for readers (XDMF, h5py) that only look at one group.
            g.link_hard(&self.topology_rest_path, "rest_positions")
                .ctx(&path, || {
                    format!(
                        "hard-linking {} into /frames/{name}",
                        self.topology_rest_path
                    )
                })?;
            g.link_hard(&self.topology_tets_path, "tets")
                .ctx(&path, || {
                    format!(
                        "hard-linking {} into /frames/{name}",
                        self.topology_tets_path
                    )
                })?;
        }
        let stress = frame.stress.as_flattened();
        write_matrix(&path, &g, "stress", frame.stress.len(), 6, stress)?;
        for (fields, center) in [(frame.element_fields, "Cell"), (frame.node_fields, "Node")] {
            for f in fields {
                let rows = f.data.len() / f.cols;
                write_matrix(&path, &g, f.name, rows, f.cols, f.data)?;
                let ds = g
                    .dataset(f.name)
                    .ctx(&path, || format!("reopening field {}", f.name))?;
                write_attr(&path, &ds, "center", &vlen_str(&path, "center", center)?)?;
            }
        }
        if let Some(c) = frame.cracks {
            let cg = g
                .create_group("cracks")
                .ctx(&path, || format!("creating /frames/{name}/cracks"))?;
            write_vec3(&path, &cg, "vertices", &c.vertices)?;
            write_indices(&path, &cg, "triangles", &c.triangles)?;
            let ids: Vec<[usize; 1]> = c.crack.iter().map(|&k| [k]).collect();
            write_indices(&path, &cg, "crack", &ids)?;
        }
        self.flush_stats()?;
        self.uncommitted.push(name.to_string());
        if self
            .last_commit
            .is_none_or(|t| t.elapsed() >= COMMIT_INTERVAL)
        {
            self.commit(file)?;
        }

        if frame.topology_changed {
            self.topology_rest_path = format!("/frames/{name}/rest_positions");
            self.topology_tets_path = format!("/frames/{name}/tets");
            self.n_nodes = frame.positions.len();
            self.n_elems = frame.tets.len();
        }
        self.next_frame += 1;
        Ok(())
    }

    fn validate_frame(&self, frame: &Frame) -> Result<(), OutputError> {
        let path = &self.path;
        let n = frame.positions.len();
        let m = frame.tets.len();
        if frame.velocities.len() != n || frame.rest_positions.len() != n {
            return Err(invalid(
                path,
                format!(
                    "frame step {}: positions has {n} rows, velocities {}, rest_positions {}",
                    frame.step,
                    frame.velocities.len(),
                    frame.rest_positions.len()
                ),
            ));
        }
        if frame.stress.len() != m {
            return Err(invalid(
                path,
                format!(
                    "frame step {}: stress has {} rows for {m} tets",
                    frame.step,
                    frame.stress.len()
                ),
            ));
        }
        if !frame.topology_changed && (n != self.n_nodes || m != self.n_elems) {
            return Err(invalid(
                path,
                format!(
                    "frame step {}: topology_changed is false but counts changed \
                     ({} → {n} nodes, {} → {m} tets)",
                    frame.step, self.n_nodes, self.n_elems
                ),
            ));
        }
        if frame.topology_changed {
            check_tets(path, &format!("frame step {}", frame.step), frame.tets, n)?;
        }
        let mut seen: Vec<&str> = Vec::new();
        for (fields, rows, kind) in [
            (frame.element_fields, m, "element"),
            (frame.node_fields, n, "node"),
        ] {
            for f in fields {
                if f.name.is_empty()
                    || f.name == "."
                    || f.name.contains('/')
                    || f.name.contains('\0')
                    || RESERVED_FRAME_NAMES.contains(&f.name)
                {
                    return Err(invalid(
                        path,
                        format!("invalid {kind} field name {:?}", f.name),
                    ));
                }
                if seen.contains(&f.name) {
                    return Err(invalid(path, format!("duplicate field name {:?}", f.name)));
                }
                seen.push(f.name);
                let expected = rows.checked_mul(f.cols);
                if f.cols == 0 || expected != Some(f.data.len()) {
                    return Err(invalid(
                        path,
                        format!(
                            "{kind} field {:?}: {} values for {rows} rows × {} cols",
                            f.name,
                            f.data.len(),
                            f.cols
                        ),
                    ));
                }
            }
        }
        if seen.contains(&"cracks") && frame.cracks.is_some() {
            return Err(invalid(
                path,
                "a field is named \"cracks\", like the crack group",
            ));
        }
        if let Some(c) = frame.cracks {
            let k = c.vertices.len();
            if c.crack.len() != c.triangles.len()
                || c.triangles.as_flattened().iter().any(|&i| i >= k)
            {
                return Err(invalid(
                    path,
                    format!(
                        "crack surface: {} triangles, {} crack ids, indices must be < {k}",
                        c.triangles.len(),
                        c.crack.len()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Appends one row to `/stats`. Rows are buffered and written at the next
    /// `write_frame`, at `finish`, on drop, or when 1024 rows are pending.
    pub fn append_stats(&mut self, s: &StepStats) -> Result<(), OutputError> {
        self.pending_stats.push(*s);
        if self.pending_stats.len() >= STATS_MAX_PENDING {
            self.flush_stats()?;
        }
        Ok(())
    }

    /// Marks every uncommitted frame complete: a first flush puts all their
    /// datasets in the file before any marker exists, so no crash can leave a
    /// "complete" frame with missing data; a second flush writes the markers.
    fn commit(&mut self, file: &File) -> Result<(), OutputError> {
        self.last_commit = Some(std::time::Instant::now());
        if self.uncommitted.is_empty() {
            return Ok(());
        }
        let path = self.path.clone();
        file.flush()
            .ctx(&path, || "flushing frames before commit".into())?;
        for name in std::mem::take(&mut self.uncommitted) {
            let g = file
                .group(&format!("frames/{name}"))
                .ctx(&path, || format!("opening /frames/{name} to commit it"))?;
            write_attr(&path, &g, "complete", &1u8)?;
        }
        file.flush()
            .ctx(&path, || "flushing frame completion".into())
    }

    /// Writes pending stats rows to `/stats` (without H5Fflush).
    fn flush_stats(&mut self) -> Result<(), OutputError> {
        if self.pending_stats.is_empty() {
            return Ok(());
        }
        let path = self.path.clone();
        let stats = self
            .file()?
            .group("stats")
            .ctx(&path, || "opening /stats".into())?;
        let old = self.stats_rows;
        let new = old + self.pending_stats.len();
        for (name, col) in STATS_COLUMNS {
            let ds = stats
                .dataset(name)
                .ctx(&path, || format!("opening /stats/{name}"))?;
            ds.resize(new)
                .ctx(&path, || format!("resizing /stats/{name} to {new} rows"))?;
            let rows = &self.pending_stats;
            let written = match col {
                StatsColumn::U64(f) => {
                    let v: Vec<u64> = rows.iter().map(f).collect();
                    ds.write_slice(&v, old..new)
                }
                StatsColumn::U32(f) => {
                    let v: Vec<u32> = rows.iter().map(f).collect();
                    ds.write_slice(&v, old..new)
                }
                StatsColumn::F64(f) => {
                    let v: Vec<f64> = rows.iter().map(f).collect();
                    ds.write_slice(&v, old..new)
                }
            };
            written.ctx(&path, || {
                format!("writing rows {old}..{new} of /stats/{name}")
            })?;
        }
        self.stats_rows = new;
        self.pending_stats.clear();
        Ok(())
    }

    /// Flushes stats, closes the file and writes the XDMF sidecar
    /// (`<file>.xdmf`). Returns nothing; the sidecar path is
    /// `path.with_extension("xdmf")`.
    pub fn finish(mut self) -> Result<(), OutputError> {
        self.flush_stats()?;
        let path = self.path.clone();
        if let Some(file) = self.file.take() {
            self.commit(&file)?;
            file.flush().ctx(&path, || "flushing before close".into())?;
            file.close().ctx(&path, || "closing the file".into())?;
        }
        write_xdmf(&path)?;
        Ok(())
    }

    /// Opens an existing icefem file to continue it.
    ///
    /// Finds the last frame whose `complete` attribute is 1, deletes every
    /// frame group after it, truncates each `/stats` column to the rows before
    /// the first row whose step exceeds that frame's step (and to the shortest
    /// column, in case a kill interrupted a stats append), and returns a
    /// writer whose next frame follows it, plus the frame's data.
    ///
    /// Deleted groups' space is not reclaimed (an HDF5 limitation; `h5repack`
    /// compacts the file).
    pub fn resume(path: &Path) -> Result<(Self, ResumeFrame), OutputError> {
        check_hdf5_signature(path)?;
        let file = crash_safe_options()
            .open_rw(path)
            .ctx(path, || "opening for resume".into())?;
        close_on_exec(&file);
        check_icefem_layout(path, &file)?;
        let scene_text = read_string_attr(path, &file, "scene")?;
        let frames = file
            .group("frames")
            .ctx(path, || "opening /frames".into())?;
        let list = list_frames(path, &frames)?;
        let Some(last) = list.iter().rev().find(|f| f.complete) else {
            return Err(OutputError::NoCompleteFrame {
                path: path.to_path_buf(),
            });
        };
        let last_index = last.index;
        let last_name = last.name.clone();
        for f in list.iter().filter(|f| f.index > last_index) {
            frames.unlink(&f.name).ctx(path, || {
                format!("deleting incomplete frame /frames/{}", f.name)
            })?;
        }

        let g = frames
            .group(&last_name)
            .ctx(path, || format!("opening /frames/{last_name}"))?;
        let rf = read_frame(path, &g, scene_text)?;

        let stats_rows = truncate_stats(path, &file, rf.step)?;
        file.flush()
            .ctx(path, || "flushing after resume cleanup".into())?;

        let writer = Self {
            path: path.to_path_buf(),
            file: Some(file),
            next_frame: last_index + 1,
            topology_rest_path: format!("/frames/{last_name}/rest_positions"),
            topology_tets_path: format!("/frames/{last_name}/tets"),
            n_nodes: rf.positions.len(),
            n_elems: rf.tets.len(),
            stats_rows,
            pending_stats: Vec::new(),
            uncommitted: Vec::new(),
            last_commit: None,
        };
        Ok((writer, rf))
    }
}

impl Drop for OutputWriter {
    fn drop(&mut self) {
        // Best effort: an error here cannot be reported, and `finish` already
        // emptied the buffer on the normal path.
        if self.file.is_some() {
            let _ = self.flush_stats();
            if let Some(f) = self.file.clone() {
                let _ = self.commit(&f);
            }
        }
    }
}

/// Creates the empty, extendable `/stats/{name}` column.
fn create_stats_column(
    path: &Path,
    stats: &Group,
    name: &str,
    col: StatsColumn,
) -> Result<Dataset, OutputError> {
    let builder = stats.new_dataset_builder();
    let builder = match col {
        StatsColumn::U64(_) => builder.empty::<u64>(),
        StatsColumn::U32(_) => builder.empty::<u32>(),
        StatsColumn::F64(_) => builder.empty::<f64>(),
    };
    builder
        .shape(0..)
        .chunk(STATS_CHUNK_ROWS)
        .create(name)
        .ctx(path, || format!("creating /stats/{name}"))
}

/// Truncates `/stats` for `resume`; returns the row count kept. A column the file lacks
/// (written before the column existed) is created with 0 in every row it has.
fn truncate_stats(path: &Path, file: &File, last_step: u64) -> Result<usize, OutputError> {
    let stats = file.group("stats").ctx(path, || "opening /stats".into())?;
    let rows = stats
        .dataset("step")
        .ctx(path, || "opening /stats/step".into())?
        .shape()
        .first()
        .copied()
        .unwrap_or(0);
    let mut columns = Vec::with_capacity(STATS_COLUMNS.len());
    for (name, col) in STATS_COLUMNS {
        let ds = if stats.link_exists(name) {
            stats
                .dataset(name)
                .ctx(path, || format!("opening /stats/{name}"))?
        } else {
            let ds = create_stats_column(path, &stats, name, col)?;
            // Rows beyond the old extent read as the fill value, 0.
            ds.resize(rows).ctx(path, || {
                format!("sizing the new /stats/{name} to {rows} rows")
            })?;
            ds
        };
        let shape = ds.shape();
        if shape.len() != 1 {
            return Err(corrupt(
                path,
                format!("/stats/{name} has shape {shape:?}, expected 1-D"),
            ));
        }
        columns.push((name, ds, shape[0]));
    }
    let min_len = columns.iter().map(|c| c.2).min().unwrap_or(0);
    let steps: Vec<u64> = columns[0]
        .1
        .read_raw::<u64>()
        .ctx(path, || "reading /stats/step".into())?;
    let keep = steps
        .iter()
        .take(min_len)
        .position(|&s| s > last_step)
        .unwrap_or(min_len.min(steps.len()));
    for (name, ds, len) in &columns {
        if *len != keep {
            ds.resize(keep)
                .ctx(path, || format!("truncating /stats/{name} to {keep} rows"))?;
        }
    }
    Ok(keep)
}

/// One entry of `/frames`, as found on disk.
struct FrameEntry {
    index: usize,
    name: String,
    complete: bool,
}

/// Lists frame groups sorted by index. Members whose names are not decimal
/// indices are ignored (they are not ours to judge).
fn list_frames(path: &Path, frames: &Group) -> Result<Vec<FrameEntry>, OutputError> {
    let names = frames
        .member_names()
        .ctx(path, || "listing /frames".into())?;
    let mut out = Vec::new();
    for name in names {
        if name.is_empty() || !name.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        let Ok(index) = name.parse::<usize>() else {
            continue;
        };
        // A frame is complete only if the attribute exists and reads as 1;
        // anything else (missing, wrong type, other value) means incomplete.
        let complete = frames
            .group(&name)
            .ok()
            .and_then(|g| g.attr("complete").ok())
            .and_then(|a| a.read_scalar::<u8>().ok())
            == Some(1);
        out.push(FrameEntry {
            index,
            name,
            complete,
        });
    }
    out.sort_by_key(|f| f.index);
    Ok(out)
}

/// Reads a frame group back into owned data, validating shapes and indices.
fn read_frame(path: &Path, g: &Group, scene_text: String) -> Result<ResumeFrame, OutputError> {
    let gname = g.name();
    let step = read_attr::<u64>(path, g, "step")?;
    let time = read_attr::<f64>(path, g, "time")?;
    let positions = read_vec3(path, g, "positions")?;
    let velocities = read_vec3(path, g, "velocities")?;
    let rest_positions = read_vec3(path, g, "rest_positions")?;
    let n = positions.len();
    if velocities.len() != n || rest_positions.len() != n {
        return Err(corrupt(
            path,
            format!("{gname}: positions, velocities and rest_positions row counts differ"),
        ));
    }
    let tets = read_tets(path, g, "tets", n)?;
    let m = tets.len();

    let mut element_fields = Vec::new();
    let mut node_fields = Vec::new();
    let names = g.member_names().ctx(path, || format!("listing {gname}"))?;
    for name in names {
        if RESERVED_FRAME_NAMES.contains(&name.as_str()) {
            continue;
        }
        let Ok(ds) = g.dataset(&name) else {
            continue; // a subgroup or something else: not a field
        };
        let shape = ds.shape();
        let (rows, cols) = match shape.as_slice() {
            [r] => (*r, 1),
            [r, c] => (*r, *c),
            _ => {
                return Err(corrupt(path, format!("{gname}/{name} has shape {shape:?}")));
            }
        };
        let center = ds.attr("center").ok().and_then(|a| read_string(&a).ok());
        // Without a `center` attribute, fall back to the row count
        // (element first, matching how the writer validates).
        let is_cell = match center.as_deref() {
            Some("Cell") => true,
            Some("Node") => false,
            _ => rows == m,
        };
        let expected_rows = if is_cell { m } else { n };
        if rows != expected_rows {
            return Err(corrupt(
                path,
                format!("{gname}/{name} has {rows} rows, expected {expected_rows}"),
            ));
        }
        let data = ds
            .read_raw::<f64>()
            .ctx(path, || format!("reading {gname}/{name}"))?;
        if is_cell {
            element_fields.push((name, cols, data));
        } else {
            node_fields.push((name, cols, data));
        }
    }
    Ok(ResumeFrame {
        step,
        time,
        scene_text,
        positions,
        velocities,
        rest_positions,
        tets,
        element_fields,
        node_fields,
    })
}

/// Makes an HDF5 variable-length UTF-8 string (rejects interior NULs).
fn vlen_str(path: &Path, what: &str, s: &str) -> Result<VarLenUnicode, OutputError> {
    VarLenUnicode::from_str(s).map_err(|e| invalid(path, format!("{what}: {e}")))
}

fn write_attr<T: H5Type>(
    path: &Path,
    loc: &hdf5::Location,
    name: &str,
    value: &T,
) -> Result<(), OutputError> {
    loc.new_attr::<T>()
        .create(name)
        .and_then(|a| a.write_scalar(value))
        .ctx(path, || {
            format!("writing attribute {name} on {}", loc.name())
        })
}

fn read_attr<T: H5Type>(path: &Path, loc: &hdf5::Location, name: &str) -> Result<T, OutputError> {
    loc.attr(name)
        .and_then(|a| a.read_scalar::<T>())
        .ctx(path, || {
            format!("reading attribute {name} of {}", loc.name())
        })
}

/// Reads a scalar string attribute written as variable-length UTF-8 or ASCII
/// (the latter for files touched by other tools).
fn read_string(attr: &hdf5::Attribute) -> hdf5::Result<String> {
    match attr.read_scalar::<VarLenUnicode>() {
        Ok(s) => Ok(s.as_str().to_owned()),
        Err(e) => attr
            .read_scalar::<VarLenAscii>()
            .map(|s| s.as_str().to_owned())
            .map_err(|_| e),
    }
}

fn read_string_attr(path: &Path, loc: &hdf5::Location, name: &str) -> Result<String, OutputError> {
    loc.attr(name).and_then(|a| read_string(&a)).ctx(path, || {
        format!("reading attribute {name} of {}", loc.name())
    })
}

/// Datasets with fewer values than this are stored contiguous and uncompressed:
/// for a few kilobytes, chunk indexes and deflate cost more time (and often
/// bytes) than they save — a 200-tet run would spend most of its time in zlib.
const COMPRESS_MIN_VALUES: usize = 4096;

/// Writes a row-major `rows × cols` f64 matrix (1-D when `cols == 1`),
/// chunked and compressed when it holds at least `COMPRESS_MIN_VALUES` values.
fn write_matrix(
    path: &Path,
    g: &Group,
    name: &str,
    rows: usize,
    cols: usize,
    data: &[f64],
) -> Result<(), OutputError> {
    let ctx = || format!("writing {}/{name} [{rows}, {cols}]", g.name());
    if cols == 1 {
        let view = ArrayView1::from(data);
        let mut b = g.new_dataset_builder();
        if rows >= COMPRESS_MIN_VALUES {
            b = compress(b.chunk(rows.min(FRAME_CHUNK_VALUES)));
        }
        b.with_data(view).create(name).ctx(path, ctx)?;
    } else {
        let view = ArrayView2::from_shape((rows, cols), data)
            .map_err(|e| invalid(path, format!("{name}: {e}")))?;
        let mut b = g.new_dataset_builder();
        if rows * cols >= COMPRESS_MIN_VALUES {
            let chunk_rows = (FRAME_CHUNK_VALUES / cols).clamp(1, rows);
            b = compress(b.chunk((chunk_rows, cols)));
        }
        b.with_data(view).create(name).ctx(path, ctx)?;
    }
    Ok(())
}

/// Shuffle + deflate level 1: cheap, and shuffle (which must precede deflate)
/// makes the slowly varying high bytes of f64/i64 compress well.
fn compress(b: hdf5::dataset::DatasetBuilder) -> hdf5::dataset::DatasetBuilder {
    if hdf5::filters::deflate_available() {
        b.shuffle().deflate(1)
    } else {
        b
    }
}

fn write_vec3(path: &Path, g: &Group, name: &str, v: &[[f64; 3]]) -> Result<(), OutputError> {
    write_matrix(path, g, name, v.len(), 3, v.as_flattened())
}

fn write_tets(path: &Path, g: &Group, name: &str, tets: &[[usize; 4]]) -> Result<(), OutputError> {
    write_indices(path, g, name, tets)
}

/// Writes rows of N indices as i64 [rows, N] ([rows] when N = 1), compressed when large.
fn write_indices<const N: usize>(
    path: &Path,
    g: &Group,
    name: &str,
    rows: &[[usize; N]],
) -> Result<(), OutputError> {
    let mut flat = Vec::with_capacity(rows.len() * N);
    for &i in rows.as_flattened() {
        // Indices were checked against the node count, which is a slice
        // length and so fits in i64 on every supported platform.
        flat.push(i64::try_from(i).map_err(|_| invalid(path, format!("index {i} too large")))?);
    }
    let ctx = || format!("writing {}/{name} [{}, {N}]", g.name(), rows.len());
    let mut b = g.new_dataset_builder();
    if flat.len() >= COMPRESS_MIN_VALUES {
        let chunk_rows = (FRAME_CHUNK_VALUES / N).min(rows.len());
        b = compress(if N == 1 {
            b.chunk(chunk_rows)
        } else {
            b.chunk((chunk_rows, N))
        });
    }
    if N == 1 {
        b.with_data(ArrayView1::from(&flat))
            .create(name)
            .ctx(path, ctx)?;
    } else {
        let view = ArrayView2::from_shape((rows.len(), N), &flat)
            .map_err(|e| invalid(path, format!("{name}: {e}")))?;
        b.with_data(view).create(name).ctx(path, ctx)?;
    }
    Ok(())
}

fn check_tets(path: &Path, what: &str, tets: &[[usize; 4]], n: usize) -> Result<(), OutputError> {
    if let Some((e, t)) = tets
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&i| i >= n))
    {
        return Err(invalid(
            path,
            format!("{what}: tet {e} = {t:?} references a node ≥ node count {n}"),
        ));
    }
    Ok(())
}

/// Opens `g/name`, checking it is 2-D with `cols` columns; returns the dataset and its rows.
fn open_2d(
    path: &Path,
    g: &Group,
    name: &str,
    cols: usize,
) -> Result<(Dataset, usize), OutputError> {
    let ds = g
        .dataset(name)
        .ctx(path, || format!("opening {}/{name}", g.name()))?;
    let shape = ds.shape();
    match shape.as_slice() {
        [r, c] if *c == cols => Ok((ds, *r)),
        _ => Err(corrupt(
            path,
            format!(
                "{}/{name} has shape {shape:?}, expected [rows, {cols}]",
                g.name()
            ),
        )),
    }
}

fn read_vec3(path: &Path, g: &Group, name: &str) -> Result<Vec<[f64; 3]>, OutputError> {
    let (ds, rows) = open_2d(path, g, name, 3)?;
    let flat = ds
        .read_raw::<f64>()
        .ctx(path, || format!("reading {}/{name}", g.name()))?;
    if rows.checked_mul(3) != Some(flat.len()) {
        return Err(corrupt(path, format!("{}/{name}: short read", g.name())));
    }
    Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

fn read_tets(path: &Path, g: &Group, name: &str, n: usize) -> Result<Vec<[usize; 4]>, OutputError> {
    let (ds, rows) = open_2d(path, g, name, 4)?;
    // Reading as i64 lets HDF5 convert u64/i32/… files too; out-of-range
    // values make the read fail rather than wrap.
    let flat = ds
        .read_raw::<i64>()
        .ctx(path, || format!("reading {}/{name}", g.name()))?;
    if rows.checked_mul(4) != Some(flat.len()) {
        return Err(corrupt(path, format!("{}/{name}: short read", g.name())));
    }
    let mut out = Vec::with_capacity(rows);
    for (e, c) in flat.chunks_exact(4).enumerate() {
        let mut t = [0usize; 4];
        for (k, &v) in c.iter().enumerate() {
            t[k] = usize::try_from(v).ok().filter(|&i| i < n).ok_or_else(|| {
                corrupt(
                    path,
                    format!(
                        "{}/{name}: tet {e} has node index {v} outside 0..{n}",
                        g.name()
                    ),
                )
            })?;
        }
        out.push(t);
    }
    Ok(out)
}

/// Rejects files without the HDF5 signature, which HDF5 searches for at
/// offset 0 and at every power of two from 512 (user blocks).
fn check_hdf5_signature(path: &Path) -> Result<(), OutputError> {
    const SIG: [u8; 8] = [0x89, b'H', b'D', b'F', b'\r', b'\n', 0x1a, b'\n'];
    let io = |context: &str| {
        let context = context.to_string();
        move |source| OutputError::Io {
            path: path.to_path_buf(),
            context,
            source,
        }
    };
    let mut f = std::fs::File::open(path).map_err(io("opening"))?;
    let len = f.metadata().map_err(io("reading metadata"))?.len();
    let mut offset = 0u64;
    while offset + 8 <= len {
        use std::io::Seek as _;
        f.seek(std::io::SeekFrom::Start(offset))
            .map_err(io("seeking"))?;
        let mut buf = [0u8; 8];
        f.read_exact(&mut buf).map_err(io("reading"))?;
        if buf == SIG {
            return Ok(());
        }
        offset = if offset == 0 { 512 } else { offset * 2 };
    }
    Err(OutputError::NotHdf5 {
        path: path.to_path_buf(),
    })
}

fn check_icefem_layout(path: &Path, file: &File) -> Result<(), OutputError> {
    let not = |reason: &str| OutputError::NotIcefem {
        path: path.to_path_buf(),
        reason: reason.into(),
    };
    if !file.link_exists("mesh") || file.group("mesh").is_err() {
        return Err(not("no /mesh group"));
    }
    let has_version = file
        .attr_names()
        .map(|names| names.iter().any(|n| n == "icefem_version"))
        .unwrap_or(false);
    if !has_version {
        return Err(not("no icefem_version root attribute"));
    }
    if !file.link_exists("frames") || file.group("frames").is_err() {
        return Err(not("no /frames group"));
    }
    Ok(())
}

fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            _ => out.push(c),
        }
    }
    out
}

/// XDMF `DataType` and `Precision` of a dataset, or `None` for types XDMF cannot describe.
fn xdmf_number_type(ds: &Dataset) -> Option<(&'static str, usize)> {
    let desc = ds.dtype().ok()?.to_descriptor().ok()?;
    let size = |s: IntSize| s as usize;
    match desc {
        TypeDescriptor::Float(FloatSize::U4) => Some(("Float", 4)),
        TypeDescriptor::Float(FloatSize::U8) => Some(("Float", 8)),
        TypeDescriptor::Integer(s) => Some(("Int", size(s))),
        TypeDescriptor::Unsigned(s) => Some(("UInt", size(s))),
        _ => None,
    }
}

/// One `<DataItem>` referencing `h5_name:h5_path`, or `None` if the dataset's
/// type is not expressible in XDMF.
fn xdmf_data_item(ds: &Dataset, h5_name: &str, indent: &str) -> Option<String> {
    let (ty, prec) = xdmf_number_type(ds)?;
    let dims: Vec<String> = ds.shape().iter().map(|d| d.to_string()).collect();
    Some(format!(
        "{indent}<DataItem Dimensions=\"{}\" DataType=\"{ty}\" Precision=\"{prec}\" Format=\"HDF\">{}:{}</DataItem>\n",
        dims.join(" "),
        xml_escape(h5_name),
        xml_escape(&ds.name())
    ))
}

/// XDMF attribute type for a dataset of per-row values.
///
/// 6-column data (stress, plastic strain) is declared `Matrix`, not
/// `Tensor6`: XDMF's Tensor6 component order is xx xy xz yy yz zz, while
/// icefem stores Voigt order xx yy zz yz xz xy, so `Tensor6` would make
/// ParaView silently mislabel components.
fn xdmf_attribute_type(shape: &[usize]) -> &'static str {
    match shape {
        [_] | [_, 1] => "Scalar",
        [_, 3] => "Vector",
        _ => "Matrix",
    }
}

/// Opens one time step's `<Grid>` in `xml`: its time, topology (type, element count, nodes per
/// element, index data item) and geometry (XYZ data item). The caller adds attributes and
/// closes it.
fn xdmf_grid_start(
    xml: &mut String,
    name: &str,
    time: f64,
    (kind, count, nodes): (&str, usize, usize),
    topology: &str,
    geometry: &str,
) {
    let _ = writeln!(xml, "      <Grid Name=\"{name}\" GridType=\"Uniform\">");
    let _ = writeln!(xml, "        <Time Value=\"{time:e}\"/>");
    let _ = writeln!(
        xml,
        "        <Topology TopologyType=\"{kind}\" NumberOfElements=\"{count}\" NodesPerElement=\"{nodes}\">"
    );
    xml.push_str(topology);
    xml.push_str("        </Topology>\n        <Geometry GeometryType=\"XYZ\">\n");
    xml.push_str(geometry);
    xml.push_str("        </Geometry>\n");
}

/// The crack surfaces of the frames that have any, as a temporal collection (`icefem_cracks`:
/// triangles, with the crack index per triangle) for `RUN.cracks.xdmf`; empty without
/// fracture.
fn xdmf_cracks(h5_path: &Path, h5_name: &str, frames: &Group) -> Result<String, OutputError> {
    let mut xml = String::new();
    let ind = "          ";
    for entry in list_frames(h5_path, frames)?
        .into_iter()
        .filter(|f| f.complete)
    {
        let g = frames
            .group(&entry.name)
            .ctx(h5_path, || format!("opening /frames/{}", entry.name))?;
        let Ok(cracks) = g.group("cracks") else {
            continue;
        };
        let (Ok(triangles), Ok(vertices), Ok(crack)) = (
            cracks.dataset("triangles"),
            cracks.dataset("vertices"),
            cracks.dataset("crack"),
        ) else {
            continue;
        };
        let count = triangles.shape().first().copied().unwrap_or(0);
        let items = [&triangles, &vertices, &crack].map(|d| xdmf_data_item(d, h5_name, ind));
        let [Some(t), Some(v), Some(c)] = items else {
            continue;
        };
        if count == 0 {
            continue;
        }
        let time = read_attr::<f64>(h5_path, &g, "time")?;
        let name = format!("cracks_{}", entry.name);
        xdmf_grid_start(&mut xml, &name, time, ("Triangle", count, 3), &t, &v);
        xml.push_str(
            "        <Attribute Name=\"crack\" AttributeType=\"Scalar\" Center=\"Cell\">\n",
        );
        xml.push_str(&c);
        xml.push_str("        </Attribute>\n      </Grid>\n");
    }
    if xml.is_empty() {
        return Ok(xml);
    }
    Ok(format!(
        "    <Grid Name=\"icefem_cracks\" GridType=\"Collection\" CollectionType=\"Temporal\">\n{xml}    </Grid>\n"
    ))
}

/// Writes `<file>.xdmf` next to the HDF5 file: an XDMF 3 temporal collection
/// with one uniform grid per complete frame (incomplete frames are skipped).
///
/// Each grid has `Tetrahedron` topology from the frame's `tets`, `XYZ`
/// geometry from `positions` (m), and attributes `velocity` (Node Vector,
/// m/s), `rest_position` (Node Vector, m; displacement = coordinates −
/// rest_position, e.g. with ParaView's Calculator), `stress` (Cell Matrix of
/// 6 Voigt components xx yy zz yz xz xy, Pa) and every element / node field
/// under its own name. HDF5 references use the file name only, i.e. a path
/// relative to the sidecar. The sidecar is written to a temporary file and
/// renamed, so a viewer never sees half of it.
pub fn write_xdmf(h5_path: &Path) -> Result<PathBuf, OutputError> {
    check_hdf5_signature(h5_path)?;
    let file = File::open(h5_path).ctx(h5_path, || "opening to write the XDMF sidecar".into())?;
    close_on_exec(&file);
    check_icefem_layout(h5_path, &file)?;
    let h5_name = h5_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| invalid(h5_path, "path has no file name"))?;
    if h5_name.contains(':') {
        // XDMF separates file and dataset with ':'; a colon in the name is ambiguous.
        return Err(invalid(
            h5_path,
            "file name contains ':', which XDMF cannot reference",
        ));
    }
    let frames = file
        .group("frames")
        .ctx(h5_path, || "opening /frames".into())?;

    let mut xml = String::new();
    xml.push_str("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
    xml.push_str("<Xdmf xmlns:xi=\"http://www.w3.org/2001/XInclude\" Version=\"3.0\">\n");
    xml.push_str("  <Domain>\n");
    xml.push_str(
        "    <Grid Name=\"icefem\" GridType=\"Collection\" CollectionType=\"Temporal\">\n",
    );
    for entry in list_frames(h5_path, &frames)?
        .into_iter()
        .filter(|f| f.complete)
    {
        let g = frames
            .group(&entry.name)
            .ctx(h5_path, || format!("opening /frames/{}", entry.name))?;
        let time = read_attr::<f64>(h5_path, &g, "time")?;
        let (tets, m) = open_2d(h5_path, &g, "tets", 4)?;
        let (positions, n) = open_2d(h5_path, &g, "positions", 3)?;
        let ind = "          ";
        let item = |ds: &Dataset| {
            xdmf_data_item(ds, &h5_name, ind).ok_or_else(|| {
                corrupt(
                    h5_path,
                    format!("{} has a type XDMF cannot describe", ds.name()),
                )
            })
        };
        let name = format!("frame_{}", entry.name);
        let (topology, geometry) = (item(&tets)?, item(&positions)?);
        xdmf_grid_start(
            &mut xml,
            &name,
            time,
            ("Tetrahedron", m, 4),
            &topology,
            &geometry,
        );

        // (xdmf name, dataset, center). Built-ins first, then fields by name.
        let mut attrs: Vec<(String, Dataset, &str)> = Vec::new();
        for (xname, dname, center) in [
            ("velocity", "velocities", "Node"),
            ("rest_position", "rest_positions", "Node"),
            ("stress", "stress", "Cell"),
        ] {
            if let Ok(ds) = g.dataset(dname) {
                attrs.push((xname.into(), ds, center));
            }
        }
        let names = g
            .member_names()
            .ctx(h5_path, || format!("listing /frames/{}", entry.name))?;
        for name in names {
            if RESERVED_FRAME_NAMES.contains(&name.as_str()) {
                continue;
            }
            let Ok(ds) = g.dataset(&name) else { continue };
            let center = ds.attr("center").ok().and_then(|a| read_string(&a).ok());
            let center = match center.as_deref() {
                Some("Cell") => "Cell",
                Some("Node") => "Node",
                _ => continue, // unknown centering: cannot place it on the mesh
            };
            attrs.push((name, ds, center));
        }
        for (xname, ds, center) in attrs {
            let shape = ds.shape();
            let rows = shape.first().copied().unwrap_or(0);
            let expected = if center == "Node" { n } else { m };
            // Skip anything whose shape does not fit the grid rather than
            // emit a sidecar that crashes the reader.
            if shape.is_empty() || shape.len() > 2 || rows != expected {
                continue;
            }
            let Some(di) = xdmf_data_item(&ds, &h5_name, ind) else {
                continue;
            };
            let _ = writeln!(
                xml,
                "        <Attribute Name=\"{}\" AttributeType=\"{}\" Center=\"{center}\">",
                xml_escape(&xname),
                xdmf_attribute_type(&shape)
            );
            xml.push_str(&di);
            xml.push_str("        </Attribute>\n");
        }
        xml.push_str("      </Grid>\n");
    }
    xml.push_str("    </Grid>\n  </Domain>\n</Xdmf>\n");
    let cracks = xdmf_cracks(h5_path, &h5_name, &frames)?;
    drop(frames);
    drop(file);

    let xdmf_path = h5_path.with_extension("xdmf");
    let tmp = xdmf_path.with_extension("xdmf.tmp");
    let io = |context: &'static str| {
        let p = xdmf_path.clone();
        move |source| OutputError::Io {
            path: p,
            context: context.into(),
            source,
        }
    };
    std::fs::write(&tmp, xml).map_err(io("writing the XDMF sidecar"))?;
    std::fs::rename(&tmp, &xdmf_path).map_err(io("renaming the XDMF sidecar into place"))?;
    if !cracks.is_empty() {
        // A file of its own: readers that take one grid collection per file (meshio, and
        // ParaView's default view of it) keep reading the tet mesh from RUN.xdmf.
        let path = h5_path.with_extension("cracks.xdmf");
        let io = |source| OutputError::Io {
            path: path.clone(),
            context: "writing the crack-surface XDMF sidecar".into(),
            source,
        };
        let xml = format!(
            "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<Xdmf xmlns:xi=\"http://www.w3.org/2001/XInclude\" Version=\"3.0\">\n  <Domain>\n{cracks}  </Domain>\n</Xdmf>\n"
        );
        std::fs::write(&path, xml).map_err(io)?;
    }
    Ok(xdmf_path)
}

/// A crack triangle as drawn: its three vertices (m) and the crack it belongs to.
pub type CrackTriangle = ([[f64; 3]; 3], usize);

/// A mesh as stored: rest positions (m) and tets (0-based node indices).
pub type StoredMesh = (Vec<[f64; 3]>, Vec<[usize; 4]>);

/// One complete frame read back for viewing: the frame's state plus its stress and crack
/// triangles (which [`ResumeFrame`] leaves out).
#[derive(Debug, Clone)]
pub struct StoredFrame {
    /// Frame index (the number in `/frames/NNNNNN`).
    pub index: usize,
    /// Everything a resume reads (positions, topology, element and node fields).
    pub state: ResumeFrame,
    /// Per-element Cauchy stress (Pa), Voigt xx yy zz yz xz xy; empty if the frame has none.
    pub stress: Vec<[f64; 6]>,
    /// Crack triangles as drawn (fracture runs; empty otherwise).
    pub crack_triangles: Vec<CrackTriangle>,
}

impl StoredFrame {
    /// The per-element field `name` as `(cols, row-major values)`, if the frame has it.
    pub fn element_field(&self, name: &str) -> Option<(usize, &[f64])> {
        self.state
            .element_fields
            .iter()
            .find(|(n, _, _)| n == name)
            .map(|(_, cols, data)| (*cols, data.as_slice()))
    }
}

/// Read-only access to the complete frames of an icefem file (a finished run or one that was
/// cut off: incomplete frames are not listed).
pub struct FrameReader {
    path: PathBuf,
    file: File,
    /// Complete frames, by index.
    frames: Vec<FrameEntry>,
    /// The `step` attribute of each of `frames`.
    steps: Vec<u64>,
    scene_text: String,
    scene_path: String,
}

impl FrameReader {
    /// Opens `path`, checking that it is an icefem file with at least one complete frame.
    pub fn open(path: &Path) -> Result<Self, OutputError> {
        check_hdf5_signature(path)?;
        let file = File::open(path).ctx(path, || "opening".into())?;
        close_on_exec(&file);
        check_icefem_layout(path, &file)?;
        let scene_text = read_string_attr(path, &file, "scene")?;
        let scene_path = read_string_attr(path, &file, "scene_path").unwrap_or_default();
        let group = file
            .group("frames")
            .ctx(path, || "opening /frames".into())?;
        let frames: Vec<FrameEntry> = list_frames(path, &group)?
            .into_iter()
            .filter(|f| f.complete)
            .collect();
        if frames.is_empty() {
            return Err(OutputError::NoCompleteFrame {
                path: path.to_path_buf(),
            });
        }
        let steps = frames
            .iter()
            .map(|f| {
                let g = group
                    .group(&f.name)
                    .ctx(path, || format!("opening /frames/{}", f.name))?;
                read_attr::<u64>(path, &g, "step")
            })
            .collect::<Result<Vec<u64>, _>>()?;
        Ok(FrameReader {
            path: path.to_path_buf(),
            file,
            frames,
            steps,
            scene_text,
            scene_path,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The scene text the run was started with.
    pub fn scene_text(&self) -> &str {
        &self.scene_text
    }

    /// Where the run's scene was read from (empty if the file does not say).
    pub fn scene_path(&self) -> &str {
        &self.scene_path
    }

    /// Indices of the complete frames, ascending.
    pub fn frame_indices(&self) -> Vec<usize> {
        self.frames.iter().map(|f| f.index).collect()
    }

    /// The time step each complete frame was written at, in the order of
    /// [`FrameReader::frame_indices`] (frame = step / output_every).
    pub fn frame_steps(&self) -> &[u64] {
        &self.steps
    }

    /// The run's initial mesh, `/mesh`: rest positions (m) and tets.
    pub fn initial_mesh(&self) -> Result<StoredMesh, OutputError> {
        let g = self
            .file
            .group("mesh")
            .ctx(&self.path, || "opening /mesh".into())?;
        let rest = read_vec3(&self.path, &g, "rest_positions")?;
        let tets = read_tets(&self.path, &g, "tets", rest.len())?;
        Ok((rest, tets))
    }

    /// Reads complete frame `index`; an index that is not a complete frame is an error that
    /// names the frames there are.
    pub fn read(&self, index: usize) -> Result<StoredFrame, OutputError> {
        let path = &self.path;
        let Some(entry) = self.frames.iter().find(|f| f.index == index) else {
            let (first, last) = (
                self.frames[0].index,
                self.frames[self.frames.len() - 1].index,
            );
            return Err(OutputError::NoSuchFrame {
                path: path.clone(),
                index,
                available: format!("{} complete frames, {first} … {last}", self.frames.len()),
            });
        };
        let g = self
            .file
            .group(&format!("frames/{}", entry.name))
            .ctx(path, || format!("opening /frames/{}", entry.name))?;
        let state = read_frame(path, &g, self.scene_text.clone())?;
        let stress = if g.link_exists("stress") {
            let (ds, rows) = open_2d(path, &g, "stress", 6)?;
            if rows != state.tets.len() {
                return Err(corrupt(
                    path,
                    format!(
                        "{}/stress has {rows} rows for {} tets",
                        g.name(),
                        state.tets.len()
                    ),
                ));
            }
            let flat = ds
                .read_raw::<f64>()
                .ctx(path, || format!("reading {}/stress", g.name()))?;
            flat.chunks_exact(6)
                .map(|c| std::array::from_fn(|k| c[k]))
                .collect()
        } else {
            Vec::new()
        };
        let crack_triangles = if g.link_exists("cracks") {
            read_crack_triangles(path, &g)?
        } else {
            Vec::new()
        };
        Ok(StoredFrame {
            index,
            state,
            stress,
            crack_triangles,
        })
    }
}

/// Reads `g/cracks/{vertices, triangles, crack}`.
fn read_crack_triangles(path: &Path, g: &Group) -> Result<Vec<CrackTriangle>, OutputError> {
    let cracks = g
        .group("cracks")
        .ctx(path, || format!("opening {}/cracks", g.name()))?;
    let vertices = read_vec3(path, &cracks, "vertices")?;
    let (ds, rows) = open_2d(path, &cracks, "triangles", 3)?;
    let flat = ds
        .read_raw::<i64>()
        .ctx(path, || format!("reading {}/triangles", cracks.name()))?;
    let ids = cracks
        .dataset("crack")
        .and_then(|d| d.read_raw::<i64>())
        .ctx(path, || format!("reading {}/crack", cracks.name()))?;
    if flat.len() != 3 * rows || ids.len() != rows {
        return Err(corrupt(
            path,
            format!(
                "{}: triangles and crack have different row counts",
                cracks.name()
            ),
        ));
    }
    let vertex = |v: i64| {
        usize::try_from(v)
            .ok()
            .and_then(|i| vertices.get(i).copied())
            .ok_or_else(|| {
                corrupt(
                    path,
                    format!("{}/triangles: vertex index {v} out of range", cracks.name()),
                )
            })
    };
    flat.chunks_exact(3)
        .zip(&ids)
        .map(|(t, &id)| {
            let id = usize::try_from(id)
                .map_err(|_| corrupt(path, format!("{}/crack: negative id", cracks.name())))?;
            Ok(([vertex(t[0])?, vertex(t[1])?, vertex(t[2])?], id))
        })
        .collect()
}

/// Human-readable summary of an icefem output file, for `icefem info`:
/// version, scene path, node / element counts, frames (complete /
/// incomplete), time range, stats rows, and the datasets of the last
/// complete frame with dtypes and shapes.
///
/// Errors with `NotHdf5` on a non-HDF5 file and `NotIcefem` on an HDF5 file
/// without `/mesh`, `/frames` or the `icefem_version` root attribute.
pub fn describe(path: &Path) -> Result<String, OutputError> {
    check_hdf5_signature(path)?;
    let file = File::open(path).ctx(path, || "opening".into())?;
    close_on_exec(&file);
    check_icefem_layout(path, &file)?;
    let version = read_string_attr(path, &file, "icefem_version")?;
    let scene_path = read_string_attr(path, &file, "scene_path").unwrap_or_else(|_| "?".into());
    let mesh = file.group("mesh").ctx(path, || "opening /mesh".into())?;
    let count = |g: &Group, name: &str| -> String {
        g.dataset(name)
            .ok()
            .and_then(|d| d.shape().first().copied())
            .map_or_else(|| "?".into(), |r| r.to_string())
    };
    let frames = file
        .group("frames")
        .ctx(path, || "opening /frames".into())?;
    let list = list_frames(path, &frames)?;
    let n_complete = list.iter().filter(|f| f.complete).count();

    let mut s = String::new();
    let _ = writeln!(s, "icefem output {}", path.display());
    let _ = writeln!(s, "  icefem version : {version}");
    let _ = writeln!(s, "  scene path     : {scene_path}");
    let _ = writeln!(
        s,
        "  initial mesh   : {} nodes, {} elements",
        count(&mesh, "rest_positions"),
        count(&mesh, "tets")
    );
    let _ = writeln!(
        s,
        "  frames         : {} complete, {} incomplete",
        n_complete,
        list.len() - n_complete
    );
    let step_time = |f: &FrameEntry| -> Option<(u64, f64)> {
        let g = frames.group(&f.name).ok()?;
        let step = g.attr("step").ok()?.read_scalar::<u64>().ok()?;
        let time = g.attr("time").ok()?.read_scalar::<f64>().ok()?;
        Some((step, time))
    };
    let complete: Vec<&FrameEntry> = list.iter().filter(|f| f.complete).collect();
    match (complete.first(), complete.last()) {
        (Some(first), Some(last)) => match (step_time(first), step_time(last)) {
            (Some((s0, t0)), Some((s1, t1))) => {
                let _ = writeln!(
                    s,
                    "  time range     : {t0} s .. {t1} s (steps {s0} .. {s1})"
                );
            }
            _ => {
                let _ = writeln!(s, "  time range     : ? (unreadable step/time attributes)");
            }
        },
        _ => {
            let _ = writeln!(s, "  time range     : (no complete frame)");
        }
    }
    let stats_rows = file
        .group("stats")
        .ok()
        .and_then(|g| g.dataset("step").ok())
        .and_then(|d| d.shape().first().copied());
    let _ = writeln!(
        s,
        "  stats rows     : {}",
        stats_rows.map_or_else(|| "? (no /stats/step)".into(), |r| r.to_string())
    );
    if let Some(last) = complete.last() {
        let g = frames
            .group(&last.name)
            .ctx(path, || format!("opening /frames/{}", last.name))?;
        let _ = writeln!(s, "  last complete frame /frames/{}:", last.name);
        let names = g
            .member_names()
            .ctx(path, || format!("listing /frames/{}", last.name))?;
        for name in names {
            let Ok(ds) = g.dataset(&name) else {
                let triangles = g
                    .dataset(&format!("{name}/triangles"))
                    .ok()
                    .and_then(|t| t.shape().first().copied());
                let _ = match triangles {
                    Some(t) => writeln!(s, "    {name:<16} group: {t} crack triangles"),
                    None => writeln!(s, "    {name:<16} (not a dataset)"),
                };
                continue;
            };
            let dtype = ds
                .dtype()
                .and_then(|t| t.to_descriptor())
                .map_or_else(|_| "?".into(), |d| d.to_string());
            let links = ds.loc_info().map(|i| i.num_links).unwrap_or(1);
            let shared = if links > 1 {
                format!("  (shared by {links} hard links)")
            } else {
                String::new()
            };
            let _ = writeln!(s, "    {name:<16} {dtype:<8} {:?}{shared}", ds.shape());
        }
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{RwLock, RwLockReadGuard};

    /// HDF5 opens files without `O_CLOEXEC` and holds an `flock` on them, so a
    /// child process spawned while another test has a file open inherits the
    /// descriptor and its lock, making that test's next open fail with
    /// "unable to lock file" until the child exits. Tests touching HDF5 hold
    /// this lock shared; the test that spawns a child holds it exclusively.
    static SPAWN_GUARD: RwLock<()> = RwLock::new(());

    fn hdf5_guard() -> RwLockReadGuard<'static, ()> {
        SPAWN_GUARD.read().unwrap_or_else(|e| e.into_inner())
    }

    /// A 2×1×1 box of 8 nodes split into 5 tets, plus a 9th node used after
    /// a "topology change".
    fn mesh() -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
        let p = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ];
        let t = vec![
            [0, 1, 3, 4],
            [1, 2, 3, 6],
            [1, 4, 5, 6],
            [3, 4, 6, 7],
            [1, 3, 4, 6],
        ];
        (p, t)
    }

    fn header<'a>(p: &'a [[f64; 3]], t: &'a [[usize; 4]]) -> RunHeader<'a> {
        RunHeader {
            scene_text: "[solver]\ndt = 1e-3 # ünïcode\n",
            scene_path: "scenes/box.toml",
            version: "0.1.0-test",
            rest_positions: p,
            tets: t,
        }
    }

    fn stats(step: u64) -> StepStats {
        StepStats {
            step,
            time: step as f64 * 1e-3,
            dt: 1e-3,
            newton_iterations: 3,
            newton_solves: 2,
            linear_iterations: 7,
            factorizations: 2,
            substeps: 1,
            residual: 1e-9,
            energy: 1.5,
            kinetic_energy: 0.5,
            elastic_energy: 0.75,
            potential_energy: 0.25,
            contact_energy: 0.0,
            t_assembly: 0.01,
            t_factorization: 0.02,
            t_solve: 0.003,
            t_step: 0.04,
            elements: 6 + step,
            crack_faces: 2 * step,
            fracture_events: 1,
            separation_stress: 2.5e6,
            t_fracture: 0.005,
            t_remesh: 0.0,
            t_resolve: 0.0,
        }
    }

    /// Owned data behind one test frame, values depending on `k` so frames differ.
    struct FrameData {
        pos: Vec<[f64; 3]>,
        vel: Vec<[f64; 3]>,
        rest: Vec<[f64; 3]>,
        tets: Vec<[usize; 4]>,
        stress: Vec<[f64; 6]>,
        eig: Vec<f64>,
        plastic: Vec<f64>,
        temp: Vec<f64>,
    }

    fn frame_data(k: usize, rest: &[[f64; 3]], tets: &[[usize; 4]]) -> FrameData {
        let kf = k as f64;
        let n = rest.len();
        let m = tets.len();
        FrameData {
            // Irrational-ish values to catch any precision loss.
            pos: rest
                .iter()
                .map(|p| [p[0] + 0.1 * kf / 3.0, p[1], p[2] - kf * 1e-17])
                .collect(),
            vel: (0..n)
                .map(|i| [i as f64 / 7.0, -kf, std::f64::consts::PI])
                .collect(),
            rest: rest.to_vec(),
            tets: tets.to_vec(),
            stress: (0..m)
                .map(|e| {
                    let e = e as f64;
                    [e, e + 1.0, e + 2.0, e + 3.0, e + 4.0, kf * 1e6 + 0.1]
                })
                .collect(),
            eig: (0..m).map(|e| e as f64 * 1e-3 + kf).collect(),
            plastic: (0..m * 6).map(|i| i as f64 / 11.0 + kf).collect(),
            temp: (0..n).map(|i| 263.15 + i as f64 + kf).collect(),
        }
    }

    fn write(w: &mut OutputWriter, k: usize, d: &FrameData, topology_changed: bool) {
        let ef = [
            Field {
                name: "eigenstrain",
                cols: 1,
                data: &d.eig,
            },
            Field {
                name: "plastic_strain",
                cols: 6,
                data: &d.plastic,
            },
        ];
        let nf = [Field {
            name: "temperature",
            cols: 1,
            data: &d.temp,
        }];
        w.write_frame(&Frame {
            step: 10 * k as u64,
            time: 10.0 * k as f64 * 1e-3,
            positions: &d.pos,
            velocities: &d.vel,
            rest_positions: &d.rest,
            tets: &d.tets,
            topology_changed,
            stress: &d.stress,
            element_fields: &ef,
            node_fields: &nf,
            cracks: None,
        })
        .unwrap();
    }

    /// Mesh after a fake fracture: node 9 duplicates node 6 for the last tet.
    fn split_mesh() -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
        let (mut p, mut t) = mesh();
        p.push(p[6]);
        t[4] = [1, 3, 4, 8];
        (p, t)
    }

    /// Writes 3 frames (frame 2 with a topology change) and stats rows 0..=20.
    fn write_run(path: &Path) -> (Vec<FrameData>, Vec<StepStats>) {
        let (p, t) = mesh();
        let (p2, t2) = split_mesh();
        let mut w = OutputWriter::create(path, &header(&p, &t)).unwrap();
        let mut all = Vec::new();
        let mut rows = Vec::new();
        for k in 0..3 {
            let d = if k < 2 {
                frame_data(k, &p, &t)
            } else {
                frame_data(k, &p2, &t2)
            };
            for step in (10 * k as u64).saturating_sub(9)..=10 * k as u64 {
                if k == 0 && step > 0 {
                    break;
                }
                let s = stats(step);
                w.append_stats(&s).unwrap();
                rows.push(s);
            }
            write(&mut w, k, &d, k == 2);
            all.push(d);
        }
        assert_eq!(w.frame_count(), 3);
        w.finish().unwrap();
        (all, rows)
    }

    fn read_f64(f: &File, p: &str) -> Vec<f64> {
        f.dataset(p).unwrap().read_raw::<f64>().unwrap()
    }

    #[test]
    fn write_three_frames_and_read_back() {
        let _guard = hdf5_guard();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.h5");
        let (data, rows) = write_run(&path);

        let f = File::open(&path).unwrap();
        let s: VarLenUnicode = f.attr("scene").unwrap().read_scalar().unwrap();
        assert_eq!(s.as_str(), "[solver]\ndt = 1e-3 # ünïcode\n");
        let v: VarLenUnicode = f.attr("icefem_version").unwrap().read_scalar().unwrap();
        assert_eq!(v.as_str(), "0.1.0-test");
        assert_eq!(f.dataset("mesh/tets").unwrap().shape(), vec![5, 4]);

        for (k, d) in data.iter().enumerate() {
            let g = format!("frames/{k:06}");
            let grp = f.group(&g).unwrap();
            assert_eq!(
                grp.attr("complete").unwrap().read_scalar::<u8>().unwrap(),
                1
            );
            assert_eq!(
                grp.attr("step").unwrap().read_scalar::<u64>().unwrap(),
                10 * k as u64
            );
            assert_eq!(
                read_f64(&f, &format!("{g}/positions")),
                d.pos.as_flattened()
            );
            assert_eq!(
                read_f64(&f, &format!("{g}/velocities")),
                d.vel.as_flattened()
            );
            assert_eq!(
                read_f64(&f, &format!("{g}/stress")),
                d.stress.as_flattened()
            );
            assert_eq!(read_f64(&f, &format!("{g}/eigenstrain")), d.eig);
            assert_eq!(
                f.dataset(&format!("{g}/eigenstrain")).unwrap().shape(),
                vec![5]
            );
            assert_eq!(
                f.dataset(&format!("{g}/plastic_strain")).unwrap().shape(),
                vec![5, 6]
            );
            assert_eq!(read_f64(&f, &format!("{g}/plastic_strain")), d.plastic);
            assert_eq!(read_f64(&f, &format!("{g}/temperature")), d.temp);
            let tets = f
                .dataset(&format!("{g}/tets"))
                .unwrap()
                .read_raw::<i64>()
                .unwrap();
            let expect: Vec<i64> = d.tets.as_flattened().iter().map(|&i| i as i64).collect();
            assert_eq!(tets, expect);
        }

        // Frames 0 and 1 share /mesh's objects; frame 2 has its own.
        let token = |p: &str| f.dataset(p).unwrap().loc_info().unwrap().token;
        for name in ["tets", "rest_positions"] {
            let mesh_tok = token(&format!("mesh/{name}"));
            assert_eq!(token(&format!("frames/000000/{name}")), mesh_tok);
            assert_eq!(token(&format!("frames/000001/{name}")), mesh_tok);
            assert_ne!(token(&format!("frames/000002/{name}")), mesh_tok);
            let info = f
                .dataset(&format!("mesh/{name}"))
                .unwrap()
                .loc_info()
                .unwrap();
            assert_eq!(info.num_links, 3);
        }

        // Stats: one row per step, all columns.
        assert_eq!(
            f.dataset("stats/step").unwrap().read_raw::<u64>().unwrap(),
            rows.iter().map(|r| r.step).collect::<Vec<_>>()
        );
        assert_eq!(rows.len(), 21);
        for (name, _) in STATS_COLUMNS {
            assert_eq!(
                f.dataset(&format!("stats/{name}")).unwrap().shape(),
                vec![21]
            );
        }
        assert_eq!(
            f.dataset("stats/newton_iterations")
                .unwrap()
                .read_raw::<u32>()
                .unwrap(),
            vec![3; 21]
        );
        assert_eq!(read_f64(&f, "stats/t_solve"), vec![0.003; 21]);

        // XDMF sidecar exists and references the frames by relative name.
        let xdmf = std::fs::read_to_string(path.with_extension("xdmf")).unwrap();
        assert_eq!(xdmf.matches("GridType=\"Uniform\"").count(), 3);
        assert!(xdmf.contains("run.h5:/frames/000002/tets"));
        assert!(!xdmf.contains(&dir.path().display().to_string()));
        assert!(xdmf.contains("Name=\"plastic_strain\" AttributeType=\"Matrix\" Center=\"Cell\""));
        assert!(xdmf.contains("Name=\"eigenstrain\" AttributeType=\"Scalar\" Center=\"Cell\""));
        assert!(xdmf.contains("Name=\"temperature\" AttributeType=\"Scalar\" Center=\"Node\""));
    }

    #[test]
    fn describe_reports_counts() {
        let _guard = hdf5_guard();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.h5");
        write_run(&path);
        let d = describe(&path).unwrap();
        assert!(d.contains("icefem version : 0.1.0-test"), "{d}");
        assert!(d.contains("scene path     : scenes/box.toml"), "{d}");
        assert!(d.contains("8 nodes, 5 elements"), "{d}");
        assert!(d.contains("3 complete, 0 incomplete"), "{d}");
        assert!(d.contains("steps 0 .. 20"), "{d}");
        assert!(d.contains("stats rows     : 21"), "{d}");
        assert!(d.contains("positions        float64  [9, 3]"), "{d}");
        assert!(d.contains("plastic_strain   float64  [5, 6]"), "{d}");
    }

    #[test]
    fn invalid_frames_are_rejected_before_writing() {
        let _guard = hdf5_guard();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.h5");
        let (p, t) = mesh();
        let mut w = OutputWriter::create(&path, &header(&p, &t)).unwrap();
        let d = frame_data(0, &p, &t);
        let short = &d.eig[..3];
        let cases: [(&[Field], &[[usize; 4]]); 4] = [
            (
                &[Field {
                    name: "eigenstrain",
                    cols: 1,
                    data: short,
                }],
                &d.tets,
            ),
            (
                &[Field {
                    name: "stress",
                    cols: 1,
                    data: &d.eig,
                }],
                &d.tets,
            ),
            (
                &[Field {
                    name: "a/b",
                    cols: 1,
                    data: &d.eig,
                }],
                &d.tets,
            ),
            (&[], &[[0, 1, 2, 99]; 5]),
        ];
        for (ef, tets) in cases {
            let r = w.write_frame(&Frame {
                step: 0,
                time: 0.0,
                positions: &d.pos,
                velocities: &d.vel,
                rest_positions: &d.rest,
                tets,
                topology_changed: true,
                stress: &d.stress,
                element_fields: ef,
                node_fields: &[],
                cracks: None,
            });
            assert!(matches!(r, Err(OutputError::InvalidInput { .. })), "{r:?}");
        }
        // Unchanged topology with a different node count.
        let (p2, t2) = split_mesh();
        let d2 = frame_data(0, &p2, &t2);
        let r = w.write_frame(&Frame {
            step: 0,
            time: 0.0,
            positions: &d2.pos,
            velocities: &d2.vel,
            rest_positions: &d2.rest,
            tets: &d2.tets,
            topology_changed: false,
            stress: &d2.stress,
            element_fields: &[],
            node_fields: &[],
            cracks: None,
        });
        assert!(matches!(r, Err(OutputError::InvalidInput { .. })), "{r:?}");
        assert_eq!(w.frame_count(), 0);
        write(&mut w, 0, &d, false);
        assert_eq!(w.frame_count(), 1);
    }

    /// Environment variable through which the parent test tells the re-executed
    /// test binary where to write the file it then "crashes" on.
    const CRASH_ENV: &str = "ICEFEM_OUTPUT_CRASH_HELPER_PATH";

    /// Not a real test: when `CRASH_ENV` is set, writes two complete frames,
    /// starts a third (group without `complete`, extra stats rows, flushed),
    /// then aborts — no destructors, no HDF5 close — like a SIGKILL.
    #[test]
    fn crash_helper() {
        let Ok(path) = std::env::var(CRASH_ENV) else {
            return;
        };
        let path = PathBuf::from(path);
        let (p, t) = mesh();
        let mut w = OutputWriter::create(&path, &header(&p, &t)).unwrap();
        for k in 0..2 {
            for step in (10 * k as u64).saturating_sub(9)..=10 * k as u64 {
                w.append_stats(&stats(step)).unwrap();
            }
            write(&mut w, k, &frame_data(k, &p, &t), false);
        }
        // Frames are committed in batches; commit the two as the interval would.
        let file = w.file.clone().unwrap();
        w.commit(&file).unwrap();
        for step in 11..=17 {
            w.append_stats(&stats(step)).unwrap();
        }
        w.flush_stats().unwrap();
        let file = w.file.as_ref().unwrap();
        let g = file.create_group("frames/000002").unwrap();
        write_attr(&path, &g, "step", &20u64).unwrap();
        write_vec3(&path, &g, "positions", &p).unwrap();
        file.flush().unwrap();
        std::process::abort();
    }

    #[test]
    fn resume_after_kill() {
        let spawn_guard = SPAWN_GUARD.write().unwrap_or_else(|e| e.into_inner());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("killed.h5");
        // Re-run this test binary on `crash_helper` only; its abort is the "kill".
        let module = module_path!();
        let test_name = match module.split_once("::") {
            Some((_, rest)) => format!("{rest}::crash_helper"),
            None => "crash_helper".into(),
        };
        let out = std::process::Command::new(std::env::current_exe().unwrap())
            .args([
                test_name.as_str(),
                "--exact",
                "--nocapture",
                "--test-threads=1",
            ])
            .env(CRASH_ENV, &path)
            .output()
            .unwrap();
        drop(spawn_guard);
        let _guard = hdf5_guard();
        assert!(!out.status.success(), "helper should have aborted: {out:?}");
        assert!(path.exists(), "helper did not run: {out:?}");

        let before = describe(&path).unwrap();
        assert!(before.contains("2 complete, 1 incomplete"), "{before}");
        assert!(before.contains("stats rows     : 18"), "{before}");

        let (mut w, rf) = OutputWriter::resume(&path).unwrap();
        assert_eq!(w.frame_count(), 2);
        let (p, t) = mesh();
        let d = frame_data(1, &p, &t);
        assert_eq!(rf.step, 10);
        assert_eq!(rf.time.to_bits(), (10.0f64 * 1e-3).to_bits());
        assert_eq!(rf.scene_text, "[solver]\ndt = 1e-3 # ünïcode\n");
        let bits = |v: &[[f64; 3]]| {
            v.as_flattened()
                .iter()
                .map(|x| x.to_bits())
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&rf.positions), bits(&d.pos));
        assert_eq!(bits(&rf.velocities), bits(&d.vel));
        assert_eq!(bits(&rf.rest_positions), bits(&d.rest));
        assert_eq!(rf.tets, d.tets);
        assert_eq!(
            rf.element_fields,
            vec![
                ("eigenstrain".to_string(), 1, d.eig.clone()),
                ("plastic_strain".to_string(), 6, d.plastic.clone())
            ]
        );
        assert_eq!(
            rf.node_fields,
            vec![("temperature".to_string(), 1, d.temp.clone())]
        );

        // Continue the run: frame 2 gets the same name the partial one had.
        for step in 11..=20 {
            w.append_stats(&stats(step)).unwrap();
        }
        write(&mut w, 2, &frame_data(2, &p, &t), false);
        w.finish().unwrap();

        let f = File::open(&path).unwrap();
        let steps = f.dataset("stats/step").unwrap().read_raw::<u64>().unwrap();
        assert_eq!(steps, (0..=20).collect::<Vec<u64>>());
        for (name, _) in STATS_COLUMNS {
            assert_eq!(
                f.dataset(&format!("stats/{name}")).unwrap().shape(),
                vec![21]
            );
        }
        let g2 = f.group("frames/000002").unwrap();
        assert_eq!(g2.attr("complete").unwrap().read_scalar::<u8>().unwrap(), 1);
        assert_eq!(
            read_f64(&f, "frames/000002/velocities"),
            frame_data(2, &p, &t).vel.as_flattened()
        );
        // Still linked to the mesh topology through the resumed frame.
        let tok = |p: &str| f.dataset(p).unwrap().loc_info().unwrap().token;
        assert_eq!(tok("frames/000002/tets"), tok("mesh/tets"));
        let after = describe(&path).unwrap();
        assert!(after.contains("3 complete, 0 incomplete"), "{after}");
    }

    #[test]
    fn resume_adds_a_stats_column_the_file_lacks() {
        // A file written before `/stats/newton_solves` existed: resuming creates the column
        // with 0 in the rows already there, and the resumed steps fill in their values.
        let _guard = hdf5_guard();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("older.h5");
        let (p, t) = mesh();
        let mut w = OutputWriter::create(&path, &header(&p, &t)).unwrap();
        for step in 0..=10 {
            w.append_stats(&stats(step)).unwrap();
        }
        write(&mut w, 1, &frame_data(1, &p, &t), false);
        w.finish().unwrap();
        File::open_rw(&path)
            .unwrap()
            .group("stats")
            .unwrap()
            .unlink("newton_solves")
            .unwrap();

        let (mut w, rf) = OutputWriter::resume(&path).unwrap();
        assert_eq!(rf.step, 10);
        for step in 11..=12 {
            w.append_stats(&stats(step)).unwrap();
        }
        w.finish().unwrap();
        let f = File::open(&path).unwrap();
        let solves = f
            .dataset("stats/newton_solves")
            .unwrap()
            .read_raw::<u32>()
            .unwrap();
        let mut expected = vec![0; 11];
        expected.extend([2, 2]);
        assert_eq!(solves, expected);
        for (name, _) in STATS_COLUMNS {
            assert_eq!(
                f.dataset(&format!("stats/{name}")).unwrap().shape(),
                vec![13]
            );
        }
    }

    #[test]
    fn resume_without_complete_frame() {
        let _guard = hdf5_guard();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("empty.h5");
        let (p, t) = mesh();
        let w = OutputWriter::create(&path, &header(&p, &t)).unwrap();
        drop(w);
        let r = OutputWriter::resume(&path);
        assert!(
            matches!(r, Err(OutputError::NoCompleteFrame { .. })),
            "{:?}",
            r.err()
        );
    }

    #[test]
    fn foreign_files_are_rejected() {
        let _guard = hdf5_guard();
        let dir = tempfile::tempdir().unwrap();
        let text = dir.path().join("notes.h5");
        std::fs::write(&text, "this is not HDF5 at all, just some text\n").unwrap();
        let e = describe(&text).unwrap_err();
        assert!(matches!(e, OutputError::NotHdf5 { .. }), "{e:?}");
        assert!(e.to_string().contains("notes.h5"), "{e}");
        let e = OutputWriter::resume(&text).err().unwrap();
        assert!(matches!(e, OutputError::NotHdf5 { .. }), "{e:?}");

        let empty = dir.path().join("empty.h5");
        std::fs::write(&empty, "").unwrap();
        assert!(matches!(describe(&empty), Err(OutputError::NotHdf5 { .. })));

        let missing = dir.path().join("missing.h5");
        assert!(matches!(describe(&missing), Err(OutputError::Io { .. })));

        let plain = dir.path().join("plain.h5");
        {
            let f = File::create(&plain).unwrap();
            f.new_dataset_builder()
                .with_data(&[1.0f64, 2.0])
                .create("x")
                .unwrap();
        }
        let e = describe(&plain).unwrap_err();
        assert!(matches!(e, OutputError::NotIcefem { .. }), "{e:?}");
        assert!(e.to_string().contains("plain.h5"), "{e}");
        assert!(matches!(
            OutputWriter::resume(&plain),
            Err(OutputError::NotIcefem { .. })
        ));
        assert!(matches!(
            write_xdmf(&plain),
            Err(OutputError::NotIcefem { .. })
        ));

        // /mesh present but no version attribute.
        {
            let f = File::open_rw(&plain).unwrap();
            f.create_group("mesh").unwrap();
        }
        let e = describe(&plain).unwrap_err();
        assert!(e.to_string().contains("icefem_version"), "{e}");
    }

    #[test]
    fn malformed_frame_content_is_an_error_not_a_panic() {
        let _guard = hdf5_guard();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mal.h5");
        let (p, t) = mesh();
        let mut w = OutputWriter::create(&path, &header(&p, &t)).unwrap();
        write(&mut w, 0, &frame_data(0, &p, &t), true);
        drop(w);
        {
            // Replace the frame's tets by an out-of-range index set and
            // velocities by a wrongly shaped array.
            let f = File::open_rw(&path).unwrap();
            let g = f.group("frames/000000").unwrap();
            g.unlink("tets").unwrap();
            g.new_dataset_builder()
                .with_data(&ndarray::arr2(&[[0i64, 1, 2, 3], [0, 1, 2, -1]]))
                .create("tets")
                .unwrap();
        }
        let e = OutputWriter::resume(&path).err().unwrap();
        assert!(matches!(e, OutputError::Corrupt { .. }), "{e:?}");
        {
            let f = File::open_rw(&path).unwrap();
            let g = f.group("frames/000000").unwrap();
            g.unlink("velocities").unwrap();
            g.new_dataset_builder()
                .with_data(&[1.0f64, 2.0])
                .create("velocities")
                .unwrap();
        }
        let e = OutputWriter::resume(&path).err();
        assert!(matches!(e, Some(OutputError::Corrupt { .. })), "{e:?}");
        assert!(describe(&path).is_ok());
    }
}
