//! VTK XML for ParaView: per frame and object an unstructured grid of triangles,
//! `RUN_ice_NNNNNN.vtu`, `RUN_cracks_NNNNNN.vtu` and, for a run with rigid obstacles,
//! `RUN_obstacles_NNNNNN.vtu`, and `RUN.pvd`, the collection that lists them with the frames'
//! times (s) as time steps and the objects as parts 0 (ice), 1 (cracks) and 2 (obstacles).
//! ParaView opens the `.pvd` as one time series of blocks; each `.vtu` stands on
//! its own for other readers (meshio reads `.vtu`, not `.vtm` multiblocks, which is why the
//! objects are files of their own rather than one multiblock per frame).
//!
//! Point data: `velocity` (m/s, 3 components), `freeze_state`, `plastic_strain`, `von_mises`
//! (Pa), `temperature` (°C) where the run has them; Float64, like the points (m, z up). Arrays are inline binary
//! (base64 of a UInt64 byte count and the little-endian values), uncompressed.
//!
//! Written by hand rather than with `vtkio` 0.6.3: it builds with our compiler, but through
//! `nom` 3.2 and `quick-xml` 0.22, which Rust flags as code a future version will reject
//! (rust-lang/rust#79813), and its data model is the legacy format's; the XML here is
//! 100 lines.

use std::fmt::Write as _;
use std::path::PathBuf;

use base64::Engine as _;

use super::target::Target;
use super::{objects, write_file, ExportError, ExportFrame, Sink, SurfaceMesh, VELOCITY};

/// VTK's cell type of a linear triangle.
const VTK_TRIANGLE: u8 = 5;

/// Writes two VTU files per frame and the collection at the end.
pub(super) struct VtuSink {
    target: Target,
    /// (time, part, file name) of every file written.
    datasets: Vec<(f64, usize, String)>,
    files: Vec<PathBuf>,
}

/// The collection's path.
pub(super) fn collection_file(target: &Target) -> PathBuf {
    target.dir.join(format!("{}.pvd", target.stem))
}

impl VtuSink {
    /// Frames into `target`'s folder.
    pub fn new(target: &Target) -> Self {
        VtuSink {
            target: target.clone(),
            datasets: Vec::new(),
            files: Vec::new(),
        }
    }
}

impl Sink for VtuSink {
    fn frame(&mut self, frame: &ExportFrame) -> Result<(), ExportError> {
        for (part, (name, mesh)) in objects(frame).into_iter().enumerate() {
            let file = self.target.frame_file(Some(name), frame.number);
            write_file(&file, vtu_text(mesh).as_bytes())?;
            let file_name = file.file_name().unwrap_or_default().to_string_lossy();
            self.datasets
                .push((frame.time, part, file_name.into_owned()));
            self.files.push(file);
        }
        Ok(())
    }

    fn finish(mut self: Box<Self>) -> Result<Vec<PathBuf>, ExportError> {
        let mut text = String::from(
            "<?xml version=\"1.0\"?>\n\
             <VTKFile type=\"Collection\" version=\"1.0\" byte_order=\"LittleEndian\">\n\
             <Collection>\n",
        );
        for (time, part, file) in &self.datasets {
            let _ = writeln!(
                text,
                "<DataSet timestep=\"{time}\" part=\"{part}\" file=\"{}\"/>",
                escape(file)
            );
        }
        text += "</Collection>\n</VTKFile>\n";
        let file = collection_file(&self.target);
        write_file(&file, text.as_bytes())?;
        self.files.push(file);
        Ok(self.files)
    }
}

/// The VTU document of `mesh`.
fn vtu_text(mesh: &SurfaceMesh) -> String {
    let (n, m) = (mesh.points.len(), mesh.triangles.len());
    let mut text = format!(
        "<?xml version=\"1.0\"?>\n\
         <VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n\
         <UnstructuredGrid>\n<Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{m}\">\n"
    );
    let scalars = match mesh.scalars.last() {
        Some(s) => format!(" Scalars=\"{}\"", s.name),
        None => String::new(),
    };
    let _ = writeln!(text, "<PointData{scalars} Vectors=\"{VELOCITY}\">");
    let velocity = mesh.velocity.iter().flatten().copied();
    data_array(&mut text, "Float64", Some(VELOCITY), 3, f64_bytes(velocity));
    for s in &mesh.scalars {
        let values = s.values.iter().copied();
        data_array(&mut text, "Float64", Some(s.name), 1, f64_bytes(values));
    }
    text += "</PointData>\n<Points>\n";
    let points = mesh.points.iter().flatten().copied();
    data_array(&mut text, "Float64", None, 3, f64_bytes(points));
    text += "</Points>\n<Cells>\n";
    let connectivity = mesh.triangles.iter().flatten().map(|&i| i as i64);
    let offsets = (1..=m as i64).map(|k| 3 * k);
    data_array(
        &mut text,
        "Int64",
        Some("connectivity"),
        1,
        i64_bytes(connectivity),
    );
    data_array(&mut text, "Int64", Some("offsets"), 1, i64_bytes(offsets));
    data_array(&mut text, "UInt8", Some("types"), 1, vec![VTK_TRIANGLE; m]);
    text += "</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
    text
}

/// Little-endian bytes of `values`.
fn f64_bytes(values: impl Iterator<Item = f64>) -> Vec<u8> {
    values.flat_map(f64::to_le_bytes).collect()
}

/// Little-endian bytes of `values`.
fn i64_bytes(values: impl Iterator<Item = i64>) -> Vec<u8> {
    values.flat_map(i64::to_le_bytes).collect()
}

/// Appends a binary `DataArray` of `bytes` (the values, little endian).
fn data_array(
    text: &mut String,
    kind: &str,
    name: Option<&str>,
    components: usize,
    bytes: Vec<u8>,
) {
    let name = name.map_or(String::new(), |n| format!(" Name=\"{n}\""));
    let mut block = (bytes.len() as u64).to_le_bytes().to_vec();
    block.extend_from_slice(&bytes);
    let _ = writeln!(
        text,
        "<DataArray type=\"{kind}\"{name} NumberOfComponents=\"{components}\" format=\"binary\">{}</DataArray>",
        base64::engine::general_purpose::STANDARD.encode(block)
    );
}

/// `s` with XML's special characters escaped, for an attribute value.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::PointScalar;
    use std::path::Path;

    #[test]
    fn an_array_is_its_byte_count_and_values_in_base64() {
        let mesh = SurfaceMesh {
            points: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            scalars: vec![PointScalar {
                name: "von_mises",
                values: vec![1.5, 2.5, 3.5],
            }],
            velocity: vec![[0.0; 3]; 3],
        };
        let text = vtu_text(&mesh);
        let line = text
            .lines()
            .find(|l| l.contains("Name=\"von_mises\""))
            .unwrap();
        let encoded = &line[line.find('>').unwrap() + 1..line.rfind('<').unwrap()];
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(encoded)
            .unwrap();
        assert_eq!(u64::from_le_bytes(bytes[..8].try_into().unwrap()), 24);
        let values: Vec<f64> = bytes[8..]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(values, [1.5, 2.5, 3.5]);
        assert!(text.contains("NumberOfPoints=\"3\" NumberOfCells=\"1\""));
    }

    #[test]
    fn the_collection_lists_each_object_of_each_frame_at_its_time() {
        let dir = std::env::temp_dir().join(format!("icefem_pvd_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let target = Target::new(
            Path::new("a&b.h5"),
            super::super::ExportFormat::Vtu,
            Some(&dir),
        );
        let mut sink = Box::new(VtuSink::new(&target));
        for (number, time) in [(0, 0.0), (1, 0.25)] {
            let frame = ExportFrame {
                number,
                index: 10 * number,
                time,
                ice: SurfaceMesh::default(),
                cracks: SurfaceMesh::default(),
                obstacles: None,
            };
            sink.frame(&frame).unwrap();
        }
        let files = sink.finish().unwrap();
        assert_eq!(files.len(), 5);
        let pvd = std::fs::read_to_string(collection_file(&target)).unwrap();
        let sets: Vec<&str> = pvd.lines().filter(|l| l.starts_with("<DataSet")).collect();
        assert_eq!(sets.len(), 4);
        assert_eq!(
            sets[3],
            "<DataSet timestep=\"0.25\" part=\"1\" file=\"a&amp;b_cracks_000001.vtu\"/>"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
