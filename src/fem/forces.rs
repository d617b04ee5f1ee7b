//! Nodal forces of a stress given in an element's frame, by the simulation's own force
//! formula: what the fracture criterion splits into tensile and compressive parts.

use nalgebra::{Matrix3, Vector3};

/// The stress an element's nodal forces balance, in the element's frame, and the map from a
/// stress in that frame to nodal forces: fᵢ = −(R σ Rᵀ) gᵢ with gᵢ = V G ∇Nᵢ
/// ([`ElasticLaw::force_frame`](super::ElasticLaw::force_frame)), the forces the simulation
/// balances. Built by [`ElasticLaw::stress_forces`](super::ElasticLaw::stress_forces).
#[derive(Clone, Copy, Debug)]
pub struct StressForces {
    /// The stress σ (Pa) in the element's frame.
    pub stress: Matrix3<f64>,
    /// The rotation R of the element's frame (element frame → world).
    pub rotation: Matrix3<f64>,
    /// gᵢ = V G ∇Nᵢ of the four vertices (m²): the rest volume times the shape-function
    /// gradients in the frame of the forces.
    pub weighted_grads: [Vector3<f64>; 4],
}

impl StressForces {
    /// The nodal forces fᵢ = −(R s Rᵀ) gᵢ (N) of a stress `s` (Pa) in the element's frame.
    pub fn forces(&self, s: &Matrix3<f64>) -> [Vector3<f64>; 4] {
        let world = self.rotation * s * self.rotation.transpose();
        self.weighted_grads.map(|g| -world * g)
    }
}
