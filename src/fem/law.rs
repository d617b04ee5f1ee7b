//! The elastic law of an element ([`ElasticLaw`]: what one elastic model differs in from
//! another), the parameters of one element's law ([`Law`]), and the element evaluations built
//! on them: energy, gradient and stiffness, Cauchy stress, and the stress the nodal forces
//! balance.
#![allow(non_snake_case)]

use super::element::{add_stiffness, offset_grads, ElementEval, ElementRest};
use super::forces::StressForces;
use super::material::Material;
use super::offset::StrainOffset;
use super::response::{solid_response, Flow};
use super::tensor::{to_voigt, Tangent};
use super::volume::VolumeChange;
use nalgebra::{Matrix3, Vector3};

/// An elastic model of a linear tetrahedron: its strain measure, how a strain offset ε* enters
/// it, and the energy density, stress and tangent of its solid and of its water.
///
/// In the manner of fenris's `HyperelasticMaterial` (`compute_energy_density`,
/// `compute_stress_tensor`, `contract_stress_tensor_with`), but per element: a linear tet has a
/// single quadrature point, so each method evaluates one element. The required methods are the
/// model's kernels, written in terms of the displacement gradient H = F − I (so a small strain
/// keeps the precision of the strain, not of the positions); the provided methods build the element
/// evaluations on them. The scene's [`ElasticModel`](super::ElasticModel) resolves to a
/// `&'static dyn ElasticLaw` ([`Law::model`]): each provided method is one virtual call per
/// element, inside which every kernel call is static (each implementing type has its own copy of
/// the provided methods).
///
/// Conventions: `vec(P)` column major (entry `P[a][k]` at `a + 3k`); energy densities in J/m³,
/// stresses and moduli in Pa, strains dimensionless.
pub trait ElasticLaw: std::fmt::Debug + Send + Sync {
    /// The elastic displacement gradient He = Fe − I of an element with displacement gradient
    /// `H` and strain offset ε* = `offset`, and the offset factor A through which He varies
    /// with H (He = H A + const) where A is not the identity; `None` means A = I, so the
    /// element's forces and stiffness use the rest shape-function gradients ∇Nᵢ, else Aᵀ∇Nᵢ.
    fn elastic_gradient(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
    ) -> (Matrix3<f64>, Option<Matrix3<f64>>);

    /// The solid's energy density Ψ (J/m³) and first Piola–Kirchhoff stress P (Pa) for the
    /// elastic displacement gradient `He`, of the material `material` that flows by `flow`,
    /// if given (see [`solid_response`]); if `tangent` is given, dP/dFe is written
    /// into it (every entry). With `project` the tangent is made positive semi-definite where
    /// the model's exact tangent can be indefinite.
    fn solid(
        &self,
        material: &Material,
        flow: Option<Flow>,
        He: &Matrix3<f64>,
        tangent: Option<&mut Tangent>,
        project: bool,
    ) -> (f64, Matrix3<f64>);

    /// The energy density Ψ (J/m³) and first Piola–Kirchhoff stress P (Pa) of unfrozen water
    /// with bulk modulus `bulk` (Pa) and no shear stiffness, for the elastic displacement
    /// gradient `He`; if `tangent` is given, dP/dFe is *added* to it. With `project` any
    /// indefinite part of the tangent is left out.
    fn water(
        &self,
        bulk: f64,
        He: &Matrix3<f64>,
        tangent: Option<&mut Tangent>,
        project: bool,
    ) -> (f64, Matrix3<f64>);

    /// The volume change θ of the element's elastic deformation and its derivatives (see
    /// [`VolumeChange`]), for the displacement gradient `H` and strain `offset`, with what the
    /// second derivative needs if `with_hessian`.
    fn volume_change(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
        with_hessian: bool,
    ) -> VolumeChange;

    /// The elastic strain ε (dimensionless) of the element in its own frame, and the rotation
    /// R (element frame → world) of that frame, for the displacement gradient `H` and strain
    /// `offset`. The solid's stress is [`solid_response`] of this strain (in the element's
    /// frame), and plasticity's return mapping acts on it.
    fn elastic_strain(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
    ) -> (Matrix3<f64>, Matrix3<f64>);

    /// The volume change θ (dimensionless) through which the water's pressure K θ acts in the
    /// element's Cauchy stress, for the displacement gradient `H`, the strain `offset` and
    /// the elastic strain `strain` of [`ElasticLaw::elastic_strain`].
    fn water_volume_change(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
        strain: &Matrix3<f64>,
    ) -> f64;

    /// The frame G of the element's nodal forces (dimensionless): the force that a stress σ
    /// in the element's frame exerts on vertex i is −V R σ Rᵀ G ∇Nᵢ, the force formula of
    /// [`ElasticLaw::element_eval`], for the element's `rotation` R and strain `offset`.
    fn force_frame(&self, rotation: &Matrix3<f64>, offset: &StrainOffset) -> Matrix3<f64>;

    /// The stress (Pa) in the element's frame whose nodal forces (see
    /// [`ElasticLaw::force_frame`]) are those of a pressure `p` (Pa) acting through the volume
    /// change θ of [`ElasticLaw::volume_change`], p ∂θ/∂x, at the elastic strain `strain`.
    fn pressure_stress(&self, strain: &Matrix3<f64>, p: f64) -> Matrix3<f64>;

    /// Whether the tangent of an elastic (not yielding) solid and of water is the same for
    /// every deformation and strain offset: an element's stiffness then changes only with its
    /// material.
    fn constant_tangent(&self) -> bool;

    /// Evaluates one element: energy `V Ψ` (J), gradient `V P ∇Nᵢ` (N) and, if
    /// `with_hessian`, the stiffness `V Bᵀ (dP/dF) B` (N/m), for the vertex displacements `u`
    /// (m) and the strain `offset`. The law is the solid's of `law` (scaled ice while freezing,
    /// yielding if `law` has an elastic limit) plus, if its `water_bulk` > 0, the water's;
    /// `law.model` is this law. The offset factor A of [`ElasticLaw::elastic_gradient`]
    /// enters through the shape-function gradients: He = H A + (A − I) varies with the vertex
    /// displacements through Aᵀ∇Nᵢ, so the gradient is V Pe Aᵀ∇Nᵢ and the stiffness
    /// V B'ᵀ (dPe/dFe) B' with B' built from Aᵀ∇Nᵢ.
    // The arguments are the element's independent inputs; bundling them would only add a type.
    #[allow(clippy::too_many_arguments)]
    fn element_eval(
        &self,
        law: &Law,
        rest: &ElementRest,
        u: &[Vector3<f64>; 4],
        offset: &StrainOffset,
        with_hessian: bool,
        project: bool,
        out: &mut ElementEval,
    ) {
        let H = rest.displacement_gradient(u);
        // Zeroed only when asked for: an energy or gradient pass skips the 81 entries.
        let mut tangent = with_hessian.then(Tangent::zeros);
        let (He, factor) = self.elastic_gradient(&H, offset);
        let (psi, P) = {
            let mut t = tangent.as_mut();
            let (psi, P) = self.solid(&law.material, law.flow, &He, t.as_deref_mut(), project);
            if law.water_bulk > 0.0 {
                let (psi_w, P_w) = self.water(law.water_bulk, &He, t, project);
                (psi + psi_w, P + P_w)
            } else {
                (psi, P)
            }
        };
        let grads = match factor {
            Some(A) => offset_grads(&A, rest),
            None => rest.grads,
        };
        let v = rest.volume;
        out.energy = v * psi;
        for (i, gi) in grads.iter().enumerate() {
            let g = v * P * gi;
            out.gradient[3 * i..3 * i + 3].copy_from_slice(g.as_slice());
        }
        if let Some(tangent) = &tangent {
            out.hessian = [0.0; 144];
            add_stiffness(&grads, v, tangent, &mut out.hessian);
        }
    }

    /// Cauchy stress of an element in the world frame (Pa), Voigt order xx yy zz yz xz xy:
    /// R σ Rᵀ with σ the solid's stress of the elastic strain ([`ElasticLaw::elastic_strain`];
    /// a yielding solid's stress is the returned one, [`solid_response`]), plus the water's
    /// pressure K θ on the diagonal ([`ElasticLaw::water_volume_change`]); `law.model` is this
    /// law.
    fn element_stress(
        &self,
        law: &Law,
        rest: &ElementRest,
        u: &[Vector3<f64>; 4],
        offset: &StrainOffset,
    ) -> [f64; 6] {
        let H = rest.displacement_gradient(u);
        let (strain, R) = self.elastic_strain(&H, offset);
        let solid = solid_response(&law.material, law.flow, &strain).sigma;
        let mut sigma = R * solid * R.transpose();
        if law.water_bulk > 0.0 {
            let volume_change = self.water_volume_change(&H, offset, &strain);
            sigma += Matrix3::identity() * (law.water_bulk * volume_change);
        }
        to_voigt(&sigma)
    }

    /// The stress an element's nodal forces balance, in its frame, with the map from a stress
    /// to those forces (see [`StressForces`]): the solid's stress as the solve balanced it
    /// (returned onto the yield surface), plus, with the nodal volumetric energy, the stress
    /// of the element's pressure `pressure` (Pa) acting through its volume change
    /// ([`ElasticLaw::pressure_stress`]); `law.model` is this law.
    fn stress_forces(
        &self,
        law: &Law,
        rest: &ElementRest,
        u: &[Vector3<f64>; 4],
        offset: &StrainOffset,
        pressure: Option<f64>,
    ) -> StressForces {
        let (strain, rotation) = self.elastic_strain(&rest.displacement_gradient(u), offset);
        let frame = self.force_frame(&rotation, offset);
        let mut stress = solid_response(&law.material, law.flow, &strain).sigma;
        if let Some(p) = pressure {
            stress += self.pressure_stress(&strain, p);
        }
        StressForces {
            stress,
            rotation,
            weighted_grads: rest.grads.map(|g| frame * g * rest.volume),
        }
    }
}

/// The constitutive law of one element: its elastic model, the solid's material (scaled ice
/// while it freezes), the bulk modulus of its water part and, if it can yield, its elastic
/// limit.
#[derive(Clone, Copy, Debug)]
pub struct Law {
    /// Strain measure and response ([`ElasticModel::law`](super::ElasticModel::law)).
    pub model: &'static dyn ElasticLaw,
    /// The solid's Lamé constants (Pa) and density (kg/m³).
    pub material: Material,
    /// Bulk modulus of the element's water part (Pa; 0 for none).
    pub water_bulk: f64,
    /// How the element's deviatoric strain flows within the solve, if it does: its elastic
    /// limit or its creep over the step (see [`solid_response`]).
    pub flow: Option<Flow>,
}

impl Law {
    /// An elastic solid of `material` without water, with the elastic model `model`.
    pub fn elastic(model: &'static dyn ElasticLaw, material: Material) -> Self {
        Law {
            model,
            material,
            water_bulk: 0.0,
            flow: None,
        }
    }
}

/// Evaluates one element with its law: [`ElasticLaw::element_eval`] of `law.model`.
// The arguments are the element's independent inputs; bundling them would only add a type.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn element_eval(
    law: &Law,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
    with_hessian: bool,
    project: bool,
    out: &mut ElementEval,
) {
    law.model
        .element_eval(law, rest, u, offset, with_hessian, project, out);
}

/// Cauchy stress of an element (Pa, Voigt xx yy zz yz xz xy) with its law:
/// [`ElasticLaw::element_stress`] of `law.model`.
#[inline]
pub fn element_stress(
    law: &Law,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
) -> [f64; 6] {
    law.model.element_stress(law, rest, u, offset)
}

/// The stress an element's nodal forces balance and its map to those forces, with its law:
/// [`ElasticLaw::stress_forces`] of `law.model`.
#[inline]
pub fn stress_forces(
    law: &Law,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
    pressure: Option<f64>,
) -> StressForces {
    law.model.stress_forces(law, rest, u, offset, pressure)
}
