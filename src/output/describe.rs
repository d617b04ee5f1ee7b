//! [`summary`] and [`describe`]: what `icefem info` prints about a run's file (JSON or text).

use std::fmt::Write as _;
use std::path::Path;

use hdf5::{File, Group};

use super::hdf5_io::{
    check_hdf5_signature, check_icefem_layout, close_on_exec, list_frames, read_string_attr,
    FrameEntry, Hdf5Context,
};
use super::OutputError;

/// What an icefem output file holds, for `icefem info` (text or `--json`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct FileSummary {
    /// The file.
    pub path: String,
    /// Version of the icefem that wrote it.
    pub icefem_version: String,
    /// The scene file's path as the run recorded it (`None`: not recorded).
    pub scene_path: Option<String>,
    /// Nodes of the scene's mesh (`None`: unreadable).
    pub nodes: Option<usize>,
    /// Elements of the scene's mesh.
    pub elements: Option<usize>,
    /// The mesh obstacles stored in the file (`/obstacles/<k>`): obstacle index and triangles.
    pub mesh_obstacles: Vec<(usize, Option<usize>)>,
    /// Complete frames.
    pub complete_frames: usize,
    /// Frames begun but not completed (a run cut off while writing).
    pub incomplete_frames: usize,
    /// Step and time (s) of the first and last complete frames.
    pub first: Option<FrameTime>,
    /// See `first`.
    pub last: Option<FrameTime>,
    /// Rows of `/stats` (one per step).
    pub stats_rows: Option<usize>,
    /// The last complete frame's datasets.
    pub last_frame: Vec<DatasetSummary>,
}

/// A frame's step and time.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct FrameTime {
    /// Frame index (`/frames/NNNNNN`).
    pub frame: usize,
    /// Step.
    pub step: u64,
    /// Time (s).
    pub time: f64,
}

/// One dataset, or group of datasets (`cracks`, `tensors`), of a frame.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DatasetSummary {
    /// Its name in the frame.
    pub name: String,
    /// Element type (`float64`, `int64`, …; `group` for a group).
    pub dtype: String,
    /// Shape (empty for a group).
    pub shape: Vec<usize>,
    /// How many hard links share the data (more than one: unchanged since an earlier frame).
    pub links: usize,
    /// A group's datasets.
    pub members: Vec<DatasetSummary>,
}

impl DatasetSummary {
    /// The dataset or group `name` of `g` (`None`: neither).
    fn of(g: &Group, name: &str) -> Option<Self> {
        if let Ok(ds) = g.dataset(name) {
            return Some(DatasetSummary {
                name: name.into(),
                dtype: ds
                    .dtype()
                    .and_then(|t| t.to_descriptor())
                    .map_or_else(|_| "?".into(), |d| d.to_string()),
                shape: ds.shape(),
                links: ds.loc_info().map(|i| i.num_links).unwrap_or(1),
                members: Vec::new(),
            });
        }
        let group = g.group(name).ok()?;
        Some(DatasetSummary {
            name: name.into(),
            dtype: "group".into(),
            shape: Vec::new(),
            links: 1,
            members: group
                .member_names()
                .unwrap_or_default()
                .iter()
                .filter_map(|n| Self::of(&group, n))
                .collect(),
        })
    }
}

/// The summary of the icefem output file at `path`.
///
/// Errors with `NotHdf5` on a non-HDF5 file and `NotIcefem` on an HDF5 file
/// without `/mesh`, `/frames` or the `icefem_version` root attribute.
pub fn summary(path: &Path) -> Result<FileSummary, OutputError> {
    check_hdf5_signature(path)?;
    let file = File::open(path).ctx(path, || "opening".into())?;
    close_on_exec(&file);
    check_icefem_layout(path, &file)?;
    let icefem_version = read_string_attr(path, &file, "icefem_version")?;
    let scene_path = read_string_attr(path, &file, "scene_path").ok();
    let mesh = file.group("mesh").ctx(path, || "opening /mesh".into())?;
    let rows = |g: &Group, name: &str| {
        g.dataset(name)
            .ok()
            .and_then(|d| d.shape().first().copied())
    };
    let frames = file
        .group("frames")
        .ctx(path, || "opening /frames".into())?;
    let list = list_frames(path, &frames)?;
    let mut mesh_obstacles: Vec<(usize, Option<usize>)> = match file.group("obstacles") {
        Ok(g) => g
            .member_names()
            .unwrap_or_default()
            .iter()
            .filter_map(|n| {
                Some((
                    n.parse().ok()?,
                    g.group(n).ok().and_then(|o| rows(&o, "triangles")),
                ))
            })
            .collect(),
        Err(_) => Vec::new(),
    };
    mesh_obstacles.sort_unstable();
    let complete: Vec<&FrameEntry> = list.iter().filter(|f| f.complete).collect();
    let frame_time = |f: &FrameEntry| -> Option<FrameTime> {
        let g = frames.group(&f.name).ok()?;
        Some(FrameTime {
            frame: f.name.parse().ok()?,
            step: g.attr("step").ok()?.read_scalar::<u64>().ok()?,
            time: g.attr("time").ok()?.read_scalar::<f64>().ok()?,
        })
    };
    let stats_rows = file.group("stats").ok().and_then(|g| rows(&g, "step"));
    let mut last_frame = Vec::new();
    if let Some(last) = complete.last() {
        let g = frames
            .group(&last.name)
            .ctx(path, || format!("opening /frames/{}", last.name))?;
        let names = g
            .member_names()
            .ctx(path, || format!("listing /frames/{}", last.name))?;
        last_frame = names
            .iter()
            .filter_map(|n| DatasetSummary::of(&g, n))
            .collect();
    }
    Ok(FileSummary {
        path: path.display().to_string(),
        icefem_version,
        scene_path,
        nodes: rows(&mesh, "rest_positions"),
        elements: rows(&mesh, "tets"),
        mesh_obstacles,
        complete_frames: complete.len(),
        incomplete_frames: list.len() - complete.len(),
        first: complete.first().and_then(|f| frame_time(f)),
        last: complete.last().and_then(|f| frame_time(f)),
        stats_rows,
        last_frame,
    })
}

/// Human-readable summary of an icefem output file, for `icefem info`: version, scene path,
/// node / element counts, frames (complete / incomplete), time range, stats rows, and the
/// datasets of the last complete frame with dtypes and shapes. Errors as [`summary`].
pub fn describe(path: &Path) -> Result<String, OutputError> {
    let f = summary(path)?;
    let known = |v: Option<usize>| v.map_or_else(|| "?".into(), |r| r.to_string());
    let mut s = String::new();
    let _ = writeln!(s, "icefem output {}", f.path);
    let _ = writeln!(s, "  icefem version : {}", f.icefem_version);
    let _ = writeln!(
        s,
        "  scene path     : {}",
        f.scene_path.as_deref().unwrap_or("?")
    );
    let _ = writeln!(
        s,
        "  initial mesh   : {} nodes, {} elements",
        known(f.nodes),
        known(f.elements)
    );
    if !f.mesh_obstacles.is_empty() {
        let list: Vec<String> = f
            .mesh_obstacles
            .iter()
            .map(|(k, t)| format!("[[obstacle]] {k} ({} triangles)", known(*t)))
            .collect();
        let _ = writeln!(s, "  mesh obstacles : {}", list.join(", "));
    }
    let _ = writeln!(
        s,
        "  frames         : {} complete, {} incomplete",
        f.complete_frames, f.incomplete_frames
    );
    let _ = match (f.complete_frames, f.first, f.last) {
        (0, _, _) => writeln!(s, "  time range     : (no complete frame)"),
        (_, Some(a), Some(b)) => writeln!(
            s,
            "  time range     : {} s .. {} s (steps {} .. {})",
            a.time, b.time, a.step, b.step
        ),
        _ => writeln!(s, "  time range     : ? (unreadable step/time attributes)"),
    };
    let _ = writeln!(
        s,
        "  stats rows     : {}",
        f.stats_rows
            .map_or_else(|| "? (no /stats/step)".into(), |r| r.to_string())
    );
    if let Some(last) = f.last.filter(|_| f.complete_frames > 0) {
        let _ = writeln!(s, "  last complete frame /frames/{:06}:", last.frame);
    }
    for d in &f.last_frame {
        let _ = if d.dtype == "group" {
            match d.members.iter().find(|m| m.name == "triangles") {
                Some(t) => writeln!(
                    s,
                    "    {:<16} group: {} crack triangles",
                    d.name,
                    t.shape.first().unwrap_or(&0)
                ),
                None => {
                    let members: Vec<String> = d
                        .members
                        .iter()
                        .map(|m| format!("{} {:?}", m.name, m.shape))
                        .collect();
                    writeln!(s, "    {:<16} group: {}", d.name, members.join(", "))
                }
            }
        } else {
            let shared = if d.links > 1 {
                format!("  (shared by {} hard links)", d.links)
            } else {
                String::new()
            };
            writeln!(s, "    {:<16} {:<8} {:?}{shared}", d.name, d.dtype, d.shape)
        };
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::super::test_support::{hdf5_guard, write_run};
    use super::describe;

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
        assert!(
            d.contains("tensors          group: plastic_strain [5, 9], stress [5, 9]"),
            "{d}"
        );
    }
}
