//! Linear-tetrahedron kinematics and constitutive laws: rest data, deformation gradient,
//! the elastic models behind [`ElasticLaw`] (`linear` small strain, `corotated`), element
//! energy, gradient and stiffness, and element stress.
//!
//! Conventions: `F = Ds · Dm⁻¹` with `Ds = [x1 − x0, x2 − x0, x3 − x0]`; `vec(F)` is column
//! major (entry `F[a][k]` at `a + 3k`); energies in J, forces in N, stiffness in N/m.
//!
//! - `material`: Lamé constants and Hooke's law ([`Material`]).
//! - `response`: the solid's stress response to an elastic strain, with a flow rule: the
//!   smoothed yield or creep ([`solid_response`], [`Flow`]).
//! - `kinematics`: signed SVD, polar rotation, the determinant and its derivatives.
//! - `offset`: strain offsets ε* and the natural shape's inverse A = F*⁻¹ ([`StrainOffset`]).
//! - `law`: the elastic model interface ([`ElasticLaw`]), one element's [`Law`], and the
//!   element evaluations built on them ([`element_eval`], [`element_stress`],
//!   [`stress_forces`]).
//! - `linear`, `corotated`: the elastic models ([`Linear`], [`Corotated`]).
//! - `element`: rest data ([`ElementRest`]), the evaluation result ([`ElementEval`]) and the
//!   stiffness Bᵀ T B.
//! - `volume`: an element's volume change for the nodal volumetric energy ([`VolumeChange`]).
//! - `forces`: nodal forces of a stress in an element's frame ([`StressForces`]).
//! - `tensor`: the tangent type, Voigt notation, von Mises and principal stress.
//!
//! An elastic model is a file implementing [`ElasticLaw`] and its variant of [`ElasticModel`]
//! (the scene's `model`) resolved in [`ElasticModel::law`].
//!
//! The small kernels an element evaluation calls across these files are `#[inline]`: each file
//! is its own codegen unit, and without the hint they are not inlined across files (measured:
//! 2–9 % more time per element).

mod corotated;
mod element;
mod forces;
mod kinematics;
mod law;
mod linear;
mod material;
mod offset;
mod response;
mod tensor;
mod volume;

pub use corotated::Corotated;
pub use element::{ElementEval, ElementRest};
pub use forces::StressForces;
pub use kinematics::{polar_rotation, signed_svd};
pub use law::{element_eval, element_stress, stress_forces, ElasticLaw, Law};
pub use linear::Linear;
pub use material::Material;
pub use offset::StrainOffset;
pub use response::{
    creep_stress_norm, deviatoric_stress_norm, solid_response, Flow, SolidResponse, YIELD_SMOOTHING,
};
pub use tensor::{from_voigt, max_principal, to_voigt, von_mises, Tangent};
pub use volume::VolumeChange;

/// Which elastic model the elastic energy uses: the scene's `[material] model`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ElasticModel {
    /// Small strain ε = sym(F) − I ([`Linear`]): linear, exact for small displacements, but a
    /// rigid rotation produces spurious strain and forces.
    Linear,
    /// Corotated ([`Corotated`]): F = R S (polar decomposition), ε = S − I. Rotation invariant.
    Corotated,
}

impl ElasticModel {
    /// The law of this model: where a model's name becomes its implementation (a static,
    /// so resolving it is a branch and calling it one virtual call per element).
    #[inline]
    pub fn law(self) -> &'static dyn ElasticLaw {
        match self {
            ElasticModel::Linear => &Linear,
            ElasticModel::Corotated => &Corotated,
        }
    }
}

#[cfg(test)]
pub(crate) mod tests;
