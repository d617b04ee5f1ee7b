//! Triangle surface meshes of rigid obstacles, read from Wavefront OBJ, STL, PLY or Gmsh
//! `.msh` files.
//!
//! OBJ files are parsed by the `tobj` crate (`obj`), STL and PLY files by
//! `surface_formats`, Gmsh files by [`super::gmsh`]. Coordinates are
//! multiplied by a scale factor on reading, so that a file drawn in millimetres can be used
//! with `scale = 1e-3`; everything here is in metres after that.

mod obj;

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use super::gmsh::{self, GmshError};
use super::orientation::{consistent_orientation, enclosed_volume, winding_number};
use super::surface_formats::{read_ply, read_stl, Geometry, ReadFailure};

/// A triangle surface mesh (m): a rigid obstacle's boundary. Triangles are oriented with
/// outward normals by the right-hand rule (counter-clockwise seen from outside).
///
/// The orientation is the file's as read; [`TriSurface::orient_outward`] makes a closed
/// surface's consistent and outward (an open surface has no inside: its orientation says on
/// which side the ice is).
#[derive(Clone, Debug, PartialEq)]
pub struct TriSurface {
    /// Vertex positions (m).
    pub vertices: Vec<Vector3<f64>>,
    /// Vertex indices of each triangle, 0-based, counter-clockwise seen from outside.
    pub triangles: Vec<[usize; 3]>,
}

/// Why a triangle surface is unusable (see [`TriSurface::check`]). Vertices and triangles
/// are numbered from 0, in the order of [`TriSurface`]'s arrays.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum InvalidSurface {
    /// The surface has no triangles.
    #[error("the surface has no triangles ({vertices} vertices): an obstacle needs at least one")]
    NoTriangles {
        /// Number of vertices.
        vertices: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error(
        "vertex {vertex} has a non-finite coordinate {position:?}: coordinates must be finite \
         numbers (m)"
    )]
    NonFinite {
        /// The vertex.
        vertex: usize,
        /// Its position (m).
        position: [f64; 3],
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} refers to vertex {vertex}, but the surface has only {vertices} \
         vertices: indices must be below {vertices}"
    )]
    BadIndex {
        /// The triangle.
        triangle: usize,
        /// The vertex index it holds.
        vertex: usize,
        /// Number of vertices.
        vertices: usize,
    },
    /// A triangle has (near) zero area: a repeated vertex or three collinear corners.
    #[error(
        "triangle {triangle} (vertices {corners:?} at {positions:?} m) is degenerate: its area \
         {area:e} m² is at most {tolerance:e} m² (1e-12 × the squared diagonal of the bounding \
         box); a triangle needs three distinct corners that are not collinear"
    )]
    Degenerate {
        /// The triangle.
        triangle: usize,
        /// Its vertex indices.
        corners: [usize; 3],
        /// Its corner positions (m).
        positions: [[f64; 3]; 3],
        /// Its area (m²).
        area: f64,
        /// The largest area taken as zero (m²).
        tolerance: f64,
    },
    /// A closed surface whose triangles cannot be oriented consistently (a one-sided surface).
    #[error(
        "the surface is closed but one-sided: triangle {triangle} cannot face the same side as \
         its neighbours whichever way it is turned; an obstacle's closed surface must bound a \
         solid"
    )]
    NotOrientable {
        /// A triangle where the orientation runs into itself.
        triangle: usize,
    },
}

impl InvalidSurface {
    /// The triangle at fault, if the problem is one triangle's.
    pub fn triangle(&self) -> Option<usize> {
        match self {
            InvalidSurface::BadIndex { triangle, .. }
            | InvalidSurface::Degenerate { triangle, .. }
            | InvalidSurface::NotOrientable { triangle } => Some(*triangle),
            InvalidSurface::NoTriangles { .. } | InvalidSurface::NonFinite { .. } => None,
        }
    }
}

/// Error reading an obstacle surface file. Every message names the file and, where it is
/// known, the line (OBJ) or triangle at fault.
#[derive(Debug, thiserror::Error)]
pub enum SurfaceError {
    /// The file could not be read (missing, unreadable, ...).
    #[error("cannot read obstacle surface file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        #[source]
        source: std::io::Error,
    },
    /// The file name ends in none of the extensions read.
    #[error(
        "surface file {path} has an unsupported extension: expected .obj (Wavefront OBJ), \
         .stl (STL, ASCII or binary), .ply (PLY) or .msh (Gmsh 2.2 or 4.1), in any letter case"
    )]
    UnknownExtension {
        /// The file.
        path: PathBuf,
    },
    /// The scale factor is not a finite positive number.
    #[error(
        "cannot read obstacle surface file {path} with scale {scale}: the scale must be a \
         finite number > 0 (a negative one would mirror the surface and turn its normals in)"
    )]
    BadScale {
        /// The file.
        path: PathBuf,
        /// The scale given.
        scale: f64,
    },
    /// A line of an OBJ file is malformed.
    #[error("OBJ file {path}, line {line}: {message}")]
    ObjLine {
        /// The file.
        path: PathBuf,
        /// The line (from 1).
        line: usize,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// An OBJ file is malformed in a way not tied to one line.
    #[error("OBJ file {path}: {message}")]
    Obj {
        /// The file.
        path: PathBuf,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// An OBJ file has no faces.
    #[error(
        "OBJ file {path} has no faces: an obstacle needs a closed or open triangle surface \
         (faces `f` of 3 or more vertices; quads and polygons are split into triangles)"
    )]
    NoFaces {
        /// The file.
        path: PathBuf,
    },
    /// An STL or PLY file is malformed.
    #[error("{format} file {path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// "STL" or "PLY".
        format: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A Gmsh file is malformed or has no linear triangles (the message names the file).
    #[error(transparent)]
    Gmsh(GmshError),
    /// The surface read is unusable (degenerate triangle, non-finite coordinate, ...).
    #[error("obstacle surface file {path}{location}: {problem}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Where in the file, e.g. " (triangle 3 comes from the face on line 17)", or empty.
        location: String,
        /// What is wrong (boxed: it is large, and errors are passed around by value).
        problem: Box<InvalidSurface>,
    },
}

impl TriSurface {
    /// Builds a surface and [checks](TriSurface::check) it.
    pub fn new(
        vertices: Vec<Vector3<f64>>,
        triangles: Vec<[usize; 3]>,
    ) -> Result<Self, InvalidSurface> {
        let surface = TriSurface {
            vertices,
            triangles,
        };
        surface.check()?;
        Ok(surface)
    }

    /// Reads `.obj` (Wavefront OBJ), `.stl` (STL, ASCII or binary), `.ply` (PLY, ASCII or
    /// binary) or `.msh` (Gmsh 2.2 or 4.1, ASCII or binary) by the extension, in any letter
    /// case, multiplies the coordinates by `scale` (finite, > 0; the
    /// file's unit in m, e.g. 1e-3 for millimetres) and [checks](TriSurface::check) the
    /// result. OBJ: all faces of all objects and groups form the surface, polygons split into
    /// triangles. Gmsh: the linear triangles (element type 2), volume elements ignored.
    /// Vertices that no triangle uses are not kept.
    pub fn read(path: &Path, scale: f64) -> Result<Self, SurfaceError> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(SurfaceError::BadScale {
                path: path.to_path_buf(),
                scale,
            });
        }
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match extension.as_deref() {
            Some("obj") => obj::read_obj(path, scale),
            Some("msh") => read_gmsh(path, scale),
            Some("stl") => read_indexed(path, "STL", read_stl(path, scale)),
            Some("ply") => read_indexed(path, "PLY", read_ply(path, scale)),
            _ => Err(SurfaceError::UnknownExtension {
                path: path.to_path_buf(),
            }),
        }
    }

    /// Checks the surface: at least one triangle, finite coordinates, vertex indices in
    /// range, and no degenerate triangle (repeated vertex, or area at most 1e-12 × the squared
    /// diagonal of the bounding box of all vertices). Vertices no triangle uses are allowed.
    /// Orientation and closedness are not checked.
    pub fn check(&self) -> Result<(), InvalidSurface> {
        let n = self.vertices.len();
        if self.triangles.is_empty() {
            return Err(InvalidSurface::NoTriangles { vertices: n });
        }
        for (vertex, p) in self.vertices.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(InvalidSurface::NonFinite {
                    vertex,
                    position: [p.x, p.y, p.z],
                });
            }
        }
        for (triangle, corners) in self.triangles.iter().enumerate() {
            if let Some(&vertex) = corners.iter().find(|&&v| v >= n) {
                return Err(InvalidSurface::BadIndex {
                    triangle,
                    vertex,
                    vertices: n,
                });
            }
        }
        let (lo, hi) = self.bounding_box();
        let tolerance = 1e-12 * (hi - lo).norm_squared();
        for (triangle, &corners) in self.triangles.iter().enumerate() {
            let area = self.triangle_area(triangle);
            let [a, b, c] = corners;
            if a == b || b == c || a == c || area <= tolerance {
                return Err(InvalidSurface::Degenerate {
                    triangle,
                    corners,
                    positions: corners.map(|v| self.vertices[v].into()),
                    area,
                    tolerance,
                });
            }
        }
        Ok(())
    }

    /// Axis-aligned bounding box of all vertices (min, max) in m; infinite and inverted when
    /// there are no vertices.
    pub fn bounding_box(&self) -> (Vector3<f64>, Vector3<f64>) {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for p in &self.vertices {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (lo, hi)
    }

    /// Area of triangle `t` (m²).
    pub fn triangle_area(&self, t: usize) -> f64 {
        let [a, b, c] = self.triangles[t].map(|v| self.vertices[v]);
        0.5 * (b - a).cross(&(c - a)).norm()
    }

    /// Whether every edge is shared by exactly two triangles (a closed surface).
    pub fn is_closed(&self) -> bool {
        let mut uses: std::collections::HashMap<(usize, usize), u32> = Default::default();
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        uses.values().all(|&n| n == 2)
    }

    /// The generalised winding number of the surface at `x` (Jacobson et al. 2013): the
    /// signed solid angle of its triangles at `x` over 4π. For a closed, consistently oriented
    /// surface it is ±1 inside (+1 with outward normals) and 0 outside, whichever way the
    /// surface is oriented as a whole; on the surface it is not defined.
    pub fn winding_number(&self, x: &Vector3<f64>) -> f64 {
        winding_number(&self.vertices, &self.triangles, x)
    }

    /// Orients a closed surface consistently and outward: every edge is then traversed in
    /// opposite directions by its two triangles, and each connected piece encloses a positive
    /// volume — or a negative one when it lies inside an odd number of the other pieces (the
    /// inner wall of a hollow shell faces its cavity). Returns how many triangles were
    /// reversed. A surface that is not closed is left as it is (its orientation is the
    /// ice's side). Gmsh writes each surface of a solid in its own parametrisation, so its
    /// boundary meshes come out partly reversed.
    pub fn orient_outward(&mut self) -> Result<usize, InvalidSurface> {
        if !self.is_closed() {
            return Ok(0);
        }
        let (reversed, piece, pieces) = consistent_orientation(&self.triangles)
            .map_err(|triangle| InvalidSurface::NotOrientable { triangle })?;
        let mut oriented = self.clone();
        for (t, &r) in reversed.iter().enumerate() {
            if r {
                oriented.triangles[t].swap(1, 2);
            }
        }
        let piece_of = |p: usize| -> Vec<[usize; 3]> {
            (0..oriented.triangles.len())
                .filter(|&t| piece[t] == p)
                .map(|t| oriented.triangles[t])
                .collect()
        };
        let triangles: Vec<Vec<[usize; 3]>> = (0..pieces).map(piece_of).collect();
        let mut flip_piece = vec![false; pieces];
        for (p, own) in triangles.iter().enumerate() {
            // A piece inside an odd number of others bounds a cavity: it faces into it.
            let probe = self.vertices[own[0][0]];
            let depth = (0..pieces)
                .filter(|&q| q != p)
                .filter(|&q| winding_number(&self.vertices, &triangles[q], &probe).abs() > 0.5)
                .count();
            let volume = enclosed_volume(&self.vertices, own);
            flip_piece[p] = (volume < 0.0) == depth.is_multiple_of(2);
        }
        let mut count = 0;
        for (t, triangle) in self.triangles.iter_mut().enumerate() {
            if reversed[t] != flip_piece[piece[t]] {
                triangle.swap(1, 2);
                count += 1;
            }
        }
        Ok(count)
    }

    /// Volume enclosed by the surface (m³), by the divergence theorem: positive for a closed
    /// surface with outward normals, negative if its normals point inward. For an open
    /// surface the value depends on the origin and means nothing.
    pub fn enclosed_volume(&self) -> f64 {
        enclosed_volume(&self.vertices, &self.triangles)
    }
}

impl SurfaceError {
    /// The error for an unusable surface read from `path`; `location` says where in the file
    /// the problem is (or returns an empty string).
    fn invalid(
        path: &Path,
        problem: InvalidSurface,
        location: impl Fn(&InvalidSurface) -> String,
    ) -> Self {
        SurfaceError::Invalid {
            path: path.to_path_buf(),
            location: location(&problem),
            problem: Box::new(problem),
        }
    }
}

/// The checked surface of an STL or PLY file's geometry (triangles numbered in the file's face
/// order, polygons split).
fn read_indexed(
    path: &Path,
    format: &'static str,
    read: Result<Geometry, ReadFailure>,
) -> Result<TriSurface, SurfaceError> {
    let (vertices, triangles) = read.map_err(|failure| match failure {
        ReadFailure::Io(source) => SurfaceError::Io {
            path: path.to_path_buf(),
            source,
        },
        ReadFailure::Format(message) => SurfaceError::Format {
            path: path.to_path_buf(),
            format,
            message,
        },
    })?;
    TriSurface::new(vertices, triangles)
        .map_err(|problem| SurfaceError::invalid(path, problem, |_| String::new()))
}

// ---------------------------------------------------------------------------------------
// Gmsh

fn read_gmsh(path: &Path, scale: f64) -> Result<TriSurface, SurfaceError> {
    let (nodes, triangles) = gmsh::read_msh_triangles(path).map_err(|error| match error {
        GmshError::Io { path, source } => SurfaceError::Io { path, source },
        other => SurfaceError::Gmsh(other),
    })?;
    let vertices = nodes.iter().map(|&p| Vector3::from(p) * scale).collect();
    TriSurface::new(vertices, triangles).map_err(|problem| {
        SurfaceError::invalid(path, problem, |problem| match problem {
            InvalidSurface::NonFinite { .. } => " (vertices are numbered from 0 in ascending \
                node tag order, among the nodes of triangles)"
                .to_string(),
            InvalidSurface::BadIndex { .. }
            | InvalidSurface::Degenerate { .. }
            | InvalidSurface::NotOrientable { .. } => {
                " (triangles are numbered from 0 in the file's order of its triangle \
                elements, type 2)"
                    .to_string()
            }
            InvalidSurface::NoTriangles { .. } => String::new(),
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("solver_tests/data/surface")
            .join(name)
    }

    /// Writes `content` to `name` in a new temp dir; returns the dir (keep it alive) and path.
    fn write(name: &str, content: &[u8]) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, content).unwrap();
        (dir, path)
    }

    /// Reads `content` as file `name` and returns the error message, checking it names the
    /// file.
    fn error_of(name: &str, content: &str) -> (SurfaceError, String) {
        let (_dir, path) = write(name, content.as_bytes());
        let error = TriSurface::read(&path, 1.0).unwrap_err();
        let message = error.to_string();
        assert!(
            message.contains(&path.display().to_string()),
            "{message:?} does not name {}",
            path.display()
        );
        (error, message)
    }

    /// The problem of an [`SurfaceError::Invalid`].
    fn problem(error: &SurfaceError) -> Option<&InvalidSurface> {
        match error {
            SurfaceError::Invalid { problem, .. } => Some(problem),
            _ => None,
        }
    }

    fn assert_outward(surface: &TriSurface, centre: Vector3<f64>) {
        for t in &surface.triangles {
            let [a, b, c] = t.map(|v| surface.vertices[v]);
            let normal = (b - a).cross(&(c - a));
            assert!(normal.dot(&((a + b + c) / 3.0 - centre)) > 0.0, "{t:?}");
        }
    }

    #[test]
    fn obj_cube_of_quads_is_12_outward_triangles_enclosing_scale_cubed() {
        // Two groups, an object, normals, a relative face, a polyline, a missing mtllib.
        for scale in [1.0, 0.5, 3.0] {
            let surface = TriSurface::read(&fixture("unit_cube_quads.obj"), scale).unwrap();
            assert_eq!(surface.triangles.len(), 12);
            // Vertices shared by the two groups stay shared.
            assert_eq!(surface.vertices.len(), 8);
            let volume = surface.enclosed_volume();
            assert!(
                (volume - scale.powi(3)).abs() < 1e-12 * scale.powi(3),
                "{volume}"
            );
            assert_outward(&surface, Vector3::repeat(0.5 * scale));
            let (lo, hi) = surface.bounding_box();
            assert_eq!((lo, hi), (Vector3::zeros(), Vector3::repeat(scale)));
        }
    }

    #[test]
    fn obj_extension_is_case_insensitive_and_polygons_are_fans() {
        // A regular hexagon (one polygon face) in the plane z = 0, normal +z.
        let mut content = String::new();
        for k in 0..6 {
            let angle = std::f64::consts::PI / 3.0 * k as f64;
            content += &format!("v {} {} 0\n", angle.cos(), angle.sin());
        }
        content += "f 1 2 3 4 5 6\n";
        let (_dir, path) = write("hexagon.OBJ", content.as_bytes());
        let surface = TriSurface::read(&path, 2.0).unwrap();
        assert_eq!(surface.triangles.len(), 4);
        let area: f64 = (0..4).map(|t| surface.triangle_area(t)).sum();
        let expected = 1.5 * 3f64.sqrt() * 4.0; // (3√3/2) r², r = 2
        assert!((area - expected).abs() < 1e-12, "{area}");
        for t in &surface.triangles {
            let [a, b, c] = t.map(|v| surface.vertices[v]);
            assert!((b - a).cross(&(c - a)).z > 0.0);
        }
    }

    #[test]
    fn gmsh_squares_in_2_2_and_4_1_read_alike() {
        for name in ["square_v22_ascii.msh", "square_v41_ascii.msh"] {
            let surface = TriSurface::read(&fixture(name), 2.0).unwrap();
            // The point, line and tet elements and the unused node are dropped.
            let expected: Vec<Vector3<f64>> = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
                .iter()
                .map(|&[x, y]| Vector3::new(x, y, 0.5) * 2.0)
                .collect();
            assert_eq!(surface.vertices, expected, "{name}");
            assert_eq!(surface.triangles, [[0, 1, 2], [0, 2, 3]], "{name}");
            assert_eq!(surface.triangle_area(0) + surface.triangle_area(1), 4.0);
            for t in &surface.triangles {
                let [a, b, c] = t.map(|v| surface.vertices[v]);
                assert!((b - a).cross(&(c - a)).z > 0.0, "{name}: normal not +z");
            }
        }
    }

    #[test]
    fn missing_files_are_io_errors_naming_them() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["nope.obj", "nope.msh"] {
            let path = dir.path().join(name);
            let error = TriSurface::read(&path, 1.0).unwrap_err();
            assert!(matches!(error, SurfaceError::Io { .. }), "{error:?}");
            assert!(error.to_string().contains(&path.display().to_string()));
        }
    }

    #[test]
    fn unknown_extension_and_bad_scale() {
        let (error, message) = error_of("cube.step", "ISO-10303-21;\n");
        assert!(matches!(error, SurfaceError::UnknownExtension { .. }));
        assert!(
            [".obj", ".stl", ".ply", ".msh"]
                .iter()
                .all(|e| message.contains(e)),
            "{message}"
        );
        // An STL file that is not one names itself.
        let (error, _) = error_of("cube.stl", "solid cube\n");
        assert!(matches!(error, SurfaceError::Format { .. }), "{error:?}");
        let (_dir, path) = write("noext", b"v 0 0 0\n");
        assert!(matches!(
            TriSurface::read(&path, 1.0),
            Err(SurfaceError::UnknownExtension { .. })
        ));
        let cube = fixture("unit_cube_quads.obj");
        for scale in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let error = TriSurface::read(&cube, scale).unwrap_err();
            assert!(matches!(error, SurfaceError::BadScale { .. }), "{scale}");
            assert!(error.to_string().contains("unit_cube_quads.obj"));
        }
    }

    #[test]
    fn obj_without_faces() {
        for content in ["", "# nothing\n", "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\n"] {
            let (error, message) = error_of("empty.obj", content);
            assert!(matches!(error, SurfaceError::NoFaces { .. }), "{message}");
            assert!(message.contains("has no faces"), "{message}");
        }
    }

    #[test]
    fn obj_index_out_of_range_names_the_line() {
        let base = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        for (face, needle) in [
            ("f 1 2 4", "vertex index 4 is out of range"),
            ("f 1 2 0", "vertex index 0 is out of range"),
            ("f -1 -2 -4", "vertex index -4 is out of range"),
            ("f 1 x/2 3", "bad face corner 'x/2'"),
            ("f 1/1 2/x 3", "bad face"), // found by tobj, located by LineCounter
            ("f 1 2", "at least 3 corners"),
        ] {
            let (error, message) = error_of("bad.obj", &format!("{base}# the face\n{face}\n"));
            assert!(
                matches!(error, SurfaceError::ObjLine { line: 5, .. }),
                "{face}: {message}"
            );
            assert!(message.contains(needle), "{face}: {message}");
        }
        // tobj's own errors carry the line too.
        let (error, message) = error_of("bad.obj", "v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n");
        assert!(
            matches!(error, SurfaceError::ObjLine { line: 2, .. }),
            "{message}"
        );
        assert!(message.contains("bad vertex"), "{message}");
    }

    #[test]
    fn obj_non_finite_coordinate_names_the_line() {
        for value in ["nan", "NaN", "inf", "-infinity"] {
            let content = format!("v 0 0 0\nv 1 0 0\nv 0 {value} 0\nf 1 2 3\n");
            let (error, message) = error_of("nan.obj", &content);
            assert!(
                matches!(error, SurfaceError::ObjLine { line: 3, .. }),
                "{message}"
            );
            assert!(message.contains("not finite"), "{message}");
        }
    }

    #[test]
    fn obj_degenerate_triangle_names_its_face() {
        // Collinear corners, and a repeated vertex.
        for (faces, line) in [
            ("f 1 2 3\nf 1 2 4\n", 6),
            ("f 1 2 3\nf 1 1 2\n", 6),
            ("f 1 2 4 3\n", 5),
        ] {
            let content = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n{faces}");
            let (error, message) = error_of("flat.obj", &content);
            assert!(
                matches!(problem(&error), Some(InvalidSurface::Degenerate { .. })),
                "{message}"
            );
            assert!(message.contains("degenerate"), "{message}");
            assert!(message.contains(&format!("line {line}")), "{message}");
        }
    }

    #[test]
    fn obj_ignores_what_an_obstacle_does_not_need() {
        // Bad texture/normal data, unknown statements and non-UTF-8 comments are not geometry.
        let mut content = b"# caf\xe9\nmtllib nowhere.mtl\nvt 0 x\nvn\ncstype bezier\n".to_vec();
        content
            .extend(b"v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\ng side\r\nusemtl none\r\nf 1/7 2/8 3/9\r\n");
        let (_dir, path) = write("extras.obj", &content);
        let surface = TriSurface::read(&path, 1.0).unwrap();
        assert_eq!(surface.triangles, [[0, 1, 2]]);
    }

    #[test]
    fn gmsh_errors_name_the_file() {
        let v22 = std::fs::read_to_string(fixture("square_v22_ascii.msh")).unwrap();
        // No triangles: drop both.
        let no_triangles = v22
            .replace("$Elements\n5\n", "$Elements\n3\n")
            .replace("3 2 2 1 1 1 2 3\n", "")
            .replace("4 2 2 1 1 1 3 4\n", "");
        let (error, message) = error_of("none.msh", &no_triangles);
        assert!(matches!(error, SurfaceError::Gmsh(_)), "{message}");
        assert!(
            message.contains("has no triangles (Gmsh element type 2)"),
            "{message}"
        );
        // Second-order triangle, quadrangle.
        let second = v22.replace("4 2 2 1 1 1 3 4\n", "4 9 2 1 1 1 3 4 5 5 5\n");
        let (_, message) = error_of("p2.msh", &second);
        assert!(message.contains("higher-order triangle"), "{message}");
        assert!(message.contains("element 4"), "{message}");
        let quad = v22.replace("4 2 2 1 1 1 3 4\n", "4 3 2 1 1 1 2 3 4\n");
        let (_, message) = error_of("quad.msh", &quad);
        assert!(message.contains("quadrangle"), "{message}");
        // A collinear triangle.
        let flat = v22.replace("4 2 2 1 1 1 3 4\n", "4 2 2 1 1 1 2 9\n");
        let flat = flat.replace("9 7 7 7", "9 2 0 0.5");
        let (error, message) = error_of("flat.msh", &flat);
        assert!(
            matches!(
                problem(&error),
                Some(InvalidSurface::Degenerate { triangle: 1, .. })
            ),
            "{message}"
        );
        assert!(message.contains("triangle elements, type 2"), "{message}");
        // NaN coordinate.
        let nan = v22.replace("3 1 1 0.5", "3 nan 1 0.5");
        let (error, message) = error_of("nan.msh", &nan);
        assert!(
            matches!(
                problem(&error),
                Some(InvalidSurface::NonFinite { vertex: 2, .. })
            ),
            "{message}"
        );
        // Not a Gmsh file at all.
        let (_, message) = error_of("text.msh", "hello\n");
        assert!(message.contains("not a Gmsh mesh file"), "{message}");
    }

    #[test]
    fn check_catches_each_problem() {
        let v = |x: f64, y: f64| Vector3::new(x, y, 0.0);
        let square = vec![v(0.0, 0.0), v(1.0, 0.0), v(1.0, 1.0), v(0.0, 1.0)];
        assert!(TriSurface::new(square.clone(), vec![[0, 1, 2], [0, 2, 3]]).is_ok());
        // An unused vertex is fine.
        assert!(TriSurface::new(square.clone(), vec![[0, 1, 2]]).is_ok());
        assert_eq!(
            TriSurface::new(square.clone(), vec![]).unwrap_err(),
            InvalidSurface::NoTriangles { vertices: 4 }
        );
        assert!(matches!(
            TriSurface::new(square.clone(), vec![[0, 1, 4]]).unwrap_err(),
            InvalidSurface::BadIndex {
                triangle: 0,
                vertex: 4,
                vertices: 4
            }
        ));
        let mut nan = square.clone();
        nan[3].y = f64::NAN;
        assert!(matches!(
            TriSurface::new(nan, vec![[0, 1, 2]]).unwrap_err(),
            InvalidSurface::NonFinite { vertex: 3, .. }
        ));
        // Degenerate relative to the size: a sliver of height 1e-7 in a 1 m box passes
        // (area 5e-8 > 1e-12 × 2), one of height 1e-13 does not.
        let mut sliver = square.clone();
        sliver[2] = v(0.5, 1e-7);
        assert!(TriSurface::new(sliver.clone(), vec![[0, 1, 2], [0, 1, 3]]).is_ok());
        sliver[2] = v(0.5, 1e-13);
        let error = TriSurface::new(sliver, vec![[0, 1, 3], [0, 1, 2]]).unwrap_err();
        assert!(
            matches!(error, InvalidSurface::Degenerate { triangle: 1, .. }),
            "{error}"
        );
        // The same shapes scaled down to micrometres are judged alike.
        let tiny: Vec<_> = square.iter().map(|p| p * 1e-6).collect();
        assert!(TriSurface::new(tiny, vec![[0, 1, 2], [0, 2, 3]]).is_ok());
    }
}

/// The closed surface of the box [lo, hi]³ (two triangles a face, outward), its vertices
/// numbered from `offset`: a test fixture.
#[cfg(test)]
pub(crate) fn box_surface(lo: f64, hi: f64, offset: usize) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>) {
    let vertices = (0..8)
        .map(|i| {
            let c = |bit: usize| if i & bit == 0 { lo } else { hi };
            Vector3::new(c(1), c(2), c(4))
        })
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .map(|t| t.map(|v| v + offset))
        .collect();
    (vertices, triangles)
}

#[cfg(test)]
mod orientation_tests {
    use super::*;

    /// Whether every edge is run in opposite directions by its two triangles.
    fn consistent(triangles: &[[usize; 3]]) -> bool {
        let mut directed = std::collections::HashSet::new();
        triangles
            .iter()
            .flat_map(|t| (0..3).map(move |k| (t[k], t[(k + 1) % 3])))
            .all(|edge| directed.insert(edge))
    }

    #[test]
    fn a_box_with_reversed_triangles_is_turned_outward() {
        let (vertices, mut triangles) = box_surface(0.0, 1.0, 0);
        for t in [1, 4, 5, 9] {
            triangles[t].swap(1, 2);
        }
        let mut surface = TriSurface::new(vertices, triangles).unwrap();
        assert!(!consistent(&surface.triangles));
        assert_eq!(surface.orient_outward().unwrap(), 4);
        assert!(consistent(&surface.triangles));
        assert!((surface.enclosed_volume() - 1.0).abs() < 1e-15);
        // All of them reversed: all turned back.
        for t in &mut surface.triangles {
            t.swap(1, 2);
        }
        assert_eq!(surface.orient_outward().unwrap(), 12);
        assert!((surface.enclosed_volume() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn the_inner_wall_of_a_hollow_box_faces_its_cavity() {
        // Outer box [0, 3]³ and inner box [1, 2]³, both written outward.
        let (mut vertices, mut triangles) = box_surface(0.0, 3.0, 0);
        let (inner_vertices, inner_triangles) = box_surface(1.0, 2.0, 8);
        vertices.extend(inner_vertices);
        triangles.extend(inner_triangles);
        let mut surface = TriSurface::new(vertices, triangles).unwrap();
        assert_eq!(surface.orient_outward().unwrap(), 12);
        assert!((surface.enclosed_volume() - 26.0).abs() < 1e-13);
        // Inside the wall, in the cavity, outside.
        let w = |x: f64| surface.winding_number(&Vector3::new(x, 1.5, 1.5));
        assert!((w(0.5) - 1.0).abs() < 1e-12 && w(1.5).abs() < 1e-12 && w(3.5).abs() < 1e-12);
    }

    #[test]
    fn the_winding_number_does_not_depend_on_the_orientation() {
        let (vertices, triangles) = box_surface(0.0, 1.0, 0);
        let mut surface = TriSurface::new(vertices, triangles).unwrap();
        let (inside, outside) = (Vector3::new(0.3, 0.6, 0.2), Vector3::new(1.3, 0.6, 0.2));
        assert!((surface.winding_number(&inside) - 1.0).abs() < 1e-12);
        assert!(surface.winding_number(&outside).abs() < 1e-12);
        for t in &mut surface.triangles {
            t.swap(1, 2);
        }
        assert!((surface.winding_number(&inside) + 1.0).abs() < 1e-12);
        assert!(surface.winding_number(&outside).abs() < 1e-12);
    }

    #[test]
    fn a_one_sided_closed_surface_is_refused_and_an_open_one_kept() {
        // The six-vertex projective plane: every edge in two triangles, no orientation.
        let projective_plane = [
            [0, 1, 2],
            [0, 2, 3],
            [0, 3, 4],
            [0, 4, 5],
            [0, 5, 1],
            [1, 2, 4],
            [2, 3, 5],
            [3, 4, 1],
            [4, 5, 2],
            [5, 1, 3],
        ];
        let vertices = (0..6)
            .map(|i| {
                let a = i as f64;
                Vector3::new(a.cos(), a.sin(), (2.0 * a).sin() + 0.1 * a)
            })
            .collect();
        let mut surface = TriSurface::new(vertices, projective_plane.to_vec()).unwrap();
        assert!(surface.is_closed());
        let error = surface.orient_outward().unwrap_err();
        assert!(
            matches!(error, InvalidSurface::NotOrientable { .. }),
            "{error}"
        );
        // One face of a box, reversed, is open and kept as written.
        let (vertices, triangles) = box_surface(0.0, 1.0, 0);
        let mut open = TriSurface::new(vertices, vec![triangles[0], [0, 3, 2]]).unwrap();
        let before = open.triangles.clone();
        assert_eq!(open.orient_outward().unwrap(), 0);
        assert_eq!(open.triangles, before);
    }
}

#[cfg(test)]
mod format_tests {
    use super::*;

    #[test]
    fn stl_and_ply_surfaces_read_closed_and_bad_files_name_themselves() {
        let dir = tempfile::tempdir().unwrap();
        // A tetrahedron in ASCII STL: each triangle lists its corners again; equal corners
        // become one vertex, so the surface reads closed.
        let corners = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let faces = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
        let mut stl = String::from("solid t\n");
        for f in faces {
            stl += "facet normal 0 0 0\nouter loop\n";
            for v in f {
                let p = corners[v];
                stl += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
            }
            stl += "endloop\nendfacet\n";
        }
        stl += "endsolid t\n";
        let path = dir.path().join("t.STL");
        std::fs::write(&path, stl).unwrap();
        let surface = TriSurface::read(&path, 2.0).unwrap();
        assert_eq!((surface.vertices.len(), surface.triangles.len()), (4, 4));
        assert!(surface.is_closed());
        assert!((surface.enclosed_volume() - 8.0 / 6.0).abs() < 1e-12);
        // A PLY file whose faces have no index list.
        let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty float area\nend_header\n0 0 0\n1 0 0\n0 1 0\n0.5\n";
        let path = dir.path().join("bad.ply");
        std::fs::write(&path, ply).unwrap();
        let message = TriSurface::read(&path, 1.0).unwrap_err().to_string();
        assert!(
            message.contains("PLY file")
                && message.contains("bad.ply")
                && message.contains("vertex_indices"),
            "{message}"
        );
    }
}
