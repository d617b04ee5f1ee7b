//! HDF5 output of an icefem run, plus its XDMF sidecar for ParaView / meshio.
//!
//! - [`OutputWriter`] (`writer.rs`) creates a run's file and appends frames and `/stats` rows;
//! - [`OutputWriter::resume`] (`resume.rs`) reopens it after its last complete frame and reads
//!   that frame back as a [`ResumeFrame`];
//! - [`write_xdmf`] (`xdmf.rs`) writes the XDMF sidecars;
//! - [`FrameReader`] (`reader.rs`) reads complete frames back for `render`, `figure` and
//!   `export`; [`SurfaceExtractor`] (`surfaces.rs`) finds their outer and crack surfaces;
//! - [`summary`] and [`describe`] (`describe.rs`) are what `icefem info` prints (JSON, text);
//! - `hdf5_io.rs` holds the HDF5 helpers these share (attributes, matrices, index arrays, the
//!   signature and layout checks, the listing of `/frames`).
//!
//! # File layout
//!
//! ```text
//! /                      attrs: scene (TOML text), scene_path, icefem_version, format_version (u32)
//! /mesh/rest_positions   f64 [n, 3]  reference configuration (m)
//! /mesh/tets             i64 [m, 4]  0-based node indices of each linear tetrahedron
//! /obstacles/<k>         the scene's k-th [[obstacle]] when it is a triangle mesh, at t = 0:
//!     vertices           f64 [v, 3] (m)
//!     triangles          i64 [t, 3]  indices into vertices
//! /frames/NNNNNN         one group per output frame, NNNNNN = 0-based frame index (6+ digits)
//!     attrs: step (u64), time (f64, s), complete (u8, = 1, written last)
//!     positions          f64 [n, 3]  (m)   f32 with `[output] drawn_precision = "single"`
//!     velocities         f64 [n, 3]  (m/s)
//!     rest_positions     f64 [n, 3]  (m)   hard link to the previous frame's when topology is unchanged
//!     tets               i64 [m, 4]        hard link to the previous frame's when topology is unchanged
//!     stress             f64 [m, 6]  Cauchy stress, Voigt order xx yy zz yz xz xy (Pa); f32 as positions
//!     <field>            f64 [rows] if cols == 1, else [rows, cols]; attr center = "Cell" | "Node";
//!                        f32 as positions for the fields only drawn (`DRAWN_DATASETS`)
//!     tensors/           with `[output] tensor_matrices`: stress and every 6-column (Voigt) field
//!                        again as 3 × 3 matrices (f32 as positions):
//!         <name>         f64 [rows, 9]  row-major xx xy xz yx yy yz zx zy zz; attr center
//!     cracks/            fracture runs only: the crack faces as separate triangles
//!         vertices       f64 [3t, 3] (m), drawn with the rendering gap where a crack is closed (f32 as positions)
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
//! Each frame is written as an anonymous group (marked `complete = 1`) that nothing in the
//! file's tree refers to yet. Frames are committed in batches: a first flush puts the batch's
//! groups on disk; then the `/stats` rows are written and each group is linked into `/frames`
//! as `NNNNNN`, and a second flush writes those links. A commit happens after the first
//! frame, whenever [`COMMIT_INTERVAL`] has passed since the last one, and when the writer
//! finishes or is dropped — so a run writing a frame every few milliseconds does not spend its
//! time flushing, and a killed run loses at most the last interval. Between commits the file
//! on disk does not change under what it already holds: HDF5's metadata cache writes only
//! when flushed, and freed space is never reused (see `crash_safe_options`); the first flush
//! of a commit writes only objects that nothing reaches yet. A process killed at any moment
//! but the second flush of a commit (the `/frames` index and `/stats`, a few kilobytes)
//! therefore leaves a readable file in which every linked frame is whole;
//! [`OutputWriter::resume`] continues after the last. (H5Fflush hands the data to the OS; it
//! does not fsync, so this protects against a killed process, not against a power loss.)
//! The file has superblock version 2 (the
//! HDF5 1.8 format, which the file-space setting needs), not version 3, whose
//! "open for writing" flag would make a killed run's file unopenable without
//! `h5clear`.
//!
//! The XDMF sidecars are rewritten (atomically) after the commits, so a killed run's file
//! opens in ParaView with its committed frames. A frame is begun only when the file system
//! (and the process's file-size limit) has room for it, the uncommitted frames and a reserve
//! for the commit ([`OutputError::NoSpace`] otherwise): a full disk stops the run with every
//! committed frame readable, and `--resume` continues it once there is room.
//!
//! # Ownership
//!
//! See `ownership.rs`: a run holds a lock on its file that other runs see and readers do not
//! (HDF5's own locking is off, so `info`, `render`, h5py and ParaView read a live run's
//! complete frames); a new run writes beside its target and takes its place only after a
//! frame past its first step, so a run that fails at its start leaves the old file as it was;
//! an existing file is replaced only on request ([`OutputWriter::replace`]) and only if it is
//! an icefem file no run is writing.

mod background;
mod blocks;
mod describe;
mod hdf5_io;
mod ownership;
mod reader;
mod resume;
mod surfaces;
#[cfg(test)]
mod test_support;
mod writer;
mod xdmf;

pub use background::BackgroundWriter;
pub use blocks::{frame_columns, mesh_columns, ColumnValues, FrameColumn, FrameLayout};
pub use describe::{describe, summary, DatasetSummary, FileSummary, FrameTime};
pub use reader::{parse_frame_range, CrackTriangle, FrameReader, StoredFrame, StoredMesh};
pub use resume::{FrameHead, ResumeFrame, StoredField};
pub use surfaces::{FrameMesh, SurfaceExtractor};
pub use writer::{OutputWriter, COMMIT_INTERVAL};
pub use xdmf::write_xdmf;

use std::path::{Path, PathBuf};

use crate::fracture::cracks::CrackSurface;

/// Version of the on-disk layout described in the module docs, stored as
/// root attribute `format_version`. Bump when the layout changes incompatibly.
pub const FORMAT_VERSION: u32 = 1;

/// Dataset names inside a frame group that are not user fields.
const RESERVED_FRAME_NAMES: [&str; 5] = [
    "positions",
    "velocities",
    "rest_positions",
    "tets",
    "stress",
];

/// Groups inside a frame group: the crack surface and the symmetric tensors as 3 × 3 matrices.
const FRAME_GROUPS: [&str; 2] = ["cracks", "tensors"];

/// Fails unless `name` may name a field of a frame (of `kind`: "node", "element" or "row")
/// and is not among the names `seen` so far, to which it is added.
fn check_field_name<'a>(
    path: &Path,
    kind: &str,
    name: &'a str,
    seen: &mut Vec<&'a str>,
) -> Result<(), OutputError> {
    if name.is_empty()
        || name == "."
        || name.contains('/')
        || name.contains('\0')
        || RESERVED_FRAME_NAMES.contains(&name)
        || FRAME_GROUPS.contains(&name)
    {
        return Err(invalid(path, format!("invalid {kind} field name {name:?}")));
    }
    if seen.contains(&name) {
        return Err(invalid(path, format!("duplicate field name {name:?}")));
    }
    seen.push(name);
    Ok(())
}

/// The group of a frame holding each symmetric tensor as 3 × 3 matrices.
const TENSORS: &str = "tensors";

/// Frame datasets that only pictures and exports use: no resumed run reads them (a resumed
/// run continues from `displacement`, `velocities` and the state fields). With
/// [`FrameOptions::drawn_single`] they are stored in single precision, as is everything in
/// `tensors/` and the crack surfaces' `vertices`.
pub const DRAWN_DATASETS: [&str; 8] = [
    "positions",
    "stress",
    "von_mises",
    "max_principal_stress",
    "plastic_strain_norm",
    "contact_normal_force",
    "contact_friction_force",
    "contact_active",
];

/// What frames store beyond a resumed run's state (`[output]`): derived copies and the
/// precision of what is only drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameOptions {
    /// Store every symmetric tensor a second time as 3 × 3 matrices (`tensors/<name>`, the
    /// layout VTK's XDMF readers show as tensors).
    pub tensor_matrices: bool,
    /// Store the scalars computed from other fields: von Mises, largest principal stress and
    /// ‖ε_p‖ per element, and whether each node is in contact (readers compute them from
    /// `stress`, `plastic_strain` and `contact_normal_force` in a file without them).
    pub derived_scalars: bool,
    /// Store the [`DRAWN_DATASETS`], `tensors/` and the crack vertices as 32-bit floats (7
    /// significant digits: 1e-8 m on a 10 cm body), halving their size.
    pub drawn_single: bool,
}

impl Default for FrameOptions {
    /// Everything, in double precision.
    fn default() -> Self {
        FrameOptions {
            tensor_matrices: true,
            derived_scalars: true,
            drawn_single: false,
        }
    }
}

impl FrameOptions {
    /// Whether the frame dataset `name` (a top-level dataset of the frame group) is stored in
    /// single precision.
    pub fn single(&self, name: &str) -> bool {
        self.drawn_single && DRAWN_DATASETS.contains(&name)
    }
}

/// Symmetric tensors in Voigt order xx yy zz yz xz xy, 6 values each, as 3 × 3 matrices,
/// row-major (xx xy xz, yx yy yz, zx zy zz), 9 values each: the layout VTK's XDMF readers
/// read as a tensor.
pub fn voigt_to_matrices(voigt: &[f64]) -> Vec<f64> {
    (voigt.chunks_exact(6))
        .flat_map(|v| [v[0], v[5], v[4], v[5], v[1], v[3], v[4], v[3], v[2]])
        .collect()
}

/// One per-element or per-node field stored in a frame, row-major (rows × cols).
///
/// `rows` is implied: the element count for element fields, the node count for
/// node fields; `data.len()` must equal `rows * cols`. Units are the caller's
/// (document them in the field name's meaning, e.g. strain is dimensionless).
///
/// A field of 6 columns is a symmetric tensor in Voigt order xx yy zz yz xz xy (off-diagonal
/// entries are tensor components); the writer also stores it as 3 × 3 matrices in
/// `tensors/<name>` [rows, 9], the layout the XDMF sidecar shows.
pub struct Field<'a> {
    /// Dataset name inside the frame group; must not contain `/`, be `.`, or
    /// collide with a built-in dataset or group (`positions`, `velocities`,
    /// `rest_positions`, `tets`, `stress`, `cracks`, `tensors`).
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
    /// The initial mesh, `/mesh`.
    pub mesh: HeaderMesh<'a>,
    /// The triangle surfaces of the scene's mesh obstacles, `/obstacles/<index>`.
    pub obstacles: &'a [ObstacleMesh],
}

/// The run header's mesh: `/mesh/rest_positions` [n, 3] (m) and `/mesh/tets` [m, 4] (i64,
/// 0-based node indices).
#[derive(Clone, Copy, Debug)]
pub enum HeaderMesh<'a> {
    /// Given whole: initial reference node positions and tetrahedra.
    Whole {
        rest_positions: &'a [[f64; 3]],
        tets: &'a [[usize; 4]],
    },
    /// Of `nodes` nodes and `elements` elements, whose rows arrive in blocks after the file
    /// is created ([`OutputWriter::write_rows`] with the columns of [`mesh_columns`], then
    /// [`OutputWriter::end_mesh`]): what the writing process of a distributed run does,
    /// holding no whole mesh.
    InBlocks { nodes: usize, elements: usize },
}

impl HeaderMesh<'_> {
    /// Nodes and elements.
    pub fn counts(&self) -> (usize, usize) {
        match self {
            HeaderMesh::Whole {
                rest_positions,
                tets,
            } => (rest_positions.len(), tets.len()),
            HeaderMesh::InBlocks { nodes, elements } => (*nodes, *elements),
        }
    }
}

/// A triangle-mesh obstacle's surface at t = 0, as the scene placed it (scaled and
/// translated): group `/obstacles/<index>` with `vertices` f64 [v, 3] (m) and `triangles`
/// i64 [t, 3] (0-based, outward by the right-hand rule).
#[derive(Clone, Debug, PartialEq)]
pub struct ObstacleMesh {
    /// Which `[[obstacle]]` of the scene it is (0-based, in the scene's order).
    pub index: usize,
    /// Vertices at t = 0 (m).
    pub vertices: Vec<[f64; 3]>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[usize; 3]>,
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
    /// `stress` [m, 6] (and as 3 × 3 matrices, `tensors/stress` [m, 9]).
    pub stress: &'a [[f64; 6]],
    /// Extra per-element state (e.g. `eigenstrain` m×1, `plastic_strain` m×6).
    pub element_fields: &'a [Field<'a>],
    /// Extra per-node state (e.g. `temperature` n×1).
    pub node_fields: &'a [Field<'a>],
    /// State stored as rows of any count (e.g. `crack_gaps`, one row p, q, g per pair of
    /// copies of a split node): what a resumed run continues from, not drawn (not in the
    /// XDMF sidecar); attribute `center` = "Rows".
    pub row_fields: &'a [Field<'a>],
    /// Scalar attributes of the frame besides `step` and `time` (e.g. `next_dt`, s): state
    /// a resumed run continues from.
    pub attributes: &'a [(&'a str, f64)],
    /// Crack surfaces (fracture runs), group `cracks`: `vertices` f64 [k, 3] (m),
    /// `triangles` i64 \[t, 3\] (indices into `vertices`), `crack` i64 \[t\] (which crack).
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
    /// Switches of Newton to the projected Hessian in the step, after the exact one was
    /// found indefinite.
    pub projections: u32,
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
    /// Nodes the fracture criterion applies to after the step (all their elements frozen).
    pub eligible_nodes: u64,
    /// Eligible nodes above the toughness after the step's splits, not counting refused ones.
    pub nodes_above_toughness: u64,
    /// Eligible nodes above the toughness after the step's splits whose split is refused.
    pub refused_nodes: u64,
    /// Splits refused during the step.
    pub refused_splits: u32,
    /// Total crack area at rest after the step, one side (m²).
    pub crack_area: f64,
    /// Crack polygons after the step (planar crack pieces per scene element, counted once).
    pub crack_polygons: u64,
    /// Wall-clock time of the fracture check and splits after the step (s).
    pub t_fracture: f64,
    /// Wall-clock time of rebuilding the simulation on a split mesh (s).
    pub t_remesh: f64,
    /// Wall-clock time of taking the step again on the split meshes (s).
    pub t_resolve: f64,
    /// Newton iterations of the heat step (0 without `[thermal]`).
    pub heat_newton_iterations: u32,
    /// |enthalpy change − heat in through the boundary| of the heat step (J; 0 without
    /// `[thermal]`).
    pub heat_imbalance: f64,
    /// Solves of the heat step: 1, plus one per round of cancelled conduction couplings at
    /// nodes that would otherwise end the step as new local extrema (0 without `[thermal]`).
    pub heat_passes: u32,
    /// Mesh edges whose positive conduction coupling the heat step cancelled (0 without
    /// `[thermal]` and on meshes without obtuse tetrahedra).
    pub heat_cancelled_edges: u64,
    /// Wall-clock time of the heat step (s).
    pub t_heat: f64,
    /// Estimated local displacement error of the step (m; 0 in a static analysis).
    pub local_error: f64,
    /// The adaptive control's error measure of the step (≤ 1 when accepted on merit; 0
    /// without adaptive steps).
    pub error_ratio: f64,
    /// Tries of the step the adaptive control rejected before it.
    pub rejected_steps: u32,
}

/// Errors of the output module. Every variant names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The HDF5 library reported an error.
    #[error("{}: HDF5 error while {context}: {}", path.display(), hdf5_io::concise(error))]
    Hdf5 {
        /// File concerned.
        path: PathBuf,
        /// What was being done, e.g. "writing /frames/000003/positions [n, 3]".
        context: String,
        /// The library's error (its whole error stack; the message shows its gist).
        error: hdf5::Error,
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
    /// Another icefem run is writing the file (it holds the run lock).
    #[error("{}: another icefem run is writing this file; wait for it to end or choose another output", path.display())]
    InUse {
        /// File concerned.
        path: PathBuf,
    },
    /// A new run was asked to write over an existing run's file without leave to replace it.
    #[error("{} exists: pass --force to replace it, or --resume {} to continue it", path.display(), path.display())]
    Exists {
        /// File concerned.
        path: PathBuf,
    },
    /// The output path holds something that is not an icefem file; it is never replaced.
    #[error("{}: refusing to write the output over it: {reason}", path.display())]
    Foreign {
        /// File concerned.
        path: PathBuf,
        /// What the path holds.
        reason: String,
    },
    /// The disk (or the process's file-size limit) has no room for the next frame; the frames
    /// committed so far stay readable.
    #[error("{}: no room for frame {frame} ({needed} bytes needed with the reserve, {available} available); frames up to {last_committed} are kept", path.display(), needed = bytes(*needed), available = bytes(*available), last_committed = frame.saturating_sub(1))]
    NoSpace {
        /// File concerned.
        path: PathBuf,
        /// Index of the frame that was not written.
        frame: usize,
        /// Bytes the frame and the commit reserve need.
        needed: u64,
        /// Bytes available (free space on the file system, or below the file-size limit).
        available: u64,
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

/// A byte count in the unit that reads best (B, kB, MB, GB; decimal).
fn bytes(n: u64) -> String {
    match n {
        0..1_000 => format!("{n} B"),
        1_000..1_000_000 => format!("{:.1} kB", n as f64 / 1e3),
        1_000_000..1_000_000_000 => format!("{:.1} MB", n as f64 / 1e6),
        _ => format!("{:.2} GB", n as f64 / 1e9),
    }
}

/// An [`OutputError::Corrupt`] for `path`.
fn corrupt(path: &Path, reason: impl Into<String>) -> OutputError {
    OutputError::Corrupt {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

/// An [`OutputError::InvalidInput`] for `path`.
fn invalid(path: &Path, reason: impl Into<String>) -> OutputError {
    OutputError::InvalidInput {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}
