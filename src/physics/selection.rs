//! Where a condition applies: a box, or a named physical group of a Gmsh file (a volume or a
//! surface). Membership is geometric, in rest coordinates: a node, face or element belongs to
//! a group when it lies on the group's triangles or in its tets. That way a group keeps its
//! meaning on a mesh made from the file's by fracture (split nodes keep their rest position;
//! a face split into two lies on the same triangle).

use super::grid::BoxGrid;
use super::Region;
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

/// Where a Dirichlet condition, traction, eigenstrain or material applies.
#[derive(Clone, Debug, PartialEq)]
pub enum Selection {
    /// Nodes, face centroids or element centroids in a box.
    Box(Region),
    /// A named physical group.
    Group(Arc<Group>),
}

impl From<Region> for Selection {
    fn from(region: Region) -> Self {
        Selection::Box(region)
    }
}

impl Selection {
    /// Whether the node at rest position `p` (m) is selected: in the box, on a surface group's
    /// triangles or in (or on) a volume group's tets.
    pub fn contains_node(&self, p: &Vector3<f64>) -> bool {
        match self {
            Selection::Box(r) => r.contains(p),
            Selection::Group(g) => g.contains(p),
        }
    }

    /// Whether the boundary face with rest corners `corners` is selected: its centroid in the
    /// box or on a group's triangles (a volume group selects no face).
    pub fn contains_face(&self, corners: &[Vector3<f64>; 3]) -> bool {
        let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
        match self {
            Selection::Box(r) => r.contains(&centroid),
            Selection::Group(g) => g.dim == 2 && g.contains(&centroid),
        }
    }

    /// Whether the element with rest corners `corners` is selected: its centroid in the box
    /// or in a volume group's tets (a surface group selects no element).
    pub fn contains_element(&self, corners: &[Vector3<f64>; 4]) -> bool {
        let centroid = corners.iter().sum::<Vector3<f64>>() / 4.0;
        match self {
            Selection::Box(r) => r.contains(&centroid),
            Selection::Group(g) => g.dim == 3 && g.contains(&centroid),
        }
    }

    /// The selection in words, for messages: `box [..] – [..]` or `group "name"`.
    pub fn describe(&self) -> String {
        match self {
            Selection::Box(r) => format!(
                "box {:?} – {:?}",
                <[f64; 3]>::from(r.min),
                <[f64; 3]>::from(r.max)
            ),
            Selection::Group(g) => format!("group {:?}", g.name),
        }
    }
}

/// A named physical group in rest coordinates: the triangles of a surface or the tets of a
/// volume, with a grid to find those near a point.
#[derive(Clone, Debug)]
pub struct Group {
    /// The group's name in the mesh file.
    pub name: String,
    /// 2: a surface, 3: a volume.
    pub dim: u8,
    /// The corners of its simplices (m): triangles use the first three.
    simplices: Vec<[Vector3<f64>; 4]>,
    /// The simplices' bounding boxes, registered by index.
    grid: BoxGrid,
    /// Distance within which a point counts as on a triangle or in a tet (m).
    tolerance: f64,
}

impl PartialEq for Group {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name && self.dim == other.dim && self.simplices == other.simplices
    }
}

impl Group {
    /// A surface group of the given triangles (rest corners, m).
    pub fn surface(name: &str, triangles: &[[Vector3<f64>; 3]]) -> Self {
        let simplices = triangles.iter().map(|t| [t[0], t[1], t[2], t[2]]).collect();
        Self::new(name, 2, simplices)
    }

    /// A volume group of the given tets (rest corners, m).
    pub fn volume(name: &str, tets: &[[Vector3<f64>; 4]]) -> Self {
        Self::new(name, 3, tets.to_vec())
    }

    fn new(name: &str, dim: u8, simplices: Vec<[Vector3<f64>; 4]>) -> Self {
        let corners = || simplices.iter().flatten();
        let lo = corners().fold(Vector3::repeat(f64::INFINITY), |a, p| a.inf(p));
        let hi = corners().fold(Vector3::repeat(f64::NEG_INFINITY), |a, p| a.sup(p));
        // Points of the group are its mesh's own node positions (or averages of them): a
        // billionth of its size is far above their round-off and far below any element.
        let tolerance = 1e-9 * (hi - lo).norm().max(f64::MIN_POSITIVE);
        // Cells about the size of a simplex keep a query to a few candidates.
        let edge: f64 = simplices.iter().map(|s| (s[1] - s[0]).norm()).sum::<f64>()
            / simplices.len().max(1) as f64;
        let mut grid = BoxGrid::new(edge.max(tolerance));
        let pad = Vector3::repeat(tolerance);
        for (k, s) in simplices.iter().enumerate() {
            let lo = s.iter().fold(s[0], |a, p| a.inf(p)) - pad;
            let hi = s.iter().fold(s[0], |a, p| a.sup(p)) + pad;
            grid.insert(&lo, &hi, k as u32);
        }
        Group {
            name: name.to_string(),
            dim,
            simplices,
            grid,
            tolerance,
        }
    }

    /// Number of triangles (surface) or tets (volume).
    pub fn len(&self) -> usize {
        self.simplices.len()
    }

    /// Whether the group has no simplices.
    pub fn is_empty(&self) -> bool {
        self.simplices.is_empty()
    }

    /// The same group with more simplices (a name given in several bodies' files).
    pub fn merged(&self, other: &Group) -> Group {
        let mut simplices = self.simplices.clone();
        simplices.extend_from_slice(&other.simplices);
        Self::new(&self.name, self.dim, simplices)
    }

    /// Whether `p` (m) is on one of the group's triangles or in one of its tets, within the
    /// tolerance.
    pub fn contains(&self, p: &Vector3<f64>) -> bool {
        self.grid.at(p).iter().any(|&k| {
            let s = &self.simplices[k as usize];
            if self.dim == 2 {
                on_triangle(p, [s[0], s[1], s[2]], self.tolerance)
            } else {
                in_tet(p, s, self.tolerance)
            }
        })
    }
}

/// Whether `p` is within `tol` of the triangle `t`.
fn on_triangle(p: &Vector3<f64>, t: [Vector3<f64>; 3], tol: f64) -> bool {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let n = e1.cross(&e2);
    let area2 = n.norm();
    if area2 == 0.0 {
        return false;
    }
    let d = p - t[0];
    if (d.dot(&n) / area2).abs() > tol {
        return false;
    }
    // Barycentric coordinates of p's projection, each allowed `tol` over in length terms.
    let b1 = d.cross(&e2).dot(&n) / (area2 * area2);
    let b2 = e1.cross(&d).dot(&n) / (area2 * area2);
    let slack = tol / e1.norm().min(e2.norm()).min((t[2] - t[1]).norm());
    b1 >= -slack && b2 >= -slack && b1 + b2 <= 1.0 + slack
}

/// Whether `p` is in the tet `t` or within about `tol` of it.
fn in_tet(p: &Vector3<f64>, t: &[Vector3<f64>; 4], tol: f64) -> bool {
    let m = Matrix3::from_columns(&[t[1] - t[0], t[2] - t[0], t[3] - t[0]]);
    let Some(inverse) = m.try_inverse() else {
        return false;
    };
    let b = inverse * (p - t[0]);
    let shortest = (0..4)
        .flat_map(|i| (i + 1..4).map(move |j| (t[i] - t[j]).norm()))
        .fold(f64::INFINITY, f64::min);
    let slack = tol / shortest;
    b.iter().all(|&c| c >= -slack) && b.sum() <= 1.0 + slack
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
        Vector3::new(x, y, z)
    }

    #[test]
    fn points_on_a_surface_and_in_a_volume_are_found_and_others_not() {
        let square = Group::surface(
            "top",
            &[
                [v(0., 0., 1.), v(1., 0., 1.), v(1., 1., 1.)],
                [v(0., 0., 1.), v(1., 1., 1.), v(0., 1., 1.)],
            ],
        );
        assert!(square.contains(&v(0.3, 0.6, 1.0)));
        assert!(square.contains(&v(1.0, 1.0, 1.0)), "a corner");
        assert!(square.contains(&v(0.5, 0.5, 1.0)), "the shared edge");
        assert!(
            !square.contains(&v(0.5, 0.5, 1.0 + 1e-6)),
            "above the plane"
        );
        assert!(
            !square.contains(&v(1.0 + 1e-6, 0.5, 1.0)),
            "beside the edge"
        );
        let tet = Group::volume(
            "ice",
            &[[v(0., 0., 0.), v(1., 0., 0.), v(0., 1., 0.), v(0., 0., 1.)]],
        );
        assert!(tet.contains(&v(0.2, 0.2, 0.2)));
        assert!(tet.contains(&v(0.0, 0.0, 1.0)), "a vertex");
        assert!(!tet.contains(&v(0.4, 0.4, 0.4)), "beyond the slanted face");
        let face = [v(0.0, 0.0, 1.0), v(0.5, 0.0, 1.0), v(0.0, 0.5, 1.0)];
        assert!(Selection::Group(Arc::new(square)).contains_face(&face));
        assert!(
            !Selection::Group(Arc::new(tet)).contains_face(&face),
            "volumes select no faces"
        );
    }
}
