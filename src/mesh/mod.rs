//! Tetrahedral meshes: the rest configuration, generators, Gmsh input, topology queries and
//! quality checks.
//!
//! All coordinates are in metres. Tets are 0-based and positively oriented:
//! `det[x1 − x0, x2 − x0, x3 − x0] > 0`.

pub mod generate;
pub mod gmsh;
pub mod orientation;
pub mod parts;
pub mod surface;
mod surface_formats;
pub mod tetrahedralise;

pub use generate::{box_mesh, BoxGrid};
pub use parts::{parts, parts_of};

use nalgebra::{Matrix3, Vector3};

/// Errors found while building or checking a mesh.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The mesh has no nodes or no tetrahedra.
    #[error("mesh is empty ({nodes} nodes, {tets} tetrahedra)")]
    Empty { nodes: usize, tets: usize },
    /// A tet refers to a node that does not exist.
    #[error("tetrahedron {tet} refers to node {node}, but the mesh has only {nodes} nodes")]
    BadIndex {
        tet: usize,
        node: usize,
        nodes: usize,
    },
    /// A node coordinate is NaN or infinite.
    #[error("node {node} has a non-finite coordinate {position:?}")]
    NonFinite { node: usize, position: [f64; 3] },
    /// A tet has (near) zero volume or repeated vertices.
    #[error("tetrahedron {tet} is degenerate (volume {volume:e} m³, vertices {vertices:?})")]
    Degenerate {
        tet: usize,
        volume: f64,
        vertices: [usize; 4],
    },
    /// A tet is inverted (negative signed volume).
    #[error("tetrahedron {tet} is inverted (signed volume {volume:e} m³, vertices {vertices:?}); swap two vertices")]
    Inverted {
        tet: usize,
        volume: f64,
        vertices: [usize; 4],
    },
    /// A node is not used by any tet (it would have no mass and no stiffness).
    #[error("node {node} belongs to no tetrahedron")]
    Orphan { node: usize },
    /// Generator arguments out of range.
    #[error("invalid mesh generator input: {0}")]
    Generator(String),
    /// An error in a mesh file, told by the file's own node and element tags.
    #[error("{0}")]
    InFile(String),
}

impl MeshError {
    /// The error told by a file's tags: `nodes[i]` is node i's tag, `elements[t]` tet t's
    /// (Gmsh numbers both from 1, and not necessarily contiguously).
    pub fn in_file(self, nodes: &[u64], elements: &[u64]) -> MeshError {
        let node = |i: usize| nodes.get(i).map_or(i as u64, |&t| t);
        let element = |t: usize| elements.get(t).map_or(t as u64, |&t| t);
        let message = match &self {
            MeshError::Degenerate {
                tet,
                volume,
                vertices,
            } => format!(
                "element {} is degenerate (volume {volume:e} m³, nodes {:?})",
                element(*tet),
                vertices.map(node)
            ),
            MeshError::Inverted {
                tet,
                volume,
                vertices,
            } => format!(
                "element {} is inverted (signed volume {volume:e} m³, nodes {:?})",
                element(*tet),
                vertices.map(node)
            ),
            MeshError::NonFinite { node: i, position } => {
                format!("node {} has a non-finite coordinate {position:?}", node(*i))
            }
            _ => return self,
        };
        MeshError::InFile(message)
    }
}

/// Makes every tet of `tets` positively oriented over the positions `rest` (m) by swapping
/// its vertices 1 and 2 where its signed volume is negative; returns how many were swapped.
/// Tets of zero volume are left as they are (for [`TetMesh::new`] to refuse as degenerate).
/// Generators differ in the orientation they write: half of scikit-fem's tets are negative.
pub fn reorient(rest: &[[f64; 3]], tets: &mut [[usize; 4]]) -> usize {
    let mut swapped = 0;
    for tet in tets.iter_mut() {
        let Some(p) = tet
            .iter()
            .map(|&v| rest.get(v).map(|x| Vector3::from(*x)))
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        if (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0])) < 0.0 {
            tet.swap(1, 2);
            swapped += 1;
        }
    }
    swapped
}

/// A tetrahedral mesh in its rest configuration.
#[derive(Clone, Debug)]
pub struct TetMesh {
    /// Rest positions of the nodes (m).
    pub rest: Vec<Vector3<f64>>,
    /// Node indices of each tetrahedron, 0-based, positively oriented.
    pub tets: Vec<[usize; 4]>,
}

/// The four faces of a tet, each ordered so that its normal (right-hand rule) points out of a
/// positively oriented tet.
pub const TET_FACES: [[usize; 3]; 4] = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];

impl TetMesh {
    /// Builds a mesh and checks it: indices in range, finite coordinates, every node used,
    /// every tet positively oriented with a volume above `1e-12 ×` the mean tet volume.
    pub fn new(rest: Vec<Vector3<f64>>, tets: Vec<[usize; 4]>) -> Result<Self, MeshError> {
        let mesh = TetMesh { rest, tets };
        mesh.check()?;
        Ok(mesh)
    }

    /// Builds a mesh that may have nodes no tet uses, and checks it otherwise as
    /// [`TetMesh::new`] does: a process's part of a split mesh, which can keep a node whose
    /// elements it holds a split moved to the node's copy (for its faces and pieces; no model
    /// is built on it).
    pub fn with_unused_nodes(
        rest: Vec<Vector3<f64>>,
        tets: Vec<[usize; 4]>,
    ) -> Result<Self, MeshError> {
        let mesh = TetMesh { rest, tets };
        mesh.check_elements(true)?;
        Ok(mesh)
    }

    /// Builds a mesh from plain arrays (see [`TetMesh::new`]).
    pub fn from_arrays(rest: &[[f64; 3]], tets: Vec<[usize; 4]>) -> Result<Self, MeshError> {
        Self::new(rest.iter().map(|p| Vector3::from(*p)).collect(), tets)
    }

    /// The meshes side by side as one mesh of several parts (nodes renumbered, not merged).
    pub fn concat(parts: Vec<TetMesh>) -> Result<Self, MeshError> {
        let mut rest = Vec::new();
        let mut tets = Vec::new();
        for part in parts {
            let offset = rest.len();
            tets.extend(part.tets.iter().map(|t| t.map(|v| v + offset)));
            rest.extend(part.rest);
        }
        TetMesh::new(rest, tets)
    }

    /// Number of nodes.
    pub fn num_nodes(&self) -> usize {
        self.rest.len()
    }

    /// Number of tetrahedra.
    pub fn num_tets(&self) -> usize {
        self.tets.len()
    }

    /// The edge matrix `[x1 − x0, x2 − x0, x3 − x0]` of tet `t` for the given positions.
    pub fn edge_matrix(positions: &[Vector3<f64>], tet: &[usize; 4]) -> Matrix3<f64> {
        let x0 = positions[tet[0]];
        Matrix3::from_columns(&[
            positions[tet[1]] - x0,
            positions[tet[2]] - x0,
            positions[tet[3]] - x0,
        ])
    }

    /// Mean edge length of the boundary triangles at rest (m): the size contact penalties
    /// are scaled by.
    pub fn mean_boundary_edge(&self) -> f64 {
        mean_edge(&self.perimeters(&self.boundary_faces()))
    }

    /// The rest perimeter of each of `faces` (m), its edges added in the face's node order.
    pub fn perimeters(&self, faces: &[BoundaryFace]) -> Vec<f64> {
        (faces.iter())
            .map(|f| {
                let [a, b, c] = f.nodes.map(|i| self.rest[i]);
                (b - a).norm() + (c - b).norm() + (a - c).norm()
            })
            .collect()
    }

    /// Each node's share of the rest area of the faces `faces` (m²): a third of each face's.
    pub fn area_shares(&self, faces: &[BoundaryFace]) -> Vec<f64> {
        let mut area = vec![0.0; self.num_nodes()];
        for f in faces {
            let [a, b, c] = f.nodes.map(|i| self.rest[i]);
            let share = 0.5 * (b - a).cross(&(c - a)).norm() / 3.0;
            f.nodes.iter().for_each(|&v| area[v] += share);
        }
        area
    }

    /// Signed rest volume of tet `t` (m³).
    pub fn signed_volume(&self, t: usize) -> f64 {
        Self::edge_matrix(&self.rest, &self.tets[t]).determinant() / 6.0
    }

    /// Total rest volume (m³).
    pub fn volume(&self) -> f64 {
        (0..self.num_tets()).map(|t| self.signed_volume(t)).sum()
    }

    /// Axis-aligned bounding box of the rest positions (min, max) in m.
    pub fn bounding_box(&self) -> (Vector3<f64>, Vector3<f64>) {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for p in &self.rest {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (lo, hi)
    }

    fn check(&self) -> Result<(), MeshError> {
        self.check_elements(false)
    }

    /// [`TetMesh::check`], nodes no tet uses let through if `unused_nodes`.
    fn check_elements(&self, unused_nodes: bool) -> Result<(), MeshError> {
        let n = self.num_nodes();
        if n == 0 || self.tets.is_empty() {
            return Err(MeshError::Empty {
                nodes: n,
                tets: self.tets.len(),
            });
        }
        for (i, p) in self.rest.iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(MeshError::NonFinite {
                    node: i,
                    position: [p.x, p.y, p.z],
                });
            }
        }
        let mut used = vec![false; n];
        for (t, tet) in self.tets.iter().enumerate() {
            for &v in tet {
                if v >= n {
                    return Err(MeshError::BadIndex {
                        tet: t,
                        node: v,
                        nodes: n,
                    });
                }
                used[v] = true;
            }
        }
        if let Some(node) = used.iter().position(|u| !u).filter(|_| !unused_nodes) {
            return Err(MeshError::Orphan { node });
        }
        // Degeneracy is judged against the mean element size so that the check is independent
        // of the unit scale of the mesh; 1e-12 admits aspect ratios far beyond 1e3.
        let (lo, hi) = self.bounding_box();
        let mean_volume = self.tets.len() as f64;
        let mean_volume = ((hi - lo)
            .iter()
            .map(|d| d.max(f64::MIN_POSITIVE))
            .product::<f64>()
            / mean_volume)
            .max(f64::MIN_POSITIVE);
        for (t, tet) in self.tets.iter().enumerate() {
            let volume = self.signed_volume(t);
            let repeated = (0..4).any(|a| (a + 1..4).any(|b| tet[a] == tet[b]));
            if repeated || volume.abs() <= 1e-12 * mean_volume {
                return Err(MeshError::Degenerate {
                    tet: t,
                    volume,
                    vertices: *tet,
                });
            }
            if volume < 0.0 {
                return Err(MeshError::Inverted {
                    tet: t,
                    volume,
                    vertices: *tet,
                });
            }
        }
        Ok(())
    }

    /// For each node, the tets that contain it and the local index (0..4) of the node in each,
    /// in compressed form: entries `offsets[i]..offsets[i + 1]` of `entries` belong to node i.
    pub fn node_to_tets(&self) -> NodeTets {
        let n = self.num_nodes();
        let mut offsets = vec![0usize; n + 1];
        for tet in &self.tets {
            for &v in tet {
                offsets[v + 1] += 1;
            }
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        let mut fill = offsets.clone();
        let mut entries = vec![(0u32, 0u8); offsets[n]];
        for (t, tet) in self.tets.iter().enumerate() {
            for (local, &v) in tet.iter().enumerate() {
                entries[fill[v]] = (t as u32, local as u8);
                fill[v] += 1;
            }
        }
        NodeTets { offsets, entries }
    }

    /// Boundary faces (faces that belong to exactly one tet), each oriented with its normal
    /// pointing out of the body, paired with the tet it belongs to. Sorted for determinism.
    pub fn boundary_faces(&self) -> Vec<BoundaryFace> {
        self.boundary_faces_of(&vec![true; self.tets.len()])
    }

    /// The boundary faces (as [`TetMesh::boundary_faces`]) of the part of the mesh made of
    /// the tets `t` with `keep[t]`: the mesh's boundary faces of kept tets, and the faces
    /// between a kept tet and one that is not (a cut through the mesh).
    pub fn boundary_faces_of(&self, keep: &[bool]) -> Vec<BoundaryFace> {
        // A face is another kept tet's too only if that tet holds the face's lowest node:
        // looking there needs the nodes' tets (8 bytes a tet's vertex), where sorting every
        // face of the mesh to pair them needed 20 bytes a face and more.
        let around = self.node_to_tets();
        let mut faces = Vec::new();
        for (t, tet) in self.tets.iter().enumerate().filter(|(t, _)| keep[*t]) {
            for f in TET_FACES {
                let nodes = f.map(|a| tet[a]);
                let lowest = nodes[0].min(nodes[1]).min(nodes[2]);
                let shared = around.of(lowest).iter().any(|&(other, _)| {
                    let other = other as usize;
                    other != t && keep[other] && nodes.iter().all(|v| self.tets[other].contains(v))
                });
                if !shared {
                    faces.push(BoundaryFace { nodes, tet: t });
                }
            }
        }
        faces.sort_unstable_by_key(|f| {
            let mut key = f.nodes;
            key.sort_unstable();
            key
        });
        faces
    }

    /// The boundary faces marked in `marks` (one per tet; bit `f` marks the face
    /// `TET_FACES[f]`), ordered as [`TetMesh::boundary_faces`]: the boundary of a whole mesh
    /// given its [`TetMesh::boundary_marks`], on a part of it that cannot tell the whole
    /// boundary from its cut.
    pub fn faces_marked(&self, marks: &[u8]) -> Vec<BoundaryFace> {
        let mut faces: Vec<BoundaryFace> = (self.tets.iter().zip(marks).enumerate())
            .flat_map(|(t, (tet, &m))| {
                (TET_FACES.iter().enumerate())
                    .filter(move |(f, _)| m & (1 << f) != 0)
                    .map(move |(_, face)| BoundaryFace {
                        nodes: face.map(|a| tet[a]),
                        tet: t,
                    })
            })
            .collect();
        faces.sort_unstable_by_key(|f| {
            let mut key = f.nodes;
            key.sort_unstable();
            key
        });
        faces
    }

    /// Which faces of each tet are on the boundary (bit `f`: `TET_FACES[f]`).
    pub fn boundary_marks(&self) -> Vec<u8> {
        let mut marks = vec![0u8; self.num_tets()];
        for face in self.boundary_faces() {
            let tet = self.tets[face.tet];
            let f = (TET_FACES.iter())
                .position(|s| s.map(|a| tet[a]) == face.nodes)
                .expect("a boundary face is one of its tet's faces");
            marks[face.tet] |= 1 << f;
        }
        marks
    }

    /// Quality of every tet: the ratio of the inscribed-sphere radius to the circumscribed one,
    /// scaled so a regular tet has quality 1 (degenerate → 0).
    pub fn quality(&self) -> Vec<f64> {
        self.tets
            .iter()
            .map(|tet| {
                radius_ratio([
                    self.rest[tet[0]],
                    self.rest[tet[1]],
                    self.rest[tet[2]],
                    self.rest[tet[3]],
                ])
            })
            .collect()
    }
}

/// Node → tet adjacency in compressed form (see [`TetMesh::node_to_tets`]).
#[derive(Clone, Debug)]
pub struct NodeTets {
    /// `offsets[i]..offsets[i + 1]` indexes the entries of node i.
    pub offsets: Vec<usize>,
    /// (tet index, local vertex index in that tet).
    pub entries: Vec<(u32, u8)>,
}

impl NodeTets {
    /// The (tet, local index) pairs of node `i`.
    pub fn of(&self, i: usize) -> &[(u32, u8)] {
        &self.entries[self.offsets[i]..self.offsets[i + 1]]
    }
}

/// A boundary triangle with outward orientation and its owning tet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundaryFace {
    /// Node indices, counter-clockwise seen from outside.
    pub nodes: [usize; 3],
    /// The tet this face belongs to.
    pub tet: usize,
}

/// The mean edge length of triangles of `perimeters` (m), added in their order: what
/// [`TetMesh::mean_boundary_edge`] gives for a mesh's boundary.
pub fn mean_edge(perimeters: &[f64]) -> f64 {
    perimeters.iter().sum::<f64>() / (3.0 * perimeters.len().max(1) as f64)
}

/// Normalised radius ratio 3 r_in / r_circ of a tet (1 for a regular tet, 0 when degenerate).
pub fn radius_ratio(x: [Vector3<f64>; 4]) -> f64 {
    let a = x[1] - x[0];
    let b = x[2] - x[0];
    let c = x[3] - x[0];
    let six_v = a.dot(&b.cross(&c)).abs();
    if six_v == 0.0 {
        return 0.0;
    }
    let area =
        |p: Vector3<f64>, q: Vector3<f64>, r: Vector3<f64>| 0.5 * (q - p).cross(&(r - p)).norm();
    let surface = area(x[0], x[1], x[2])
        + area(x[0], x[1], x[3])
        + area(x[0], x[2], x[3])
        + area(x[1], x[2], x[3]);
    let r_in = 0.5 * six_v / surface; // 3V / S
                                      // Circumradius: |a|²(b×c) + |b|²(c×a) + |c|²(a×b) over 2·(6V)... (standard formula).
    let num = a.norm_squared() * b.cross(&c)
        + b.norm_squared() * c.cross(&a)
        + c.norm_squared() * a.cross(&b);
    let r_circ = num.norm() / (2.0 * six_v);
    3.0 * r_in / r_circ
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_tet() -> TetMesh {
        TetMesh::from_arrays(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            vec![[0, 1, 2, 3]],
        )
        .unwrap()
    }

    #[test]
    fn inverted_tet_is_an_error_naming_it() {
        let err = TetMesh::from_arrays(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
            ],
            vec![[0, 2, 1, 3]],
        )
        .unwrap_err();
        assert!(matches!(err, MeshError::Inverted { tet: 0, .. }), "{err}");
    }

    #[test]
    fn the_boundary_marks_give_back_the_boundary_faces() {
        let mesh = box_mesh([0.0; 3], [1.0, 0.5, 0.5], [3, 2, 2], 6).unwrap();
        let marks = mesh.boundary_marks();
        // 2 triangles for each of the box's 2(3·2 + 3·2 + 2·2) cell faces.
        assert_eq!(marks.iter().map(|m| m.count_ones()).sum::<u32>(), 64);
        let (got, want) = (mesh.faces_marked(&marks), mesh.boundary_faces());
        assert_eq!(got.len(), want.len());
        for (a, b) in got.iter().zip(&want) {
            assert_eq!((a.nodes, a.tet), (b.nodes, b.tet));
        }
    }

    #[test]
    fn single_tet_has_four_outward_boundary_faces() {
        let mesh = unit_tet();
        let faces = mesh.boundary_faces();
        assert_eq!(faces.len(), 4);
        let centroid = Vector3::new(0.25, 0.25, 0.25);
        for f in faces {
            let [a, b, c] = f.nodes.map(|i| mesh.rest[i]);
            let normal = (b - a).cross(&(c - a));
            assert!(normal.dot(&((a + b + c) / 3.0 - centroid)) > 0.0);
        }
    }

    #[test]
    fn regular_tet_quality_is_one() {
        let s = 1.0 / 2f64.sqrt();
        let x = [
            Vector3::new(1.0, 0.0, -s),
            Vector3::new(-1.0, 0.0, -s),
            Vector3::new(0.0, 1.0, s),
            Vector3::new(0.0, -1.0, s),
        ];
        assert!((radius_ratio(x) - 1.0).abs() < 1e-12);
        assert!(unit_tet().quality()[0] < 1.0);
    }
}
