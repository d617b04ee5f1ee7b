//! The crack surfaces of a fractured mesh, for output and counting.
//!
//! A crack face is a boundary face of the current mesh that does not lie on the boundary of
//! the scene's mesh. Every current element lies inside the scene element it came from (its
//! origin: splits only subdivide), so a boundary face of it lies on the original boundary
//! exactly when it is coplanar with one of its origin's faces that was a boundary face. This
//! holds however often a crack face has been subdivided since, which pairing the two sides of
//! a crack by their shared rest positions would not.
//!
//! Faces are grouped into cracks (connected components through shared edges, the two sides of
//! a crack being joined where the crack ends at shared edge nodes). For rendering, crack faces
//! that are closed or interpenetrate are drawn pulled back into their own element by half a
//! small gap each, so the two sides of a closed crack do not coincide (the paper's rendering
//! gap); an open crack is drawn where it is.

use crate::mesh::TetMesh;
use nalgebra::Vector3;
use petgraph::unionfind::UnionFind;
use std::collections::HashMap;

/// Boundary planes of the scene's mesh, per scene element.
#[derive(Clone, Debug)]
pub struct OriginalBoundary {
    /// The scene elements whose planes are kept (ascending; `None`: all, `planes` indexed by
    /// scene element).
    held: Option<Vec<usize>>,
    /// For each scene element kept, (point, unit outward normal) of its boundary faces.
    planes: Vec<Vec<(Vector3<f64>, Vector3<f64>)>>,
    /// Number of scene elements.
    scene_elements: usize,
    /// Length below which a rest distance counts as zero (m).
    tolerance: f64,
}

impl OriginalBoundary {
    /// Records the boundary of the scene's mesh.
    pub fn new(mesh: &TetMesh) -> Self {
        let (lo, hi) = mesh.bounding_box();
        let faces = mesh.boundary_faces();
        Self::of_faces(mesh, &faces, (None, mesh.num_tets()), (hi - lo).norm())
    }

    /// The boundary planes of a process's part of the scene's mesh: `mesh` is the part, whose
    /// element `k` is scene element `elements[k]` (ascending), `marks` its elements' faces on
    /// the scene mesh's boundary ([`TetMesh::faces_marked`]), in a scene mesh of
    /// `scene_elements` elements whose bounding box has the diagonal `diagonal` (m).
    pub fn of_part(
        mesh: &TetMesh,
        (elements, marks): (&[usize], &[u8]),
        scene_elements: usize,
        diagonal: f64,
    ) -> Self {
        let faces = mesh.faces_marked(marks);
        Self::of_faces(
            mesh,
            &faces,
            (Some(elements.to_vec()), scene_elements),
            diagonal,
        )
    }

    /// The planes of `faces` of `mesh`, whose elements are the scene elements `held` (all,
    /// by number, if `None`), in a scene mesh of `scene_elements` elements whose bounding box
    /// has the diagonal `diagonal`.
    fn of_faces(
        mesh: &TetMesh,
        faces: &[crate::mesh::BoundaryFace],
        (held, scene_elements): (Option<Vec<usize>>, usize),
        diagonal: f64,
    ) -> Self {
        let mut planes = vec![Vec::new(); mesh.num_tets()];
        for face in faces {
            let [a, b, c] = face.nodes.map(|i| mesh.rest[i]);
            let normal = (b - a).cross(&(c - a)).normalize();
            planes[face.tet].push((a, normal));
        }
        OriginalBoundary {
            held,
            planes,
            scene_elements,
            // Rest positions of split nodes are convex combinations of scene nodes: coplanar
            // points are off the plane by round-off only (1e-16 relative per operation).
            tolerance: 1e-9 * diagonal,
        }
    }

    /// Number of scene elements (the valid `origin` values are below it).
    pub fn num_elements(&self) -> usize {
        self.scene_elements
    }

    /// Whether the rest triangle `points` of an element lying in scene element `origin` is on
    /// the scene mesh's boundary (on a part: `origin` one of its scene elements).
    pub fn on_boundary(&self, origin: usize, points: &[Vector3<f64>; 3]) -> bool {
        let planes = match &self.held {
            None => &self.planes[origin],
            Some(held) => match held.binary_search(&origin) {
                Ok(k) => &self.planes[k],
                Err(_) => return false,
            },
        };
        planes.iter().any(|(p, n)| {
            points
                .iter()
                .all(|x| (x - p).dot(n).abs() <= self.tolerance)
        })
    }
}

/// One crack face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrackFace {
    /// Its nodes, ordered so the normal points out of its element.
    pub nodes: [usize; 3],
    /// The element it bounds.
    pub element: usize,
    /// Which crack (connected crack surface) it belongs to, 0-based.
    pub crack: usize,
}

/// The crack faces of `mesh`, whose element `e` came from scene element `origin[e]`.
pub fn crack_faces(
    mesh: &TetMesh,
    origin: &[usize],
    original: &OriginalBoundary,
) -> Vec<CrackFace> {
    let mut faces: Vec<CrackFace> = mesh
        .boundary_faces()
        .into_iter()
        .filter(|f| !original.on_boundary(origin[f.tet], &f.nodes.map(|i| mesh.rest[i])))
        .map(|f| CrackFace {
            nodes: f.nodes,
            element: f.tet,
            crack: 0,
        })
        .collect();
    // Cracks: components of faces sharing an edge, nodes identified by rest position (the two
    // copies of a split node coincide at rest).
    let mut canonical: HashMap<[u64; 3], usize> = HashMap::new();
    let mut key_of = |i: usize| {
        let x = mesh.rest[i];
        let key = [x.x.to_bits(), x.y.to_bits(), x.z.to_bits()];
        *canonical.entry(key).or_insert(i)
    };
    let mut union = UnionFind::<usize>::new(faces.len());
    let mut edge_owner: HashMap<(usize, usize), usize> = HashMap::new();
    for (k, face) in faces.iter().enumerate() {
        let c = face.nodes.map(&mut key_of);
        for j in 0..3 {
            let (a, b) = (c[j], c[(j + 1) % 3]);
            let owner = *edge_owner.entry((a.min(b), a.max(b))).or_insert(k);
            union.union(owner, k);
        }
    }
    let mut ids: HashMap<usize, usize> = HashMap::new();
    for (k, face) in faces.iter_mut().enumerate() {
        let root = union.find_mut(k);
        let next = ids.len();
        face.crack = *ids.entry(root).or_insert(next);
    }
    faces
}

/// Total area of the crack surfaces at rest (m²), one side: half the rest area of `faces`
/// (both sides of every crack) of a mesh with rest positions `rest`.
pub fn crack_area(faces: &[CrackFace], rest: &[Vector3<f64>]) -> f64 {
    let twice: f64 = faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.nodes.map(|i| rest[i]);
            (b - a).cross(&(c - a)).norm()
        })
        .sum();
    0.25 * twice
}

/// Number of crack polygons: the planar pieces of the crack surfaces inside one scene element
/// each, counted once for the two sides of a crack.
///
/// A split cuts the elements around a node with one plane, and later splits subdivide the
/// faces it made; so the crack faces of one side that lie in one scene element and in one
/// rest plane are one polygon (the paper's count of crack-surface polygons), however many
/// triangles it has become. The faces are grouped by scene element (`origin` of their
/// element), rest plane (unit normal and offset, to 1e-9 of the mesh size) and side (the
/// sign of their outward normal against the plane's): a crack through an element gives two
/// groups there, one per side, and a crack along a face between two scene elements one in
/// each; the count is half the number of groups, rounded up.
pub fn crack_polygons(faces: &[CrackFace], rest: &[Vector3<f64>], origin: &[usize]) -> usize {
    let scale = rest.iter().map(|x| x.amax()).fold(0.0, f64::max);
    polygon_sides(faces, rest, origin, scale).div_ceil(2)
}

/// The groups [`crack_polygons`] counts (one per polygon and side) among `faces` of a mesh
/// with rest positions `rest` and scene elements `origin`, whose largest rest coordinate
/// (in magnitude) is `scale` (m): the faces of a scene element's children are in its groups
/// only, so the processes holding parts of a mesh (each its own elements' faces, with the
/// whole mesh's `scale`) count the whole mesh's groups between them.
pub fn polygon_sides(
    faces: &[CrackFace],
    rest: &[Vector3<f64>],
    origin: &[usize],
    scale: f64,
) -> usize {
    if scale <= 0.0 {
        return 0;
    }
    let quantum = 1e-9;
    let mut groups = std::collections::HashSet::new();
    for f in faces {
        let [a, b, c] = f.nodes.map(|i| rest[i]);
        let cross = (b - a).cross(&(c - a));
        if cross.norm() == 0.0 {
            continue;
        }
        let outward = cross.normalize();
        // The plane's normal, signed so that its largest component is positive.
        let k = outward.iamax();
        let side = outward[k].signum();
        let n = outward * side;
        let round = |v: f64| (v / quantum).round() as i64;
        let key = (
            origin[f.element],
            [round(n.x), round(n.y), round(n.z)],
            round(n.dot(&a) / scale),
            side > 0.0,
        );
        groups.insert(key);
    }
    groups.len()
}

/// Crack polygons (see [`crack_polygons`]) of a stored mesh made by splitting the elements of
/// the scene mesh whose boundary is `original`: rest positions `rest` (m), `tets`, and each
/// element's scene element `origin`; 0 if the arrays do not form a valid mesh.
pub fn count_polygons(
    original: &OriginalBoundary,
    rest: &[[f64; 3]],
    tets: &[[usize; 4]],
    origin: &[usize],
) -> usize {
    match TetMesh::from_arrays(rest, tets.to_vec()) {
        Ok(mesh)
            if origin.len() == mesh.num_tets()
                && origin.iter().all(|&o| o < original.num_elements()) =>
        {
            crack_polygons(&crack_faces(&mesh, origin, original), &mesh.rest, origin)
        }
        _ => 0,
    }
}

/// Crack faces as triangles for rendering: three own vertices per face (m), displaced where
/// the crack is closed (see the module docs), and each triangle's crack.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CrackSurface {
    /// Vertex positions (m), three per triangle.
    pub vertices: Vec<[f64; 3]>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[usize; 3]>,
    /// Crack of each triangle.
    pub crack: Vec<usize>,
}

impl CrackSurface {
    /// Triangles of `faces` of a mesh with rest positions `rest` at the current `positions`
    /// (m); `gap` (m) is the smallest opening drawn between the two sides of a crack.
    pub fn new(
        faces: &[CrackFace],
        rest: &[Vector3<f64>],
        positions: &[Vector3<f64>],
        gap: f64,
    ) -> Self {
        // Copies of a split node share its rest position.
        let mut copies: HashMap<[u64; 3], Vec<usize>> = HashMap::new();
        for face in faces {
            for &i in &face.nodes {
                let x = rest[i];
                let list = copies
                    .entry([x.x.to_bits(), x.y.to_bits(), x.z.to_bits()])
                    .or_default();
                if !list.contains(&i) {
                    list.push(i);
                }
            }
        }
        let mut surface = CrackSurface::default();
        for face in faces {
            let [a, b, c] = face.nodes.map(|i| positions[i]);
            let cross = (b - a).cross(&(c - a));
            let normal = if cross.norm() > 0.0 {
                cross.normalize()
            } else {
                Vector3::zeros()
            };
            // Opening: how far the other side's copies of the face's nodes lie beyond it along
            // its outward normal (largest over its nodes; 0 where the crack ends at shared
            // nodes, negative where the sides interpenetrate).
            let mut opening = f64::NEG_INFINITY;
            for &i in &face.nodes {
                let x = rest[i];
                for &j in &copies[&[x.x.to_bits(), x.y.to_bits(), x.z.to_bits()]] {
                    if j != i {
                        opening = opening.max((positions[j] - positions[i]).dot(&normal));
                    }
                }
            }
            if opening == f64::NEG_INFINITY {
                opening = 0.0; // no copies: the crack is closed at this face
            }
            let shift = -0.5 * (gap - opening).max(0.0) * normal;
            let first = surface.vertices.len();
            for x in [a, b, c] {
                let y = x + shift;
                surface.vertices.push([y.x, y.y, y.z]);
            }
            surface.triangles.push([first, first + 1, first + 2]);
            surface.crack.push(face.crack);
        }
        surface
    }
}
