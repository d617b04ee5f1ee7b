//! The constitutive law of one element and the element evaluations built on it.
#![allow(non_snake_case)]

use super::corotated::{corotated, corotated_strain};
use super::element::{add_stiffness, offset_grads, ElementEval, ElementRest};
use super::kinematics::{add_det_hessian, cofactor, det_minus_one, polar_rotation};
use super::linear::linear_tangent;
use super::material::Material;
use super::offset::{offset_elastic_gradient, StrainOffset};
use super::response::solid_response;
use super::tensor::{to_voigt, Tangent};
use super::volume::VolumeChange;
use super::ElasticModel;
use nalgebra::{Matrix3, SMatrix, Vector3};

/// The constitutive law of one element: its strain measure, the solid's material (scaled ice
/// while it freezes), the bulk modulus of its water part and, if it can yield, its elastic
/// limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Law {
    /// Strain measure.
    pub model: ElasticModel,
    /// The solid's Lamé constants (Pa) and density (kg/m³).
    pub material: Material,
    /// Bulk modulus of the element's water part (Pa; 0 for none).
    pub water_bulk: f64,
    /// Elastic limit γ (dimensionless) if the element yields (see [`solid_response`]).
    pub yield_limit: Option<f64>,
}

impl Law {
    /// An elastic solid of `material` without water.
    pub fn elastic(model: ElasticModel, material: Material) -> Self {
        Law {
            model,
            material,
            water_bulk: 0.0,
            yield_limit: None,
        }
    }
}

/// Energy density Ψ (J/m³), first Piola–Kirchhoff stress P (Pa) and, if asked, the tangent
/// dP/dF for the elastic displacement gradient `He = Fe − I`.
/// The solid may yield with elastic limit `yield_limit` (see [`solid_response`]).
pub fn constitutive(
    model: ElasticModel,
    mat: &Material,
    yield_limit: Option<f64>,
    He: &Matrix3<f64>,
    tangent: Option<&mut Tangent>,
    project: bool,
) -> (f64, Matrix3<f64>) {
    match model {
        ElasticModel::Linear => {
            let eps = 0.5 * (He + He.transpose());
            let response = solid_response(mat, yield_limit, &eps);
            if let Some(t) = tangent {
                *t = linear_tangent(response.mu, response.lambda);
                if response.flow_drop != 0.0 {
                    // − flow_drop n⊗n with n = ε'/‖ε'‖ (symmetric, so n : dF = n : sym(dF)).
                    let dev = response.sigma - Matrix3::identity() * (response.sigma.trace() / 3.0);
                    let n = SMatrix::<f64, 9, 1>::from_column_slice(dev.normalize().as_slice());
                    *t -= response.flow_drop * n * n.transpose();
                }
            }
            (response.psi, response.sigma)
        }
        ElasticModel::Corotated => corotated(mat, yield_limit, He, tangent, project),
    }
}

/// Energy density, stress and (added into `tangent`) the tangent of unfrozen water with bulk
/// modulus `bulk` (Pa) and no shear stiffness, for the elastic displacement gradient `He`.
/// Linear: Ψ = K/2 tr(ε)². Corotated: Ψ = K/2 (J − 1)² with J = det Fe, the exact volume
/// ratio — a shear-free corotated law, K/2 (Σsᵢ − 3)², would let an element collapse to zero
/// volume at zero energy. With `project` the indefinite (J − 1) ∂²J term is left out.
fn water(
    model: ElasticModel,
    bulk: f64,
    He: &Matrix3<f64>,
    tangent: Option<&mut Tangent>,
    project: bool,
) -> (f64, Matrix3<f64>) {
    match model {
        ElasticModel::Linear => {
            let tr = He.trace();
            if let Some(t) = tangent {
                for a in 0..3 {
                    for b in 0..3 {
                        t[(a + 3 * a, b + 3 * b)] += bulk;
                    }
                }
            }
            (0.5 * bulk * tr * tr, Matrix3::identity() * (bulk * tr))
        }
        ElasticModel::Corotated => {
            let F = Matrix3::identity() + He;
            let cof = cofactor(&F);
            let j1 = det_minus_one(He);
            let P = cof * (bulk * j1);
            if let Some(t) = tangent {
                let g = SMatrix::<f64, 9, 1>::from_column_slice(cof.as_slice());
                *t += bulk * g * g.transpose();
                if !project {
                    add_det_hessian(&F, bulk * j1, t);
                }
            }
            (0.5 * bulk * j1 * j1, P)
        }
    }
}

/// Evaluates one element: energy `V Ψ`, gradient `V P ∇Nᵢ` and, if `with_hessian`, the stiffness
/// `V Bᵀ (dP/dF) B`. The law is the solid's (scaled ice while freezing, yielding if the law
/// has an elastic limit) plus, if its `water_bulk` > 0, the water term of [`water`].
///
/// The strain offset ε* (eigenstrain, plastic strain) enters as σ = C : (ε − ε*) in the linear
/// model, and multiplicatively, `Fe = F F*⁻¹`, in the corotated one (see
/// [`offset_elastic_gradient`]) — the same to first order, but exact for a free body: an
/// isotropic ε* = e I gives a stress-free state scaled by exactly (1 + e).
// The arguments are the element's independent inputs; bundling them would only add a type.
#[allow(clippy::too_many_arguments)]
pub fn element_eval(
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
    let model = law.model;
    let law = |He: &Matrix3<f64>, mut t: Option<&mut Tangent>| {
        let (psi, P) = constitutive(
            model,
            &law.material,
            law.yield_limit,
            He,
            t.as_deref_mut(),
            project,
        );
        if law.water_bulk > 0.0 {
            let (psi_w, P_w) = water(model, law.water_bulk, He, t, project);
            (psi + psi_w, P + P_w)
        } else {
            (psi, P)
        }
    };
    let t = tangent.as_mut();
    // The offset factor A enters through the shape-function gradients: He = H A + (A − I)
    // varies with the vertex displacements through Aᵀ∇Nᵢ, so the gradient is V Pe Aᵀ∇Nᵢ and
    // the stiffness V B'ᵀ (dPe/dFe) B' with B' built from Aᵀ∇Nᵢ.
    let (psi, P, grads) = match model {
        // σ = C:(sym H − ε*); the tangent does not depend on ε*.
        ElasticModel::Linear => {
            let (psi, P) = law(&(H - offset.strain), t);
            (psi, P, rest.grads)
        }
        ElasticModel::Corotated if offset.is_zero() => {
            let (psi, P) = law(&H, t);
            (psi, P, rest.grads)
        }
        ElasticModel::Corotated => {
            let (A, He) = offset_elastic_gradient(offset, &H);
            let (psi, Pe) = law(&He, t);
            (psi, Pe, offset_grads(&A, rest))
        }
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

/// The volume change of an element's elastic deformation (see [`VolumeChange`]), with its
/// second derivative if `with_hessian`. Corotated: θ = J − 1 of Fe = F A (the exact volume
/// ratio, as for water), formed without cancellation.
pub fn volume_change(
    model: ElasticModel,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
    with_hessian: bool,
) -> VolumeChange {
    let H = rest.displacement_gradient(u);
    match model {
        ElasticModel::Linear => VolumeChange {
            theta: H.trace() - offset.strain.trace(),
            gradient: Matrix3::identity(),
            deformation: None,
            offset_factor: Matrix3::identity(),
        },
        ElasticModel::Corotated => {
            let (A, He) = offset_elastic_gradient(offset, &H);
            let Fe = Matrix3::identity() + He;
            VolumeChange {
                theta: det_minus_one(&He),
                gradient: cofactor(&Fe) * A.transpose(),
                deformation: with_hessian.then_some(Fe),
                offset_factor: A,
            }
        }
    }
}

/// Elastic strain of an element and the rotation of its frame: linear, ε = sym(H) − ε* in the
/// world frame (R = I); corotated, S − I of Fe = F (I + ε*)⁻¹ = R S, in the element's frame.
/// Plasticity's return mapping acts on this strain.
pub fn elastic_strain(
    model: ElasticModel,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
) -> (Matrix3<f64>, Matrix3<f64>) {
    let H = rest.displacement_gradient(u);
    match model {
        ElasticModel::Linear => (
            0.5 * (H + H.transpose()) - offset.strain,
            Matrix3::identity(),
        ),
        ElasticModel::Corotated => {
            let (_, He) = offset_elastic_gradient(offset, &H);
            let R = polar_rotation(&(Matrix3::identity() + He));
            (corotated_strain(&R, &He), R)
        }
    }
}

/// Cauchy stress of an element in the world frame (Pa), Voigt order xx yy zz yz xz xy.
/// Linear: σ = C:(ε − ε*). Corotated: σ = R (C:(S − I)) Rᵀ for Fe = F (I + ε*)⁻¹ = R S.
/// A yielding solid's stress is the returned one ([`solid_response`]). Water adds its
/// pressure: −K tr(ε) (linear) or −K (J − 1) (corotated) on the diagonal.
pub fn element_stress(
    law: &Law,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
) -> [f64; 6] {
    let (model, water_bulk) = (law.model, law.water_bulk);
    let (strain, R) = elastic_strain(model, rest, u, offset);
    let solid = solid_response(&law.material, law.yield_limit, &strain).sigma;
    let mut sigma = R * solid * R.transpose();
    if water_bulk > 0.0 {
        let volume_change = match model {
            ElasticModel::Linear => strain.trace(),
            ElasticModel::Corotated => {
                let (_, He) = offset_elastic_gradient(offset, &rest.displacement_gradient(u));
                det_minus_one(&He)
            }
        };
        sigma += Matrix3::identity() * (water_bulk * volume_change);
    }
    to_voigt(&sigma)
}
