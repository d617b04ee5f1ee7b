//! Triangle surfaces from STL (ASCII or binary, by the `stl_io` crate) and PLY (ASCII or
//! binary, by the `ply-rs` crate) files: vertices and faces only. STL repeats a vertex in every
//! triangle that uses it; `stl_io` merges exactly equal ones, so that a closed STL surface reads
//! as closed. PLY polygons are split into fans from their first corner, as OBJ's.

use std::path::Path;

use nalgebra::Vector3;
use ply_rs::parser::Parser;
use ply_rs::ply::{DefaultElement, Property};

/// Vertices (times `scale`) and triangles of a surface file.
pub(super) type Geometry = (Vec<Vector3<f64>>, Vec<[usize; 3]>);

/// Why a file could not be read: the file system, or its content (what is wrong).
#[derive(Debug)]
pub(super) enum ReadFailure {
    Io(std::io::Error),
    Format(String),
}

/// Reads an STL file.
pub(super) fn read_stl(path: &Path, scale: f64) -> Result<Geometry, ReadFailure> {
    let mut file = std::fs::File::open(path).map_err(ReadFailure::Io)?;
    let mesh = stl_io::read_stl(&mut file).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound | std::io::ErrorKind::PermissionDenied => ReadFailure::Io(e),
        _ => ReadFailure::Format(e.to_string()),
    })?;
    let vertices = mesh
        .vertices
        .iter()
        .map(|v| Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64) * scale)
        .collect();
    let triangles = mesh.faces.iter().map(|f| f.vertices).collect();
    Ok((vertices, triangles))
}

/// Reads a PLY file: the `vertex` element's `x`, `y`, `z` and the `face` element's
/// `vertex_indices` (or `vertex_index`) lists.
pub(super) fn read_ply(path: &Path, scale: f64) -> Result<Geometry, ReadFailure> {
    let file = std::fs::File::open(path).map_err(ReadFailure::Io)?;
    let mut reader = std::io::BufReader::new(file);
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut reader)
        .map_err(|e| ReadFailure::Format(e.to_string()))?;
    let missing = |what: &str| ReadFailure::Format(format!("no {what}"));
    let elements = |name: &str| {
        ply.payload
            .get(name)
            .ok_or_else(|| missing(&format!("`{name}` element")))
    };
    let mut vertices = Vec::new();
    for (i, vertex) in elements("vertex")?.iter().enumerate() {
        let coordinate = |axis: &str| {
            vertex
                .get(axis)
                .and_then(number)
                .ok_or_else(|| ReadFailure::Format(format!("vertex {i} has no number `{axis}`")))
        };
        vertices.push(Vector3::new(coordinate("x")?, coordinate("y")?, coordinate("z")?) * scale);
    }
    let mut triangles = Vec::new();
    for (f, face) in elements("face")?.iter().enumerate() {
        let corners = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .and_then(indices)
            .ok_or_else(|| {
                ReadFailure::Format(format!("face {f} has no integer list `vertex_indices`"))
            })?;
        if corners.len() < 3 {
            return Err(ReadFailure::Format(format!(
                "face {f} has {} corners: a face needs at least 3",
                corners.len()
            )));
        }
        for k in 1..corners.len() - 1 {
            triangles.push([corners[0], corners[k], corners[k + 1]]);
        }
    }
    Ok((vertices, triangles))
}

/// A scalar property as a number.
fn number(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

/// An integer list property as vertex indices (negative indices are refused as none).
fn indices(p: &Property) -> Option<Vec<usize>> {
    fn all<T: Copy>(v: &[T], f: impl Fn(T) -> Option<usize>) -> Option<Vec<usize>> {
        v.iter().map(|&x| f(x)).collect()
    }
    match p {
        Property::ListChar(v) => all(v, |x| usize::try_from(x).ok()),
        Property::ListUChar(v) => all(v, |x| Some(x as usize)),
        Property::ListShort(v) => all(v, |x| usize::try_from(x).ok()),
        Property::ListUShort(v) => all(v, |x| Some(x as usize)),
        Property::ListInt(v) => all(v, |x| usize::try_from(x).ok()),
        Property::ListUInt(v) => all(v, |x| Some(x as usize)),
        _ => None,
    }
}
