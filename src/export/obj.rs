//! Wavefront OBJ: one `RUN_NNNNNN.obj` per frame holding the objects `o ice`, `o cracks` and,
//! for a run with rigid obstacles, `o obstacles`.
//!
//! OBJ holds geometry only: the attributes (freeze state, plastic strain, von Mises, velocity)
//! cannot live in it — export PLY, VTU or USD for them. Coordinates in metres with z up (in
//! Blender's OBJ import, set "Up Axis" to Z: its default is Y). Written by hand: an OBJ file
//! is `v` and `f` lines, which no crate makes shorter.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::target::Target;
use super::{objects, run_name, write_file, ExportError, ExportFrame, Sink};

/// Writes one OBJ file per frame.
pub(super) struct ObjSink {
    target: Target,
    run: String,
    files: Vec<PathBuf>,
}

impl ObjSink {
    /// Frames of the run `run` into `target`'s folder.
    pub fn new(target: &Target, run: &Path) -> Self {
        ObjSink {
            target: target.clone(),
            run: run_name(run),
            files: Vec::new(),
        }
    }
}

impl Sink for ObjSink {
    fn frame(&mut self, frame: &ExportFrame) -> Result<(), ExportError> {
        let mut text = format!(
            "# icefem export of {}: frame {} of the run, t = {} s; metres, z up.\n\
             # OBJ holds no attributes: export PLY, VTU or USD for the fields.\n",
            self.run, frame.index, frame.time
        );
        // OBJ numbers vertices from 1 through the whole file.
        let mut first = 1;
        for (name, mesh) in objects(frame) {
            // Writing to a String cannot fail.
            let _ = writeln!(text, "o {name}");
            for [x, y, z] in &mesh.points {
                let _ = writeln!(text, "v {x} {y} {z}");
            }
            for t in &mesh.triangles {
                let [a, b, c] = t.map(|i| i + first);
                let _ = writeln!(text, "f {a} {b} {c}");
            }
            first += mesh.points.len();
        }
        let file = self.target.frame_file(None, frame.number);
        write_file(&file, text.as_bytes())?;
        self.files.push(file);
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<Vec<PathBuf>, ExportError> {
        Ok(self.files)
    }
}
