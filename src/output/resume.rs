//! Resuming a run: [`OutputWriter::resume`] reopens the file after its last complete restart
//! point (a frame on the output grid), discards what came after it, and reads that frame back as a [`ResumeFrame`] (which the
//! frame reader also uses for every frame it reads).

use std::ops::Range;
use std::path::Path;

use hdf5::{File, Group};

use super::hdf5_io::{
    check_hdf5_signature, check_icefem_layout, close_on_exec, list_frames, open_2d, read_attr,
    read_range, read_string, read_string_attr, read_tet_rows, read_tets, Hdf5Context,
};
use super::ownership::RunLock;
use super::writer::{crash_safe_options, create_stats_column, STATS_COLUMNS};
use super::xdmf::read_records;
use super::{corrupt, OutputError, OutputWriter, RESERVED_FRAME_NAMES};

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
    /// Every per-element field, sorted by name.
    /// Does not include `stress`; read it with the hdf5 crate if needed.
    pub element_fields: Vec<StoredField>,
    /// Every per-node field, sorted by name.
    pub node_fields: Vec<StoredField>,
    /// Every field of rows of any count (`center` = "Rows"), sorted by name.
    pub row_fields: Vec<StoredField>,
    /// The frame's scalar attributes besides `step`, `time` and `complete` (f64 ones).
    pub attributes: Vec<(String, f64)>,
}

impl ResumeFrame {
    /// The frame as bytes, for [`ResumeFrame::from_bytes`] in another process.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let put = |out: &mut Vec<u8>, x: u64| out.extend_from_slice(&x.to_le_bytes());
        let put_str = |out: &mut Vec<u8>, t: &str| {
            put(out, t.len() as u64);
            out.extend_from_slice(t.as_bytes());
        };
        let put_f64s = |out: &mut Vec<u8>, v: &[f64]| {
            put(out, v.len() as u64);
            v.iter()
                .for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
        };
        put(&mut out, self.step);
        put(&mut out, self.time.to_bits());
        put_str(&mut out, &self.scene_text);
        for rows in [&self.positions, &self.velocities, &self.rest_positions] {
            put_f64s(&mut out, rows.as_flattened());
        }
        put(&mut out, self.tets.len() as u64);
        self.tets
            .iter()
            .flatten()
            .for_each(|&v| put(&mut out, v as u64));
        for fields in [&self.element_fields, &self.node_fields, &self.row_fields] {
            put(&mut out, fields.len() as u64);
            for f in fields {
                put_str(&mut out, &f.name);
                put(&mut out, f.columns as u64);
                put_f64s(&mut out, &f.data);
            }
        }
        put(&mut out, self.attributes.len() as u64);
        for (name, value) in &self.attributes {
            put_str(&mut out, name);
            put(&mut out, value.to_bits());
        }
        out
    }

    /// The frame [`ResumeFrame::to_bytes`] wrote; `None` if the bytes are not one.
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        let mut r = ByteReader { bytes, at: 0 };
        let step = r.word()?;
        let time = f64::from_bits(r.word()?);
        let scene_text = r.string()?;
        let mut rows = || -> Option<Vec<[f64; 3]>> {
            let flat = r.f64s()?;
            (flat.len() % 3 == 0).then(|| flat.chunks(3).map(|c| [c[0], c[1], c[2]]).collect())
        };
        let (positions, velocities, rest_positions) = (rows()?, rows()?, rows()?);
        let n = r.count()?;
        if n > bytes.len() / 32 {
            return None;
        }
        let flat: Vec<usize> = (0..4 * n).map(|_| r.count()).collect::<Option<_>>()?;
        let tets = flat.chunks(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
        let mut fields = || -> Option<Vec<StoredField>> {
            (0..r.count()?)
                .map(|_| {
                    Some(StoredField {
                        name: r.string()?,
                        columns: r.count()?,
                        data: r.f64s()?,
                    })
                })
                .collect()
        };
        let (element_fields, node_fields, row_fields) = (fields()?, fields()?, fields()?);
        let attributes = (0..r.count()?)
            .map(|_| Some((r.string()?, f64::from_bits(r.word()?))))
            .collect::<Option<_>>()?;
        (r.at == bytes.len()).then_some(ResumeFrame {
            step,
            time,
            scene_text,
            positions,
            velocities,
            rest_positions,
            tets,
            element_fields,
            node_fields,
            row_fields,
            attributes,
        })
    }

    /// The scalar attribute `name`, if the frame has it.
    pub fn attribute(&self, name: &str) -> Option<f64> {
        self.attributes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| *v)
    }
}

/// Reads what [`ResumeFrame::to_bytes`] wrote.
struct ByteReader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl ByteReader<'_> {
    fn word(&mut self) -> Option<u64> {
        let end = self.at.checked_add(8)?;
        let word = u64::from_le_bytes(self.bytes.get(self.at..end)?.try_into().ok()?);
        self.at = end;
        Some(word)
    }

    fn count(&mut self) -> Option<usize> {
        usize::try_from(self.word()?).ok()
    }

    fn string(&mut self) -> Option<String> {
        let n = self.count()?;
        let end = self.at.checked_add(n)?;
        let text = std::str::from_utf8(self.bytes.get(self.at..end)?)
            .ok()?
            .to_owned();
        self.at = end;
        Some(text)
    }

    fn f64s(&mut self) -> Option<Vec<f64>> {
        let n = self.count()?;
        // A length the bytes cannot hold is refused before allocating.
        if n > (self.bytes.len() - self.at) / 8 {
            return None;
        }
        (0..n).map(|_| Some(f64::from_bits(self.word()?))).collect()
    }
}

/// One per-element or per-node field read back from a frame (owned), row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredField {
    /// Dataset name inside the frame group, e.g. `eigenstrain` or `displacement`.
    pub name: String,
    /// Components per row (1 for a field stored as a 1-D dataset).
    pub columns: usize,
    /// Row-major values, `rows * columns` long, one row per element (element fields) or per
    /// node (node fields), in the units the run wrote them in (e.g. displacement in m,
    /// strains dimensionless).
    pub data: Vec<f64>,
}

impl OutputWriter {
    /// Opens an existing icefem file to continue it.
    ///
    /// Finds the last frame whose `complete` attribute is 1 and whose `restart_point`
    /// attribute is 1 (a frame on the output grid, after which the run forgot its solver
    /// memory; the final frame of a run that stopped between grid frames is not one, and is
    /// computed again), deletes every frame group after it, truncates each `/stats` column to the rows before
    /// the first row whose step exceeds that frame's step (and to the shortest
    /// column, in case a kill interrupted a stats append), and returns a
    /// writer whose next frame follows it, plus the frame's data.
    ///
    /// Deleted groups' space is not reclaimed (an HDF5 limitation; `h5repack`
    /// compacts the file).
    pub fn resume(path: &Path) -> Result<(Self, ResumeFrame), OutputError> {
        Self::resume_until(path, f64::INFINITY)
    }

    /// [`OutputWriter::resume`] for a run to `end_time` (s): a last complete frame at or past
    /// it is resumed from even if it is not a restart point (nothing is computed after it;
    /// the caller reports one past the end time), so the file keeps it.
    pub fn resume_until(path: &Path, end_time: f64) -> Result<(Self, ResumeFrame), OutputError> {
        let (writer, head) = Self::resume_head(path, end_time)?;
        let (nodes, elements) = (writer.n_nodes, writer.n_elems);
        let frame = head.with_rows(
            |name, cols, per_node| {
                writer.resumed_rows(name, cols, 0..if per_node { nodes } else { elements })
            },
            || writer.resumed_tets(0..elements),
        )?;
        Ok((writer, frame))
    }

    /// [`OutputWriter::resume_until`] without the frame's per-node and per-element rows:
    /// its head, whose rows [`OutputWriter::resumed_rows`] and
    /// [`OutputWriter::resumed_tets`] then read a block at a time.
    pub fn resume_head(path: &Path, end_time: f64) -> Result<(Self, FrameHead), OutputError> {
        check_hdf5_signature(path)?;
        let lock = RunLock::acquire(path)?;
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
        // The last restart point (a frame on the output grid); in a file without the marker,
        // the last complete frame.
        let restart_point = |name: &str| {
            frames
                .group(name)
                .ok()
                .and_then(|g| g.attr("restart_point").ok())
                .and_then(|a| a.read_scalar::<f64>().ok())
        };
        let complete = || list.iter().rev().filter(|f| f.complete);
        let marked = complete().any(|f| restart_point(&f.name).is_some());
        let at_end = complete().next().filter(|f| {
            let time = frames
                .group(&f.name)
                .ok()
                .and_then(|g| g.attr("time").ok())
                .and_then(|a| a.read_scalar::<f64>().ok());
            time.is_some_and(|t| t >= end_time * (1.0 - 1e-9))
        });
        let mut resumable = at_end
            .into_iter()
            .chain(complete().filter(|f| !marked || restart_point(&f.name) == Some(1.0)));
        let Some(last) = resumable.next() else {
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
        let head = read_head(path, &g, scene_text)?;

        let records = read_records(path, &file)?;
        let stats_rows = truncate_stats(path, &file, head.frame.step)?;
        file.flush()
            .ctx(path, || "flushing after resume cleanup".into())?;

        let writer = Self {
            location: path.to_path_buf(),
            target: path.to_path_buf(),
            _lock: lock,
            uncommitted_bytes: 0,
            file: Some(file),
            next_frame: last_index + 1,
            topology: format!("/frames/{last_name}"),
            unlinked_topology: None,
            options: super::FrameOptions::default(),
            n_nodes: head.nodes,
            n_elems: head.elements,
            stats_rows,
            pending_stats: Vec::new(),
            uncommitted: Vec::new(),
            records,
            last_commit: None,
            last_sidecars: None,
            last_fields: None,
            open: None,
        };
        Ok((writer, head))
    }

    /// Rows `rows` of the dataset `name` (`cols` columns) of the frame this writer resumed
    /// from, before any frame is written.
    pub fn resumed_rows(
        &self,
        name: &str,
        cols: usize,
        rows: Range<usize>,
    ) -> Result<Vec<f64>, OutputError> {
        let ds = self.resumed_dataset(name)?;
        read_range(&self.location, &ds, cols, rows)
    }

    /// Rows `rows` of the tets of the frame this writer resumed from, before any frame is
    /// written.
    pub fn resumed_tets(&self, rows: Range<usize>) -> Result<Vec<[usize; 4]>, OutputError> {
        let ds = self.resumed_dataset("tets")?;
        read_tet_rows(&self.location, &ds, self.n_nodes, rows)
    }

    fn resumed_dataset(&self, name: &str) -> Result<hdf5::Dataset, OutputError> {
        let path = &self.location;
        let at = format!("{}/{name}", self.topology);
        self.file()?
            .dataset(&at)
            .ctx(path, || format!("opening {at}"))
    }
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

/// Reads a frame group back into owned data, validating shapes and indices.
pub(super) fn read_frame(
    path: &Path,
    g: &Group,
    scene_text: String,
) -> Result<ResumeFrame, OutputError> {
    let head = read_head(path, g, scene_text)?;
    let (nodes, elements) = (head.nodes, head.elements);
    head.with_rows(
        |name, cols, per_node| {
            let ds = g
                .dataset(name)
                .ctx(path, || format!("opening {}/{name}", g.name()))?;
            read_range(path, &ds, cols, 0..if per_node { nodes } else { elements })
        },
        || read_tets(path, g, "tets", nodes),
    )
}

/// A frame's scalars, its `Rows` fields and the names and columns of its per-node and
/// per-element datasets, without their rows: what a distributed resume reads first, each
/// process then taking its own rows as blocks of them arrive.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameHead {
    /// The frame without its per-node and per-element rows (its node and element fields
    /// have no data).
    pub frame: ResumeFrame,
    /// Rows of its per-node datasets (nodes of its mesh).
    pub nodes: usize,
    /// Rows of its per-element datasets (elements of its mesh).
    pub elements: usize,
}

impl FrameHead {
    /// The frame with its rows: `values(name, columns, per_node)` gives the rows of the
    /// dataset `name` (positions, velocities, rest positions, fields), `tets()` the tets.
    pub fn with_rows<E>(
        self,
        mut values: impl FnMut(&str, usize, bool) -> Result<Vec<f64>, E>,
        tets: impl FnOnce() -> Result<Vec<[usize; 4]>, E>,
    ) -> Result<ResumeFrame, E> {
        let mut frame = self.frame;
        let mut vec3 = |name| -> Result<Vec<[f64; 3]>, E> {
            let flat = values(name, 3, true)?;
            Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
        };
        frame.positions = vec3("positions")?;
        frame.velocities = vec3("velocities")?;
        frame.rest_positions = vec3("rest_positions")?;
        frame.tets = tets()?;
        for f in &mut frame.element_fields {
            f.data = values(&f.name, f.columns, false)?;
        }
        for f in &mut frame.node_fields {
            f.data = values(&f.name, f.columns, true)?;
        }
        Ok(frame)
    }

    /// The head as bytes, for [`FrameHead::from_bytes`] in another process.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend_from_slice(&(self.nodes as u64).to_le_bytes());
        out.extend_from_slice(&(self.elements as u64).to_le_bytes());
        out.extend(self.frame.to_bytes());
        out
    }

    /// The head [`FrameHead::to_bytes`] wrote; `None` if the bytes are not one.
    pub fn from_bytes(bytes: &[u8]) -> Option<Self> {
        let mut r = ByteReader { bytes, at: 0 };
        let (nodes, elements) = (r.count()?, r.count()?);
        Some(FrameHead {
            frame: ResumeFrame::from_bytes(&bytes[r.at..])?,
            nodes,
            elements,
        })
    }
}

/// The head of a frame group (see [`FrameHead`]), its datasets' shapes checked against one
/// another.
fn read_head(path: &Path, g: &Group, scene_text: String) -> Result<FrameHead, OutputError> {
    let gname = g.name();
    let step = read_attr::<u64>(path, g, "step")?;
    let time = read_attr::<f64>(path, g, "time")?;
    let rows_of = |name, cols| open_2d(path, g, name, cols).map(|(_, rows)| rows);
    let n = rows_of("positions", 3)?;
    if rows_of("velocities", 3)? != n || rows_of("rest_positions", 3)? != n {
        return Err(corrupt(
            path,
            format!("{gname}: positions, velocities and rest_positions row counts differ"),
        ));
    }
    let m = rows_of("tets", 4)?;

    let mut element_fields = Vec::new();
    let mut node_fields = Vec::new();
    let mut row_fields = Vec::new();
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
        if center.as_deref() == Some("Rows") {
            let data = ds
                .read_raw::<f64>()
                .ctx(path, || format!("reading {gname}/{name}"))?;
            row_fields.push(StoredField {
                name,
                columns: cols,
                data,
            });
            continue;
        }
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
        let field = StoredField {
            name,
            columns: cols,
            data: Vec::new(),
        };
        if is_cell {
            element_fields.push(field);
        } else {
            node_fields.push(field);
        }
    }
    let attributes = g
        .attr_names()
        .unwrap_or_default()
        .into_iter()
        .filter(|n| !matches!(n.as_str(), "step" | "time" | "complete"))
        .filter_map(|n| {
            let v = g.attr(&n).and_then(|a| a.read_scalar::<f64>()).ok()?;
            Some((n, v))
        })
        .collect();
    Ok(FrameHead {
        frame: ResumeFrame {
            step,
            time,
            scene_text,
            positions: Vec::new(),
            velocities: Vec::new(),
            rest_positions: Vec::new(),
            tets: Vec::new(),
            element_fields,
            node_fields,
            row_fields,
            attributes,
        },
        nodes: n,
        elements: m,
    })
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    #[test]
    fn a_frame_survives_its_bytes_and_damaged_bytes_are_refused() {
        let frame = super::ResumeFrame {
            step: 7,
            time: 0.25,
            scene_text: "[mesh] é".into(),
            positions: vec![[1.0, -2.0, 3.5], [f64::MIN_POSITIVE, 0.0, -0.0]],
            velocities: vec![[0.1, 0.2, 0.3], [4.0, 5.0, 6.0]],
            rest_positions: vec![[0.0; 3], [1.0; 3]],
            tets: vec![[0, 1, 1, 0]],
            element_fields: vec![super::StoredField {
                name: "plastic_strain".into(),
                columns: 6,
                data: (0..6).map(f64::from).collect(),
            }],
            node_fields: Vec::new(),
            row_fields: vec![super::StoredField {
                name: "crack_gaps".into(),
                columns: 3,
                data: vec![3.0, 4.0, -1e-6],
            }],
            attributes: vec![("next_dt".into(), 1e-3)],
        };
        let bytes = frame.to_bytes();
        assert_eq!(super::ResumeFrame::from_bytes(&bytes), Some(frame));
        for cut in [0, 8, bytes.len() / 2, bytes.len() - 1] {
            assert_eq!(super::ResumeFrame::from_bytes(&bytes[..cut]), None);
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert_eq!(super::ResumeFrame::from_bytes(&longer), None);
    }

    use hdf5::File;

    use super::super::hdf5_io::{write_attr, write_vec3};
    use super::super::test_support::{
        frame_data, hdf5_guard, header, mesh, read_f64, stats, write, SPAWN_GUARD,
    };
    use super::super::writer::STATS_COLUMNS;
    use super::super::{describe, OutputError, OutputWriter};
    use super::StoredField;

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
        w.commit(&file, false).unwrap();
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
                StoredField {
                    name: "eigenstrain".to_string(),
                    columns: 1,
                    data: d.eig.clone()
                },
                StoredField {
                    name: "plastic_strain".to_string(),
                    columns: 6,
                    data: d.plastic.clone()
                }
            ]
        );
        assert_eq!(
            rf.node_fields,
            vec![StoredField {
                name: "temperature".to_string(),
                columns: 1,
                data: d.temp.clone()
            }]
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
        w.finish().unwrap();
        let r = OutputWriter::resume(&path);
        assert!(
            matches!(r, Err(OutputError::NoCompleteFrame { .. })),
            "{:?}",
            r.err()
        );
    }

    #[test]
    fn malformed_frame_content_is_an_error_not_a_panic() {
        let _guard = hdf5_guard();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mal.h5");
        let (p, t) = mesh();
        let mut w = OutputWriter::create(&path, &header(&p, &t)).unwrap();
        write(&mut w, 0, &frame_data(0, &p, &t), true);
        w.finish().unwrap();
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
