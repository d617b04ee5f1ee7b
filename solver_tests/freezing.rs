//! Freezing and plasticity against closed-form answers: free expansion, confined expansion in
//! the container, the freezing front's arrival, the return mapping, and the paper's scene.

mod common;
use common::*;
use icefem::fem::ElasticModel;
use icefem::mesh::{box_mesh, TetMesh};
use icefem::physics::contact::Shape;
use icefem::physics::freezing::{Freezing, Water};
use icefem::physics::plasticity::Plasticity;
use icefem::physics::{Contact, Dirichlet, Elasticity, Model, Obstacle, Region};
use icefem::sim::{Analysis, Simulation};
use nalgebra::{Matrix3, Vector3};

/// 1.09^(1/3) − 1: the linear expansion of water freezing.
const E_MAX: f64 = 0.029_142_466_571_506_54;

/// Everything frozen from the first step on: a front that crosses the body instantly.
fn frozen_at_once(mesh: &TetMesh) -> Freezing {
    let (min, max) = mesh.bounding_box();
    with_water_shear(Freezing::from_front(
        mesh,
        &Region { min, max },
        [true; 6],
        1e9,
        0.0,
        0.0,
        1.09,
        Water::Bulk { modulus: 2.2e9 },
    ))
}

/// The scenes' default regularising shear modulus of water, 1e-4 of the ice's.
fn with_water_shear(mut f: Freezing) -> Freezing {
    f.water_shear = 1e-4 * ICE.mu;
    f
}

/// Rollers on the faces x = 0, y = 0, z = 0 of a box at the origin: each holds its normal
/// axis, so the body may expand freely but not move or rotate.
fn symmetry_rollers() -> Vec<Dirichlet> {
    (0..3)
        .map(|a| {
            let mut max = Vector3::repeat(1e9);
            max[a] = 1e-12;
            let mut axes = [false; 3];
            axes[a] = true;
            Dirichlet {
                amplitude: Default::default(),
                region: Region {
                    min: Vector3::repeat(-1e9),
                    max,
                }
                .into(),
                axes,
                displacement: Vector3::zeros(),
                velocity: Vector3::zeros(),
            }
        })
        .collect()
}

fn model(mesh: TetMesh, law: ElasticModel, dirichlet: Vec<Dirichlet>) -> Model {
    let elasticity = Elasticity::new(&mesh, ICE, law);
    Model::new(mesh, elasticity, Vector3::zeros(), &[], None, dirichlet).unwrap()
}

#[test]
fn free_cube_frozen_at_once_expands_stress_free() {
    assert!((E_MAX - (1.09f64.cbrt() - 1.0)).abs() < 1e-17);
    for law in [ElasticModel::Linear, ElasticModel::Corotated] {
        let mesh = box_mesh([0.0; 3], [0.05, 0.04, 0.03], [2, 2, 2], 6).unwrap();
        let mut m = model(mesh, law, symmetry_rollers());
        m.freezing = Some(frozen_at_once(&m.mesh));
        let mut sim = Simulation::new(m, settings(Analysis::Static, 1.0)).unwrap();
        sim.step().unwrap();
        // Every edge of every tet grows by exactly (1 + e).
        let x = sim.positions();
        let mut worst: f64 = 0.0;
        for tet in &sim.model.mesh.tets {
            for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                let rest = (sim.model.mesh.rest[tet[a]] - sim.model.mesh.rest[tet[b]]).norm();
                let now = (Vector3::from(x[tet[a]]) - Vector3::from(x[tet[b]])).norm();
                worst = worst.max((now / rest - (1.0 + E_MAX)).abs());
            }
        }
        let stress = sim
            .stresses()
            .iter()
            .flatten()
            .fold(0.0f64, |m, s| m.max(s.abs()));
        eprintln!("{law:?}: edge ratio error {worst:e}, max |σ| {stress:e} Pa");
        // The expansion is 2.9e-2; 1e-10 is round-off of the solve (ice stiffness 1e11 Pa
        // against positions of 1e-2 m).
        assert!(worst < 1e-10, "{law:?}: edge ratio off by {worst:e}");
        // Stress-free to the Newton tolerance: 1e-10 of the confined stress E e ≈ 3e9 Pa.
        assert!(stress < 0.3, "{law:?}: max |σ| = {stress:e} Pa");
    }
}

/// A cube frozen at once inside a frictionless container (floor and four walls, top open):
/// returns (top rise / height, lateral stress σ_xx in Pa) in the middle of the top.
fn confined_cube(law: ElasticModel) -> (f64, f64, Simulation) {
    let size = 0.04;
    let mesh = box_mesh([0.0; 3], [size; 3], [2, 2, 2], 6).unwrap();
    // A stiff penalty (1e18 N/m³) makes the walls rigid to 1e-7 of the expansion.
    let container = Obstacle {
        shape: Shape::Container {
            inner: Region {
                min: Vector3::zeros(),
                max: Vector3::new(size, size, 2.0 * size),
            },
        },
        motion: Default::default(),
        stiffness: 1e18,
        friction: 0.0,
    };
    let mut m = model(mesh, law, vec![]);
    let contact = Contact::new(&m.mesh, vec![container], 1e-4);
    m.add_obstacles(contact);
    m.freezing = Some(frozen_at_once(&m.mesh));
    // Steps of 1 s are static for ice (its period is ~10 µs); backward Euler damps the rest.
    let mut sim = Simulation::new(m, settings(Analysis::Dynamic, 1.0)).unwrap();
    for _ in 0..5 {
        sim.step().unwrap();
    }
    let top: Vec<usize> = (0..sim.model.num_nodes())
        .filter(|&i| sim.model.mesh.rest[i].z > size - 1e-12)
        .collect();
    let rise = top.iter().map(|&i| sim.state.u[3 * i + 2]).sum::<f64>() / top.len() as f64;
    let sxx = sim.stresses().iter().map(|s| s[0]).sum::<f64>() / sim.model.mesh.num_tets() as f64;
    (rise / size, sxx, sim)
}

#[test]
fn confined_cube_rises_and_presses_the_walls_as_the_closed_form_says() {
    let (lambda, mu) = (ICE.lambda, ICE.mu);
    let e = E_MAX;
    // Linear: ε_xx = ε_yy = 0, σ_zz = 0 ⇒ ε_zz = (3λ + 2μ) e / (λ + 2μ), and
    // σ_xx = λ (ε_zz − 3e) − 2μ e = −2μ e (3λ + 2μ) / (λ + 2μ).
    let (strain, sxx, _) = confined_cube(ElasticModel::Linear);
    let strain_exact = (3.0 * lambda + 2.0 * mu) * e / (lambda + 2.0 * mu);
    let sxx_exact = -2.0 * mu * e * (3.0 * lambda + 2.0 * mu) / (lambda + 2.0 * mu);
    eprintln!("linear: rise/H {strain} vs {strain_exact}, σ_xx {sxx:e} vs {sxx_exact:e} Pa");
    // The walls give by σ/k ≈ 5e-9 m against an expansion of 1e-3 m: 1e-5 relative.
    assert!((strain - strain_exact).abs() < 1e-5 * strain_exact);
    assert!((sxx - sxx_exact).abs() < 1e-5 * sxx_exact.abs());
    // Corotated, multiplicative offset Fe = F / (1 + e) with F = diag(1, 1, 1 + ε):
    // S − I = diag(a, a, c), a = 1/(1 + e) − 1; σ_zz = 0 ⇒ c = −2λa / (λ + 2μ),
    // 1 + ε = (1 + c)(1 + e); σ_xx = λ (2a + c) + 2μ a.
    let (strain, sxx, _) = confined_cube(ElasticModel::Corotated);
    let a = 1.0 / (1.0 + e) - 1.0;
    let c = -2.0 * lambda * a / (lambda + 2.0 * mu);
    let strain_exact = (1.0 + c) * (1.0 + e) - 1.0;
    let sxx_exact = lambda * (2.0 * a + c) + 2.0 * mu * a;
    eprintln!("corotated: rise/H {strain} vs {strain_exact}, σ_xx {sxx:e} vs {sxx_exact:e} Pa");
    assert!((strain - strain_exact).abs() < 1e-5 * strain_exact);
    assert!((sxx - sxx_exact).abs() < 1e-5 * sxx_exact.abs());
}

#[test]
fn frozen_volume_follows_the_front_and_elements_freeze_gradually() {
    // Cooling from the bottom only at 1 mm/s, no transition: the ice is the layer below
    // z = speed · t. An element's state is the share of its volume behind the front (sampled
    // at 35 interior points), so the frozen volume Σ s V follows the front's, elements freeze
    // from their lowest vertex's arrival to their highest's, and no two elements of a layer
    // of cells jump to ice in the same step unless the front reaches them together.
    let mesh = box_mesh([0.0; 3], [0.02, 0.02, 0.05], [1, 1, 5], 6).unwrap();
    let speed = 1e-3;
    let (min, max) = mesh.bounding_box();
    let mut cooling = [false; 6];
    cooling[4] = true;
    let freezing = with_water_shear(Freezing::from_front(
        &mesh,
        &Region { min, max },
        cooling,
        speed,
        0.0,
        0.0,
        1.09,
        Water::Bulk { modulus: 2.2e9 },
    ));
    let z_range: Vec<(f64, f64)> = mesh
        .tets
        .iter()
        .map(|t| {
            let z = t.map(|v| mesh.rest[v].z);
            (
                z.iter().copied().fold(f64::INFINITY, f64::min),
                z.iter().copied().fold(0.0, f64::max),
            )
        })
        .collect();
    let volumes: Vec<f64> = mesh
        .tets
        .iter()
        .map(|t| {
            let [a, b, c, d] = t.map(|v| mesh.rest[v]);
            (b - a).cross(&(c - a)).dot(&(d - a)).abs() / 6.0
        })
        .collect();
    let mut m = model(mesh, ElasticModel::Corotated, symmetry_rollers());
    m.freezing = Some(freezing);
    let mut sim = Simulation::new(m, settings(Analysis::Dynamic, 0.5)).unwrap();
    let mut previous = vec![0.0; volumes.len()];
    let mut worst: f64 = 0.0;
    while sim.state.time < 60.0 {
        sim.step().unwrap();
        let front = speed * sim.state.time;
        let states = &sim.state.history.freeze_state;
        let frozen: f64 = states.iter().zip(&volumes).map(|(s, v)| s * v).sum();
        let exact = 0.02 * 0.02 * front.min(0.05);
        worst = worst.max((frozen - exact).abs() / (0.02 * 0.02 * 0.01));
        for (e, s) in states.iter().enumerate() {
            let (lo, hi) = z_range[e];
            assert!(*s >= previous[e], "element {e} thawed");
            if front < lo {
                assert_eq!(*s, 0.0, "element {e} froze before the front reached it");
            }
            if front >= hi {
                assert_eq!(*s, 1.0, "element {e} not frozen after the front passed it");
            }
            // The eigenstrain follows the state.
            assert!((sim.state.history.eigenstrain[e] - s * E_MAX).abs() < 1e-16);
        }
        previous.clone_from(states);
    }
    eprintln!("largest error of the frozen volume: {worst:.4} of a cell");
    // 35 samples in 5 layers per element: the frozen share of a cell the front crosses is
    // off by at most about half a layer of samples, 1/10 of the cell.
    assert!(worst < 0.1, "frozen volume off by {worst} of a cell");
}

/// A 2 cm cube under homogeneous strain: rollers on x = 0, y = 0, z = 0 and prescribed normal
/// displacements `d` on the faces x = L, y = L, z = L.
fn strained_cube(law: ElasticModel, plasticity: Plasticity) -> Simulation {
    let l = 0.02;
    let mesh = box_mesh([0.0; 3], [l; 3], [2, 2, 2], 6).unwrap();
    let mut dirichlet = symmetry_rollers();
    for a in 0..3 {
        let mut min = Vector3::repeat(-1e9);
        min[a] = l - 1e-12;
        let mut axes = [false; 3];
        axes[a] = true;
        dirichlet.push(Dirichlet {
            amplitude: Default::default(),
            region: Region {
                min,
                max: Vector3::repeat(1e9),
            }
            .into(),
            axes,
            displacement: Vector3::zeros(),
            velocity: Vector3::zeros(),
        });
    }
    let mut m = model(mesh, law, dirichlet);
    m.elasticity.plasticity = Some(plasticity);
    Simulation::new(m, settings(Analysis::Static, 1.0)).unwrap()
}

/// Imposes the homogeneous strain diag(strain) on the cube and solves.
fn impose(sim: &mut Simulation, strain: [f64; 3]) {
    for (a, e) in strain.iter().enumerate() {
        sim.model.dirichlet[3 + a].displacement[a] = e * 0.02;
    }
    sim.step().unwrap();
}

fn max_plastic(sim: &Simulation) -> f64 {
    sim.state
        .history
        .plastic_strain
        .iter()
        .map(|p| p.norm())
        .fold(0.0, f64::max)
}

#[test]
fn uniaxial_strain_beyond_the_limit_leaves_the_return_mapping_plastic_strain() {
    let gamma = 1e-3;
    let p = Plasticity {
        elastic_limit: gamma,
        cap: None,
    };
    // Uniaxial strain ε along z: ‖dev‖ = √(2/3) ε. Load to ‖dev‖ = 1.5 γ, then back to zero:
    // ε_p = (‖dev‖ − (1 + δ)γ)/‖dev‖ dev(ε) stays (unloading reaches ‖ε_p‖ = 0.4 γ, elastic).
    let eps = 1.5 * gamma / (2.0f64 / 3.0).sqrt();
    let dev = Matrix3::from_diagonal(&Vector3::new(-eps / 3.0, -eps / 3.0, 2.0 * eps / 3.0));
    // The element keeps (1 + δ)γ of deviatoric strain, the end of the smoothed yield
    // transition, where the stress is the yield stress 2μγ.
    let kept = (1.0 + icefem::fem::YIELD_SMOOTHING) * gamma;
    let expected = dev * (1.0 - kept / dev.norm());
    for (law, tol, stress_tol) in [
        // Linear: exact up to the solve (1e-12 of the strain).
        (ElasticModel::Linear, 1e-12, 1e-11),
        // Corotated: its strain S − I differs from the linear one at second order (ε² ~ 1e-6
        // of a 1e-3 strain), and so does the plastic strain; the residual stress also feels
        // the multiplicative offset: (I + ε_p)⁻¹ = I − ε_p + ε_p² adds λ tr(ε_p²) to σ_zz,
        // (λ / 2μ) ‖ε_p‖ ≈ 6e-4 of it (measured 1.1e-3 with the corotated strain's own terms).
        (ElasticModel::Corotated, 1e-5, 3e-3),
    ] {
        let mut sim = strained_cube(law, p);
        impose(&mut sim, [0.0, 0.0, eps]);
        // Loaded: the converged stress is on the yield surface, von Mises = √(3/2)·2μγ, in
        // every element (the solve's stress is the returned one, not a trial stress). Linear:
        // to the solve's tolerance; corotated: its strain differs at second order (ε ~ 1e-3).
        let yield_stress = 1.5f64.sqrt() * 2.0 * ICE.mu * gamma;
        for s in sim.stresses() {
            let p = (s[0] + s[1] + s[2]) / 3.0;
            let dev2 = (s[0] - p).powi(2)
                + (s[1] - p).powi(2)
                + (s[2] - p).powi(2)
                + 2.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]);
            let von_mises = (1.5 * dev2).sqrt();
            assert!(
                (von_mises / yield_stress - 1.0).abs() < 10.0 * tol,
                "{law:?}: von Mises {von_mises:e} Pa against the yield stress {yield_stress:e} Pa"
            );
        }
        impose(&mut sim, [0.0, 0.0, 0.0]);
        for (e, ep) in sim.state.history.plastic_strain.iter().enumerate() {
            assert!(
                (ep - expected).norm() < tol * expected.norm(),
                "{law:?} element {e}: ε_p = {ep}, expected {expected}"
            );
        }
        // Residual stress after unloading: σ = C:(0 − ε_p) = −2μ ε_p (ε_p is traceless).
        let s = sim.stresses()[0];
        let sigma_zz = -2.0 * ICE.mu * expected[(2, 2)];
        eprintln!("{law:?}: residual σ_zz {} vs −2μ ε_p,zz = {sigma_zz}", s[2]);
        assert!(
            (s[2] - sigma_zz).abs() < stress_tol * sigma_zz.abs(),
            "{law:?}: σ_zz {}",
            s[2]
        );
        // Below the limit nothing accumulates.
        let mut sim = strained_cube(law, p);
        impose(&mut sim, [0.0, 0.0, 0.85 * gamma / (2.0f64 / 3.0).sqrt()]);
        assert_eq!(max_plastic(&sim), 0.0, "{law:?}: yielded below the limit");
        // Pure volume change, 30 × the limit: never yields.
        let mut sim = strained_cube(law, p);
        impose(&mut sim, [0.03; 3]);
        assert!(
            max_plastic(&sim) < 1e-12,
            "{law:?}: volumetric strain yielded"
        );
    }
    // The cap holds however far it is loaded.
    let capped = Plasticity {
        elastic_limit: gamma,
        cap: Some(2e-3),
    };
    let mut sim = strained_cube(ElasticModel::Corotated, capped);
    for k in 1..=5 {
        impose(&mut sim, [0.0, 0.0, 0.004 * k as f64]);
        assert!(
            max_plastic(&sim) <= 2e-3 * (1.0 + 1e-12),
            "cap exceeded: {}",
            max_plastic(&sim)
        );
    }
}

/// The paper's scene, loaded from its file, and its end time (s).
fn paper_scene() -> (Simulation, f64) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/freezing_container.toml");
    let scene = icefem::scene::Scene::load(&path).unwrap();
    let sim = Simulation::new(scene.model.clone(), scene.settings).unwrap();
    (sim, scene.end_time)
}

/// While the outer layer freezes (steps 250–450 of the paper's scene: the wall pressures grow
/// every step), friction at the walls is Coulomb's with the normal force of the *end* of the
/// step: at a node pressed against one wall, the friction force is at most α λ (sticking) and
/// exactly α λ where the node slides — to the re-lag tolerance. And the lag starts from the
/// normal force extrapolated in time, so that one Newton solve per step is usually enough:
/// 237 solves in these 201 steps; from λ at the start of the step it took 438 (and 4 248
/// Newton iterations over the first 600 steps instead of 2 359).
#[test]
fn wall_friction_is_coulomb_with_the_end_of_step_normal_force_while_freezing() {
    let (mut sim, _) = paper_scene();
    let contact = sim.model.obstacle_contact().cloned().unwrap();
    let alpha = contact.obstacles[0].friction;
    let eps = contact.smoothing_velocity * sim.settings.dt;
    let (mut solves, mut steps, mut sliding, mut checked) = (0, 0, 0, 0);
    for n in 1..=450 {
        let before = sim.state.u.clone();
        let report = sim.step().unwrap();
        if n < 250 {
            continue;
        }
        steps += 1;
        solves += report.newton_solves;
        let forces = sim.contact_forces().unwrap();
        let node = |f: &[f64], i: usize| Vector3::new(f[3 * i], f[3 * i + 1], f[3 * i + 2]);
        let largest = (0..sim.model.num_nodes())
            .map(|i| node(&forces.normal, i).norm())
            .fold(0.0, f64::max);
        // The lagged λ of every pair is within FRICTION_RELAG_TOLERANCE × the largest λ of the
        // end-of-step one; at a node that leaves a neighbouring wall a lagged λ there may still
        // be that small and non-zero, hence twice the tolerance.
        let slack = 2.0 * icefem::sim::FRICTION_RELAG_TOLERANCE * largest;
        for i in 0..sim.model.num_nodes() {
            let normal = node(&forces.normal, i);
            // Nodes against exactly one wall (the normal force along one axis).
            if normal.iter().filter(|c| **c != 0.0).count() != 1 {
                continue;
            }
            let lambda = normal.norm();
            let friction = node(&forces.friction, i).norm();
            let wall = normal / lambda;
            let du = node(&sim.state.u, i) - node(&before, i);
            let slip = (du - wall * wall.dot(&du)).norm();
            checked += 1;
            assert!(
                friction <= alpha * (lambda + slack),
                "step {n}, node {i}: friction {friction} N > α λ = {} N",
                alpha * lambda
            );
            if slip > eps {
                sliding += 1;
                assert!(
                    friction >= alpha * (lambda - slack),
                    "step {n}, node {i} slides {slip} m: friction {friction} N < α λ = {} N",
                    alpha * lambda
                );
            }
        }
    }
    eprintln!(
        "{checked} node-steps checked, {sliding} sliding; {solves} Newton solves in {steps} steps"
    );
    assert!(sliding > 100 && checked > sliding);
    assert!(
        (solves as f64) < 1.5 * steps as f64,
        "{solves} Newton solves in {steps} steps"
    );
}

#[test]
fn paper_scene_freezes_2400_frames_with_bounded_energy() {
    let (mut sim, end_time) = paper_scene();
    let steps = icefem::run::step_count(end_time, sim.settings.dt);
    assert_eq!(steps, 2400);
    // Upper bound: the whole volume expanded by e against rigid confinement stores at most
    // ½ K (3e)² V (K the ice's bulk modulus); gravity adds ~1e-3 J.
    let volume = 0.1 * 0.1 * 0.1;
    let bound = 0.5 * ICE.bulk() * (3.0 * E_MAX).powi(2) * volume;
    let top: Vec<usize> = (0..sim.model.num_nodes())
        .filter(|&i| sim.model.mesh.rest[i].z > 0.1 - 1e-12)
        .collect();
    let started = std::time::Instant::now();
    let mut halved = 0;
    for n in 1..=steps {
        // Each step converges (an error would fail here).
        let report = sim.step().unwrap();
        halved += u32::from(report.substeps > 1);
        let e = report.energies.total();
        assert!(
            e.is_finite() && e.abs() < bound,
            "step {n}: energy {e} J (bound {bound} J)"
        );
        if n % 400 == 0 && n >= 1200 {
            let rise: Vec<f64> = top.iter().map(|&i| sim.state.u[3 * i + 2]).collect();
            let (lo, hi) = rise
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &r| {
                    (a.min(r), b.max(r))
                });
            // For calibrating fracture (issue 6): the largest separation stress v⁺/A.
            let separation = icefem::fracture::separation(
                &sim.model.elasticity,
                &sim.state.history,
                &sim.model.mesh.tets,
                &sim.state.u,
                &sim.contact_forces().map_or(Vec::new(), |c| {
                    c.normal
                        .iter()
                        .zip(&c.friction)
                        .map(|(n, f)| n + f)
                        .collect()
                }),
                icefem::fracture::area_floor(&sim.model.mesh),
                None,
            )
            .iter()
            .map(|s| s.stress())
            .fold(0.0, f64::max);
            eprintln!(
                "frame {n}: max ‖ε_p‖ {:.4e}, top rise {lo:.4e} … {hi:.4e} m, frozen {:.1} %, energy {e:.4e} J, max separation stress {separation:.3e} Pa",
                max_plastic(&sim),
                100.0 * sim.state.history.freeze_state.iter().filter(|s| **s >= 1.0).count() as f64
                    / sim.model.mesh.num_tets() as f64
            );
        }
    }
    eprintln!(
        "2400 steps in {:.1} s, {halved} halved",
        started.elapsed().as_secs_f64()
    );
    // Everything froze, and the top deformed unevenly (plastic flow is not uniform).
    assert!(sim.state.history.freeze_state.iter().all(|s| *s >= 1.0));
    assert!(max_plastic(&sim) > 0.0);
}

/// The paper's scene with the Cholesky factor kept as CG's preconditioner, in single
/// precision (`reuse_factorization`, the 1e5-tet scene's solver), follows the run that
/// factorises at every refresh through the freezing onset (steps 150–300: the outer layer
/// starts to freeze and press the walls), with far fewer factorisations.
#[test]
fn a_reused_single_precision_factor_follows_the_direct_solver_while_freezing() {
    use icefem::solver::FactorPrecision;
    let (mut direct, _) = paper_scene();
    let (mut reused, _) = paper_scene();
    reused.settings.factor_reuse = true;
    reused.settings.factor_precision = FactorPrecision::Single;
    let mut reused = Simulation::new(reused.model.clone(), reused.settings).unwrap();
    let (mut f_direct, mut f_reused) = (0, 0);
    let (mut n_direct, mut n_reused) = (0, 0);
    let mut worst: f64 = 0.0;
    for n in 1..=300 {
        let d = direct.step().unwrap().newton;
        let r = reused.step().unwrap().newton;
        f_direct += d.factorizations;
        f_reused += r.factorizations;
        n_direct += d.iterations;
        n_reused += r.iterations;
        let scale = direct.state.u.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = direct
            .state
            .u
            .iter()
            .zip(&reused.state.u)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        worst = worst.max(diff / scale.max(f64::MIN_POSITIVE));
        // Both stop Newton at 1e-9 of the force scale; CG with the kept factor solves each
        // Newton system only as accurately as Newton asks, so the iterates differ by about
        // the Newton tolerance times the conditioning of the step's system. Measured: at most
        // 1.5e-8 of max |u| over these steps (245 factorisations direct, 23 reused); 1e-6
        // leaves room while catching a wrong solve.
        assert!(diff <= 1e-6 * scale, "step {n}: {diff:e} of {scale:e}");
    }
    eprintln!(
        "factorisations: {f_direct} direct, {f_reused} reused; Newton iterations: {n_direct} \
         direct, {n_reused} reused; max |Δu| / max |u| = {worst:e}"
    );
    assert_eq!(
        reused.linear_solver().factor_precision(),
        Some(FactorPrecision::Single)
    );
    assert!(2 * f_reused < f_direct, "{f_reused} vs {f_direct}");
    // The kept factor's chord iterations bring the contact part of the matrix to each iterate
    // (the direct solver's chord keeps the whole Hessian of the solve's first iterate), so
    // nodes leaving the walls or passing between sticking and sliding do not stall them; the
    // yielding elements' tangents are not brought up to date, and cost a few iterations.
    // Measured: 924 Newton iterations against 866; 1.2 × leaves room while catching a stalled
    // kept factor.
    assert!(
        (n_reused as f64) < 1.2 * n_direct as f64,
        "{n_reused} vs {n_direct} Newton iterations"
    );
}

#[test]
fn freezing_from_the_surface_or_the_obstacles_matches_the_box_faces_it_equals() {
    // On a box the distance to its surface is the distance to the nearest of its six faces,
    // and in the freezing container the faces touching the container are the walls and the
    // floor: the schedules must agree sample for sample (distances are exact, so to 1e-12 s).
    let scene = |cooling: &str| {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/scenes/freezing_container.toml"
        ))
        .unwrap();
        let start = text.find("cooling = ").unwrap();
        let end = start + text[start..].find('\n').unwrap();
        let text = format!("{}cooling = {cooling}{}", &text[..start], &text[end..]);
        icefem::scene::Scene::parse(&text, std::path::Path::new("/tmp/freezing.toml")).unwrap()
    };
    let arrival = |cooling: &str| {
        scene(cooling)
            .model
            .freezing
            .unwrap()
            .arrival()
            .unwrap()
            .to_vec()
    };
    let same = |a: &[[f64; icefem::physics::freezing::SAMPLES]],
                b: &[[f64; icefem::physics::freezing::SAMPLES]]| {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f64, f64::max)
    };
    let walls_and_floor = arrival(r#"["walls", "bottom"]"#);
    let obstacles = arrival(r#"["obstacles"]"#);
    let d = same(&walls_and_floor, &obstacles);
    assert!(d < 1e-12, "obstacles vs walls + bottom: {d:e} s");
    let six = arrival(r#"["walls", "bottom", "top"]"#);
    let surface = arrival(r#"["surface"]"#);
    let d = same(&six, &surface);
    assert!(d < 1e-12, "surface vs all six faces: {d:e} s");
}

#[test]
fn surface_cooling_errors_name_the_field() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/freezing_container.toml"
    ))
    .unwrap();
    let with = |cooling: &str| text.replace(r#"cooling = ["walls", "bottom", "top"]"#, cooling);
    let err = |t: &str| {
        icefem::scene::Scene::parse(t, std::path::Path::new("/tmp/freezing.toml"))
            .unwrap_err()
            .to_string()
    };
    let e = err(&with(r#"cooling = ["surface", "walls"]"#));
    assert!(
        e.contains("freezing.cooling") && e.contains("stand alone"),
        "{e}"
    );
    let e = err(&with(
        "cooling = [\"surface\"]\nmin = [0.0, 0.0, 0.0]\nmax = [0.1, 0.1, 0.1]",
    ));
    assert!(e.contains("freezing.min"), "{e}");
    // No obstacle at all: nothing touches one.
    let start = text.find("[[obstacle]]").unwrap();
    let end = start + text[start..].find("[freezing]").unwrap();
    let bare = format!("{}{}", &text[..start], &text[end..]);
    let e = err(&bare.replace(
        r#"cooling = ["walls", "bottom", "top"]"#,
        r#"cooling = ["obstacles"]"#,
    ));
    assert!(
        e.contains("freezing.cooling") && e.contains("no boundary face"),
        "{e}"
    );
}
