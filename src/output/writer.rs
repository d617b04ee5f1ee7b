//! [`OutputWriter`]: creates a run's file, appends frames and `/stats` rows, and commits
//! frames in batches (see the crash-safety section of the module docs).

use std::path::{Path, PathBuf};

use hdf5::{Dataset, File, Group};

use super::blocks::OpenFrame;
use super::hdf5_io::{
    check_cracks, check_tets, close_on_exec, link_dataset, link_object, vlen_str, write_attr,
    write_cracks, write_indices, write_tets, write_values, write_vec3, Hdf5Context,
};
use super::ownership::{check_target, partial_path, remove_stale_partials, take_place, RunLock};
use super::xdmf::{write_sidecars, FrameRecord};
use super::{
    check_field_name, corrupt, invalid, voigt_to_matrices, Field, Frame, FrameOptions, HeaderMesh,
    OutputError, RunHeader, StepStats, FORMAT_VERSION, TENSORS,
};

/// Rows appended to `/stats` per chunk; 4096 rows × 8 B = 32 KiB chunks keep
/// small runs small and long runs from having millions of chunks.
const STATS_CHUNK_ROWS: usize = 4096;

/// Pending stats rows are written out once this many accumulate, so memory
/// stays bounded even if frames are rare.
const STATS_MAX_PENDING: usize = 1024;

/// How one `/stats` column is extracted from a [`StepStats`] row.
#[derive(Clone, Copy)]
pub(super) enum StatsColumn {
    U64(fn(&StepStats) -> u64),
    U32(fn(&StepStats) -> u32),
    F64(fn(&StepStats) -> f64),
}

/// The `/stats` columns, named exactly as the `StepStats` fields. `step` must
/// stay first: `resume` reads it to decide where to truncate.
pub(super) const STATS_COLUMNS: [(&str, StatsColumn); 40] = [
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
    ("projections", StatsColumn::U32(|s| s.projections)),
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
    ("eligible_nodes", StatsColumn::U64(|s| s.eligible_nodes)),
    (
        "nodes_above_toughness",
        StatsColumn::U64(|s| s.nodes_above_toughness),
    ),
    ("refused_nodes", StatsColumn::U64(|s| s.refused_nodes)),
    ("refused_splits", StatsColumn::U32(|s| s.refused_splits)),
    ("crack_area", StatsColumn::F64(|s| s.crack_area)),
    ("crack_polygons", StatsColumn::U64(|s| s.crack_polygons)),
    ("t_fracture", StatsColumn::F64(|s| s.t_fracture)),
    ("t_remesh", StatsColumn::F64(|s| s.t_remesh)),
    ("t_resolve", StatsColumn::F64(|s| s.t_resolve)),
    (
        "heat_newton_iterations",
        StatsColumn::U32(|s| s.heat_newton_iterations),
    ),
    ("heat_imbalance", StatsColumn::F64(|s| s.heat_imbalance)),
    ("heat_passes", StatsColumn::U32(|s| s.heat_passes)),
    (
        "heat_cancelled_edges",
        StatsColumn::U64(|s| s.heat_cancelled_edges),
    ),
    ("t_heat", StatsColumn::F64(|s| s.t_heat)),
    ("local_error", StatsColumn::F64(|s| s.local_error)),
    ("error_ratio", StatsColumn::F64(|s| s.error_ratio)),
    ("rejected_steps", StatsColumn::U32(|s| s.rejected_steps)),
];

/// Group name of frame `index`: at least 6 digits so that names sort in
/// frame order in tools that list members alphabetically (h5ls, HDFView).
fn frame_name(index: usize) -> String {
    format!("{index:06}")
}

/// Writes one run's frames and per-step statistics to an HDF5 file.
///
/// Dropping a writer without [`finish`](Self::finish) still commits what was written and
/// writes buffered stats rows (best effort); a new run's file that never took its target's
/// place is removed, leaving the target as it was.
pub struct OutputWriter {
    /// Where the file is now: `target`, or the hidden partial file of a new run not yet in its
    /// place (see `ownership`).
    pub(super) location: PathBuf,
    /// Where the run's file belongs.
    pub(super) target: PathBuf,
    /// This run's write lock on its file.
    pub(super) _lock: RunLock,
    /// Bytes of the frames written since the last commit (what the commit's flush may still
    /// have to put on disk).
    pub(super) uncommitted_bytes: u64,
    /// `None` only after `finish` took it, so `Drop` knows there is nothing to do.
    pub(super) file: Option<File>,
    /// Index of the next frame group to create.
    pub(super) next_frame: usize,
    /// The group holding the current topology (`rest_positions`, `tets`), which a frame with
    /// unchanged topology hard-links to: its path once linked into the file, or the frame
    /// group itself while that frame is not committed yet.
    pub(super) topology: String,
    pub(super) unlinked_topology: Option<Group>,
    /// What frames store besides a resumed run's state, and in which precision.
    pub(super) options: FrameOptions,
    /// Node / element counts of the current topology, to reject a frame that
    /// claims unchanged topology but has different sizes.
    pub(super) n_nodes: usize,
    pub(super) n_elems: usize,
    /// Rows already in `/stats`.
    pub(super) stats_rows: usize,
    /// Rows not yet written to `/stats`.
    pub(super) pending_stats: Vec<StepStats>,
    /// Frames written but not yet linked into `/frames`: name, sidecar record and the
    /// (anonymous) group.
    pub(super) uncommitted: Vec<(String, FrameRecord, Group)>,
    /// The sidecar records of the complete frames.
    pub(super) records: Vec<FrameRecord>,
    /// When the last commit happened (`None`: never).
    pub(super) last_commit: Option<std::time::Instant>,
    /// When the sidecars were last rewritten and how long that took (`None`: never).
    pub(super) last_sidecars: Option<(std::time::Instant, std::time::Duration)>,
    /// The last frame's group and its fields' values: a field with the same values in the next
    /// frame is hard-linked to it instead of written again (`None` after a resume or reopen).
    pub(super) last_fields: Option<(Group, Vec<StoredValues>)>,
    /// The frame being written in blocks of rows ([`OutputWriter::begin_frame`]), if any.
    pub(super) open: Option<OpenFrame>,
}

/// A field's values as a frame stored them: name, columns, single precision, the values.
pub(super) struct StoredValues {
    name: String,
    cols: usize,
    single: bool,
    data: Vec<f64>,
}

impl StoredValues {
    /// Whether `f`, stored in single precision if `single`, stores exactly these values.
    fn holds(&self, f: &Field, single: bool) -> bool {
        self.name == f.name
            && self.cols == f.cols
            && self.single == single
            && self.data.len() == f.data.len()
            && self
                .data
                .iter()
                .zip(f.data)
                .all(|(a, b)| a.to_bits() == b.to_bits())
    }
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
pub(super) fn crash_safe_options() -> hdf5::file::FileBuilder {
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
    // HDF5's own file lock off: readers may open the file while it is written (the run's
    // lock is `ownership::RunLock`).
    builder
        .with_fapl(|fapl| fapl.mdc_config(&cache).file_locking(false))
        .with_fcpl(|fcpl| fcpl.file_space_strategy(FileSpaceStrategy::None));
    builder
}

/// Metadata-cache size above which the writer closes and reopens its file (bytes).
const CACHE_REOPEN_BYTES: usize = 1 << 20;

/// Bytes held by `file`'s metadata cache (0 if HDF5 cannot tell).
fn metadata_cache_bytes(file: &File) -> usize {
    let (mut max, mut min_clean, mut current, mut entries) = (0usize, 0usize, 0usize, 0i32);
    // SAFETY: `file` is an open file id; the call fills the four values it is given.
    let status = hdf5::sync::sync(|| unsafe {
        hdf5_sys::h5f::H5Fget_mdc_size(
            file.id(),
            &mut max,
            &mut min_clean,
            &mut current,
            &mut entries,
        )
    });
    if status < 0 {
        0
    } else {
        current
    }
}

/// Bytes one `/stats` row takes (34 columns of 8 bytes at most).
const STATS_ROW_BYTES: u64 = 8 * STATS_COLUMNS.len() as u64;

/// Room kept free beyond the frames for a commit's metadata and the XDMF sidecars (bytes);
/// [`OutputWriter::check_room`] adds 2 % of the file for the metadata that grows with it.
const COMMIT_RESERVE: u64 = 1 << 20;

/// Bytes a frame's datasets take uncompressed (an upper bound of what it adds to the file),
/// plus its groups' and attributes' headers.
fn frame_bytes(frame: &Frame) -> u64 {
    let rows3 = 24 * frame.positions.len() as u64;
    // Stress in Voigt order and as 3 × 3 matrices.
    let mut bytes = 16_384 + 2 * rows3 + 120 * frame.stress.len() as u64;
    if frame.topology_changed {
        bytes += rows3 + 32 * frame.tets.len() as u64;
    }
    for f in (frame.element_fields.iter())
        .chain(frame.node_fields)
        .chain(frame.row_fields)
    {
        // A 6-column field is stored again as matrices: 8 + 8 × 9 / 6 bytes a value.
        let per_value = if f.cols == 6 { 20 } else { 8 };
        bytes += per_value * f.data.len() as u64;
    }
    if let Some(c) = frame.cracks {
        bytes += 24 * (c.vertices.len() + c.triangles.len()) as u64 + 8 * c.crack.len() as u64;
    }
    bytes
}

/// Bytes that may still be written to `path`, now `written` bytes long: the free space of its
/// file system for unprivileged users, and below the process's file-size limit if it has one;
/// `None` when neither can be read.
fn available_bytes(path: &Path, written: u64) -> Option<u64> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let free = free_space(dir);
    // SAFETY: getrlimit fills the struct it is given.
    let limit = unsafe {
        let mut l = std::mem::zeroed::<libc::rlimit>();
        (libc::getrlimit(libc::RLIMIT_FSIZE, &mut l) == 0 && l.rlim_cur != libc::RLIM_INFINITY)
            .then(|| (l.rlim_cur as u64).saturating_sub(written))
    };
    match (free, limit) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// Free bytes of the file system holding `dir`, for unprivileged users.
fn free_space(dir: &Path) -> Option<u64> {
    use std::os::unix::ffi::OsStrExt as _;
    let c = std::ffi::CString::new(dir.as_os_str().as_bytes()).ok()?;
    // SAFETY: `c` is a NUL-terminated path and `s` a struct statvfs fills.
    unsafe {
        let mut s = std::mem::zeroed::<libc::statvfs>();
        (libc::statvfs(c.as_ptr(), &mut s) == 0).then(|| s.f_bavail as u64 * s.f_frsize as u64)
    }
}

/// The sidecars are rewritten at a commit when the time since their last rewrite is at least
/// this many times what that rewrite took (at most 1/20 of a run's time goes to them).
const SIDECAR_SHARE: u32 = 20;

/// Longest wall time between two commits of written frames (see the module docs).
pub const COMMIT_INTERVAL: std::time::Duration = std::time::Duration::from_millis(500);

impl OutputWriter {
    /// Starts a new run's file for `target` and writes the run header: root attributes,
    /// `/mesh`, empty `/frames` and empty `/stats` columns. An existing `target` is an error
    /// ([`OutputError::Exists`]); see [`replace`](Self::replace).
    ///
    /// The file is written beside `target` and takes its place once a frame after the first
    /// is committed, or at [`finish`](Self::finish); a writer dropped before that removes it.
    pub fn create(target: &Path, header: &RunHeader) -> Result<Self, OutputError> {
        Self::start(target, header, false)
    }

    /// As [`create`](Self::create), but an existing icefem file at `target` that no run is
    /// writing is replaced (when the new run takes its place). Anything else at `target` —
    /// another kind of file, a directory, a file a run is writing — is still refused.
    pub fn replace(target: &Path, header: &RunHeader) -> Result<Self, OutputError> {
        Self::start(target, header, true)
    }

    fn start(target: &Path, header: &RunHeader, replace: bool) -> Result<Self, OutputError> {
        check_target(target, replace)?;
        remove_stale_partials(target);
        let path = &partial_path(target);
        let (n_nodes, n_elems) = header.mesh.counts();
        match Self::write_header(path, header) {
            Ok((file, lock, open)) => Ok(Self {
                location: path.clone(),
                target: target.to_path_buf(),
                _lock: lock,
                uncommitted_bytes: 0,
                file: Some(file),
                next_frame: 0,
                topology: "/mesh".into(),
                unlinked_topology: None,
                options: FrameOptions::default(),
                n_nodes,
                n_elems,
                stats_rows: 0,
                pending_stats: Vec::new(),
                uncommitted: Vec::new(),
                records: Vec::new(),
                last_commit: None,
                last_sidecars: None,
                last_fields: None,
                open,
            }),
            Err(e) => {
                let _ = std::fs::remove_file(path);
                Err(e)
            }
        }
    }

    /// Creates the file at `path`, locks it and writes the run header; the header's mesh open
    /// for its rows if they come in blocks.
    fn write_header(
        path: &Path,
        header: &RunHeader,
    ) -> Result<(File, RunLock, Option<OpenFrame>), OutputError> {
        if let HeaderMesh::Whole {
            rest_positions,
            tets,
        } = header.mesh
        {
            check_tets(path, "mesh", tets, rest_positions.len())?;
        }
        for o in header.obstacles {
            let v = o.vertices.len();
            if o.triangles.as_flattened().iter().any(|&i| i >= v) {
                return Err(invalid(
                    path,
                    format!("obstacle {}: a triangle index is not < {v}", o.index),
                ));
            }
        }
        let scene = vlen_str(path, "scene", header.scene_text)?;
        let scene_path = vlen_str(path, "scene_path", header.scene_path)?;
        let version = vlen_str(path, "icefem_version", header.version)?;

        let file = crash_safe_options()
            .create_excl(path)
            .ctx(path, || "creating the file".into())?;
        close_on_exec(&file);
        let lock = RunLock::acquire(path)?;
        let root: &Group = &file;
        write_attr(path, root, "scene", &scene)?;
        write_attr(path, root, "scene_path", &scene_path)?;
        write_attr(path, root, "icefem_version", &version)?;
        write_attr(path, root, "format_version", &FORMAT_VERSION)?;

        let mesh = file
            .create_group("mesh")
            .ctx(path, || "creating /mesh".into())?;
        let open = match header.mesh {
            HeaderMesh::Whole {
                rest_positions,
                tets,
            } => {
                write_vec3(path, &mesh, "rest_positions", rest_positions)?;
                write_tets(path, &mesh, "tets", tets)?;
                None
            }
            HeaderMesh::InBlocks { nodes, elements } => {
                Some(OpenFrame::mesh(path, mesh, (nodes, elements))?)
            }
        };
        if !header.obstacles.is_empty() {
            let obstacles = file
                .create_group("obstacles")
                .ctx(path, || "creating /obstacles".into())?;
            for o in header.obstacles {
                let g = obstacles
                    .create_group(&o.index.to_string())
                    .ctx(path, || format!("creating /obstacles/{}", o.index))?;
                write_vec3(path, &g, "vertices", &o.vertices)?;
                write_indices(path, &g, "triangles", &o.triangles)?;
            }
        }
        file.create_group("frames")
            .ctx(path, || "creating /frames".into())?;
        let stats = file
            .create_group("stats")
            .ctx(path, || "creating /stats".into())?;
        for (name, col) in STATS_COLUMNS {
            create_stats_column(path, &stats, name, col)?;
        }
        file.flush().ctx(path, || "flushing the header".into())?;
        Ok((file, lock, open))
    }

    /// Number of frames in the file (the index the next frame will get).
    pub fn frame_count(&self) -> usize {
        self.next_frame
    }

    /// Path of the run's HDF5 file (where it is, or will be once the run takes its place).
    pub fn path(&self) -> &Path {
        &self.target
    }

    pub(super) fn file(&self) -> Result<&File, OutputError> {
        // Only reachable if a method were called after `finish`, which takes `self`.
        self.file
            .as_ref()
            .ok_or_else(|| invalid(&self.location, "writer already finished"))
    }

    /// Appends one frame: written as a group of its own, linked into `/frames` as
    /// `/frames/NNNNNN` at the next commit (see the module docs).
    ///
    /// All inputs are validated before anything is written, so an
    /// `InvalidInput` error leaves the file untouched.
    pub fn write_frame(&mut self, frame: &Frame) -> Result<(), OutputError> {
        self.validate_frame(frame)?;
        if self.open.is_some() {
            return Err(invalid(
                &self.location,
                "a frame or the header's mesh written in blocks is open",
            ));
        }
        let bytes = frame_bytes(frame);
        let (file, name) = self.prepare_frame(bytes)?;
        // A group that fails half-written is simply dropped: nothing links to it.
        let g = self.start_frame_group(&file, &name, (frame.step, frame.time), frame.attributes)?;
        self.write_frame_group(frame, &file, &g, &name)?;
        let record = FrameRecord::of(self.next_frame, frame, self.options, self.last_record());
        if frame.topology_changed {
            self.topology = format!("/frames/{name}");
            self.unlinked_topology = Some(g.clone());
            self.n_nodes = frame.positions.len();
            self.n_elems = frame.tets.len();
        }
        self.frame_written(&file, (name, record, g), bytes)
    }

    /// Makes ready for a frame of at most `bytes`: reopens the file if its metadata cache is
    /// large, checks there is room for the frame and the pending `/stats` rows; the file and
    /// the frame's name.
    pub(super) fn prepare_frame(&mut self, bytes: u64) -> Result<(File, String), OutputError> {
        self.reopen_if_cache_is_large()?;
        self.check_room(bytes + STATS_ROW_BYTES * self.pending_stats.len() as u64)?;
        Ok((self.file()?.clone(), frame_name(self.next_frame)))
    }

    /// The sidecar record of the last frame written, committed or not.
    pub(super) fn last_record(&self) -> Option<&FrameRecord> {
        (self.uncommitted.last().map(|(_, r, _)| r)).or(self.records.last())
    }

    /// Creates the anonymous group of frame `name` (to be linked by the commit) with its step,
    /// time (s) and other attributes; an error if `/frames` already has a frame of that name.
    pub(super) fn start_frame_group(
        &self,
        file: &File,
        name: &str,
        (step, time): (u64, f64),
        attributes: &[(&str, f64)],
    ) -> Result<Group, OutputError> {
        let path = &self.location;
        let frames = file
            .group("frames")
            .ctx(path, || "opening /frames".into())?;
        if frames.link_exists(name) {
            return Err(corrupt(path, format!("/frames/{name} already exists")));
        }
        let g = file
            .create_group_builder()
            .create(None)
            .ctx(path, || format!("creating the group of frame {name}"))?;
        write_attr(path, &g, "step", &step)?;
        write_attr(path, &g, "time", &time)?;
        for (name, value) in attributes {
            write_attr(path, &g, name, value)?;
        }
        Ok(g)
    }

    /// Hard-links the current topology's `rest_positions` and `tets` into frame group `g`.
    /// Hard links cost a few bytes and keep every frame self-contained for readers (XDMF,
    /// h5py) that only look at one group.
    pub(super) fn link_topology(&self, file: &File, g: &Group) -> Result<(), OutputError> {
        let path = &self.location;
        let source = match &self.unlinked_topology {
            Some(group) => group.clone(),
            None => file
                .group(&self.topology)
                .ctx(path, || format!("opening {}", self.topology))?,
        };
        link_dataset(path, &source, g, "rest_positions")?;
        link_dataset(path, &source, g, "tets")
    }

    /// Marks frame group `g` complete and queues it for the next commit (`bytes`: what it
    /// adds to the file at most); commits when the last commit is [`COMMIT_INTERVAL`] old.
    pub(super) fn frame_written(
        &mut self,
        file: &File,
        (name, record, g): (String, FrameRecord, Group),
        bytes: u64,
    ) -> Result<(), OutputError> {
        write_attr(&self.location, &g, "complete", &1u8)?;
        self.uncommitted.push((name, record, g));
        self.uncommitted_bytes += bytes;
        self.next_frame += 1;
        if self
            .last_commit
            .is_none_or(|t| t.elapsed() >= COMMIT_INTERVAL)
        {
            self.commit(file, false)?;
        }
        Ok(())
    }

    /// Writes the datasets of `frame` into its anonymous group `g` (frame `name`): it becomes
    /// a frame of the file only when the commit links it.
    fn write_frame_group(
        &mut self,
        frame: &Frame,
        file: &File,
        g: &Group,
        name: &str,
    ) -> Result<(), OutputError> {
        let path = self.location.clone();
        let options = self.options;
        // A built-in dataset of `rows` × `cols` values, in single precision if only drawn.
        let builtin = |name, rows, cols, data: &[f64]| {
            write_values(&path, g, (name, rows, cols), data, options.single(name))
        };
        let n = frame.positions.len();
        builtin("positions", n, 3, frame.positions.as_flattened())?;
        write_vec3(&path, g, "velocities", frame.velocities)?;
        if frame.topology_changed {
            write_vec3(&path, g, "rest_positions", frame.rest_positions)?;
            write_tets(&path, g, "tets", frame.tets)?;
        } else {
            self.link_topology(file, g)?;
        }
        builtin("stress", frame.stress.len(), 6, frame.stress.as_flattened())?;
        let centers = [
            (frame.element_fields, "Cell"),
            (frame.node_fields, "Node"),
            (frame.row_fields, "Rows"),
        ];
        let last = self.last_fields.take();
        let mut stored = Vec::new();
        for (fields, center) in centers {
            for f in fields {
                let single = options.single(f.name);
                // Values that have not changed since the last frame (a history that is not
                // evolving, the record of refused splits) are hard-linked to its dataset: a
                // link costs a few bytes and a fraction of a dataset's time.
                let unchanged = last
                    .as_ref()
                    .filter(|(_, values)| values.iter().any(|v| v.holds(f, single)));
                if let Some((last_group, _)) = unchanged {
                    link_dataset(&path, last_group, g, f.name)?;
                } else {
                    let shape = (f.name, f.data.len() / f.cols, f.cols);
                    let ds = write_values(&path, g, shape, f.data, single)?;
                    write_attr(&path, &ds, "center", &vlen_str(&path, "center", center)?)?;
                }
                stored.push(StoredValues {
                    name: f.name.into(),
                    cols: f.cols,
                    single,
                    data: f.data.to_vec(),
                });
            }
        }
        self.last_fields = Some((g.clone(), stored));
        if options.tensor_matrices {
            write_tensor_matrices(&path, g, name, frame, options.drawn_single)?;
        }
        if let Some(c) = frame.cracks {
            write_cracks(&path, g, name, c, options.drawn_single)?;
        }
        Ok(())
    }

    /// What frames written from now on store besides a resumed run's state (everything, in
    /// double precision, by default). Without tensor matrices the XDMF sidecar has no tensor
    /// attributes, only the scalars derived from them.
    pub fn set_frame_options(&mut self, options: FrameOptions) {
        self.options = options;
    }

    /// What frames written from now on store.
    pub fn frame_options(&self) -> FrameOptions {
        self.options
    }

    fn validate_frame(&self, frame: &Frame) -> Result<(), OutputError> {
        let path = &self.location;
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
            (frame.element_fields, Some(m), "element"),
            (frame.node_fields, Some(n), "node"),
            (frame.row_fields, None, "row"),
        ] {
            for f in fields {
                // Row fields have as many rows as their values fill.
                let rows = rows.unwrap_or(f.data.len() / f.cols.max(1));
                check_field_name(path, kind, f.name, &mut seen)?;
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
        if let Some(c) = frame.cracks {
            check_cracks(path, c)?;
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

    /// Links every uncommitted frame into `/frames`: a first flush puts their groups —
    /// complete, but not reachable from the file's tree yet — on disk, then the `/stats` rows
    /// are written and the groups linked, and a second flush writes the links. Only that
    /// second flush changes what the file already held (the `/frames` index and `/stats`),
    /// so a process killed during the first one leaves the file as the last commit did.
    ///
    /// Then the sidecars are rewritten, so a run that dies opens in ParaView with every
    /// committed frame; a new run's file takes its target's place first once it holds a frame
    /// after the first (or when `finishing`).
    pub(super) fn commit(&mut self, file: &File, finishing: bool) -> Result<(), OutputError> {
        self.last_commit = Some(std::time::Instant::now());
        let path = self.location.clone();
        if !self.uncommitted.is_empty() {
            file.flush()
                .ctx(&path, || "flushing frames before commit".into())?;
            self.flush_stats_to(file)?;
            let frames = file
                .group("frames")
                .ctx(&path, || "opening /frames".into())?;
            for (name, record, g) in std::mem::take(&mut self.uncommitted) {
                link_object(&path, &g, &frames, &name)?;
                self.records.push(record);
            }
            self.unlinked_topology = None;
            file.flush()
                .ctx(&path, || "flushing frame completion".into())?;
            self.uncommitted_bytes = 0;
        } else if !finishing {
            return Ok(());
        }
        // A new run's records are its own frames: it takes its place with two of them.
        if self.location != self.target && (self.records.len() >= 2 || finishing) {
            take_place(&self.location, &self.target)?;
            self.location = self.target.clone();
        }
        // Rewriting the sidecars writes every frame's grid again, so a long run does it only
        // when that keeps it under 1/SIDECAR_SHARE of the time since the last rewrite.
        let due = self
            .last_sidecars
            .is_none_or(|(at, took)| at.elapsed() >= took * SIDECAR_SHARE);
        if self.location == self.target && (due || finishing) {
            let start = std::time::Instant::now();
            write_sidecars(&self.target, &self.records)?;
            self.last_sidecars = Some((start, start.elapsed()));
        }
        Ok(())
    }

    /// Closes and reopens the file when its metadata cache holds more than
    /// [`CACHE_REOPEN_BYTES`] and no frame is uncommitted: with evictions off (see
    /// [`crash_safe_options`]) the cache keeps every object header the run wrote, which would
    /// otherwise grow the run's memory with every frame. Reopening between commits writes
    /// nothing the last commit did not (but `/stats` rows a long stretch without frames had
    /// to write early).
    fn reopen_if_cache_is_large(&mut self) -> Result<(), OutputError> {
        let Some(file) = &self.file else {
            return Ok(());
        };
        if !self.uncommitted.is_empty() || metadata_cache_bytes(file) < CACHE_REOPEN_BYTES {
            return Ok(());
        }
        // Pending `/stats` rows stay in memory until the next commit writes them. No object
        // of the file may stay open, or closing would not empty the cache.
        self.last_fields = None;
        let path = self.location.clone();
        let file = self.file.take().expect("checked above");
        file.close()
            .ctx(&path, || "closing to empty the metadata cache".into())?;
        let file = crash_safe_options().open_rw(&path).ctx(&path, || {
            "reopening after emptying the metadata cache".into()
        })?;
        close_on_exec(&file);
        self.file = Some(file);
        Ok(())
    }

    /// Fails with [`OutputError::NoSpace`] unless the file system (and the process's file-size
    /// limit) leaves room for `size` more bytes, the frames not yet committed and a reserve
    /// for the commit's metadata and the sidecars: a frame that does not fit is not begun, so
    /// a full disk never interrupts a write and the committed frames stay readable.
    fn check_room(&self, size: u64) -> Result<(), OutputError> {
        let written = std::fs::metadata(&self.location).map_or(0, |m| m.len());
        let needed = size + self.uncommitted_bytes + COMMIT_RESERVE + written / 50;
        let available = available_bytes(&self.location, written);
        if available.is_some_and(|a| a < needed) {
            return Err(OutputError::NoSpace {
                path: self.target.clone(),
                frame: self.next_frame,
                needed,
                available: available.unwrap_or(0),
            });
        }
        Ok(())
    }

    /// Writes pending stats rows to `/stats` (without H5Fflush).
    pub(super) fn flush_stats(&mut self) -> Result<(), OutputError> {
        let file = self.file()?.clone();
        self.flush_stats_to(&file)
    }

    /// As [`flush_stats`](Self::flush_stats), into `file`.
    fn flush_stats_to(&mut self, file: &File) -> Result<(), OutputError> {
        if self.pending_stats.is_empty() {
            return Ok(());
        }
        let path = self.location.clone();
        let stats = file.group("stats").ctx(&path, || "opening /stats".into())?;
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

    /// Commits the frames written since the last commit, puts a new run's file in its target's
    /// place, writes the sidecars (`<file>.xdmf`, and `<file>.cracks.xdmf` with fracture) and
    /// the remaining `/stats` rows, and closes the file.
    pub fn finish(mut self) -> Result<(), OutputError> {
        if let Some(file) = self.file.clone() {
            self.commit(&file, true)?;
            self.flush_stats_to(&file)?;
            self.file = None;
            let path = self.location.clone();
            file.flush().ctx(&path, || "flushing before close".into())?;
            file.close().ctx(&path, || "closing the file".into())?;
        }
        Ok(())
    }
}

impl Drop for OutputWriter {
    fn drop(&mut self) {
        // Best effort: an error here cannot be reported, and `finish` already
        // emptied the buffer on the normal path.
        if let Some(f) = self.file.take() {
            let _ = self.commit(&f, false);
            let _ = self.flush_stats_to(&f);
            if self.location != self.target {
                // The run never got past its start: the target keeps what it held.
                drop(f);
                let _ = std::fs::remove_file(&self.location);
            }
        }
    }
}

/// Creates the empty, extendable `/stats/{name}` column.
pub(super) fn create_stats_column(
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

/// Writes the symmetric tensors of `frame` (the stress and every 6-column field) again as
/// 3 × 3 matrices into group `tensors` of frame group `g` (in single precision if `single`):
/// the one layout VTK's XDMF readers both read as the tensor it is (see `xdmf.rs`).
fn write_tensor_matrices(
    path: &Path,
    g: &Group,
    name: &str,
    frame: &Frame,
    single: bool,
) -> Result<(), OutputError> {
    let stress = frame.stress.as_flattened();
    let tensors = g
        .create_group(TENSORS)
        .ctx(path, || format!("creating the tensors of frame {name}"))?;
    let voigt = std::iter::once(("stress", "Cell", stress)).chain(
        [(frame.element_fields, "Cell"), (frame.node_fields, "Node")]
            .into_iter()
            .flat_map(|(fields, center)| fields.iter().map(move |f| (f, center)))
            .filter(|(f, _)| f.cols == 6)
            .map(|(f, center)| (f.name, center, f.data)),
    );
    for (field, center, data) in voigt {
        let matrices = voigt_to_matrices(data);
        let ds = write_values(
            path,
            &tensors,
            (field, data.len() / 6, 9),
            &matrices,
            single,
        )?;
        write_attr(path, &ds, "center", &vlen_str(path, "center", center)?)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests;
