//! [`FrameReader`]: read-only access to the complete frames of a run's file, for `render`,
//! `figure` and the like.

use std::path::{Path, PathBuf};

use hdf5::{File, Group};

use super::hdf5_io::{
    check_hdf5_signature, check_icefem_layout, list_frames, open_2d, open_read, read_attr,
    read_string_attr, read_tets, read_vec3, FrameEntry, Hdf5Context,
};
use super::resume::{read_frame, ResumeFrame};
use super::{corrupt, ObstacleMesh, OutputError};
use crate::fem::{from_voigt, max_principal, von_mises};
use nalgebra::Matrix3;

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
            .find(|f| f.name == name)
            .map(|f| (f.columns, f.data.as_slice()))
    }

    /// The node field `name`: its columns and row-major data, if the frame has it.
    pub fn node_field(&self, name: &str) -> Option<(usize, &[f64])> {
        self.state
            .node_fields
            .iter()
            .find(|f| f.name == name)
            .map(|f| (f.columns, f.data.as_slice()))
    }

    /// Freeze state of each element, 0 (water) … 1 (ice); `None` when the run has no
    /// freezing.
    pub fn freeze_state(&self) -> Option<&[f64]> {
        self.scalar_field("freeze_state")
    }

    /// ‖ε_p‖ of each element: the Frobenius norm of the plastic strain tensor (the Voigt
    /// shear entries are tensor components, so each counts twice), as stored, or from
    /// `plastic_strain` in a file that does not store it; `None` when the run has no
    /// plasticity.
    pub fn plastic_strain_norm(&self) -> Option<Vec<f64>> {
        if let Some(norm) = self.scalar_field("plastic_strain_norm") {
            return Some(norm.to_vec());
        }
        let (cols, e) = self.element_field("plastic_strain")?;
        (cols == 6).then(|| e.chunks_exact(6).map(|v| from_voigt(v).norm()).collect())
    }

    /// Von Mises stress of each element (Pa), as stored, or from `stress` in a file that does
    /// not store it; `None` when the frame has neither.
    pub fn von_mises(&self) -> Option<Vec<f64>> {
        self.stress_scalar("von_mises", von_mises)
    }

    /// Largest principal stress of each element (Pa, positive in tension), as stored, or from
    /// `stress` in a file that does not store it; `None` when the frame has neither.
    pub fn max_principal_stress(&self) -> Option<Vec<f64>> {
        self.stress_scalar("max_principal_stress", max_principal)
    }

    /// The stored per-element scalar `name`, or `of` each element's stress tensor.
    fn stress_scalar(&self, name: &str, of: fn(&Matrix3<f64>) -> f64) -> Option<Vec<f64>> {
        if let Some(v) = self.scalar_field(name) {
            return Some(v.to_vec());
        }
        (!self.stress.is_empty() && self.stress.len() == self.state.tets.len())
            .then(|| self.stress.iter().map(|s| of(&from_voigt(s))).collect())
    }

    /// The one-column element field `name`, if the frame has it with a value per element.
    fn scalar_field(&self, name: &str) -> Option<&[f64]> {
        self.element_field(name)
            .filter(|(cols, v)| *cols == 1 && v.len() == self.state.tets.len())
            .map(|(_, v)| v)
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
        let file = open_read(path, "opening")?;
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

    /// The triangle surfaces of the scene's mesh obstacles stored in `/obstacles` (empty for a
    /// file without them: no mesh obstacles, or written before they were stored).
    pub fn obstacle_meshes(&self) -> Result<Vec<ObstacleMesh>, OutputError> {
        let path = &self.path;
        let Ok(group) = self.file.group("obstacles") else {
            return Ok(Vec::new());
        };
        let names = group
            .member_names()
            .ctx(path, || "listing /obstacles".into())?;
        let mut meshes = Vec::new();
        for name in names {
            let Ok(index) = name.parse::<usize>() else {
                continue;
            };
            let g = group
                .group(&name)
                .ctx(path, || format!("opening /obstacles/{name}"))?;
            let vertices = read_vec3(path, &g, "vertices")?;
            let (ds, _) = open_2d(path, &g, "triangles", 3)?;
            let flat = ds
                .read_raw::<i64>()
                .ctx(path, || format!("reading /obstacles/{name}/triangles"))?;
            let vertex = |v: i64| {
                usize::try_from(v)
                    .ok()
                    .filter(|&i| i < vertices.len())
                    .ok_or_else(|| {
                        corrupt(
                            path,
                            format!("/obstacles/{name}/triangles: vertex index {v} out of range"),
                        )
                    })
            };
            let triangles = flat
                .chunks_exact(3)
                .map(|t| Ok([vertex(t[0])?, vertex(t[1])?, vertex(t[2])?]))
                .collect::<Result<Vec<_>, OutputError>>()?;
            meshes.push(ObstacleMesh {
                index,
                vertices,
                triangles,
            });
        }
        meshes.sort_by_key(|o| o.index);
        Ok(meshes)
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

/// Parses `A:B:S` (first frame, last frame inclusive, stride; A, B and S may be empty for the
/// first frame, the last frame and 1) against the complete frames `available` (ascending,
/// not empty), as `--frames` of `render` and `export` take it.
pub fn parse_frame_range(spec: &str, available: &[usize]) -> Result<Vec<usize>, String> {
    let parts: Vec<&str> = spec.split(':').collect();
    if parts.len() > 3 {
        return Err(format!("--frames {spec:?}: expected FIRST:LAST[:STEP]"));
    }
    let (first_available, last_available) = (available[0], available[available.len() - 1]);
    let number = |k: usize, default: usize| -> Result<usize, String> {
        match parts.get(k).map(|s| s.trim()) {
            None | Some("") => Ok(default),
            Some(t) => t
                .parse::<usize>()
                .map_err(|_| format!("--frames {spec:?}: {t:?} is not a frame number ≥ 0")),
        }
    };
    let first = number(0, first_available)?;
    let last = number(1, last_available)?;
    let step = number(2, 1)?;
    if step == 0 || first > last {
        return Err(format!("--frames {spec:?}: need FIRST ≤ LAST and STEP ≥ 1"));
    }
    let frames: Vec<usize> = (first..=last).step_by(step).collect();
    if let Some(missing) = frames.iter().find(|f| available.binary_search(f).is_err()) {
        return Err(format!(
            "--frames {spec:?}: frame {missing} is not a complete frame (the file has {} complete frames, {first_available} … {last_available})",
            available.len()
        ));
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_ranges() {
        let available: Vec<usize> = (0..=100).collect();
        assert_eq!(
            parse_frame_range("10:30:10", &available),
            Ok(vec![10, 20, 30])
        );
        assert_eq!(parse_frame_range("98:", &available), Ok(vec![98, 99, 100]));
        assert_eq!(parse_frame_range("::50", &available), Ok(vec![0, 50, 100]));
        assert!(parse_frame_range("90:120", &available)
            .unwrap_err()
            .contains("frame 101"));
        assert!(parse_frame_range("5:1", &available).is_err());
        assert!(parse_frame_range("1:5:0", &available).is_err());
        assert!(parse_frame_range("a:5", &available)
            .unwrap_err()
            .contains("\"a\""));
    }
}
