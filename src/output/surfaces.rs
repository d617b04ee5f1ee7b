//! The surfaces of a stored frame, for `render` and `export`: the ice's outer surface (the
//! boundary faces of the frame's tets that are not crack faces) and its crack faces.
//!
//! Crack faces are told from outer faces by the scene mesh's boundary
//! ([`OriginalBoundary`]): in a fracture run (frames with `origin`) a boundary face of the
//! current mesh is a crack face when it does not lie on the boundary of the scene element its
//! element came from.

use std::collections::HashSet;
use std::path::Path;

use super::{corrupt, FrameReader, OutputError, StoredFrame};
use crate::fracture::cracks::{crack_faces, CrackFace, OriginalBoundary};
use crate::mesh::{BoundaryFace, TetMesh};

/// Finds the surfaces of a run's frames: holds the scene mesh's boundary in a fracture run.
#[derive(Clone, Debug)]
pub struct SurfaceExtractor {
    original: Option<OriginalBoundary>,
}

/// One frame's mesh at rest, with what its surfaces need.
#[derive(Clone, Debug)]
pub struct FrameMesh<'a> {
    /// The frame's rest positions (m) and tets.
    pub rest: TetMesh,
    /// Each element's scene element (fracture runs; `None` otherwise).
    pub origin: Option<Vec<usize>>,
    original: Option<&'a OriginalBoundary>,
}

impl SurfaceExtractor {
    /// For the frames of `reader`, whose first complete frame is `first`: reads the scene
    /// mesh (`/mesh`) when the run has fracture (`first` has `origin`).
    pub fn new(reader: &FrameReader, first: &StoredFrame) -> Result<Self, OutputError> {
        let original = match first.element_field("origin") {
            Some(_) => {
                let (rest, tets) = reader.initial_mesh()?;
                let mesh = TetMesh::from_arrays(&rest, tets)
                    .map_err(|e| corrupt(reader.path(), format!("/mesh: {e}")))?;
                Some(OriginalBoundary::new(&mesh))
            }
            None => None,
        };
        Ok(SurfaceExtractor { original })
    }

    /// The rest mesh of `frame` (of the file `path`) and, in a fracture run, each element's
    /// scene element, checked against the scene mesh.
    pub fn mesh(&self, path: &Path, frame: &StoredFrame) -> Result<FrameMesh<'_>, OutputError> {
        let state = &frame.state;
        let rest = TetMesh::from_arrays(&state.rest_positions, state.tets.clone())
            .map_err(|e| corrupt(path, format!("frame {}: {e}", frame.index)))?;
        let origin = match (&self.original, frame.element_field("origin")) {
            (Some(original), Some((1, o))) => {
                let valid =
                    |v: f64| v >= 0.0 && v.fract() == 0.0 && v < original.num_elements() as f64;
                if o.len() != state.tets.len() || !o.iter().all(|&v| valid(v)) {
                    return Err(corrupt(
                        path,
                        format!(
                            "frame {}: origin does not match the tets and the initial mesh",
                            frame.index
                        ),
                    ));
                }
                Some(o.iter().map(|&v| v as usize).collect())
            }
            _ => None,
        };
        Ok(FrameMesh {
            rest,
            origin,
            original: self.original.as_ref(),
        })
    }
}

impl FrameMesh<'_> {
    /// The outer faces of the part of the mesh made of the tets `t` with `keep[t]` (all tets
    /// when `keep` is `None`), outward, each with its tet: the part's boundary faces less the
    /// crack faces. Faces where the part was cut from the other tets count as outer.
    pub fn outer_faces(&self, keep: Option<&[bool]>) -> Vec<BoundaryFace> {
        let faces = match keep {
            Some(keep) => self.rest.boundary_faces_of(keep),
            None => self.rest.boundary_faces(),
        };
        // The whole mesh's boundary, to tell the faces along a cut (not on it).
        let mesh_boundary: Option<HashSet<[usize; 3]>> = keep.map(|_| {
            self.rest
                .boundary_faces()
                .iter()
                .map(|f| sorted(f.nodes))
                .collect()
        });
        faces
            .into_iter()
            .filter(|f| {
                let on_cut = mesh_boundary
                    .as_ref()
                    .is_some_and(|b| !b.contains(&sorted(f.nodes)));
                match (self.original, &self.origin) {
                    (Some(original), Some(origin)) if !on_cut => {
                        original.on_boundary(origin[f.tet], &f.nodes.map(|i| self.rest.rest[i]))
                    }
                    _ => true,
                }
            })
            .collect()
    }

    /// The crack faces (empty without fracture), in the order of the frame's `cracks/`
    /// triangles: the run wrote triangle k from face k, its vertices from the face's nodes.
    pub fn crack_faces(&self) -> Vec<CrackFace> {
        match (self.original, &self.origin) {
            (Some(original), Some(origin)) => crack_faces(&self.rest, origin, original),
            _ => Vec::new(),
        }
    }
}

fn sorted(mut face: [usize; 3]) -> [usize; 3] {
    face.sort_unstable();
    face
}
