//! Elasticity: patch test, rotation invariance, static cantilever convergence.
#![allow(non_snake_case)]

mod common;
use common::*;
use icefem::fem::{ElasticModel, ElementEval};
use icefem::physics::Elasticity;
use icefem::sim::Analysis;
use nalgebra::{Matrix3, Rotation3, Vector3};

/// Sums element gradients (dE/du, N) over the mesh for displacement `u`.
fn nodal_forces(el: &Elasticity, tets: &[[usize; 4]], u: &[f64]) -> (Vec<f64>, f64) {
    let mut f = vec![0.0; u.len()];
    let mut scale: f64 = 0.0;
    let mut out = ElementEval::default();
    let history = el.initial_history();
    for (e, tet) in tets.iter().enumerate() {
        el.element(tets, &history, u, e, false, &mut out);
        for k in 0..12 {
            f[3 * tet[k / 3] + k % 3] += out.gradient[k];
            scale = scale.max(out.gradient[k].abs());
        }
    }
    (f, scale)
}

#[test]
fn patch_test_linear_field_gives_exact_constant_strain_and_no_interior_force() {
    let mesh = irregular_box([4, 3, 3], [0.3, 0.2, 0.25], 0.3, 7);
    let A = Matrix3::new(1.0, 0.3, -0.2, 0.1, -0.5, 0.4, 0.25, 0.15, 0.7) * 1e-4;
    let b = Vector3::new(1e-5, -2e-5, 3e-5);
    let u: Vec<f64> = mesh
        .rest
        .iter()
        .flat_map(|p| (A * p + b).iter().copied().collect::<Vec<_>>())
        .collect();
    let eps = 0.5 * (A + A.transpose());
    for model in [ElasticModel::Linear, ElasticModel::Corotated] {
        let el = Elasticity::new(&mesh, ICE, model);
        // Constant strain: every element's stress is the same.
        let stresses = el.stresses(&mesh.tets, &el.initial_history(), &u);
        let reference = stresses[0];
        let smax = reference.iter().fold(0.0f64, |m, s| m.max(s.abs()));
        for s in &stresses {
            for k in 0..6 {
                // 1e-10 relative: well above the round-off of a 1e-4 strain, far below any
                // discretisation error.
                assert!(
                    (s[k] - reference[k]).abs() <= 1e-10 * smax,
                    "{model:?}: {s:?} vs {reference:?}"
                );
            }
        }
        if model == ElasticModel::Linear {
            let exact = ICE.hooke(&eps);
            let exact = [
                exact[(0, 0)],
                exact[(1, 1)],
                exact[(2, 2)],
                exact[(1, 2)],
                exact[(0, 2)],
                exact[(0, 1)],
            ];
            for k in 0..6 {
                assert!(
                    (reference[k] - exact[k]).abs() <= 1e-10 * smax,
                    "stress {k}: {} vs {}",
                    reference[k],
                    exact[k]
                );
            }
        }
        let (f, scale) = nodal_forces(&el, &mesh.tets, &u);
        let (lo, hi) = mesh.bounding_box();
        for (i, p) in mesh.rest.iter().enumerate() {
            let interior = (0..3).all(|a| p[a] > lo[a] + 1e-12 && p[a] < hi[a] - 1e-12);
            if interior {
                for a in 0..3 {
                    assert!(
                        f[3 * i + a].abs() <= 1e-10 * scale,
                        "{model:?} node {i}: {} (scale {scale})",
                        f[3 * i + a]
                    );
                }
            }
        }
    }
}

#[test]
fn rigid_rotation_is_force_free_for_corotated_but_not_for_linear() {
    let mesh = irregular_box([3, 3, 3], [0.1, 0.1, 0.1], 0.25, 3);
    let R =
        Rotation3::from_axis_angle(&Vector3::y_axis(), std::f64::consts::FRAC_PI_2).into_inner();
    let u: Vec<f64> = mesh
        .rest
        .iter()
        .flat_map(|p| (R * p - p).iter().copied().collect::<Vec<_>>())
        .collect();
    // Force scale of a unit strain: E times a face area.
    let unit = ICE.young() * (0.1f64 / 3.0).powi(2);
    let corot = Elasticity::new(&mesh, ICE, ElasticModel::Corotated);
    let (f, _) = nodal_forces(&corot, &mesh.tets, &u);
    let fmax = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        fmax <= 1e-12 * unit,
        "corotated: rotation produced force {fmax} N (unit {unit} N)"
    );
    // The linear model reads a 90° rotation as a strain of order 1: forces of order E·area.
    let linear = Elasticity::new(&mesh, ICE, ElasticModel::Linear);
    let (f, _) = nodal_forces(&linear, &mesh.tets, &u);
    let fmax = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        fmax > 0.1 * unit,
        "linear: spurious rotation force {fmax} N expected of order {unit} N"
    );
}

/// Tip deflection of a clamped ice beam under gravity, static, linear model.
fn cantilever_tip(cells: [usize; 3]) -> f64 {
    let (l, a) = (0.4, 0.04);
    let mesh = icefem::mesh::box_mesh([0.0; 3], [l, a, a], cells, 6).unwrap();
    let mut sim = simulation(
        mesh,
        ICE,
        ElasticModel::Linear,
        [0.0, 0.0, -9.81],
        vec![clamp_below_x(1e-9)],
        settings(Analysis::Static, 1.0),
    );
    sim.step().unwrap();
    // Mean z-displacement over the nodes of the free end.
    let tip: Vec<f64> = sim
        .model
        .mesh
        .rest
        .iter()
        .enumerate()
        .filter(|(_, p)| (p.x - l).abs() < 1e-9)
        .map(|(i, _)| sim.state.u[3 * i + 2])
        .collect();
    tip.iter().sum::<f64>() / tip.len() as f64
}

#[test]
fn static_cantilever_approaches_euler_bernoulli_monotonically() {
    let (l, a) = (0.4f64, 0.04f64);
    let q = ICE.density * 9.81 * a * a;
    let w_eb = -q * l.powi(4) / (8.0 * ICE.young() * a.powi(4) / 12.0);
    let w: Vec<f64> = [[10, 1, 1], [20, 2, 2], [40, 4, 4]]
        .iter()
        .map(|c| cantilever_tip(*c))
        .collect();
    let ratios: Vec<f64> = w.iter().map(|wi| wi / w_eb).collect();
    eprintln!("tip / Euler-Bernoulli: {ratios:?}");
    // Linear tets lock in bending: the deflection grows towards beam theory from below.
    assert!(
        ratios[0] < ratios[1] && ratios[1] < ratios[2] && ratios[2] < 1.0,
        "{ratios:?}"
    );
    // Observed rates of the error against beam theory, e = 1 − w/w_EB, per halving of h.
    // Locking keeps them pre-asymptotic: measured 0.60 then 1.14, rising towards the
    // asymptotic 2 of P1 — assert that band and that the rate rises.
    let err: Vec<f64> = ratios.iter().map(|r| 1.0 - r).collect();
    let rates = [(err[0] / err[1]).log2(), (err[1] / err[2]).log2()];
    eprintln!("observed rates {rates:?}");
    assert!(
        rates[0] > 0.4 && rates[1] > 0.9 && rates[1] > rates[0],
        "rates {rates:?}"
    );
}
