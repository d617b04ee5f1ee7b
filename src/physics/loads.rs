//! Mass and dead loads: lumped mass, gravity, surface traction.

use super::Selection;
use crate::mesh::{BoundaryFace, TetMesh};
use nalgebra::Vector3;

/// A traction (Pa, force per rest area) on the boundary faces `region` selects (centroid in a
/// box, or on a named surface), `traction` × `amplitude`(t).
#[derive(Clone, Debug, PartialEq)]
pub struct Traction {
    /// The faces it acts on.
    pub region: Selection,
    /// Traction vector at amplitude 1 (Pa).
    pub traction: Vector3<f64>,
    /// Its amplitude in time (1 throughout by default).
    pub amplitude: super::Amplitude,
}

/// Row-sum lumped mass of P1 tets: each vertex gets ρV/4 of each tet (kg per node), with ρ
/// = `density(e)` of element e (kg/m³) and V its rest volume (the same number as its
/// `ElementRest::volume`, without needing the elements' rest data).
pub fn lumped_mass(mesh: &TetMesh, density: impl Fn(usize) -> f64) -> Vec<f64> {
    let mut mass = vec![0.0; mesh.num_nodes()];
    for (e, tet) in mesh.tets.iter().enumerate() {
        let m = density(e) * mesh.signed_volume(e);
        for &v in tet {
            mass[v] += 0.25 * m;
        }
    }
    mass
}

/// Adds m g to every node's force (N).
pub fn add_gravity(mass: &[f64], gravity: &Vector3<f64>, force: &mut [f64]) {
    for (i, m) in mass.iter().enumerate() {
        for a in 0..3 {
            force[3 * i + a] += m * gravity[a];
        }
    }
}

/// Adds the consistent P1 load of a constant traction: each selected face gives t·A/3 to each
/// of its three nodes (exact for constant t).
pub fn add_traction(mesh: &TetMesh, traction: &Traction, force: &mut [f64]) {
    for face in mesh.boundary_faces() {
        let [a, b, c] = face.nodes.map(|i| mesh.rest[i]);
        if !traction.region.contains_face(&[a, b, c]) {
            continue;
        }
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        for &v in &face.nodes {
            for k in 0..3 {
                force[3 * v + k] += traction.traction[k] * area / 3.0;
            }
        }
    }
}

/// Number of boundary faces a traction acts on, and their total area (m²).
pub fn traction_faces(mesh: &TetMesh, region: &Selection) -> (usize, f64) {
    traction_faces_among(mesh, &mesh.boundary_faces(), region)
}

/// [`traction_faces`] among the boundary faces `faces` of `mesh`.
pub fn traction_faces_among(
    mesh: &TetMesh,
    faces: &[BoundaryFace],
    region: &Selection,
) -> (usize, f64) {
    let mut count = 0;
    let mut area = 0.0;
    for face in faces {
        let [a, b, c] = face.nodes.map(|i| mesh.rest[i]);
        if region.contains_face(&[a, b, c]) {
            count += 1;
            area += 0.5 * (b - a).cross(&(c - a)).norm();
        }
    }
    (count, area)
}

/// The dead loads as a term of a solve: potential −f·u of constant nodal forces.
pub struct DeadLoads<'a> {
    /// Nodal forces (N), 3 per node.
    pub force: &'a [f64],
}

impl super::term::StepTerm for DeadLoads<'_> {
    fn name(&self) -> &'static str {
        "the dead loads"
    }

    fn add(
        &mut self,
        u: &[f64],
        energy: &mut f64,
        mut gradient: Option<&mut [f64]>,
        _hessian: Option<&mut [f64]>,
    ) {
        for (d, (ud, f)) in u.iter().zip(self.force).enumerate() {
            *energy -= f * ud;
            if let Some(g) = gradient.as_deref_mut() {
                g[d] -= f;
            }
        }
    }

    fn hessian_is_fixed(&self) -> bool {
        true // linear in u: no Hessian at all
    }
}
