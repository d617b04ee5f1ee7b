//! Contact with rigid obstacles: resting penetration, friction on an incline, a cube dropped
//! into the container, triangle-mesh obstacles (flat, tilted, moving, tipping over an edge),
//! and no contact work in scenes without obstacles.

mod common;
use common::*;
use icefem::fem::ElasticModel;
use icefem::mesh::box_mesh;
use icefem::mesh::surface::TriSurface;
use icefem::physics::contact::{default_stiffness, ObstacleContact, Shape};
use icefem::physics::obstacle_mesh::ObstacleSurface;
use icefem::physics::{Contact, Elasticity, Model, Obstacle};
use icefem::scene::Scene;
use icefem::sim::{Analysis, SimError, Simulation, SolveFailure};
use nalgebra::Rotation3;
use nalgebra::Vector3;
use std::sync::Arc;

/// A 10 cm ice cube standing on the floor z = 0 under `gravity`, with friction `alpha`.
fn cube_on_floor(
    gravity: [f64; 3],
    alpha: f64,
    stiffness: Option<f64>,
    dt: f64,
    smoothing: f64,
) -> Simulation {
    let floor = Shape::HalfSpace {
        point: Vector3::zeros(),
        normal: Vector3::z(),
    };
    cube_on(
        floor,
        Rotation3::identity(),
        Vector3::zeros(),
        gravity,
        alpha,
        stiffness,
        dt,
        smoothing,
    )
}

/// The 10 cm cube rotated by `rotation` about the origin, on `shape` moving with `velocity`.
#[allow(clippy::too_many_arguments)]
fn cube_on(
    shape: Shape,
    rotation: Rotation3<f64>,
    velocity: Vector3<f64>,
    gravity: [f64; 3],
    alpha: f64,
    stiffness: Option<f64>,
    dt: f64,
    smoothing: f64,
) -> Simulation {
    let mut mesh = box_mesh([0.0; 3], [0.1; 3], [3, 3, 3], 6).unwrap();
    for p in &mut mesh.rest {
        *p = rotation * *p;
    }
    let floor = Obstacle {
        shape,
        motion: icefem::physics::Motion::translating(velocity),
        stiffness: stiffness.unwrap_or_else(|| default_stiffness(&mesh, ICE.young())),
        friction: alpha,
    };
    let contact = Contact::new(&mesh, vec![floor], smoothing);
    let elasticity = Elasticity::new(&mesh, ICE, ElasticModel::Corotated);
    let mut model =
        Model::new(mesh, elasticity, Vector3::from(gravity), &[], None, vec![]).unwrap();
    model.add_obstacles(contact);
    Simulation::new(model, settings(Analysis::Dynamic, dt)).unwrap()
}

/// Mean of a nodal quantity over the nodes selected by `pick` (by rest position).
fn mean_over(
    sim: &Simulation,
    pick: impl Fn(&Vector3<f64>) -> bool,
    value: impl Fn(usize) -> f64,
) -> f64 {
    let nodes: Vec<usize> = (0..sim.model.num_nodes())
        .filter(|&i| pick(&sim.model.mesh.rest[i]))
        .collect();
    nodes.iter().map(|&i| value(i)).sum::<f64>() / nodes.len() as f64
}

#[test]
fn resting_block_penetrates_by_weight_over_stiffness_and_does_not_drift() {
    let mut sim = cube_on_floor([0.0, 0.0, -9.81], 0.5, None, 1.0 / 30.0, 1e-4);
    let k = sim.model.obstacle_contact().unwrap().obstacles[0].stiffness;
    let weight = sim.model.total_mass() * 9.81;
    let expected = weight / (k * 0.1 * 0.1);
    // Each bottom node's area share facing the floor: a third of each bottom triangle's.
    let mesh = &sim.model.mesh;
    let mut facing = vec![0.0; mesh.num_nodes()];
    for face in mesh.boundary_faces() {
        let [a, b, c] = face.nodes.map(|i| mesh.rest[i]);
        if [a, b, c].iter().all(|p| p.z < 1e-12) {
            for i in face.nodes {
                facing[i] += 0.5 * (b - a).cross(&(c - a)).norm() / 3.0;
            }
        }
    }
    // Area-weighted mean penetration of the bottom nodes: Σ Aᵢ dᵢ / Σ Aᵢ = Σ fᵢ / (k A) = m g / (k A)
    // once the block is in equilibrium.
    let penetration = |sim: &Simulation| {
        let (mut num, mut den) = (0.0, 0.0);
        for (i, a) in facing.iter().enumerate() {
            num += a * (-sim.state.u[3 * i + 2]);
            den += a;
        }
        num / den
    };
    let mut at_500 = 0.0;
    for n in 1..=1000 {
        sim.step().unwrap();
        if n == 500 {
            at_500 = penetration(&sim);
        }
    }
    let d = penetration(&sim);
    eprintln!("penetration {d:e} m, expected m g / (k A) = {expected:e} m");
    assert!(
        (d - expected).abs() < 0.01 * expected,
        "penetration {d:e} vs {expected:e}"
    );
    // No drift between step 500 and 1000: 1e-6 of the penetration, and no sideways creep.
    assert!(
        (d - at_500).abs() < 1e-6 * expected,
        "drift {:e}",
        d - at_500
    );
    let lateral = (0..sim.model.num_nodes())
        .map(|i| sim.state.u[3 * i].abs().max(sim.state.u[3 * i + 1].abs()))
        .fold(0.0, f64::max);
    assert!(lateral < 1e-9, "lateral creep {lateral:e} m");
}

#[test]
fn block_on_incline_sticks_below_the_friction_angle_and_slides_above() {
    let alpha = 0.3;
    let g = 9.81;
    // The incline is the floor with gravity tilted by θ about y.
    let incline = |theta: f64| [g * theta.sin(), 0.0, -g * theta.cos()];
    // tan θ = 0.2 < α: sticks. Creep is bounded by the smoothing velocity ε_v (1e-6 m/s) × 2 s.
    let theta = 0.2f64.atan();
    let mut sim = cube_on_floor(incline(theta), alpha, None, 1.0 / 30.0, 1e-6);
    for _ in 0..60 {
        sim.step().unwrap();
    }
    let slip = mean_over(&sim, |p| p.z < 1e-12, |i| sim.state.u[3 * i]);
    eprintln!("stick: slip after 2 s {slip:e} m");
    assert!(
        slip.abs() < 2e-6,
        "slipped {slip:e} m below the friction angle"
    );
    // tan θ = 0.5 > α: slides with a = g (sin θ − α cos θ).
    let theta = 0.5f64.atan();
    let a_exact = g * (theta.sin() - alpha * theta.cos());
    let dt = 0.01;
    let mut sim = cube_on_floor(incline(theta), alpha, None, dt, 1e-4);
    let mut velocities = Vec::new();
    for _ in 0..200 {
        sim.step().unwrap();
        velocities.push(mean_over(&sim, |_| true, |i| sim.state.v[3 * i]));
    }
    // Slope of v(t) over the second second (the first steps settle the contact, whose normal
    // force friction lags by a step).
    let a = (velocities[199] - velocities[99]) / (100.0 * dt);
    eprintln!("slide: a = {a} m/s², expected {a_exact} m/s²");
    assert!(
        (a - a_exact).abs() < 0.02 * a_exact,
        "a = {a}, expected {a_exact}"
    );
}

#[test]
fn cube_dropped_into_container_comes_to_rest_inside_without_energy_gain() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/drop_into_container.toml");
    let scene = icefem::scene::Scene::load(&path).unwrap();
    let mut sim = Simulation::new(scene.model.clone(), scene.settings).unwrap();
    let inner = match &sim.model.obstacle_contact().unwrap().obstacles[0].shape {
        Shape::Container { inner } => *inner,
        other => panic!("expected a container, got {other:?}"),
    };
    let mut energy = sim.energies().total();
    let steps = icefem::run::step_count(scene.end_time, scene.settings.dt);
    for _ in 0..steps {
        let report = sim.step().unwrap();
        let e = report.energies.total();
        // Penalty contact is conservative and friction and backward Euler dissipate: the
        // energy may only fall, up to round-off of the sums (1e-12 relative).
        assert!(
            e <= energy + 1e-12 * energy.abs(),
            "energy rose {energy} → {e}"
        );
        energy = e;
        // No node through a wall or the floor beyond a micrometre (penalty depths here are
        // ~1e-9 m; an escaping node would be centimetres out).
        for p in sim.positions() {
            for a in 0..2 {
                assert!(
                    p[a] > inner.min[a] - 1e-6 && p[a] < inner.max[a] + 1e-6,
                    "node escaped: {p:?}"
                );
            }
            assert!(p[2] > inner.min.z - 1e-6, "node through the floor: {p:?}");
        }
    }
    let vmax = sim.state.v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    eprintln!("after {steps} steps: max |v| = {vmax:e} m/s");
    assert!(vmax < 1e-6, "not at rest: max |v| = {vmax:e} m/s");
}

#[test]
fn scene_without_obstacles_builds_no_contact_structures() {
    let mesh = box_mesh([0.0; 3], [0.1; 3], [2, 2, 2], 6).unwrap();
    let sim = simulation(
        mesh,
        ICE,
        ElasticModel::Corotated,
        [0.0, 0.0, -9.81],
        vec![],
        settings(Analysis::Dynamic, 0.01),
    );
    assert!(sim.model.obstacle_contact().is_none());
    assert!(sim.contact_forces().is_none());
    assert_eq!(sim.contact_structures_len(), 0);
}

#[test]
fn stacked_cubes_rest_on_each_other_through_ice_contact() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/stacked_cubes.toml");
    let scene = icefem::scene::Scene::load(&path).unwrap();
    let mut sim = Simulation::new(scene.model.clone(), scene.settings).unwrap();
    let ice = sim
        .model
        .ice_contact()
        .cloned()
        .expect("two parts: ice contact on");
    assert_eq!(ice.parts, 2);
    let steps = icefem::run::step_count(scene.end_time, scene.settings.dt);
    // The cubes start touching at zero gap, inside the contact penalty's onset δ (it starts at
    // g = δ, see `IceContact::penalty`): the first step finds the pairs and their energy,
    // k A δ²/6 each, which the state before it did not count. Energy is tracked from there.
    sim.step().unwrap();
    let mut energy = sim.energies().total();
    for _ in 1..steps {
        let before = sim.state.u.clone();
        let report = sim.step().unwrap();
        let e = report.energies.total();
        // Backward Euler lowers the energy of the exact step solution; the converged one may
        // differ by the work of the remaining residual, max|r| · ‖Δu‖₁ (here the energy itself
        // is only ~1e-10 J, so that term matters), plus round-off of the sums.
        let du: f64 = sim
            .state
            .u
            .iter()
            .zip(&before)
            .map(|(a, b)| (a - b).abs())
            .sum();
        let en = report.energies;
        let allowance = report.newton.residual * du
            + 1e-12 * (en.kinetic.abs() + en.elastic.abs() + en.potential.abs() + en.contact.abs());
        assert!(
            e <= energy + allowance,
            "energy rose {energy} → {e} (allowance {allowance:e})"
        );
        energy = e;
    }
    // At rest, and the lower cube carries the upper one's weight through ice–ice contact.
    let n = sim.model.num_nodes();
    let vmax = sim.state.v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(vmax < 1e-6, "not at rest: {vmax:e} m/s");
    let upper: Vec<usize> = (0..n).filter(|&i| ice.part[i] == 1).collect();
    let weight: f64 = upper.iter().map(|&i| sim.model.mass[i]).sum::<f64>() * 9.81;
    let lift: f64 = upper
        .iter()
        .map(|&i| sim.contact_forces().unwrap().normal[3 * i + 2])
        .sum();
    // Equilibrium to the Newton tolerance (1e-9 of the loads) — 1e-6 leaves room for the last
    // steps' residual motion.
    assert!(
        (lift - weight).abs() < 1e-6 * weight,
        "contact lift {lift} N vs weight {weight} N"
    );
    // No interpenetration beyond the penalty depth: the deepest node–face gap is the local
    // contact pressure over k. The mean pressure is weight / overlap area; at the lower cube's
    // edge (the upper one overhangs it) the pressure concentrates, so allow 10× the mean depth
    // (measured: 0.57×).
    let vmax = sim.state.v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let at = (&sim.state.u[..], vmax);
    let normals = ice
        .crack_sides()
        .normals(&sim.model.mesh.rest, &sim.state.u);
    let frames = ice
        .crack_sides()
        .frames(&sim.model.mesh.rest, &sim.state.u, &normals, &[]);
    let candidates = ice.candidates(&sim.model.mesh.rest, at, scene.settings.dt, &frames);
    let mut deepest: f64 = 0.0;
    ice.for_each_closest(
        &sim.model.mesh.rest,
        &sim.state.u,
        &candidates,
        |_, g, _| deepest = deepest.min(g),
    );
    let mean_depth = weight / (ice.stiffness * 0.035 * 0.035);
    eprintln!("deepest gap {deepest:e} m, mean penalty depth {mean_depth:e} m");
    assert!(
        deepest > -10.0 * mean_depth,
        "interpenetration {deepest:e} m"
    );
}

/// A 3 cm block on a 4 cm cube, gravity tilted by θ about y; the floor holds the lower cube
/// (α = 0.9), the upper block rests on it with ice–ice friction `alpha`. The block overhangs the
/// cube by 1 cm upslope and is narrower: side faces of the two bodies must not be coplanar,
/// where node-to-face contact cannot tell the side face from the top one (see README).
fn stacked_on_incline(theta: f64, alpha: f64, dt: f64) -> Simulation {
    let g = 9.81;
    let text = format!(
        r#"
[mesh]
boxes = [
    {{ origin = [0.03, 0.03, 0.0], size = [0.04, 0.04, 0.04], cells = [2, 2, 2] }},
    {{ origin = [0.02, 0.035, 0.04], size = [0.03, 0.03, 0.04], cells = [2, 2, 2] }},
]
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
[physics]
gravity = [{gx}, 0.0, {gz}]
ice_friction = {alpha}
friction_smoothing_velocity = 1e-5
[[obstacle]]
type = "halfspace"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
friction = 0.9
[time]
dt = {dt}
end_time = 1.0
"#,
        gx = g * theta.sin(),
        gz = -g * theta.cos(),
    );
    let scene = icefem::scene::Scene::parse(&text, std::path::Path::new("incline.toml")).unwrap();
    Simulation::new(scene.model, scene.settings).unwrap()
}

#[test]
fn ice_on_ice_friction_sticks_and_slides_like_coulomb() {
    let g = 9.81;
    let upper_mean_x = |sim: &Simulation, field: &[f64]| {
        let ice = sim.model.ice_contact().unwrap();
        let nodes: Vec<usize> = (0..sim.model.num_nodes())
            .filter(|&i| ice.part[i] == 1)
            .collect();
        nodes.iter().map(|&i| field[3 * i]).sum::<f64>() / nodes.len() as f64
    };
    // tan θ = 0.2 < α = 0.5: the upper cube stays on the lower one.
    let mut sim = stacked_on_incline(0.2f64.atan(), 0.5, 0.01);
    for _ in 0..30 {
        sim.step().unwrap();
    }
    let slip = upper_mean_x(&sim, &sim.state.u) - {
        let ice = sim.model.ice_contact().unwrap();
        let nodes: Vec<usize> = (0..sim.model.num_nodes())
            .filter(|&i| ice.part[i] == 0)
            .collect();
        nodes.iter().map(|&i| sim.state.u[3 * i]).sum::<f64>() / nodes.len() as f64
    };
    eprintln!("ice on ice, stick: relative slip after 0.3 s {slip:e} m");
    // Creep below the friction angle is bounded by ε_v t = 3e-6 m.
    assert!(slip.abs() < 3e-6, "upper cube slipped {slip:e} m");
    // tan θ = 0.3 > α = 0.1: it slides with a = g (sin θ − α cos θ) while the floor holds the
    // lower cube (0.9 > 0.3).
    let (theta, alpha, dt) = (0.3f64.atan(), 0.1, 0.005);
    let mut sim = stacked_on_incline(theta, alpha, dt);
    let mut v = Vec::new();
    for _ in 0..25 {
        sim.step().unwrap();
        v.push(upper_mean_x(&sim, &sim.state.v));
    }
    // Over 0.05 … 0.125 s (by then it has slid 1.5 cm, still on the cube).
    let a = (v[24] - v[9]) / (15.0 * dt);
    let expected = g * (theta.sin() - alpha * theta.cos());
    eprintln!("ice on ice, slide: a = {a} m/s², expected {expected} m/s²");
    assert!(
        (a - expected).abs() < 0.02 * expected,
        "a = {a}, expected {expected}"
    );
}

/// A square of half-width `half` (m) in the plane z = 0, as two triangles facing +z, rotated
/// by `rotation`.
fn square(half: f64, rotation: Rotation3<f64>) -> Shape {
    let vertices = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
        .map(|[x, y]| rotation * Vector3::new(half * x, half * y, 0.0))
        .to_vec();
    let surface = TriSurface {
        vertices,
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    };
    Shape::Mesh {
        surface: Arc::new(ObstacleSurface::new(&surface)),
    }
}

#[test]
fn mesh_floor_gives_the_half_space_answer() {
    // The same floor as a half-space and as two triangles: every node's plane is then the
    // half-space's, so the motions agree to round-off (the cube lands, bounces, settles).
    let g = [1.0, 0.5, -9.81];
    let mut half = cube_on_floor(g, 0.3, None, 0.01, 1e-4);
    let mut mesh = cube_on(
        square(1.0, Rotation3::identity()),
        Rotation3::identity(),
        Vector3::zeros(),
        g,
        0.3,
        None,
        0.01,
        1e-4,
    );
    let mut worst: f64 = 0.0;
    for _ in 0..50 {
        half.step().unwrap();
        mesh.step().unwrap();
        let scale = half.state.u.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = half
            .state
            .u
            .iter()
            .zip(&mesh.state.u)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        worst = worst.max(diff / scale);
    }
    eprintln!("mesh floor vs half-space: max relative difference {worst:e}");
    // Round-off of the closest-point arithmetic only (1e-10 leaves 3 orders for the Newton
    // iterates to amplify it through the stiff contact).
    assert!(worst < 1e-10, "relative difference {worst:e}");
}

#[test]
fn block_slides_down_a_tilted_mesh_incline_like_coulomb() {
    // Cube and triangle incline both tilted by θ about y, gravity vertical: the normals are no
    // longer axis-aligned. tan θ = 0.5 > α = 0.3: a = g (sin θ − α cos θ) down the slope.
    let (g, alpha, dt) = (9.81, 0.3, 0.01);
    let theta = 0.5f64.atan();
    let r = Rotation3::from_axis_angle(&Vector3::y_axis(), -theta);
    let mut sim = cube_on(
        square(10.0, r),
        r,
        Vector3::zeros(),
        [0.0, 0.0, -g],
        alpha,
        None,
        dt,
        1e-4,
    );
    let down_slope = r * -Vector3::x();
    let mut v = Vec::new();
    for _ in 0..200 {
        sim.step().unwrap();
        v.push(mean_over(
            &sim,
            |_| true,
            |i| {
                Vector3::new(
                    sim.state.v[3 * i],
                    sim.state.v[3 * i + 1],
                    sim.state.v[3 * i + 2],
                )
                .dot(&down_slope)
            },
        ));
    }
    let a = (v[199] - v[99]) / (100.0 * dt);
    let expected = g * (theta.sin() - alpha * theta.cos());
    eprintln!("tilted mesh incline: a = {a} m/s², expected {expected} m/s²");
    assert!(
        (a - expected).abs() < 0.02 * expected,
        "a = {a}, expected {expected}"
    );
}

#[test]
fn moving_mesh_floor_carries_the_block_with_it() {
    // A triangle floor rising at 0.2 m/s lifts the cube: after 1 s the cube moves with it and
    // presses on it by its weight, m g / (k A) deep, like a resting cube.
    let lift = 0.2;
    let mut sim = cube_on(
        square(1.0, Rotation3::identity()),
        Rotation3::identity(),
        Vector3::new(0.0, 0.0, lift),
        [0.0, 0.0, -9.81],
        0.3,
        None,
        1.0 / 30.0,
        1e-4,
    );
    for _ in 0..30 {
        sim.step().unwrap();
    }
    let vz = mean_over(&sim, |_| true, |i| sim.state.v[3 * i + 2]);
    let k = sim.model.obstacle_contact().unwrap().obstacles[0].stiffness;
    let expected = sim.model.total_mass() * 9.81 / (k * 0.01);
    let floor_z = lift * sim.state.time;
    let depth = floor_z - mean_over(&sim, |p| p.z < 1e-12, |i| sim.state.u[3 * i + 2]);
    eprintln!("rising floor: v_z = {vz} m/s, depth {depth:e} m (m g / (k A) = {expected:e} m)");
    // Backward Euler damps the landing transient: 1e-6 of the speed after 30 steps.
    assert!((vz - lift).abs() < 1e-6 * lift, "v_z = {vz}");
    // The bottom nodes' plain mean weights edge nodes like interior ones (the area-weighted
    // mean is exact, see the resting test): 5 %.
    assert!(
        (depth - expected).abs() < 0.05 * expected,
        "depth {depth:e} vs {expected:e}"
    );
}

#[test]
fn cube_tips_over_a_mesh_table_edge_without_entering_it() {
    // A table (closed box surface, top at z = 0, x ≤ 1/30 m) under a cube that overhangs it
    // by 6.7 cm: the cube pivots on the table's edge. The edge is an obstacle feature whose
    // plane turns with the cube; no node may enter the table. The edge lies under a row of
    // cube nodes: contact is node against surface, so an obstacle edge between nodes would cut
    // into the ice face (see README, limitations).
    let edge = 0.1 / 3.0;
    let table = icefem::bench::open_box_surface(&icefem::physics::Region {
        min: Vector3::new(-0.5, -0.5, -0.5),
        max: Vector3::new(edge, 0.5, 0.0),
    });
    // The open box's normals point into it; a table is that box seen from outside, closed.
    let mut vertices = table.vertices.clone();
    let mut triangles: Vec<[usize; 3]> =
        table.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
    let top = vertices.len();
    vertices.extend(
        [[-0.5, -0.5], [edge, -0.5], [edge, 0.5], [-0.5, 0.5]]
            .map(|[x, y]| Vector3::new(x, y, 0.0)),
    );
    triangles.extend([[top, top + 1, top + 2], [top, top + 2, top + 3]]);
    let surface = ObstacleSurface::new(&TriSurface {
        vertices,
        triangles,
    });
    let shape = Shape::Mesh {
        surface: Arc::new(surface.clone()),
    };
    let mut sim = cube_on(
        shape,
        Rotation3::identity(),
        Vector3::zeros(),
        [0.0, 0.0, -9.81],
        0.5,
        None,
        0.01,
        1e-4,
    );
    let mut deepest: f64 = 0.0;
    let mut energy = sim.energies().total();
    for _ in 0..25 {
        let report = sim.step().unwrap();
        for p in sim.positions() {
            if let Some(q) = surface.closest(Vector3::from(p), 0.01) {
                deepest = deepest.min(q.gap);
            }
        }
        let e = report.energies.total();
        assert!(
            e <= energy + 1e-9 * energy.abs().max(1.0),
            "energy rose {energy} → {e}"
        );
        energy = e;
    }
    let tilt = {
        let p = sim.positions();
        let right = mean_over(&sim, |x| x.x > 0.1 - 1e-12, |i| p[i][2]);
        let left = mean_over(&sim, |x| x.x < 1e-12, |i| p[i][2]);
        (left - right) / 0.1
    };
    eprintln!("table edge: deepest node {deepest:e} m, tilt {tilt}");
    // It tipped (the overhanging side dropped), and the penalty depth stays far below a
    // micrometre (weight / (k · edge area) ~ 1e-9 m).
    assert!(tilt > 0.05, "cube did not tip: {tilt}");
    assert!(deepest > -1e-6, "node {deepest:e} m inside the table");
}

#[test]
fn cube_slides_down_the_obj_ramp_scene_and_stops_on_the_floor() {
    // scenes/slide_down_ramp.toml: a rigid wedge read from ramp.obj in a container. The cube
    // lands on the slope, slides off its foot (x = 0.2 m) onto the floor and comes to rest;
    // no node ever enters the wedge.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/slide_down_ramp.toml");
    let scene = icefem::scene::Scene::load(&path).unwrap();
    let mut sim = Simulation::new(scene.model.clone(), scene.settings).unwrap();
    let ramp = sim.model.obstacle_contact().unwrap().obstacles[0]
        .surface()
        .expect("obstacle 0 is the OBJ ramp")
        .clone();
    assert_eq!(ramp.triangles.len(), 8, "5 faces of the prism, quads split");
    let mut deepest: f64 = 0.0;
    for _ in 0..icefem::run::step_count(scene.end_time, scene.settings.dt) {
        sim.step().unwrap();
        for p in sim.positions() {
            if let Some(q) = ramp.closest(Vector3::from(p), 0.01) {
                deepest = deepest.min(q.gap);
            }
        }
    }
    let p = sim.positions();
    let x_min = p.iter().map(|x| x[0]).fold(f64::INFINITY, f64::min);
    let z_min = p.iter().map(|x| x[2]).fold(f64::INFINITY, f64::min);
    let vmax = sim.state.v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    eprintln!(
        "ramp: deepest {deepest:e} m, final x_min {x_min} m, z_min {z_min:e} m, |v| {vmax:e}"
    );
    // Penalty depths are ~1e-10 m here; a node through the wedge would be millimetres in.
    assert!(deepest > -1e-6, "node {deepest:e} m inside the ramp");
    assert!(x_min > 0.2, "cube still on the ramp: x_min = {x_min}");
    assert!(
        z_min.abs() < 1e-6,
        "not resting on the floor: z_min = {z_min:e}"
    );
    assert!(vmax < 1e-4, "not at rest: {vmax:e} m/s");
}

#[test]
fn a_penalty_far_stiffer_than_the_ice_is_stopped_by_the_energy_balance_not_launched() {
    // The drop scene's 59 g cube with a wall stiffness of 1e25 N/m³ (1e11 × the default; the
    // scene file refuses it, built here directly): Newton stops at its round-off floor far
    // from the solution and, unchecked, the cube left a wall with 8.3 J. The balance of
    // every solve turns that into an error naming the energy that appeared.
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/drop_into_container.toml");
    let scene = icefem::scene::Scene::load(&path).unwrap();
    let mut model = scene.model.clone();
    let mut obstacles = model.obstacle_contact().unwrap().obstacles.clone();
    obstacles[0].stiffness = 1e25;
    model
        .terms
        .retain(|t| t.as_any().downcast_ref::<ObstacleContact>().is_none());
    let contact = Contact::new(&model.mesh, obstacles, 1e-4);
    model.add_obstacles(contact);
    let mut sim = Simulation::new(model, scene.settings).unwrap();
    let start = sim.energies().total();
    let steps = icefem::run::step_count(scene.end_time, scene.settings.dt);
    let mut failure = None;
    for _ in 0..steps {
        match sim.step() {
            Ok(report) => {
                // What the accepted steps may gain: 5 % of the energy that moves, here at
                // most ~0.03 J (the cube's fall), so 2e-3 J.
                let e = report.energies.total();
                assert!(
                    e <= start + 2e-3,
                    "energy {e} J after starting at {start} J"
                );
            }
            Err(e) => {
                failure = Some(e);
                break;
            }
        }
    }
    let failure = failure.expect("the run finished with a penalty of 1e25 N/m³");
    eprintln!("{failure}");
    assert!(
        matches!(
            failure,
            SimError::Step {
                cause: SolveFailure::EnergyRise(_),
                ..
            }
        ),
        "{failure}"
    );
    let message = failure.to_string();
    assert!(message.contains("more than the work"), "{message}");
    // The state is the last accepted step's, at rest-scale speeds (not metres per second).
    let vmax = sim.state.v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(vmax < 1.0, "max |v| = {vmax} m/s");
}

/// A cube on a turntable: a floor turning about the vertical axis at ω drags the cube
/// resting 10 cm off the axis by friction (μ g = 4.9 m/s² against the ω² r = 0.4 m/s²
/// needed to keep it on its circle), so it ends up turning with the floor: its centre's
/// velocity is ω × r and it stays on its circle.
#[test]
fn a_turning_floor_carries_a_resting_cube_round_by_friction() {
    let text = r#"
[[body]]
box = { origin = [-0.01, -0.01, 0.0], size = [0.02, 0.02, 0.02], cells = [2, 2, 2] }
translate = [0.1, 0.0, 0.0]
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
[physics]
gravity = [0.0, 0.0, -9.81]
[[obstacle]]
type = "halfspace"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
angular_velocity = [0.0, 0.0, 2.0]
friction = 0.5
[time]
dt = 0.002
end_time = 0.5
"#;
    let scene = Scene::parse(text, std::path::Path::new("/tmp/turntable.toml")).unwrap();
    let mut sim = Simulation::new(scene.model, scene.settings).unwrap();
    let mass = sim.model.mass.clone();
    let centre = |sim: &Simulation| -> (Vector3<f64>, Vector3<f64>) {
        let (mut x, mut v, mut m) = (Vector3::zeros(), Vector3::zeros(), 0.0);
        for (i, mi) in mass.iter().enumerate() {
            let d = |w: &[f64]| Vector3::new(w[3 * i], w[3 * i + 1], w[3 * i + 2]);
            x += *mi * (sim.model.mesh.rest[i] + d(&sim.state.u));
            v += *mi * d(&sim.state.v);
            m += mi;
        }
        (x / m, v / m)
    };
    for _ in 0..250 {
        sim.step().unwrap();
    }
    let (x, v) = centre(&sim);
    let expected = Vector3::new(0.0, 0.0, 2.0).cross(&Vector3::new(x.x, x.y, 0.0));
    // It caught up within μg / (ω r) ≈ 0.04 s and then turned with the floor for 0.45 s: the
    // remaining slip is the smoothed-friction creep (ε_v = 1e-4 m/s) and the stick of backward
    // Euler, well under 2 % of the 0.2 m/s surface speed.
    assert!(
        (v - expected).norm() < 0.02 * expected.norm(),
        "v {v} vs ω × r {expected}"
    );
    let radius = (x.x * x.x + x.y * x.y).sqrt();
    assert!((radius - 0.1).abs() < 2e-3, "radius {radius}");
    // It went round by about ω t = 1 rad (less the catch-up).
    let angle = x.y.atan2(x.x);
    assert!(angle > 0.9 && angle < 1.0, "angle {angle} rad");
}
