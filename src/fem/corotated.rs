//! The corotated law (`model = "corotated"`, the default): F = R S, ε = S − I, P = R σ(ε),
//! with the strain offset entering multiplicatively, Fe = F F*⁻¹.
#![allow(non_snake_case)]

use super::kinematics::{
    add_det_hessian, cofactor, det_minus_one, polar_rotation, polar_rotation_newton, signed_svd,
    svd_rotation,
};
use super::law::ElasticLaw;
use super::material::Material;
use super::offset::{offset_elastic_gradient, StrainOffset};
use super::response::{solid_response, Flow, SolidResponse};
use super::tensor::Tangent;
use super::volume::VolumeChange;
use nalgebra::{Matrix3, SMatrix, Vector3};

/// Corotated linear elasticity: F = R S (polar decomposition), ε = S − I, energy
/// ½ ε:C:ε and first Piola–Kirchhoff stress P = R σ(ε). Rotation invariant.
///
/// The strain offset ε* enters multiplicatively, Fe = F F*⁻¹ with the natural shape F* of
/// [`StrainOffset`] (see `offset_elastic_gradient`): the same as σ = C:(ε − ε*) to first
/// order, but exact for a free body: an isotropic ε* = e I gives a stress-free state scaled by
/// exactly (1 + e).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Corotated;

impl ElasticLaw for Corotated {
    /// He = H A + (A − I) with A = F*⁻¹ (`offset_elastic_gradient`); He = H without an
    /// offset.
    #[inline]
    fn elastic_gradient(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
    ) -> (Matrix3<f64>, Option<Matrix3<f64>>) {
        if offset.is_zero() {
            (*H, None)
        } else {
            let (A, He) = offset_elastic_gradient(offset, H);
            (He, Some(A))
        }
    }

    /// Corotated energy Ψ = μ Σ(sᵢ − 1)² + λ/2 (Σsᵢ − 3)² in the signed singular values sᵢ of F,
    /// i.e. ½ ε:C:ε with ε = S − I. Its tangent is exact; with `project` the rotational (twist)
    /// eigenvalues (ψᵢ + ψⱼ)/(sᵢ + sⱼ) that compression makes negative are replaced by their
    /// absolute value, which keeps every element stiffness positive semi-definite. Clamping them
    /// at zero instead (Teran et al. 2005) leaves the twist modes without curvature: Newton then
    /// over-steps along them, and the freezing container with fracture stalled at step 1030 that
    /// way; with |·| (the absolute-eigenvalue projection) it runs its 2400 steps.
    #[inline]
    fn solid(
        &self,
        mat: &Material,
        flow: Option<Flow>,
        He: &Matrix3<f64>,
        tangent: Option<&mut Tangent>,
        project: bool,
    ) -> (f64, Matrix3<f64>) {
        let F = Matrix3::identity() + He;
        let newton_rotation = polar_rotation_newton(&F);
        let R = newton_rotation.unwrap_or_else(|| svd_rotation(&F));
        let strain = corotated_strain(&R, He);
        let response = solid_response(mat, flow, &strain);
        // For this energy P = 2μ(F − R) + λ tr(S − I) R = R σ(S − I).
        let P = R * response.sigma;
        if let Some(t) = tangent {
            // Away from inversion (Newton's polar factor applied) the unprojected tangent needs
            // no singular vectors; projecting needs the twist eigenvalues one by one.
            if project || newton_rotation.is_none() || !corotated_tangent(&R, &strain, &response, t)
            {
                corotated_tangent_svd(&F, &response, project, t);
            }
        }
        (response.psi, P)
    }

    /// Ψ = K/2 (J − 1)², P = K (J − 1) cof(Fe), with J = det Fe the exact volume ratio — a
    /// shear-free corotated law, K/2 (Σsᵢ − 3)², would let an element collapse to zero volume
    /// at zero energy. With `project` the indefinite (J − 1) ∂²J term is left out.
    #[inline]
    fn water(
        &self,
        bulk: f64,
        He: &Matrix3<f64>,
        tangent: Option<&mut Tangent>,
        project: bool,
    ) -> (f64, Matrix3<f64>) {
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

    /// θ = J − 1 of Fe = F A (the exact volume ratio, as for water), formed without
    /// cancellation; ∂θ/∂F = cof(Fe) Aᵀ.
    #[inline]
    fn volume_change(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
        with_hessian: bool,
    ) -> VolumeChange {
        let (A, He) = offset_elastic_gradient(offset, H);
        let Fe = Matrix3::identity() + He;
        VolumeChange {
            theta: det_minus_one(&He),
            gradient: cofactor(&Fe) * A.transpose(),
            deformation: with_hessian.then_some(Fe),
            offset_factor: A,
        }
    }

    /// S − I of Fe = F (I + ε*)⁻¹ = R S, in the element's frame, and R.
    #[inline]
    fn elastic_strain(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
    ) -> (Matrix3<f64>, Matrix3<f64>) {
        let (_, He) = offset_elastic_gradient(offset, H);
        let R = polar_rotation(&(Matrix3::identity() + He));
        (corotated_strain(&R, &He), R)
    }

    /// det Fe − 1.
    #[inline]
    fn water_volume_change(
        &self,
        H: &Matrix3<f64>,
        offset: &StrainOffset,
        _strain: &Matrix3<f64>,
    ) -> f64 {
        let (_, He) = offset_elastic_gradient(offset, H);
        det_minus_one(&He)
    }

    /// G = R F*⁻ᵀ = R Aᵀ: fᵢ = −V R σ Aᵀ∇Nᵢ, the gradient V Pe Aᵀ∇Nᵢ with Pe = R σ.
    #[inline]
    fn force_frame(&self, rotation: &Matrix3<f64>, offset: &StrainOffset) -> Matrix3<f64> {
        rotation
            * offset_elastic_gradient(offset, &Matrix3::zeros())
                .0
                .transpose()
    }

    /// p J S⁻¹ for θ = det Fe − 1 with Fe = R S: ∂J/∂Fe = J Fe⁻ᵀ = R J S⁻¹, with S = I + ε.
    #[inline]
    fn pressure_stress(&self, strain: &Matrix3<f64>, p: f64) -> Matrix3<f64> {
        let s = Matrix3::identity() + strain;
        s.try_inverse().unwrap_or_else(Matrix3::identity) * (p * s.determinant())
    }

    /// The tangent rotates with the element.
    #[inline]
    fn constant_tangent(&self) -> bool {
        false
    }
}

/// Corotated strain S − I = sym(Rᵀ F) − I for F = I + H, computed without cancellation:
/// sym(Rᵀ) − I + sym(Rᵀ H), where sym(R) − I = −(|w|² I − w wᵀ)/(1 + cos θ) with w the axial
/// vector of skew(R) (|w| = sin θ). Forming S from the singular values instead would leave an
/// absolute error of ~1e-16 in the strain, i.e. 1e-9 relative at the 1e-7 strains of ice under
/// gravity, and Newton could not reduce the residual below that.
#[inline]
pub(super) fn corotated_strain(R: &Matrix3<f64>, H: &Matrix3<f64>) -> Matrix3<f64> {
    let cos_theta = 0.5 * (R.trace() - 1.0);
    let sym_r = if cos_theta > 0.0 {
        let w = Vector3::new(
            R[(2, 1)] - R[(1, 2)],
            R[(0, 2)] - R[(2, 0)],
            R[(1, 0)] - R[(0, 1)],
        ) * 0.5;
        -(Matrix3::identity() * w.norm_squared() - w * w.transpose()) / (1.0 + cos_theta)
    } else {
        0.5 * (R + R.transpose()) - Matrix3::identity()
    };
    let rh = R.transpose() * H;
    sym_r + 0.5 * (rh + rh.transpose())
}

/// The corotated tangent dP/dF in the singular basis F = U diag(s) Vᵀ, written into `t`:
/// stretch modes 2μδᵢⱼ + λ − flow_drop fᵢfⱼ (f the unit flow direction), shear modes 2μ and
/// twist modes (ψᵢ + ψⱼ)/(sᵢ + sⱼ), made |·| with `project`.
pub(super) fn corotated_tangent_svd(
    F: &Matrix3<f64>,
    response: &SolidResponse,
    project: bool,
    t: &mut Tangent,
) {
    let (mu, lambda) = (response.mu, response.lambda);
    let (U, s, V) = signed_svd(F);
    let tr = s.sum() - 3.0;
    let psi = s.map(|si| 2.0 * mu * (si - 1.0) + lambda * tr);
    // Flowing: the flow direction (deviator of the strain in singular values) loses
    // stiffness, − flow_drop n nᵀ. A creeping element at rest has a zero deviator here while
    // its response, from the strain formed otherwise, may carry a round-off flow_drop: no
    // direction, nothing to drop (normalising zero gave NaN in projected tangents).
    let flow = if response.flow_drop != 0.0 {
        s.map(|si| si - 1.0 - tr / 3.0)
            .try_normalize(0.0)
            .unwrap_or_else(Vector3::zeros)
    } else {
        Vector3::zeros()
    };
    t.fill(0.0);
    // Basis tensors D_ij = U e_i e_jᵀ Vᵀ, vectorised column-major.
    let basis = |i: usize, j: usize| -> SMatrix<f64, 9, 1> {
        let D = U.column(i) * V.column(j).transpose();
        SMatrix::<f64, 9, 1>::from_column_slice(D.as_slice())
    };
    let d = [basis(0, 0), basis(1, 1), basis(2, 2)];
    for i in 0..3 {
        for j in 0..3 {
            let h = 2.0 * mu * f64::from(i == j) - response.flow_drop * flow[i] * flow[j] + lambda;
            *t += h * d[i] * d[j].transpose();
        }
    }
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let (bij, bji) = (basis(i, j), basis(j, i));
        // Symmetric (shear) mode: (ψᵢ − ψⱼ)/(sᵢ − sⱼ) = 2μ_eff exactly for this energy.
        let flip = (bij + bji) * std::f64::consts::FRAC_1_SQRT_2;
        *t += 2.0 * mu * flip * flip.transpose();
        // Rotational mode; the denominator is guarded for elements inverted to s_i ≈ −s_j.
        let twist = (bij - bji) * std::f64::consts::FRAC_1_SQRT_2;
        let c2 = (psi[i] + psi[j]) / (s[i] + s[j]).max(1e-6);
        let c2 = if project { c2.abs() } else { c2 };
        *t += c2 * twist * twist.transpose();
    }
}

/// The unprojected corotated tangent of [`corotated_tangent_svd`] without the singular
/// vectors, from the polar factor R and the strain E = S − I of F = R S: for Z = Rᵀ dF,
///
/// ```text
/// dP = R (2μ sym Z + λ tr(Z) I − flow_drop N (N:Z) + [M w]ₓ),   w = axial(skew Z),
/// M = (tr(σ) I − σ)(tr(S) I − S)⁻¹,
/// ```
///
/// N = dev E/‖dev E‖. M has the eigenvalues (ψᵢ + ψⱼ)/(sᵢ + sⱼ) on S's eigenvectors, the
/// twist stiffnesses. Column by column (dF = eₐe_bᵀ), a sixth of the SVD's cost. Returns
/// false (and leaves `t`) if tr(S) I − S is too close to singular (an element near inversion).
pub(super) fn corotated_tangent(
    R: &Matrix3<f64>,
    strain: &Matrix3<f64>,
    response: &SolidResponse,
    t: &mut Tangent,
) -> bool {
    let (mu, lambda) = (response.mu, response.lambda);
    let tr = strain.trace();
    let stretch_sum = Matrix3::identity() * (2.0 + tr) - strain;
    // Its eigenvalues sᵢ + sⱼ are ~2 for the strains ice survives.
    if stretch_sum.determinant() < 1e-6 {
        return false;
    }
    let Some(stretch_inv) = stretch_sum.try_inverse() else {
        return false;
    };
    let sigma = strain * (2.0 * mu) + Matrix3::identity() * (lambda * tr);
    let twist = (Matrix3::identity() * sigma.trace() - sigma) * stretch_inv;
    let twist = 0.5 * (twist + twist.transpose());
    let flow = if response.flow_drop != 0.0 {
        (strain - Matrix3::identity() * (tr / 3.0))
            .try_normalize(0.0)
            .unwrap_or_else(Matrix3::zeros)
    } else {
        Matrix3::zeros()
    };
    for b in 0..3 {
        for a in 0..3 {
            // Z = Rᵀ eₐ e_bᵀ: column b is row a of R.
            let mut Z = Matrix3::zeros();
            Z.set_column(b, &R.row(a).transpose());
            let w = Vector3::new(
                Z[(2, 1)] - Z[(1, 2)],
                Z[(0, 2)] - Z[(2, 0)],
                Z[(1, 0)] - Z[(0, 1)],
            ) * 0.5;
            let Y = (Z + Z.transpose()) * mu + Matrix3::identity() * (lambda * Z.trace())
                - flow * (response.flow_drop * flow.dot(&Z))
                + (twist * w).cross_matrix();
            let dP = R * Y;
            t.set_column(
                a + 3 * b,
                &SMatrix::<f64, 9, 1>::from_column_slice(dP.as_slice()),
            );
        }
    }
    true
}
