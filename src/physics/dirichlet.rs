//! Dirichlet conditions: the nodes of a box or a named group follow a prescribed displacement
//! per axis.

use super::Selection;
use crate::mesh::TetMesh;
use nalgebra::{Matrix6, Vector3, Vector6};

/// Nodes `region` selects (by rest position) have, on each axis in `axes`, the displacement
/// `amplitude(t) · displacement + velocity · t` (m). A fixed support is the all-zero case.
#[derive(Clone, Debug, PartialEq)]
pub struct Dirichlet {
    /// Where the condition applies (rest coordinates).
    pub region: Selection,
    /// Which axes (x, y, z) are prescribed.
    pub axes: [bool; 3],
    /// Displacement at t = 0 (m).
    pub displacement: Vector3<f64>,
    /// Prescribed velocity (m/s).
    pub velocity: Vector3<f64>,
    /// Amplitude of `displacement` in time (1 throughout by default).
    pub amplitude: super::Amplitude,
}

impl Dirichlet {
    /// Nodes this condition holds.
    pub fn nodes<'a>(&'a self, mesh: &'a TetMesh) -> impl Iterator<Item = usize> + 'a {
        mesh.rest
            .iter()
            .enumerate()
            .filter(|(_, p)| self.region.contains_node(p))
            .map(|(i, _)| i)
    }

    /// Marks the constrained dofs in `mask`.
    pub fn mark(&self, mesh: &TetMesh, mask: &mut [bool]) {
        for i in self.nodes(mesh) {
            for a in (0..3).filter(|&a| self.axes[a]) {
                mask[3 * i + a] = true;
            }
        }
    }

    /// Writes the prescribed displacement at time `t` (s) into `u`.
    pub fn apply(&self, mesh: &TetMesh, t: f64, u: &mut [f64]) {
        let amplitude = self.amplitude.at(t);
        for i in self.nodes(mesh) {
            for a in (0..3).filter(|&a| self.axes[a]) {
                u[3 * i + a] = amplitude * self.displacement[a] + self.velocity[a] * t;
            }
        }
    }
}

/// Whether the constrained dofs (`constrained`, 3 per node) hold every connected part of
/// `mesh` against rigid motion: no translation or infinitesimal rotation of a part keeps all
/// its constrained dofs at zero. A part that is not held can move rigidly by any amount.
pub fn hold_every_part(mesh: &TetMesh, constrained: &[bool]) -> bool {
    let (part, count) = crate::mesh::parts(mesh);
    let mut centroid = vec![Vector3::zeros(); count];
    let mut nodes = vec![0.0; count];
    for (p, &k) in mesh.rest.iter().zip(&part) {
        centroid[k as usize] += p;
        nodes[k as usize] += 1.0;
    }
    for (c, n) in centroid.iter_mut().zip(&nodes) {
        *c /= *n;
    }
    let mut size = vec![0.0f64; count];
    for (p, &k) in mesh.rest.iter().zip(&part) {
        size[k as usize] = size[k as usize].max((p - centroid[k as usize]).norm());
    }
    // Gram matrix of the six rigid modes (translations, rotations about the centroid at
    // unit lever arm) on each part's constrained dofs: singular iff some mode leaves them
    // all at zero.
    let mut gram = vec![Matrix6::<f64>::zeros(); count];
    for (i, (p, &k)) in mesh.rest.iter().zip(&part).enumerate() {
        let k = k as usize;
        let q = (p - centroid[k]) / size[k].max(f64::MIN_POSITIVE);
        for axis in (0..3).filter(|&a| constrained[3 * i + a]) {
            let mut mode = Vector6::zeros();
            mode[axis] = 1.0;
            for r in 0..3 {
                mode[3 + r] = Vector3::ith(r, 1.0).cross(&q)[axis];
            }
            gram[k] += mode * mode.transpose();
        }
    }
    gram.into_iter().all(|g| {
        let eigenvalues = g.symmetric_eigenvalues();
        let largest = eigenvalues.max();
        // Relative to the largest: a mode held by round-off only is not held.
        largest > 0.0 && eigenvalues.min() > 1e-10 * largest
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::box_mesh;

    /// The dof mask of `mesh` with the `axes` of the nodes at x ≤ `x_max` constrained.
    fn mask(mesh: &TetMesh, x_max: f64, axes: [bool; 3]) -> Vec<bool> {
        let mut mask = vec![false; 3 * mesh.num_nodes()];
        for (i, p) in mesh.rest.iter().enumerate() {
            if p.x <= x_max {
                mask[3 * i..3 * i + 3].copy_from_slice(&axes);
            }
        }
        mask
    }

    #[test]
    fn a_clamped_face_holds_a_part_a_roller_or_nothing_does_not() {
        let mesh = box_mesh([0.0; 3], [0.4, 0.04, 0.04], [8, 1, 1], 6).unwrap();
        assert!(hold_every_part(&mesh, &mask(&mesh, 1e-9, [true; 3])));
        assert!(!hold_every_part(&mesh, &mask(&mesh, -1.0, [true; 3])));
        // A roller (x held on a face) leaves y, z and the rotation about x free.
        assert!(!hold_every_part(
            &mesh,
            &mask(&mesh, 1e-9, [true, false, false])
        ));
        // A single clamped node holds translations, not rotations about it.
        let mut one = vec![false; 3 * mesh.num_nodes()];
        one[..3].copy_from_slice(&[true; 3]);
        assert!(!hold_every_part(&mesh, &one));
        // Two parts, only one of them clamped.
        let mut two = mesh.clone();
        let offset = two.num_nodes();
        two.rest
            .extend(mesh.rest.iter().map(|p| p + Vector3::new(0.0, 1.0, 0.0)));
        two.tets
            .extend(mesh.tets.iter().map(|t| t.map(|v| v + offset)));
        let mut clamped = mask(&mesh, 1e-9, [true; 3]);
        clamped.extend(vec![false; 3 * offset]);
        assert!(!hold_every_part(&two, &clamped));
        clamped[3 * offset..].copy_from_slice(&mask(&mesh, 1e-9, [true; 3]));
        assert!(hold_every_part(&two, &clamped));
    }
}
