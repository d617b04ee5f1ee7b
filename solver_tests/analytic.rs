//! Checks against closed-form answers: eigenstrain in a free and a confined body, a column
//! under self-weight (with its convergence rate), a bar pulled by a prescribed displacement,
//! and mass-proportional damping.

mod common;
use common::*;
use icefem::fem::{ElasticModel, Material};
use icefem::mesh::{box_mesh, TetMesh};
use icefem::physics::{Dirichlet, Region};
use icefem::sim::Analysis;
use nalgebra::Vector3;

/// A Dirichlet condition on the nodes within 1e-9 of point `p` (per axis).
fn at_point(p: [f64; 3], axes: [bool; 3], displacement: [f64; 3]) -> Dirichlet {
    let p = Vector3::from(p);
    Dirichlet {
        amplitude: Default::default(),
        region: Region {
            min: p.add_scalar(-1e-9),
            max: p.add_scalar(1e-9),
        }
        .into(),
        axes,
        displacement: Vector3::from(displacement),
        velocity: Vector3::zeros(),
    }
}

/// A Dirichlet condition on the nodes of a box region (rollers when one axis is given).
fn on_box(min: [f64; 3], max: [f64; 3], axes: [bool; 3], displacement: [f64; 3]) -> Dirichlet {
    Dirichlet {
        amplitude: Default::default(),
        region: Region {
            min: Vector3::from(min),
            max: Vector3::from(max),
        }
        .into(),
        axes,
        displacement: Vector3::from(displacement),
        velocity: Vector3::zeros(),
    }
}

/// The six supports that fix the rigid motions of the cube [0, s]³ and nothing else.
fn statically_determinate(s: f64) -> Vec<Dirichlet> {
    vec![
        at_point([0.0; 3], [true; 3], [0.0; 3]),
        at_point([s, 0.0, 0.0], [false, true, true], [0.0; 3]),
        at_point([0.0, s, 0.0], [false, false, true], [0.0; 3]),
    ]
}

#[test]
fn free_body_with_uniform_eigenstrain_expands_stress_free() {
    let e = 0.0291;
    for model in [ElasticModel::Linear, ElasticModel::Corotated] {
        let mesh = irregular_box([3, 3, 3], [0.1; 3], 0.25, 11);
        let mut sim = simulation(
            mesh,
            ICE,
            model,
            [0.0; 3],
            statically_determinate(0.1),
            settings(Analysis::Static, 1.0),
        );
        sim.state.history.eigenstrain.fill(e);
        sim.step().unwrap();
        // u = e x exactly (P1 represents linear fields; the supports admit it).
        for (i, p) in sim.model.mesh.rest.iter().enumerate() {
            for a in 0..3 {
                let err = (sim.state.u[3 * i + a] - e * p[a]).abs();
                // Round-off: ~1e-16 of the 3e-3 m displacements, times the conditioning.
                assert!(err < 1e-12, "{model:?} node {i} axis {a}: {err:e}");
            }
        }
        // Zero stress: against the 3Ke ≈ 9.7e9 Pa a confined body would carry, round-off only.
        let smax = sim
            .stresses()
            .iter()
            .flatten()
            .fold(0.0f64, |m, s| m.max(s.abs()));
        assert!(
            smax < 1e-6 * 3.0 * ICE.bulk() * e,
            "{model:?}: residual stress {smax:e} Pa"
        );
    }
}

#[test]
fn confined_body_with_eigenstrain_carries_pressure_3ke() {
    let (e, s) = (0.0291, 0.1);
    // Rollers on all six faces: each face is held in its normal direction only.
    let mut supports = Vec::new();
    for a in 0..3 {
        let mut axes = [false; 3];
        axes[a] = true;
        let (mut lo_max, mut hi_min) = ([1.0; 3], [-1.0; 3]);
        lo_max[a] = 1e-9;
        hi_min[a] = s - 1e-9;
        supports.push(on_box([-1.0; 3], lo_max, axes, [0.0; 3]));
        supports.push(on_box(hi_min, [1.0; 3], axes, [0.0; 3]));
    }
    for model in [ElasticModel::Linear, ElasticModel::Corotated] {
        let mesh = irregular_box([3, 3, 3], [s; 3], 0.25, 5);
        let mut sim = simulation(
            mesh,
            ICE,
            model,
            [0.0; 3],
            supports.clone(),
            settings(Analysis::Static, 1.0),
        );
        sim.state.history.eigenstrain.fill(e);
        sim.step().unwrap();
        let p_exact = 3.0 * ICE.bulk() * e;
        let p_corot = 3.0 * ICE.bulk() * (1.0 - 1.0 / (1.0 + e)); // Fe = I/(1 + e): S − I = −e/(1 + e) I
        let expected = if model == ElasticModel::Linear {
            p_exact
        } else {
            p_corot
        };
        for sigma in sim.stresses() {
            let p = -(sigma[0] + sigma[1] + sigma[2]) / 3.0;
            assert!(
                (p - expected).abs() < 1e-9 * expected,
                "{model:?}: p = {p:e}, expected {expected:e}"
            );
            assert!(
                sigma[3..].iter().all(|s| s.abs() < 1e-9 * expected),
                "{model:?}: shear {sigma:?}"
            );
        }
        eprintln!("{model:?}: pressure {expected:.6e} Pa (3Ke = {p_exact:.6e} Pa)");
    }
}

/// ∫_tet (u_h − u)² for u_h linear with nodal values `uh` and u(z) = c0 + c1 z + c2 z², exactly:
/// e = λᵀQλ in barycentric coordinates and ∫ λ^α dV = 6V α!/(|α| + 3)!.
fn tet_error_squared(x: [Vector3<f64>; 4], uh: [f64; 4], c: [f64; 3]) -> f64 {
    let z: [f64; 4] = std::array::from_fn(|i| x[i].z);
    let a: [f64; 4] = std::array::from_fn(|i| uh[i] - c[1] * z[i]);
    let q = |i: usize, j: usize| 0.5 * (a[i] + a[j]) - c[0] - c[2] * z[i] * z[j];
    let volume = (x[1] - x[0])
        .dot(&(x[2] - x[0]).cross(&(x[3] - x[0])))
        .abs()
        / 6.0;
    let fact = [1.0, 1.0, 2.0, 6.0, 24.0];
    let mut sum = 0.0;
    for i in 0..4 {
        for j in 0..4 {
            for k in 0..4 {
                for l in 0..4 {
                    let mut count = [0usize; 4];
                    for m in [i, j, k, l] {
                        count[m] += 1;
                    }
                    let weight: f64 = count.iter().map(|&n| fact[n]).product();
                    sum += q(i, j) * q(k, l) * weight;
                }
            }
        }
    }
    6.0 * volume * sum / 5040.0 // 7! = 5040
}

#[test]
fn column_under_self_weight_converges_at_rate_two() {
    // With ν = 0 the exact 3-D solution is one-dimensional: u_z = −(ρg/E)(Lz − z²/2), u_x = u_y
    // = 0. Rollers on the sides and the base admit exactly that solution; a clamped base would
    // not disturb the continuum answer either, but on coarse meshes its discrete solution
    // spends a fifth of the tip deflection in lateral modes and stays pre-asymptotic.
    let material = Material::from_young_poisson(1e11, 0.0, 916.0);
    let (a, l, g) = (0.02, 0.2, 9.81);
    let k = material.density * g / material.young();
    let c = [0.0, -k * l, 0.5 * k];
    let mut errors = Vec::new();
    for n in [1, 2, 4, 8] {
        let mesh = box_mesh([0.0; 3], [a, a, l], [n, n, 4 * n], 6).unwrap();
        let rollers = vec![
            on_box([-1.0; 3], [1.0, 1.0, 1e-9], [false, false, true], [0.0; 3]),
            on_box([-1.0; 3], [1e-9, 1.0, 1.0], [true, false, false], [0.0; 3]),
            on_box(
                [a - 1e-9, -1.0, -1.0],
                [1.0; 3],
                [true, false, false],
                [0.0; 3],
            ),
            on_box([-1.0; 3], [1.0, 1e-9, 1.0], [false, true, false], [0.0; 3]),
            on_box(
                [-1.0, a - 1e-9, -1.0],
                [1.0; 3],
                [false, true, false],
                [0.0; 3],
            ),
        ];
        let mut sim = simulation(
            mesh,
            material,
            ElasticModel::Linear,
            [0.0, 0.0, -g],
            rollers,
            settings(Analysis::Static, 1.0),
        );
        sim.step().unwrap();
        let mesh: &TetMesh = &sim.model.mesh;
        let err2: f64 = mesh
            .tets
            .iter()
            .map(|t| {
                tet_error_squared(
                    t.map(|v| mesh.rest[v]),
                    t.map(|v| sim.state.u[3 * v + 2]),
                    c,
                )
            })
            .sum();
        errors.push(err2.sqrt());
    }
    let rates: Vec<f64> = errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect();
    eprintln!("L2 errors {errors:?}, rates {rates:?}");
    // P1 converges at h² in L2; measured 2.00 on every refinement.
    for r in rates {
        assert!((r - 2.0).abs() < 0.1, "rate {r}");
    }
}

#[test]
fn bar_pulled_by_prescribed_displacement_is_in_uniaxial_stress() {
    // x-faces held in x only, the right one moved by d; three point supports remove the
    // remaining rigid motions without resisting the lateral (Poisson) contraction.
    let (l, s, d) = (0.2, 0.04, 2e-5);
    let mesh = irregular_box([6, 2, 2], [l, s, s], 0.2, 17);
    let supports = vec![
        on_box([-1.0; 3], [1e-9, 1.0, 1.0], [true, false, false], [0.0; 3]),
        on_box(
            [l - 1e-9, -1.0, -1.0],
            [1.0; 3],
            [true, false, false],
            [d, 0.0, 0.0],
        ),
        at_point([0.0; 3], [false, true, true], [0.0; 3]),
        at_point([0.0, 0.0, s], [false, true, false], [0.0; 3]),
    ];
    let mut sim = simulation(
        mesh,
        ICE,
        ElasticModel::Linear,
        [0.0; 3],
        supports,
        settings(Analysis::Static, 1.0),
    );
    sim.step().unwrap();
    let sxx = ICE.young() * d / l;
    for sigma in sim.stresses() {
        assert!(
            (sigma[0] - sxx).abs() < 1e-9 * sxx,
            "σxx {} vs {sxx}",
            sigma[0]
        );
        assert!(sigma[1..].iter().all(|v| v.abs() < 1e-9 * sxx), "{sigma:?}");
    }
    // Lateral contraction u_y = −ν ε y.
    let nu = ICE.poisson();
    for (i, p) in sim.model.mesh.rest.iter().enumerate() {
        let expected = -nu * d / l * p.y;
        assert!(
            (sim.state.u[3 * i + 1] - expected).abs() < 1e-9 * d,
            "node {i}"
        );
    }
}

#[test]
fn mass_proportional_damping_decays_as_backward_euler_predicts() {
    // A free body translating at v0 with D = αM: M (v₁ − v₀)/h = −αM v₁ ⇒ v₁ = v₀ / (1 + αh).
    let (alpha, h) = (3.0, 0.01);
    let mesh = box_mesh([0.0; 3], [0.1; 3], [2, 2, 2], 5).unwrap();
    let elasticity = icefem::physics::Elasticity::new(&mesh, ICE, ElasticModel::Corotated);
    let damping = Some(icefem::physics::Rayleigh {
        mass: alpha,
        stiffness: 0.0,
    });
    let model =
        icefem::physics::Model::new(mesh, elasticity, Vector3::zeros(), &[], damping, vec![])
            .unwrap();
    let mut sim = icefem::sim::Simulation::new(model, settings(Analysis::Dynamic, h)).unwrap();
    let v0 = [0.3, -0.2, 0.1];
    for i in 0..sim.model.num_nodes() {
        sim.state.v[3 * i..3 * i + 3].copy_from_slice(&v0);
    }
    for n in 1..=20 {
        sim.step().unwrap();
        let factor = (1.0 + alpha * h).powi(-n);
        for (d, v) in sim.state.v.iter().enumerate() {
            // Newton stops at a residual of 1e-9 × the momentum force scale M|v|/h, which bounds
            // the velocity error by ~1e-9 |v| per step.
            assert!(
                (v - v0[d % 3] * factor).abs() < 1e-8 * 0.3,
                "step {n} dof {d}: {v} vs {}",
                v0[d % 3] * factor
            );
        }
    }
}

/// A linear 10 cm block clamped at z = 0 (static), with `extra` TOML appended; the
/// displacement field after each step of 0.25 s up to `end` s.
fn static_block_history(extra: &str, end: f64) -> Vec<(f64, Vec<f64>)> {
    let text = format!(
        "[mesh]\nbox = {{ size = [0.1, 0.1, 0.1], cells = [3, 3, 3], tets_per_cell = 5 }}\n\
         [material]\ndensity = 916.0\nyoungs_modulus = 9.99e10\npoisson_ratio = 0.35\nmodel = \"linear\"\n\
         [[dirichlet]]\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1e-9]\n\
         [time]\nanalysis = \"static\"\ndt = 0.25\nend_time = {end}\n{extra}"
    );
    let scene =
        icefem::scene::Scene::parse(&text, std::path::Path::new("/tmp/block.toml")).unwrap();
    let mut sim = icefem::sim::Simulation::new(scene.model, scene.settings).unwrap();
    let steps = icefem::run::step_count(end, 0.25);
    (0..steps)
        .map(|_| {
            sim.step().unwrap();
            (sim.state.time, sim.state.u.clone())
        })
        .collect()
}

/// Largest |a − s b| over the entries, relative to the largest |b|.
fn off_by(a: &[f64], s: f64, b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - s * y).abs()))
        / scale
}

#[test]
fn loads_gravity_and_supports_follow_their_time_functions() {
    // Linear statics: the solution at amplitude a is a times the one at amplitude 1, so each
    // step's field must be a(t) × the constant-load field, to Newton's tolerance (1e-9 of the
    // force scale; 1e-7 relative leaves room for the conditioning of the 135-dof block).
    let top = "min = [-1.0, -1.0, 0.0999999]\nmax = [1.0, 1.0, 1.0]\n";
    let cases = [
        (
            format!("[[traction]]\n{top}traction = [0.0, 0.0, -1.0e6]\n"),
            "amplitude = [[0.0, 0.0], [1.0, 1.0], [1.5, 1.0], [1.5, 0.0]]",
        ),
        (
            "[physics]\ngravity = [3.0, 0.0, -9.81]\n".into(),
            "gravity_amplitude = [[0.0, 0.0], [1.0, 1.0], [1.5, 1.0], [1.5, 0.0]]",
        ),
        (
            format!("[[dirichlet]]\n{top}axes = \"z\"\ndisplacement = [0.0, 0.0, -1e-5]\n"),
            "amplitude = [[0.0, 0.0], [1.0, 1.0], [1.5, 1.0], [1.5, 0.0]]",
        ),
    ];
    for (load, amplitude) in cases {
        let constant = static_block_history(&load, 0.25);
        let reference = &constant[0].1;
        let varying = static_block_history(&format!("{load}{amplitude}\n"), 2.0);
        for (t, u) in &varying {
            // The ramp to 1 s, held, switched off at 1.5 s.
            let a = if *t <= 1.0 + 1e-12 {
                *t
            } else if *t < 1.5 - 1e-12 {
                1.0
            } else {
                0.0
            };
            let err = off_by(u, a, reference);
            assert!(err < 1e-7, "{load}{amplitude}: t = {t}: off by {err:e}");
        }
    }
}

#[test]
fn a_traction_switched_off_leaves_the_beam_vibrating_without_energy_gain() {
    // The cantilever of scenes/cantilever.toml without gravity, pulled down at its tip by a
    // traction that is switched off at 0.2 s: from then on no work is done, so backward
    // Euler's energy may only fall (every solve's balance is checked too), and the beam swings.
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/cantilever.toml"
    ))
    .unwrap()
    .replace("gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, 0.0]")
    .replace("end_time = 2.0", "end_time = 0.6")
        + "\n[[traction]]\nmin = [0.3999999, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]\n\
           traction = [0.0, 0.0, -2.0e5]\namplitude = [[0.2, 1.0], [0.2, 0.0]]\n";
    let scene =
        icefem::scene::Scene::parse(&text, std::path::Path::new("/tmp/cantilever.toml")).unwrap();
    let mut sim = icefem::sim::Simulation::new(scene.model, scene.settings).unwrap();
    let steps = icefem::run::step_count(0.6, scene.settings.dt);
    let mut after_switch: Vec<(f64, f64)> = Vec::new();
    for _ in 0..steps {
        let report = sim.step().unwrap();
        if sim.state.time > 0.2 + 1e-9 {
            after_switch.push((report.energies.total(), report.energies.kinetic));
        }
    }
    for w in after_switch.windows(2) {
        // Round-off of the sums: 1e-12 relative.
        assert!(
            w[1].0 <= w[0].0 * (1.0 + 1e-12),
            "energy rose {} → {}",
            w[0].0,
            w[1].0
        );
    }
    let kinetic = after_switch.iter().fold(0.0f64, |m, e| m.max(e.1));
    let elastic_start = after_switch[0].0;
    assert!(
        kinetic > 0.1 * elastic_start,
        "no swing: kinetic ≤ {kinetic:e} J of {elastic_start:e} J"
    );
}

/// Ice on a steel base (the gallery's Gmsh block: physical volumes "ice" and "base",
/// surfaces "top" and "bottom"), confined laterally by rollers and pressed on its top face:
/// uniaxial strain, ε_zz = σ / (λ + 2μ) in each material, so u_z is linear in each layer with
/// a kink at the interface. P1 elements hold that field exactly, so the nodes must match it to
/// round-off: this checks named regions (support, traction, material) and per-element
/// materials together.
#[test]
fn two_materials_in_series_compress_as_uniaxial_strain_predicts() {
    let text = r#"
[mesh]
file = "two_material_block.msh"
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
model = "linear"
[materials.steel]
density = 7850.0
lambda = 1.2e11
mu = 8.0e10
region = "base"
[[dirichlet]]
region = "bottom"
axes = "z"
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1e-9, 1.0, 1.0]
axes = "x"
[[dirichlet]]
min = [0.1, -1.0, -1.0]
max = [1.0, 1.0, 1.0]
axes = "x"
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1.0, 1e-9, 1.0]
axes = "y"
[[dirichlet]]
min = [-1.0, 0.1, -1.0]
max = [1.0, 1.0, 1.0]
axes = "y"
[[traction]]
region = "top"
traction = [0.0, 0.0, -1e7]
[solver]
tolerance = 1e-12
[time]
analysis = "static"
dt = 1.0
end_time = 1.0
"#;
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gallery/x.toml");
    let scene = icefem::scene::Scene::parse(text, &path).unwrap();
    let mut sim = icefem::sim::Simulation::new(scene.model, scene.settings).unwrap();
    sim.step().unwrap();
    let (ice, steel) = (8.64e10 + 2.0 * 3.70e10, 1.2e11 + 2.0 * 8.0e10);
    let exact = |z: f64| -1e7 * (z.min(0.02) / steel + (z - 0.02).max(0.0) / ice);
    let top = exact(0.06).abs();
    let mut worst: f64 = 0.0;
    for (i, x) in sim.model.mesh.rest.iter().enumerate() {
        worst = worst.max((sim.state.u[3 * i + 2] - exact(x.z)).abs());
        // No lateral motion: the rollers and the uniaxial strain agree.
        worst = worst
            .max(sim.state.u[3 * i].abs())
            .max(sim.state.u[3 * i + 1].abs());
    }
    // A direct solve of a well-conditioned 2 000-dof system: 1e-9 of the top's displacement
    // is far above round-off and far below any modelling error (a wrong material in one
    // layer changes the answer by tens of percent).
    assert!(
        worst < 1e-9 * top,
        "worst nodal error {worst:e} m of {top:e} m"
    );
}
