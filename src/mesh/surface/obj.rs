//! Wavefront OBJ surfaces for [`super::TriSurface::read`].
//!
//! Only geometry is read from an OBJ file: its vertices (`v`) and faces (`f`). Objects,
//! groups, materials, polylines, texture coordinates and normals are dropped before tobj
//! sees the text (their lines are blanked, so line numbers stay those of the file). All
//! faces thus form one surface in which a vertex shared by two groups stays one vertex.
//! Quads and larger polygons are split into triangles as fans from their first corner,
//! which keeps their orientation and is exact for convex polygons.

use std::io::{BufRead, Read};
use std::path::Path;

use nalgebra::Vector3;

use super::{SurfaceError, TriSurface};

pub(super) fn read_obj(path: &Path, scale: f64) -> Result<TriSurface, SurfaceError> {
    let bytes = std::fs::read(path).map_err(|source| SurfaceError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let geometry = obj_geometry(&bytes).map_err(|(line, message)| SurfaceError::ObjLine {
        path: path.to_path_buf(),
        line,
        message,
    })?;

    let options = tobj::LoadOptions {
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let mut reader = LineCounter::new(&geometry.text);
    // Materials are of no use to an obstacle (and `mtllib` lines are blanked anyway).
    let loaded = tobj::load_obj_buf(&mut reader, &options, |_| Ok(Default::default()));
    let models = match loaded {
        Ok((models, _materials)) => models,
        Err(error) => return Err(tobj_error(path, error, reader.line())),
    };

    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for model in models {
        let mesh = model.mesh;
        let offset = vertices.len();
        vertices.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|p| Vector3::new(p[0], p[1], p[2]) * scale),
        );
        triangles.extend(
            mesh.indices
                .chunks_exact(3)
                .map(|t| [0, 1, 2].map(|k| offset + t[k] as usize)),
        );
    }
    if triangles.is_empty() {
        return Err(SurfaceError::NoFaces {
            path: path.to_path_buf(),
        });
    }
    // Faces become triangles in file order, n − 2 per face of n corners.
    let total: usize = geometry.faces.iter().map(|&(_, n)| n).sum();
    let traceable = total == triangles.len();
    TriSurface::new(vertices, triangles).map_err(|problem| {
        SurfaceError::invalid(path, problem, |problem| {
            let Some(triangle) = problem.triangle().filter(|_| traceable) else {
                return String::new();
            };
            let mut first = 0;
            for &(line, count) in &geometry.faces {
                if triangle < first + count {
                    return format!(" (triangle {triangle} comes from the face on line {line})");
                }
                first += count;
            }
            String::new()
        })
    })
}

/// The geometry of an OBJ file, as tobj is given it.
struct ObjGeometry {
    /// The file with only its `v` and `f` lines left; other lines are blank.
    text: Vec<u8>,
    /// (line, number of triangles) of each face, in file order.
    faces: Vec<(usize, usize)>,
}

/// The first word of an OBJ line (`v`, `f`, `#`, ...), if any.
fn keyword(line: &[u8]) -> Option<&[u8]> {
    line.split(u8::is_ascii_whitespace).find(|w| !w.is_empty())
}

/// Keeps only the `v` and `f` lines of an OBJ file and checks what tobj would report without
/// a line number (vertex indices out of range) or accept (non-finite coordinates, faces of
/// fewer than 3 corners). Errors are (line, message).
fn obj_geometry(bytes: &[u8]) -> Result<ObjGeometry, (usize, String)> {
    let total_vertices = bytes
        .split(|&b| b == b'\n')
        .filter(|line| keyword(line) == Some(b"v".as_slice()))
        .count();

    let mut text = Vec::with_capacity(bytes.len());
    let mut faces = Vec::new();
    let mut vertices = 0usize;
    for (k, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let number = k + 1;
        let at = |message: String| (number, message);
        let kind = keyword(line);
        if kind == Some(b"v".as_slice()) || kind == Some(b"f".as_slice()) {
            let line = std::str::from_utf8(line)
                .map_err(|_| at("the line is not valid UTF-8 text".to_string()))?;
            let words: Vec<&str> = line.split_whitespace().skip(1).collect();
            if kind == Some(b"v".as_slice()) {
                vertices += 1;
                check_obj_vertex(&words).map_err(at)?;
            } else {
                check_obj_face(&words, vertices, total_vertices).map_err(at)?;
                faces.push((number, words.len() - 2));
            }
            text.extend_from_slice(line.as_bytes());
        }
        text.push(b'\n');
    }
    Ok(ObjGeometry { text, faces })
}

/// A vertex line `v x y z [w | r g b]`: coordinates that parse must be finite (tobj reports
/// those that do not parse).
fn check_obj_vertex(words: &[&str]) -> Result<(), String> {
    for word in words.iter().take(3) {
        if let Ok(x) = word.parse::<f64>() {
            if !x.is_finite() {
                return Err(format!(
                    "vertex coordinate '{word}' is not finite: coordinates must be finite numbers"
                ));
            }
        }
    }
    Ok(())
}

/// A face line `f v1 v2 v3 ...`, each corner `v`, `v/vt`, `v//vn` or `v/vt/vn`: at least 3
/// corners, vertex indices from 1 to the number of vertices in the file, or negative
/// (relative: −1 is the last vertex defined above the line).
fn check_obj_face(words: &[&str], above: usize, total: usize) -> Result<(), String> {
    if words.len() < 3 {
        return Err(format!(
            "a face needs at least 3 corners, this one has {}",
            words.len()
        ));
    }
    let allowed = match above {
        0 => format!("allowed are 1 to {total} (the file's vertices)"),
        _ => format!(
            "allowed are 1 to {total} (the file's vertices) or -1 to -{above} (counting back \
             from the last vertex above this line)"
        ),
    };
    for word in words {
        let index = word.split('/').next().unwrap_or_default();
        let index: i64 = index.parse().map_err(|_| {
            format!(
                "bad face corner '{word}': expected v, v/vt, v//vn or v/vt/vn with integer indices"
            )
        })?;
        let valid = match index {
            i if i > 0 => i as u64 <= total as u64,
            i if i < 0 => i.unsigned_abs() <= above as u64,
            _ => false,
        };
        if !valid {
            return Err(format!(
                "face corner '{word}': vertex index {index} is out of range; {allowed}"
            ));
        }
    }
    Ok(())
}

/// A message for a tobj error. Those raised while reading a line get its number; the others
/// (raised when tobj assembles the faces at the end) do not.
fn tobj_error(path: &Path, error: tobj::LoadError, line: usize) -> SurfaceError {
    use tobj::LoadError as E;
    let (message, on_line) = match error {
        E::PositionParseError => (
            "bad vertex: expected `v x y z`, optionally followed by a weight w or a colour r g b"
                .to_string(),
            true,
        ),
        E::ScalingByZeroError => ("the vertex weight w is zero".to_string(), true),
        E::ColorParseError => (
            "bad vertex: after x y z, expected either a weight w or a colour r g b".to_string(),
            true,
        ),
        E::FaceParseError => (
            "bad face: expected corners v, v/vt, v//vn or v/vt/vn with integer indices".to_string(),
            true,
        ),
        E::FaceColorOutOfBounds => (
            "some vertices have a colour (`v x y z r g b`) and others do not: give all or none"
                .to_string(),
            false,
        ),
        other => (format!("cannot parse it: {other}"), false),
    };
    if on_line {
        SurfaceError::ObjLine {
            path: path.to_path_buf(),
            line,
            message,
        }
    } else {
        SurfaceError::Obj {
            path: path.to_path_buf(),
            message,
        }
    }
}

/// A reader over bytes that knows which line it last handed out, so that a tobj parse
/// error, raised on the line just read, can name that line.
struct LineCounter<'a> {
    rest: &'a [u8],
    /// Newlines consumed so far.
    newlines: usize,
    /// Whether the last byte consumed was a newline (or nothing was consumed).
    at_line_start: bool,
}

impl<'a> LineCounter<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        LineCounter {
            rest: bytes,
            newlines: 0,
            at_line_start: true,
        }
    }

    /// Number (from 1) of the line last read, in full or in part.
    fn line(&self) -> usize {
        self.newlines + usize::from(!self.at_line_start)
    }
}

impl Read for LineCounter<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = buf.len().min(self.rest.len());
        buf[..n].copy_from_slice(&self.rest[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for LineCounter<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(self.rest)
    }

    fn consume(&mut self, amount: usize) {
        let (taken, rest) = self.rest.split_at(amount.min(self.rest.len()));
        self.newlines += taken.iter().filter(|&&b| b == b'\n').count();
        if let Some(&last) = taken.last() {
            self.at_line_start = last == b'\n';
        }
        self.rest = rest;
    }
}
