//! PLY: per frame and object, `RUN_ice_NNNNNN.ply`, `RUN_cracks_NNNNNN.ply` and (rigid
//! obstacles) `RUN_obstacles_NNNNNN.ply`, binary little endian, with the point attributes as
//! vertex properties.
//!
//! Vertex properties, all `float` (f32): `x y z` (m, z up), `vx vy vz` (velocity, m/s), then
//! `freeze_state`, `plastic_strain`, `von_mises` (Pa), `temperature` (°C) where the run has
//! them. Faces:
//! `list uchar int vertex_indices`. Written by hand: `ply-rs` 0.1.3 is unmaintained, and its
//! maintained fork `ply-rs-bw` holds each vertex as a map from property name to value (an
//! allocation per vertex) where the format is a text header and packed records.

use std::path::{Path, PathBuf};

use super::target::Target;
use super::{objects, run_name, write_file, ExportError, ExportFrame, Sink, SurfaceMesh};

/// Writes two PLY files per frame.
pub(super) struct PlySink {
    target: Target,
    run: String,
    files: Vec<PathBuf>,
}

impl PlySink {
    /// Frames of the run `run` into `target`'s folder.
    pub fn new(target: &Target, run: &Path) -> Self {
        PlySink {
            target: target.clone(),
            run: run_name(run),
            files: Vec::new(),
        }
    }
}

impl Sink for PlySink {
    fn frame(&mut self, frame: &ExportFrame) -> Result<(), ExportError> {
        for (name, mesh) in objects(frame) {
            let comment = format!(
                "icefem export of {}: {name}, frame {} of the run, t = {} s; metres, z up",
                self.run, frame.index, frame.time
            );
            let file = self.target.frame_file(Some(name), frame.number);
            write_file(&file, &ply_bytes(mesh, &comment))?;
            self.files.push(file);
        }
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<Vec<PathBuf>, ExportError> {
        Ok(self.files)
    }
}

/// The binary little-endian PLY of `mesh`, with `comment` (one line) in its header.
fn ply_bytes(mesh: &SurfaceMesh, comment: &str) -> Vec<u8> {
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment {}\nelement vertex {}\n",
        comment.replace('\n', " "),
        mesh.points.len()
    );
    let names = ["x", "y", "z", "vx", "vy", "vz"]
        .into_iter()
        .chain(mesh.scalars.iter().map(|s| s.name));
    for name in names {
        header += &format!("property float {name}\n");
    }
    header += &format!(
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.triangles.len()
    );
    let record = 4 * (6 + mesh.scalars.len());
    let mut bytes =
        Vec::with_capacity(header.len() + record * mesh.points.len() + 13 * mesh.triangles.len());
    bytes.extend_from_slice(header.as_bytes());
    for (i, (x, v)) in mesh.points.iter().zip(&mesh.velocity).enumerate() {
        let scalars = mesh.scalars.iter().map(|s| s.values[i]);
        for value in x.iter().chain(v).copied().chain(scalars) {
            bytes.extend_from_slice(&(value as f32).to_le_bytes());
        }
    }
    for t in &mesh.triangles {
        bytes.push(3);
        for &i in t {
            bytes.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    bytes
}
