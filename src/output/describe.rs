//! [`describe`]: the text `icefem info` prints about a run's file.

use std::fmt::Write as _;
use std::path::Path;

use hdf5::{File, Group};

use super::hdf5_io::{
    check_hdf5_signature, check_icefem_layout, close_on_exec, list_frames, read_string_attr,
    FrameEntry, Hdf5Context,
};
use super::OutputError;

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
    if let Ok(obstacles) = file.group("obstacles") {
        let mut names = obstacles.member_names().unwrap_or_default();
        names.sort_by_key(|n| n.parse::<usize>().unwrap_or(usize::MAX));
        let list: Vec<String> = names
            .iter()
            .map(|n| {
                let triangles = obstacles
                    .group(n)
                    .map_or_else(|_| "?".into(), |g| count(&g, "triangles"));
                format!("[[obstacle]] {n} ({triangles} triangles)")
            })
            .collect();
        let _ = writeln!(s, "  mesh obstacles : {}", list.join(", "));
    }
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
                let members = g.group(&name).and_then(|m| {
                    m.member_names().map(|names| {
                        names
                            .iter()
                            .map(|n| match m.dataset(n) {
                                Ok(d) => format!("{n} {:?}", d.shape()),
                                Err(_) => n.clone(),
                            })
                            .collect::<Vec<_>>()
                            .join(", ")
                    })
                });
                let _ = match (triangles, members) {
                    (Some(t), _) => writeln!(s, "    {name:<16} group: {t} crack triangles"),
                    (None, Ok(m)) => writeln!(s, "    {name:<16} group: {m}"),
                    (None, Err(_)) => writeln!(s, "    {name:<16} (not a dataset)"),
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
