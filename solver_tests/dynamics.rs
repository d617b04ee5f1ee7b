//! Backward-Euler dynamics: energy decay, momentum, stability of ice at frame-sized steps.

mod common;
use common::*;
use icefem::fem::ElasticModel;
use icefem::mesh::box_mesh;
use icefem::sim::Analysis;
use nalgebra::Vector3;

/// A free ice cube spinning and breathing: v = ω × (X − c) + s (X − c).
fn spinning_cube(model: ElasticModel, dt: f64) -> icefem::sim::Simulation {
    let mesh = box_mesh([0.0; 3], [0.1, 0.1, 0.1], [3, 3, 3], 6).unwrap();
    let mut sim = simulation(
        mesh,
        ICE,
        model,
        [0.0; 3],
        vec![],
        settings(Analysis::Dynamic, dt),
    );
    let c = Vector3::new(0.05, 0.05, 0.05);
    let omega = Vector3::new(0.0, 0.0, 20.0);
    for (i, p) in sim.model.mesh.rest.iter().enumerate() {
        let v = omega.cross(&(p - c)) + 0.05 * (p - c);
        sim.state.v[3 * i..3 * i + 3].copy_from_slice(v.as_slice());
    }
    sim
}

fn momentum(sim: &icefem::sim::Simulation) -> Vector3<f64> {
    (0..sim.model.num_nodes())
        .map(|i| {
            sim.model.mass[i]
                * Vector3::new(
                    sim.state.v[3 * i],
                    sim.state.v[3 * i + 1],
                    sim.state.v[3 * i + 2],
                )
        })
        .sum()
}

#[test]
fn energy_never_increases_without_forcing() {
    for model in [ElasticModel::Linear, ElasticModel::Corotated] {
        for dt in [1e-5, 1e-3, 1.0 / 30.0] {
            let mut sim = spinning_cube(model, dt);
            let mut energy = sim.energies().total();
            for _ in 0..20 {
                let p0 = momentum(&sim);
                let report = sim.step().unwrap();
                // No external force: M Δv = −h Σ(residual), so linear momentum changes by at
                // most h · 3n · max|residual| (plus round-off of the element-force sums).
                let bound = dt * sim.state.u.len() as f64 * report.newton.residual
                    + 1e-14 * sim.model.total_mass();
                let drift = (momentum(&sim) - p0).norm();
                assert!(
                    drift <= bound,
                    "{model:?} dt {dt}: momentum drift {drift:e} > {bound:e}"
                );
                let e = report.energies.total();
                // Backward Euler dissipates; allow only the round-off of the energy itself.
                assert!(
                    e <= energy * (1.0 + 1e-10),
                    "{model:?} dt {dt}: energy rose {energy} → {e}"
                );
                energy = e;
            }
        }
    }
}

#[test]
fn ice_cantilever_at_frame_steps_is_stable_and_converges_fast() {
    let mesh = box_mesh([0.0; 3], [0.4, 0.04, 0.04], [20, 2, 2], 6).unwrap();
    let mut sim = ice_cantilever(mesh);
    let mut max_newton = 0;
    for _ in 0..90 {
        let r = sim.step().unwrap();
        max_newton = max_newton.max(r.newton.iterations);
        // Gravity is part of the potential: starting at rest with zero energy, the total
        // (kinetic + elastic − f·u) can only fall under backward Euler.
        assert!(r.energies.total() <= 1e-15, "energy {}", r.energies.total());
        assert!(sim
            .state
            .u
            .iter()
            .chain(&sim.state.v)
            .all(|x| x.is_finite()));
    }
    // Explicit stability would need dt < ~1.5 µs here; at 1/30 s Newton needs only a few
    // iterations because the step is dominated by the (linear-ish) elastic response.
    assert!(max_newton <= 5, "Newton took {max_newton} iterations");
    // After 3 s the beam has settled at its static deflection: compare with a static solve.
    let mesh = box_mesh([0.0; 3], [0.4, 0.04, 0.04], [20, 2, 2], 6).unwrap();
    let mut stat = simulation(
        mesh,
        ICE,
        ElasticModel::Corotated,
        [0.0, 0.0, -9.81],
        vec![clamp_below_x(1e-9)],
        settings(Analysis::Static, 1.0),
    );
    stat.step().unwrap();
    let err = rel_l2(&sim.state.u, &stat.state.u);
    // BE's numerical damping at ω·dt ≫ 1 kills the oscillation within a step or two.
    assert!(err < 1e-6, "dynamic end state differs from static by {err}");
}

/// Mass-weighted centroid of the nodes in `nodes` (m).
fn centre_of_mass(sim: &icefem::sim::Simulation, nodes: std::ops::Range<usize>) -> Vector3<f64> {
    let (mut sum, mut mass) = (Vector3::zeros(), 0.0);
    for i in nodes {
        let m = sim.model.mass[i];
        sum += m
            * (sim.model.mesh.rest[i] + Vector3::from_column_slice(&sim.state.u[3 * i..3 * i + 3]));
        mass += m;
    }
    sum / mass
}

#[test]
fn bodies_are_placed_and_thrown_as_the_scene_says() {
    // A 10 cm cube centred at its origin, turned 30° about z, lifted to z = 1 m and thrown
    // at 1 m/s along x spinning at 2 rad/s about z; a second cube at rest 0.5 m away.
    let text = r#"
[[body]]
box = { origin = [-0.05, -0.05, -0.05], size = [0.1, 0.1, 0.1], cells = [3, 3, 3] }
rotate = { axis = [0.0, 0.0, 2.0], degrees = 30.0 }
translate = [0.0, 0.0, 1.0]
velocity = [1.0, 0.0, 0.0]
angular_velocity = [0.0, 0.0, 2.0]
[[body]]
box = { size = [0.1, 0.1, 0.1], cells = [2, 2, 2] }
translate = [0.5, 0.0, 1.0]
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
[time]
dt = 0.01
end_time = 0.2
"#;
    let scene =
        icefem::scene::Scene::parse(text, std::path::Path::new("/tmp/thrown.toml")).unwrap();
    let mut sim = icefem::sim::Simulation::new(scene.model, scene.settings).unwrap();
    let first = 4 * 4 * 4; // nodes of the 3³-cell box
    assert_eq!(sim.model.num_nodes(), first + 27);
    // The first body's corner (−5, −5, −5) cm, turned 30° about z and lifted by 1 m.
    let (s, c) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
    let corner = Vector3::new(-0.05 * c + 0.05 * s, -0.05 * s - 0.05 * c, 0.95);
    assert!((sim.model.mesh.rest[0] - corner).norm() < 1e-15);
    assert!((sim.model.mesh.rest[first] - Vector3::new(0.5, 0.0, 1.0)).norm() < 1e-15);
    // v = v₀ + ω × (x − c) on the first body, zero on the second.
    let v0 = Vector3::new(1.0, 0.0, 0.0);
    let omega = Vector3::new(0.0, 0.0, 2.0);
    let c0 = centre_of_mass(&sim, 0..first);
    for i in 0..first {
        let expected = v0 + omega.cross(&(sim.model.mesh.rest[i] - c0));
        let v = Vector3::from_column_slice(&sim.state.v[3 * i..3 * i + 3]);
        // The lumped-mass centroid is the volume centroid of the uniform box: round-off only.
        assert!((v - expected).norm() < 1e-12, "node {i}: {v} vs {expected}");
    }
    assert!(sim.state.v[3 * first..].iter().all(|&v| v == 0.0));
    let m = sim.model.mass[..first].iter().sum::<f64>();
    for _ in 0..20 {
        sim.step().unwrap();
    }
    // No forces: the centre of mass flies straight at v₀ and the momentum stays m v₀, to
    // Newton's tolerance (1e-9 of the force scale).
    let path = centre_of_mass(&sim, 0..first) - c0 - v0 * sim.state.time;
    assert!(path.norm() < 1e-9, "centre of mass off its path by {path}");
    let p: Vector3<f64> = (0..first)
        .map(|i| sim.model.mass[i] * Vector3::from_column_slice(&sim.state.v[3 * i..3 * i + 3]))
        .sum();
    assert!((p - m * v0).norm() < 1e-9 * m, "momentum {p} vs {}", m * v0);
    // The second body has not moved.
    assert!(sim.state.u[3 * first..].iter().all(|&u| u.abs() < 1e-12));
}

#[test]
fn a_run_started_from_a_frame_continues_it_step_for_step() {
    // The cantilever released under gravity, written every step; a second scene starts from
    // its frame 10 (displacement and velocity) and must repeat frames 11–20 exactly: same
    // mesh, same loads (constant in time), same direct solver.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/cantilever.toml"
    ))
    .unwrap()
    .replace("cells = [40, 4, 4]", "cells = [10, 2, 2]")
    .replace("end_time = 2.0", "end_time = 0.6666666666666666");
    let first = dir.path().join("first.toml");
    std::fs::write(&first, &text).unwrap();
    let out = dir.path().join("first.h5");
    let scene = icefem::scene::Scene::load(&first).unwrap();
    let options = icefem::run::RunOptions {
        output: Some(out.clone()),
        ..Default::default()
    };
    icefem::run::run(
        &scene,
        &options,
        &std::sync::atomic::AtomicBool::new(false),
        |_| {},
    )
    .unwrap();
    let second = text.replace(
        "end_time = 0.6666666666666666",
        "end_time = 0.3333333333333333",
    ) + "\n[initial]\nfile = \"first.h5\"\nframe = 10\n";
    let scene = icefem::scene::Scene::parse(&second, &dir.path().join("second.toml")).unwrap();
    let mut sim = icefem::sim::Simulation::new(scene.model, scene.settings).unwrap();
    let reader = icefem::output::FrameReader::open(&out).unwrap();
    let at = |k: usize| reader.read(k).unwrap().state;
    let start = at(10);
    let flat = |p: &[[f64; 3]]| p.iter().flatten().copied().collect::<Vec<f64>>();
    assert_eq!(sim.state.v, flat(&start.velocities));
    for k in 11..=20 {
        sim.step().unwrap();
        // The displacement is stored exactly (the positions only to be drawn, in single
        // precision).
        let frame = reader.read(k).unwrap();
        let (_, u) = frame.node_field("displacement").unwrap();
        assert_eq!(sim.state.u, u, "frame {k}");
        assert_eq!(sim.state.v, flat(&frame.state.velocities), "frame {k}");
    }
    // Errors name the field: a frame that is not there, another mesh, a missing file.
    let err = |t: &str| {
        icefem::scene::Scene::parse(t, &dir.path().join("second.toml"))
            .unwrap_err()
            .to_string()
    };
    let e = err(&second.replace("frame = 10", "frame = 999"));
    assert!(
        e.contains("initial.frame") && e.contains("complete frames"),
        "{e}"
    );
    let e = err(&second.replace("cells = [10, 2, 2]", "cells = [10, 2, 3]"));
    assert!(e.contains("`initial`") && e.contains("another mesh"), "{e}");
    let e = err(&second.replace("first.h5", "nowhere.h5"));
    assert!(
        e.contains("initial.file") && e.contains("nowhere.h5"),
        "{e}"
    );
}
