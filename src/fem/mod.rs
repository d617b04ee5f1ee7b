//! Linear-tetrahedron kinematics and constitutive laws: rest data, deformation gradient,
//! Hooke's law for the `linear` (small-strain) and `corotated` models, element energy,
//! gradient and stiffness.
//!
//! Conventions: `F = Ds · Dm⁻¹` with `Ds = [x1 − x0, x2 − x0, x3 − x0]`; `vec(F)` is column
//! major (entry `F[a][k]` at `a + 3k`); energies in J, forces in N, stiffness in N/m.

mod corotated;
mod element;
mod kinematics;
mod law;
mod linear;
mod material;
mod offset;
mod response;
mod tensor;
mod volume;

pub use element::{ElementEval, ElementRest};
pub use kinematics::{polar_rotation, signed_svd};
pub use law::{constitutive, elastic_strain, element_eval, element_stress, volume_change, Law};
pub use material::Material;
pub(crate) use offset::offset_elastic_gradient;
pub use offset::StrainOffset;
pub use response::{deviatoric_stress_norm, solid_response, SolidResponse, YIELD_SMOOTHING};
pub use tensor::{from_voigt, max_principal, to_voigt, von_mises, Tangent};
pub use volume::VolumeChange;

/// Which strain measure the elastic energy uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ElasticModel {
    /// Small strain ε = sym(F) − I: linear, exact for small displacements, but a rigid rotation
    /// produces spurious strain and forces.
    Linear,
    /// Corotated: F = R S (polar decomposition), ε = S − I. Rotation invariant.
    Corotated,
}

#[cfg(test)]
pub(crate) mod tests;
