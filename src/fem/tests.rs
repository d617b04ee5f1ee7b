#![allow(non_snake_case)]

use super::corotated::{corotated_strain, corotated_tangent, corotated_tangent_svd};
use super::kinematics::polar_rotation_newton;
use super::offset::expm1_symmetric;
use super::*;
use crate::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

/// The paper's ice, for the unit tests of this crate.
pub(crate) const ICE: Material = Material {
    lambda: 8.64e10,
    mu: 3.70e10,
    density: 916.0,
};

fn tet() -> (ElementRest, [Vector3<f64>; 4]) {
    let mesh = TetMesh::from_arrays(
        &[
            [0.0, 0.0, 0.0],
            [0.02, 0.001, 0.0],
            [0.003, 0.018, 0.002],
            [0.001, 0.002, 0.021],
        ],
        vec![[0, 1, 2, 3]],
    )
    .unwrap();
    let rest = ElementRest::of_mesh(&mesh)[0];
    (
        rest,
        [mesh.rest[0], mesh.rest[1], mesh.rest[2], mesh.rest[3]],
    )
}

/// Gradient and Hessian against central finite differences of the energy / gradient.
fn check_derivatives(model: ElasticModel, offset: Matrix3<f64>, strain: f64) {
    check_law_derivatives(model, &ICE, 0.0, None, offset, strain);
}

/// Gradient and Hessian of `mat` plus water of bulk modulus `water` against finite
/// differences.
fn check_law_derivatives(
    model: ElasticModel,
    mat: &Material,
    water: f64,
    flow: Option<Flow>,
    offset: Matrix3<f64>,
    strain: f64,
) {
    let (rest, x0) = tet();
    // A generic deformation: a rotation of a shear plus stretch of relative size `strain`,
    // given as displacements x − X.
    let G = Matrix3::new(0.3, -0.7, 0.2, 0.5, 0.1, -0.4, -0.2, 0.6, 0.25) * strain;
    let R = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 0.9).into_inner();
    let x = x0.map(|p| R * (p + G * p) - p);
    let law = Law {
        model: model.law(),
        material: *mat,
        water_bulk: water,
        flow,
    };
    let mut e = ElementEval::default();
    element_eval(
        &law,
        &rest,
        &x,
        &StrainOffset::new(offset),
        true,
        false,
        &mut e,
    );
    let h = 1e-9;
    let scale = e.gradient.iter().map(|g| g.abs()).fold(0.0, f64::max);
    let hscale = e.hessian.iter().map(|g| g.abs()).fold(0.0, f64::max);
    for d in 0..12 {
        let mut xp = x;
        let mut xm = x;
        xp[d / 3][d % 3] += h;
        xm[d / 3][d % 3] -= h;
        let (mut ep, mut em) = (ElementEval::default(), ElementEval::default());
        element_eval(
            &law,
            &rest,
            &xp,
            &StrainOffset::new(offset),
            false,
            false,
            &mut ep,
        );
        element_eval(
            &law,
            &rest,
            &xm,
            &StrainOffset::new(offset),
            false,
            false,
            &mut em,
        );
        let fd = (ep.energy - em.energy) / (2.0 * h);
        // Energy differences lose ~8 digits to cancellation at h = 1e-9: 1e-5 relative.
        assert!(
            (fd - e.gradient[d]).abs() <= 1e-5 * scale,
            "{model:?} grad {d}: {fd} vs {}",
            e.gradient[d]
        );
        for c in 0..12 {
            let fdh = (ep.gradient[c] - em.gradient[c]) / (2.0 * h);
            assert!(
                (fdh - e.hessian[c * 12 + d]).abs() <= 1e-5 * hscale,
                "{model:?} hess ({c},{d}): {fdh} vs {}",
                e.hessian[c * 12 + d]
            );
        }
    }
}

/// Half-frozen ice: half the ice's Lamé constants.
fn half_frozen() -> Material {
    Material {
        lambda: 0.5 * ICE.lambda,
        mu: 0.5 * ICE.mu,
        density: ICE.density,
    }
}

#[test]
fn water_derivatives_match_finite_differences() {
    // Half-frozen: half the ice's Lamé constants plus half the water's bulk modulus, with
    // the expansion offset, stretched and compressed.
    let half = half_frozen();
    for model in [ElasticModel::Linear, ElasticModel::Corotated] {
        check_law_derivatives(
            model,
            &half,
            1.1e9,
            None,
            Matrix3::identity() * 0.0145,
            0.02,
        );
        check_law_derivatives(model, &half, 1.1e9, None, Matrix3::identity() * -0.03, 0.01);
        // Pure water (no shear stiffness at all).
        let none = Material {
            lambda: 0.0,
            mu: 0.0,
            density: ICE.density,
        };
        check_law_derivatives(model, &none, 2.2e9, None, Matrix3::zeros(), 0.02);
    }
}

#[test]
fn linear_derivatives_match_finite_differences() {
    check_derivatives(ElasticModel::Linear, Matrix3::zeros(), 0.0);
    check_derivatives(ElasticModel::Linear, Matrix3::identity() * 0.0291, 0.0);
}

#[test]
fn corotated_derivatives_match_finite_differences_in_tension() {
    // Stretched state: all twist eigenvalues positive, so the tangent is exact.
    let stretch = Matrix3::identity() * -0.05;
    check_derivatives(ElasticModel::Corotated, stretch, 0.01);
    let sym = Matrix3::new(0.01, 0.002, 0.0, 0.002, -0.004, 0.001, 0.0, 0.001, 0.003)
        - Matrix3::identity() * 0.05;
    check_derivatives(ElasticModel::Corotated, sym, 0.02);
}

#[test]
fn corotated_exact_tangent_matches_finite_differences_in_compression() {
    // Compressed: some twist eigenvalues are negative; the unprojected tangent is still
    // the exact Hessian.
    check_derivatives(ElasticModel::Corotated, Matrix3::identity() * 0.05, 0.02);
}

#[test]
fn corotated_tangent_without_singular_vectors_is_the_svd_one() {
    let R = nalgebra::Rotation3::from_euler_angles(0.4, -0.9, 2.2).into_inner();
    let shape = Matrix3::new(0.3, -0.7, 0.2, 0.5, 0.1, -0.4, -0.2, 0.6, 0.25);
    // Ice's strains, a large stretch, compression (negative twist stiffness) and an
    // isotropic stretch (repeated singular values: the SVD basis is arbitrary there).
    let cases = [
        R * (Matrix3::identity() + shape * 1e-4),
        R * (Matrix3::identity() + shape * 0.3),
        R * (Matrix3::identity() * 0.9 + shape * 0.05),
        R * 1.02,
    ];
    for F in cases {
        for limit in [None, Some(Flow::Yield(1e-5)), Some(CREEP)] {
            let strain = corotated_strain(&polar_rotation(&F), &(F - Matrix3::identity()));
            let response = solid_response(&ICE, limit, &strain);
            let (mut closed, mut svd) = (Tangent::zeros(), Tangent::zeros());
            assert!(corotated_tangent(
                &polar_rotation(&F),
                &strain,
                &response,
                &mut closed
            ));
            corotated_tangent_svd(&F, &response, false, &mut svd);
            // The same tangent to round-off: ~1e-15 relative, except that the SVD's flow
            // direction comes from sᵢ − 1, whose ~1e-16 absolute error is 1e-12 of a 1e-4
            // deviator (measured 2.1e-12 there); the strain here is formed without it.
            let err = (closed - svd).amax() / svd.amax();
            assert!(err < 1e-11, "{err:e} for {F} with limit {limit:?}");
        }
    }
}

#[test]
fn corotated_free_expansion_is_stress_free() {
    let (rest, x0) = tet();
    let e = 0.0291;
    let x = x0.map(|p| p * e);
    let offset = StrainOffset::new(Matrix3::identity() * e);
    let mut out = ElementEval::default();
    let law = Law::elastic(&Corotated, ICE);
    element_eval(&law, &rest, &x, &offset, false, false, &mut out);
    let gmax = out.gradient.iter().map(|g| g.abs()).fold(0.0, f64::max);
    // Forces of a 2 % strain would be ~1e7 N here; round-off leaves ~1e-16 of that.
    assert!(gmax < 1e-6, "{gmax}");
    let s = element_stress(&law, &rest, &x, &offset);
    assert!(s.iter().all(|v| v.abs() < 1e-2), "{s:?}");
}

#[test]
fn stress_forces_are_the_element_forces() {
    // The forces of the balanced stress (the fracture criterion's) are the negative element
    // gradient: of a yielding solid with an expansion and plastic offset, plus a pressure
    // acting through the volume change, in both models.
    let (rest, x0) = tet();
    let G = Matrix3::new(0.3, -0.7, 0.2, 0.5, 0.1, -0.4, -0.2, 0.6, 0.25) * 0.01;
    let R = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 0.9).into_inner();
    let u = x0.map(|p| R * (p + G * p) - p);
    let plastic = Matrix3::new(0.01, 0.002, 0.0, 0.002, -0.004, 0.001, 0.0, 0.001, -0.006);
    let offset = StrainOffset::new(plastic + Matrix3::identity() * 0.0145);
    let p = 2e6;
    for model in [ElasticModel::Linear, ElasticModel::Corotated] {
        let law = Law {
            model: model.law(),
            material: ICE,
            water_bulk: 0.0,
            flow: Some(Flow::Yield(1e-4)),
        };
        let mut e = ElementEval::default();
        element_eval(&law, &rest, &u, &offset, false, false, &mut e);
        let change = law
            .model
            .volume_change(&rest.displacement_gradient(&u), &offset, false);
        change.add_pressure(&rest, p, &mut e, false);
        let element = stress_forces(&law, &rest, &u, &offset, Some(p));
        let forces = element.forces(&element.stress);
        let scale = e.gradient.iter().map(|g| g.abs()).fold(0.0, f64::max);
        for (i, f) in forces.iter().enumerate() {
            for a in 0..3 {
                let g = e.gradient[3 * i + a];
                assert!(
                    (f[a] + g).abs() <= 1e-12 * scale,
                    "{model:?} vertex {i}, {a}: {} vs {g}",
                    f[a]
                );
            }
        }
    }
}

#[test]
fn yielding_derivatives_match_finite_differences() {
    // The strains below are 10–100 × the elastic limit: every case yields. Half-frozen
    // ice with water and an expansion offset, and ice with a plastic strain offset.
    let half = half_frozen();
    let plastic = Matrix3::new(0.01, 0.002, 0.0, 0.002, -0.004, 0.001, 0.0, 0.001, -0.006);
    for model in [ElasticModel::Linear, ElasticModel::Corotated] {
        check_law_derivatives(
            model,
            &ICE,
            0.0,
            Some(Flow::Yield(1e-3)),
            Matrix3::zeros(),
            0.02,
        );
        check_law_derivatives(model, &ICE, 0.0, Some(Flow::Yield(1e-4)), plastic, 0.01);
        let offset = Matrix3::identity() * 0.0145;
        check_law_derivatives(model, &half, 1.1e9, Some(Flow::Yield(1e-4)), offset, 0.02);
    }
}

#[test]
fn yielding_stress_is_on_the_yield_surface_and_keeps_the_volume_response() {
    let gamma = 1e-4;
    let eps = Matrix3::new(3e-3, 1e-3, 0.0, 1e-3, -1e-3, 2e-4, 0.0, 2e-4, 5e-4);
    let r = solid_response(&ICE, Some(Flow::Yield(gamma)), &eps);
    assert!(r.flow_drop > 0.0);
    let dev = r.sigma - Matrix3::identity() * (r.sigma.trace() / 3.0);
    // ‖σ'‖ = 2μγ to round-off; the pressure is the elastic one, K tr ε.
    assert!((dev.norm() - 2.0 * ICE.mu * gamma).abs() < 1e-9 * ICE.mu * gamma);
    assert!((r.sigma.trace() / 3.0 - ICE.bulk() * eps.trace()).abs() < 1e-6);
    // The radial return of the trial stress gives the same stress.
    let trial = ICE.hooke(&eps);
    let tdev = trial - Matrix3::identity() * (trial.trace() / 3.0);
    let returned = trial - tdev * (1.0 - 2.0 * ICE.mu * gamma / tdev.norm());
    assert!((returned - r.sigma).norm() < 1e-9 * trial.norm());
    // Below the limit: Hooke's law, bit for bit.
    let small = eps * 1e-3;
    assert_eq!(
        solid_response(&ICE, Some(Flow::Yield(gamma)), &small).sigma,
        ICE.hooke(&small)
    );
}

/// Creep of ice at −10 °C over a 100 s step: h B = 100 s × 3.5e-25 Pa⁻³ s⁻¹ / 2, so a
/// deviatoric stress of 1 MPa creeps 1.75e-5 in the step, comparable to its elastic strain
/// (1e6 Pa / 2μ ≈ 1.5e-4 for the test ice): the response is far from both limits.
const CREEP: Flow = Flow::Creep {
    compliance: 100.0 * 3.5e-25 / 2.0,
    exponent: 3.0,
};

#[test]
fn creeping_derivatives_match_finite_differences() {
    // Strains of 1e-3 … 2e-2 on the test ice (μ ≈ 3.4 GPa): deviatoric stresses of
    // 7–140 MPa, where a step creeps from a small share of the strain to most of it.
    let half = half_frozen();
    let inelastic = Matrix3::new(0.01, 0.002, 0.0, 0.002, -0.004, 0.001, 0.0, 0.001, -0.006);
    let offset = Matrix3::identity() * 0.0145;
    for model in [ElasticModel::Linear, ElasticModel::Corotated] {
        for strain in [1e-3, 2e-2] {
            check_law_derivatives(model, &ICE, 0.0, Some(CREEP), Matrix3::zeros(), strain);
            check_law_derivatives(model, &ICE, 0.0, Some(CREEP), inelastic, strain);
            check_law_derivatives(model, &half, 1.1e9, Some(CREEP), offset, strain);
        }
    }
}

#[test]
fn a_flowing_element_at_rest_has_a_finite_tangent() {
    // A creeping element whose deviator is zero where the tangent forms its flow direction
    // (at rest, while its response carries a round-off flow_drop) drops nothing: the
    // projected SVD tangent was NaN there and stopped the first step of a freezing scene.
    let response = SolidResponse {
        psi: 0.0,
        sigma: Matrix3::zeros(),
        mu: ICE.mu,
        lambda: ICE.lambda,
        flow_drop: 1e-3 * ICE.mu,
    };
    let rotation = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 0.9).into_inner();
    for F in [Matrix3::identity(), rotation] {
        for project in [false, true] {
            let mut svd = Tangent::zeros();
            corotated_tangent_svd(&F, &response, project, &mut svd);
            assert!(svd.iter().all(|v| v.is_finite()), "{F} project {project}");
        }
        let mut closed = Tangent::zeros();
        assert!(corotated_tangent(
            &polar_rotation(&F),
            &Matrix3::zeros(),
            &response,
            &mut closed
        ));
        assert!(closed.iter().all(|v| v.is_finite()), "{F}");
    }
}

#[test]
fn creeping_stress_meets_the_backward_euler_flow_rule() {
    // The crept strain x = r − S/2μ is the step's creep at its end stress, c Sⁿ, and the
    // pressure keeps its elastic response.
    let Flow::Creep {
        compliance,
        exponent,
    } = CREEP
    else {
        unreachable!()
    };
    for scale in [1e-6, 1e-4, 1e-3, 1e-2] {
        let eps = Matrix3::new(3.0, 1.0, 0.0, 1.0, -1.0, 0.2, 0.0, 0.2, 0.5) * scale;
        let r = solid_response(&ICE, Some(CREEP), &eps);
        let dev = eps - Matrix3::identity() * (eps.trace() / 3.0);
        let sdev = r.sigma - Matrix3::identity() * (r.sigma.trace() / 3.0);
        let s = sdev.norm();
        let crept = dev.norm() - s / (2.0 * ICE.mu);
        // The root is found to ~1e-15 of S; x is a difference of r and S/2μ, so its error
        // is ~1e-15 r, relative to x at least 1e-15 r / x.
        let tol = 1e-13 * dev.norm();
        assert!(
            (crept - compliance * s.powf(exponent)).abs() <= tol,
            "scale {scale}: {crept:e} vs {:e}",
            compliance * s.powf(exponent)
        );
        // The stress is along the strain's deviator: σ' is formed here by taking off a mean
        // stress up to ~15 × S (at 1e-2 most of the deviator has crept), so ~1e-15 × 15.
        let along = (sdev / s - dev / dev.norm()).norm();
        assert!(along < 1e-13, "scale {scale}: {along:e}");
        assert!((r.sigma.trace() / 3.0 - ICE.bulk() * eps.trace()).abs() <= 1e-9 * s);
    }
    // Without creep over the step (c = 0): Hooke's law, bit for bit.
    let none = Flow::Creep {
        compliance: 0.0,
        exponent: 3.0,
    };
    let eps = Matrix3::new(3e-3, 1e-3, 0.0, 1e-3, -1e-3, 0.0, 0.0, 0.0, 5e-4);
    assert_eq!(
        solid_response(&ICE, Some(none), &eps).sigma,
        ICE.hooke(&eps)
    );
}

#[test]
fn expm1_of_a_symmetric_matrix_is_the_eigendecomposition_s() {
    use nalgebra::SymmetricEigen;
    // Plastic strains from 1e-8 to 2: the series with scaling and squaring against
    // V diag(exp_m1(λ)) Vᵀ, to round-off relative to the result.
    let shape = Matrix3::new(0.7, 0.2, -0.1, 0.2, -0.3, 0.4, -0.1, 0.4, -0.4);
    for scale in [1e-8, 1e-4, 0.05, 0.3, 2.0] {
        let x = shape * scale;
        let eig = SymmetricEigen::new(x);
        let v = eig.eigenvectors;
        let exact = v * Matrix3::from_diagonal(&eig.eigenvalues.map(f64::exp_m1)) * v.transpose();
        let e = expm1_symmetric(&x);
        assert!(
            (e - exact).norm() <= 1e-14 * exact.norm(),
            "scale {scale}: {:e}",
            (e - exact).norm() / exact.norm()
        );
    }
}

#[test]
fn signed_svd_flags_inversion() {
    let F = Matrix3::from_diagonal(&Vector3::new(1.0, 0.5, -0.2));
    let (U, s, V) = signed_svd(&F);
    assert!(s[2] < 0.0 && U.determinant() > 0.0 && V.determinant() > 0.0);
    assert!((U * Matrix3::from_diagonal(&s) * V.transpose() - F).norm() < 1e-14);
}

#[test]
fn newton_polar_rotation_is_the_svd_rotation() {
    let R = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
    let shape = Matrix3::new(0.3, -0.7, 0.2, 0.5, 0.1, -0.4, -0.2, 0.6, 0.25);
    // From ice's strains under gravity to a large stretch.
    for strain in [1e-7, 1e-4, 1e-2, 0.3] {
        let F = R * (Matrix3::identity() + shape * strain);
        let newton = polar_rotation_newton(&F).expect("converges for det F > 0.1");
        let (U, _, V) = signed_svd(&F);
        // Both are the polar factor to round-off (each ~1e-16 per entry).
        assert!(
            (newton - U * V.transpose()).amax() < 1e-14,
            "strain {strain}"
        );
        assert!((newton.transpose() * newton - Matrix3::identity()).amax() < 1e-15);
    }
    // Inverted (or nearly): the signed SVD decides.
    let inverted = Matrix3::from_diagonal(&Vector3::new(1.0, 0.5, -0.2));
    assert!(polar_rotation_newton(&inverted).is_none());
    assert!(polar_rotation(&inverted).determinant() > 0.0);
}
