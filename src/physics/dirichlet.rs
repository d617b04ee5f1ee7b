//! Dirichlet conditions: the nodes of a box or a named group follow a prescribed displacement
//! per axis.

use super::Selection;
use crate::mesh::TetMesh;
use nalgebra::Vector3;

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
