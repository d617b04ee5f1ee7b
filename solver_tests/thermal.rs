//! Heat conduction with freezing: scikit-fem's P1 heat equation on the same mesh, Neumann's
//! two-phase Stefan solution, and the energy balance of every step.

mod common;
use common::{load_scene as load, reference_file, run_options as options};
use icefem::mesh::{box_mesh, TetMesh};
use icefem::thermal::monotone::EXTREMUM_TOLERANCE;
use icefem::thermal::neumann::Neumann;
use icefem::thermal::{Heat, HeatBoundary, Phase, Phases};

/// Lumped nodal masses ρ V / 4 per element (kg).
fn lumped_mass(mesh: &TetMesh, rho: f64) -> Vec<f64> {
    let mut m = vec![0.0; mesh.num_nodes()];
    for (e, t) in mesh.tets.iter().enumerate() {
        for &i in t {
            m[i] += rho * mesh.signed_volume(e).abs() / 4.0;
        }
    }
    m
}

#[test]
fn conduction_matches_scikit_fem_step_by_step() {
    let (file, mesh) = reference_file("heat_bar");
    let attr = |name: &str| file.attr(name).unwrap().read_scalar::<f64>().unwrap();
    let fixed = file
        .dataset("mesh/dirichlet_nodes")
        .unwrap()
        .read_raw::<i64>()
        .unwrap();
    let faces = file
        .dataset("mesh/robin_faces")
        .unwrap()
        .read_2d::<i64>()
        .unwrap();
    let reference = file
        .dataset("solution/temperature")
        .unwrap()
        .read_2d::<f64>()
        .unwrap();
    // Ice throughout, no latent heat: the linear heat equation scikit-fem solves.
    let ice = Phase {
        conductivity: attr("conductivity"),
        heat_capacity: attr("heat_capacity"),
    };
    let phases = Phases {
        ice,
        water: ice,
        latent_heat: 0.0,
        ..Phases::WATER_ICE
    };
    let boundary = HeatBoundary {
        fixed: fixed
            .iter()
            .map(|&i| (i as usize, attr("t_wall")))
            .collect(),
        convection: faces
            .rows()
            .into_iter()
            .map(|r| {
                (
                    [r[0], r[1], r[2]].map(|i| i as usize),
                    attr("h"),
                    attr("t_air"),
                )
            })
            .collect(),
    };
    let initial = vec![attr("t_initial"); mesh.num_nodes()];
    let mass = lumped_mass(&mesh, attr("density"));
    let mut heat = Heat::new(&mesh, mass, phases, &boundary, initial).unwrap();
    let dt = attr("dt");
    let (mut worst, mut factorizations) = (0.0f64, 0);
    for step in 1..reference.nrows() {
        let report = heat.step(dt, step as f64 * dt).unwrap();
        // Linear: one Newton iteration solves it.
        assert_eq!(report.newton_iterations, 1, "step {step}");
        factorizations += report.factorizations;
        let expected = reference.row(step);
        let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in heat.temperature().iter().zip(expected.iter()) {
            worst = worst.max((a - b).abs() / scale);
        }
    }
    // Both solve the same linear systems directly (scikit-fem refined to round-off): what is
    // left is the round-off of two factorisations and the Newton form's residual tolerance
    // (1e-10 of the largest diagonal times 1 K, i.e. ≤ 1e-10 K here).
    assert!(
        worst <= 1e-8,
        "largest difference {worst:.2e} of the largest temperature"
    );
    // The matrix is the same every step (fixed step, conductivities and capacities): it is
    // factorised once for the run, as scikit-fem does.
    assert_eq!(factorizations, 1);
}

/// What a Stefan run measured.
struct Front {
    /// Largest |X_h / X − 1| from a quarter of the run on (the front then several cells in).
    worst: f64,
    /// X_h / X − 1 at the end.
    at_end: f64,
    /// Largest |enthalpy change − heat in| of a step relative to the heat it moved.
    imbalance: f64,
    /// Newton iterations per step, the largest.
    newton: usize,
}

/// A slender bar (0.2 m, 5 mm square) of water at `t0` °C whose end x = 0 is held at −10 °C
/// from t = 0, the other faces insulated, in `cells` cells along x and steps of `dt` to `end`
/// (s): the front's position from the frozen mass, X_h = Σ m_i f_i / (ρ A), against
/// Neumann's solution.
fn stefan_front(cells: usize, dt: f64, phases: Phases, end: f64, t0: f64) -> Front {
    let (length, side, rho, t_wall) = (0.2, 0.005, 916.0, -10.0);
    let mesh = box_mesh([0.0; 3], [length, side, side], [cells, 1, 1], 6).unwrap();
    let fixed = (0..mesh.num_nodes())
        .filter(|&i| mesh.rest[i].x < 1e-12)
        .map(|i| (i, t_wall))
        .collect();
    let boundary = HeatBoundary {
        fixed,
        convection: Vec::new(),
    };
    let mass = lumped_mass(&mesh, rho);
    let mut heat = Heat::new(&mesh, mass, phases, &boundary, vec![t0; mesh.num_nodes()]).unwrap();
    let exact = Neumann::new(&phases, rho, t_wall, t0);
    let area = side * side;
    let mut front = Front {
        worst: 0.0,
        at_end: 0.0,
        imbalance: 0.0,
        newton: 0,
    };
    let steps = (end / dt).round() as usize;
    for k in 1..=steps {
        let t = k as f64 * dt;
        let s = heat.step(dt, t).unwrap();
        let moved = s.enthalpy_change.abs().max(s.heat_in.abs());
        front.imbalance = front.imbalance.max(s.imbalance() / moved);
        front.newton = front.newton.max(s.newton_iterations);
        if t >= end / 4.0 {
            let error = heat.frozen_mass() / (rho * area) / exact.front(t) - 1.0;
            front.worst = front.worst.max(error.abs());
            front.at_end = error;
        }
    }
    front
}

#[test]
fn the_front_follows_neumanns_two_phase_solution() {
    // Walls at −10 °C, water at +5 °C, two hours: the front reaches 30 mm. 0.5 mm cells,
    // 10 s steps, 0.1 K mushy range (the default). The error is first order in the cell
    // size and the step (the study below): 1.5 % here, 0.13 mm behind from 30 min on.
    let front = stefan_front(400, 10.0, Phases::WATER_ICE, 7200.0, 5.0);
    assert!(
        front.worst <= 0.02,
        "front position off by {:.2} %",
        100.0 * front.worst
    );
    // Every step conserves energy to the Newton tolerance (1e-10 of the largest diagonal ×
    // 1 K per node, against heat flows of watts).
    assert!(
        front.imbalance <= 1e-10,
        "energy imbalance {:.2e}",
        front.imbalance
    );
    // Newton on the piecewise-quadratic potential: a node crossing a kink of h can cost a
    // few backtracked iterations; none comes near the 50 allowed.
    assert!(
        front.newton <= 20,
        "{} Newton iterations in a step",
        front.newton
    );
}

/// The convergence study of docs/thermal.md (`cargo test --release --test thermal --
/// --ignored --nocapture`): the front's error against cell size and step.
#[test]
#[ignore]
fn stefan_convergence_study() {
    println!("| cell (mm) | step (s) | largest error, t ≥ 30 min | error at 2 h | run time (s) |");
    println!("|---|---|---|---|---|");
    let cases = [
        (100, 2.5),
        (200, 2.5),
        (400, 2.5),
        (800, 2.5),
        (400, 40.0),
        (400, 10.0),
        (400, 0.625),
    ];
    for (cells, dt) in cases {
        let start = std::time::Instant::now();
        let f = stefan_front(cells, dt, Phases::WATER_ICE, 7200.0, 5.0);
        println!(
            "| {} | {dt} | {:.2} % | {:+.2} % | {:.1} |",
            200.0 / cells as f64,
            100.0 * f.worst,
            100.0 * f.at_end,
            start.elapsed().as_secs_f64()
        );
    }
}

/// A 4 cm cube of water at +1 °C in a container whose walls and floor (−10 °C, contact
/// conductance 500 W/(m² K)) and the air above (−10 °C, 10 W/(m² K)) cool it: 10-minute steps.
/// Its ice contracts as it cools below the melting point.
const FREEZING_CUBE: &str = r#"
[mesh]
box = { size = [0.04, 0.04, 0.04], cells = [2, 2, 2] }
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
thermal_expansion = 5e-5
[physics]
gravity = [0.0, 0.0, -9.81]
[[obstacle]]
type = "container"
min = [0.0, 0.0, 0.0]
max = [0.04, 0.04, 0.06]
friction = 0.3
[thermal]
initial_temperature = 1.0
[[thermal.convection]]
faces = ["walls", "bottom"]
h = 500.0
ambient_temperature = -10.0
[[thermal.convection]]
faces = ["top"]
h = 10.0
ambient_temperature = -10.0
[plasticity]
elastic_limit = 1e-4
[time]
dt = 600.0
end_time = 7200.0
output_every = 2
"#;

/// The last frame's positions, freeze states and temperatures, and every frame's mean freeze
/// state.
fn frames(path: &std::path::Path) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let file = hdf5::File::open(path).unwrap();
    let mut names = file.group("frames").unwrap().member_names().unwrap();
    names.sort();
    let read = |name: &str, field: &str| {
        file.dataset(&format!("frames/{name}/{field}"))
            .unwrap()
            .read_raw::<f64>()
            .unwrap()
    };
    let means = names
        .iter()
        .map(|n| {
            let s = read(n, "freeze_state");
            s.iter().sum::<f64>() / s.len() as f64
        })
        .collect();
    let last = names.last().unwrap();
    (
        read(last, "positions"),
        read(last, "freeze_state"),
        read(last, "temperature"),
        means,
    )
}

#[test]
fn a_heat_solve_freezes_the_water_and_resumes_bit_identically() {
    let dir = tempfile::tempdir().unwrap();
    let scene = load(dir.path(), FREEZING_CUBE).unwrap();
    let never = std::sync::atomic::AtomicBool::new(false);
    let full = dir.path().join("full.h5");
    icefem::run::run(&scene, &options(&full, None, false), &never, |_| {}).unwrap();
    let (_, last_state, temperature, means) = frames(&full);
    // Water at the start, ice at the end, never thawing on the way (the surroundings are
    // colder than the water throughout).
    assert_eq!(means[0], 0.0);
    assert!(means.windows(2).all(|w| w[1] >= w[0] - 1e-12), "{means:?}");
    assert!(last_state.iter().all(|&s| s == 1.0), "{last_state:?}");
    assert!(
        temperature.iter().all(|&t| (-10.0..-0.1).contains(&t)),
        "{temperature:?}"
    );
    // Every heat step balances its energy to the solver tolerance: the imbalance against
    // the heat that leaves per step (the latent heat of the cube, 20 kJ, over a few steps).
    let file = hdf5::File::open(&full).unwrap();
    let stat = |name: &str| {
        file.dataset(&format!("stats/{name}"))
            .unwrap()
            .read_raw::<f64>()
            .unwrap()
    };
    let imbalance = stat("heat_imbalance").iter().fold(0.0f64, |m, v| m.max(*v));
    assert!(imbalance <= 1e-6, "heat imbalance {imbalance:.2e} J");
    let iterations = file
        .dataset("stats/heat_newton_iterations")
        .unwrap()
        .read_raw::<u32>()
        .unwrap();
    assert!(
        iterations.iter().all(|&n| (1..=20).contains(&n)),
        "{iterations:?}"
    );
    // The sidecar shows the temperature at the nodes.
    let xdmf = std::fs::read_to_string(full.with_extension("xdmf")).unwrap();
    assert!(
        xdmf.contains("<Attribute Name=\"temperature\" AttributeType=\"Scalar\" Center=\"Node\">")
    );
    // Cut at 1 h and resumed: the same end state, bit for bit.
    let half = dir.path().join("half.h5");
    icefem::run::run(&scene, &options(&half, Some(3600.0), false), &never, |_| {}).unwrap();
    icefem::run::run(&scene, &options(&half, None, true), &never, |_| {}).unwrap();
    let (p_full, s_full, t_full, _) = frames(&full);
    let (p_half, s_half, t_half, _) = frames(&half);
    assert_eq!(p_full, p_half, "positions");
    assert_eq!(s_full, s_half, "freeze states");
    assert_eq!(t_full, t_half, "temperatures");
}

#[test]
fn thermal_scene_errors_name_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let with = |extra: &str| load(dir.path(), &format!("{FREEZING_CUBE}{extra}"));
    let err = with("[freezing]\ncooling = [\"walls\"]\nfront_speed = 1e-3\n").unwrap_err();
    assert!(
        err.contains("freezing.cooling") && err.contains("heat solve places the front"),
        "{err}"
    );
    let err = load(
        dir.path(),
        &FREEZING_CUBE.replace("faces = [\"top\"]", "faces = [\"lid\"]"),
    )
    .unwrap_err();
    assert!(
        err.contains("thermal.convection[1].faces") && err.contains("\"lid\""),
        "{err}"
    );
    let err = load(
        dir.path(),
        &FREEZING_CUBE.replace("initial_temperature = 1.0", "initial_temperature = -300.0"),
    )
    .unwrap_err();
    assert!(
        err.contains("thermal.initial_temperature") && err.contains("273.15"),
        "{err}"
    );
    let err = load(dir.path(), &FREEZING_CUBE.replace("h = 10.0", "h = -1.0")).unwrap_err();
    assert!(err.contains("thermal.convection[1].h"), "{err}");
    // Without [thermal], the prescribed front needs its keys.
    let no_thermal = FREEZING_CUBE
        .split("[thermal]")
        .next()
        .unwrap()
        .replace("thermal_expansion = 5e-5\n", "")
        + "[freezing]\nwater = \"bulk\"\n[time]\ndt = 600.0\nend_time = 7200.0\n";
    let err = load(dir.path(), &no_thermal).unwrap_err();
    assert!(
        err.contains("freezing.cooling") && err.contains("required"),
        "{err}"
    );
}

/// A 2 cm cube of ice at −1 °C (ice from the start: it keeps the mesh's shape and takes no
/// freezing expansion), 27 cells, cooled to −21 °C by a cold bath on its whole surface
/// (h = 1e4 W/(m² K)), on rollers on its three lower faces: free to contract. Static steps of
/// 10 min for 2 h, ~20 of the cube's slowest thermal time constants: it ends at the bath's
/// temperature to round-off.
const COOLED_ICE_CUBE: &str = r#"
[mesh]
box = { size = [0.02, 0.02, 0.02], cells = [3, 3, 3] }
[material]
density = 917.0
youngs_modulus = 9e9
poisson_ratio = 0.33
thermal_expansion = 5e-5
[thermal]
initial_temperature = -1.0
[[thermal.convection]]
faces = ["surface"]
h = 1e4
ambient_temperature = -21.0
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1e-9, 1.0, 1.0]
axes = "x"
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1.0, 1e-9, 1.0]
axes = "y"
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1.0, 1.0, 1e-9]
axes = "z"
[time]
analysis = "static"
dt = 600.0
end_time = 7200.0
output_every = 12
"#;

/// Runs the scene `text` in `dir` to its end and reads the rest positions (m, 3 per node)
/// and `fields` of its last frame.
fn last_frame(dir: &std::path::Path, text: &str, fields: &[&str]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let scene = load(dir, text).unwrap();
    let never = std::sync::atomic::AtomicBool::new(false);
    let out = dir.join("run.h5");
    icefem::run::run(&scene, &options(&out, None, false), &never, |_| {}).unwrap();
    let file = hdf5::File::open(&out).unwrap();
    let mut names = file.group("frames").unwrap().member_names().unwrap();
    names.sort();
    let read = |path: &str| file.dataset(path).unwrap().read_raw::<f64>().unwrap();
    let last = names.last().unwrap();
    let values = fields
        .iter()
        .map(|f| read(&format!("frames/{last}/{f}")))
        .collect();
    (read("mesh/rest_positions"), values)
}

#[test]
fn ice_cooled_freely_contracts_by_its_thermal_strain_without_stress() {
    let dir = tempfile::tempdir().unwrap();
    let fields = ["temperature", "displacement", "stress"];
    let (rest, values) = last_frame(dir.path(), COOLED_ICE_CUBE, &fields);
    let [temperature, displacement, stress] = &values[..] else {
        unreachable!()
    };
    // At the bath's temperature, to the heat solve's tolerance (measured 4e-11 K).
    assert!(
        temperature.iter().all(|t| (t + 21.0).abs() < 1e-9),
        "{temperature:?}"
    );
    // ε_th = α ΔT = 5e-5 × (−20) = −1e-3, uniform: u = ε_th x from the rollers' corner. The
    // corotated model takes the offset as the element's natural shape (1 + ε_th) I, exactly;
    // what is left is round-off (measured 7.8e-16 m) and the temperatures' 4e-11 K (2e-15 of
    // strain, 4e-17 m).
    let strain = 5e-5 * -20.0;
    let worst = rest
        .iter()
        .zip(displacement)
        .map(|(x, u)| (u - strain * x).abs())
        .fold(0.0f64, f64::max);
    assert!(
        worst < 1e-14,
        "largest deviation from ε_th x: {worst:e} m (of 2e-5 m)"
    );
    // And without stress: against E ε_th = 9e6 Pa, below 1e-7 of it (measured 1.8e-3 Pa).
    let largest = stress.iter().fold(0.0f64, |m, s| m.max(s.abs()));
    assert!(largest < 0.9, "largest stress component {largest:e} Pa");
}

#[test]
fn thermal_expansion_errors_name_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let with = |value: &str| {
        load(
            dir.path(),
            &COOLED_ICE_CUBE.replace(
                "thermal_expansion = 5e-5",
                &format!("thermal_expansion = {value}"),
            ),
        )
    };
    // A table of rows is read; a wrong one names the row.
    with("[[-40.0, 4.3e-5], [0.0, 5.3e-5]]").unwrap();
    let err = with("[[0.0, 5e-5], [-10.0, 4e-5]]").unwrap_err();
    assert!(
        err.contains("material.thermal_expansion[1]") && err.contains("increase"),
        "{err}"
    );
    let err = with("0.05").unwrap_err();
    assert!(
        err.contains("material.thermal_expansion") && err.contains("1/K"),
        "{err}"
    );
    let err = with("[[0.0, 5e-5]]").unwrap_err();
    assert!(err.contains("at least two"), "{err}");
    // Thermal strain needs the heat solve's temperatures.
    let no_thermal = COOLED_ICE_CUBE
        .split("[thermal]")
        .next()
        .unwrap()
        .to_string()
        + "[time]\nanalysis = \"static\"\ndt = 1.0\nend_time = 1.0\n";
    let err = load(dir.path(), &no_thermal).unwrap_err();
    assert!(
        err.contains("material.thermal_expansion") && err.contains("[thermal]"),
        "{err}"
    );
}

#[test]
fn ice_cooled_inside_rigid_walls_takes_the_thermal_stress_of_its_bulk_modulus() {
    // The cube of `ice_cooled_freely…` on rollers on all six faces, small-strain model: no
    // strain, so σ = −(3λ + 2μ) ε_th I = −E ε_th / (1 − 2ν) I, tension as it contracts.
    let walls = "[[dirichlet]]\nmin = [0.02, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]\naxes = \"x\"\n\
                 [[dirichlet]]\nmin = [-1.0, 0.02, -1.0]\nmax = [1.0, 1.0, 1.0]\naxes = \"y\"\n\
                 [[dirichlet]]\nmin = [-1.0, -1.0, 0.02]\nmax = [1.0, 1.0, 1.0]\naxes = \"z\"\n";
    let text = COOLED_ICE_CUBE
        .replace(
            "thermal_expansion = 5e-5\n",
            "thermal_expansion = 5e-5\nmodel = \"linear\"\n",
        )
        .replace("[time]", &format!("{walls}[time]"))
        // The stress checked to 1e-9: stored in double precision.
        + "[output]\ndrawn_precision = \"double\"\n";
    let dir = tempfile::tempdir().unwrap();
    let (_, values) = last_frame(dir.path(), &text, &["stress"]);
    let stress = &values[0];
    let expected = 9e9 * (5e-5 * 20.0) / (1.0 - 2.0 * 0.33);
    for s in stress.chunks(6) {
        // Linear in the temperatures, which are at the bath's to 1e-9 K (5e-14 of strain):
        // 1e-9 of the stress leaves room for round-off in the assembly and solve.
        for &normal in &s[..3] {
            assert!(
                (normal - expected).abs() < 1e-9 * expected,
                "{s:?} vs {expected:e}"
            );
        }
        for &shear in &s[3..] {
            assert!(shear.abs() < 1e-9 * expected, "{s:?}");
        }
    }
}

/// An octant of a hollow ice sphere (a = 1 cm, b = 2 cm; gmsh, mesh size 2 mm: 2 518 tets,
/// physical surfaces "inner", "outer", "x0", "y0", "z0") at −1 °C, cooled by convection to
/// −5 °C inside and −25 °C outside until the heat is steady (static steps of 10 min for 2 h),
/// on rollers on its symmetry planes: the free sphere's steady thermal stresses. Small-strain
/// model, as the closed form.
const HOLLOW_SPHERE: &str = r#"
[mesh]
file = "hollow_sphere_octant.msh"
[material]
density = 917.0
youngs_modulus = 9e9
poisson_ratio = 0.33
model = "linear"
thermal_expansion = 5e-5
[thermal]
initial_temperature = -1.0
[[thermal.convection]]
faces = ["inner"]
h = 1e4
ambient_temperature = -5.0
[[thermal.convection]]
faces = ["outer"]
h = 1e4
ambient_temperature = -25.0
[[dirichlet]]
region = "x0"
axes = "x"
[[dirichlet]]
region = "y0"
axes = "y"
[[dirichlet]]
region = "z0"
axes = "z"
[time]
analysis = "static"
dt = 600.0
end_time = 7200.0
output_every = 12
"#;

/// Timoshenko & Goodier's radial displacement (m) of a free hollow sphere a < r < b with the
/// temperature change ΔT(r) = c + d/r from its stress-free state: with
/// I(r) = ∫ₐʳ ΔT s² ds and k = α (1 + ν)/(1 − ν),
/// u = k I / r² + C₁ r + C₂ / r², C₁ = 2α (1 − 2ν)/(1 − ν) I(b)/(b³ − a³),
/// C₂ = k a³ I(b)/(b³ − a³) (σ_r = 0 on both surfaces).
fn hollow_sphere_displacement(
    r: f64,
    (a, b): (f64, f64),
    (c, d): (f64, f64),
    (alpha, nu): (f64, f64),
) -> f64 {
    let integral = |r: f64| c * (r.powi(3) - a.powi(3)) / 3.0 + d * (r * r - a * a) / 2.0;
    let k = alpha * (1.0 + nu) / (1.0 - nu);
    let ib = integral(b) / (b.powi(3) - a.powi(3));
    let c1 = 2.0 * alpha * (1.0 - 2.0 * nu) / (1.0 - nu) * ib;
    let c2 = k * a.powi(3) * ib;
    k * integral(r) / (r * r) + c1 * r + c2 / (r * r)
}

#[test]
fn a_hollow_ice_sphere_takes_the_closed_form_thermal_displacement() {
    let dir = tempfile::tempdir().unwrap();
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("solver_tests/data/thermal");
    std::fs::copy(
        data.join("hollow_sphere_octant.msh"),
        dir.path().join("hollow_sphere_octant.msh"),
    )
    .unwrap();
    let (rest, values) = last_frame(dir.path(), HOLLOW_SPHERE, &["temperature", "displacement"]);
    let (temperature, displacement) = (&values[0], &values[1]);
    let radius: Vec<f64> = rest
        .chunks(3)
        .map(|x| (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt())
        .collect();
    // The steady temperature is A + B/r: fitted to icefem's nodal temperatures by least
    // squares, so the mechanics is checked on the heat field icefem has (within 0.27 K of
    // A + B/r on this mesh; validation/thermoelastic_sphere.md).
    let (mut s, mut s1, mut s2, mut t0, mut t1) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (&r, &t) in radius.iter().zip(temperature) {
        let q = 1.0 / r;
        (s, s1, s2, t0, t1) = (s + 1.0, s1 + q, s2 + q * q, t0 + t, t1 + t * q);
    }
    let det = s * s2 - s1 * s1;
    let (a_fit, b_fit) = ((t0 * s2 - s1 * t1) / det, (s * t1 - s1 * t0) / det);
    let change = (a_fit - -1.0, b_fit);
    let (mut worst, mut largest) = (0.0f64, 0.0f64);
    for ((x, u), &r) in rest.chunks(3).zip(displacement.chunks(3)).zip(&radius) {
        let ur = (x[0] * u[0] + x[1] * u[1] + x[2] * u[2]) / r;
        let exact = hollow_sphere_displacement(r, (0.01, 0.02), change, (5e-5, 0.33));
        worst = worst.max((ur - exact).abs());
        largest = largest.max(exact.abs());
    }
    // P1 on 2.5 mm tets with faceted surfaces: 3.68 % of the largest u_r (1.84e-5 m), falling
    // at second order to 0.31 % at 0.66 mm (validation/thermoelastic_sphere.md); 4 % bounds it.
    let relative = worst / largest;
    assert!(
        relative < 0.04,
        "u_r off the closed form by {:.2} % of its largest",
        100.0 * relative
    );
}

/// A 3 cm column of water at +0.5 °C (0.6 × 0.6 cm, 240 tets) frozen from its −x end through
/// a −10 °C wall (h = 2 000 W/(m² K)) for an hour, held across on all four sides and free
/// at its +x end: 69 % of it freezes. `EXPANSION` is replaced by `[freezing] expansion`.
const FREEZING_COLUMN: &str = r#"
[mesh]
box = { size = [0.03, 0.006, 0.006], cells = [10, 2, 2] }
[material]
density = 917.0
youngs_modulus = 9e9
poisson_ratio = 0.33
[thermal]
initial_temperature = 0.5
[[thermal.convection]]
faces = ["-x"]
h = 2000.0
ambient_temperature = -10.0
[freezing]
water = "bulk"
expansion = "EXPANSION"
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1e-9, 1.0, 1.0]
axes = "x"
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1.0, 1e-9, 1.0]
axes = "y"
[[dirichlet]]
min = [-1.0, 0.006, -1.0]
max = [1.0, 1.0, 1.0]
axes = "y"
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1.0, 1.0, 1e-9]
axes = "z"
[[dirichlet]]
min = [-1.0, -1.0, 0.006]
max = [1.0, 1.0, 1.0]
axes = "z"
[time]
analysis = "static"
dt = 60.0
end_time = 3600.0
output_every = 60
"#;

#[test]
fn ice_formed_in_water_pushes_the_water_and_leaves_the_ice_unstressed() {
    let run = |expansion: &str| {
        let dir = tempfile::tempdir().unwrap();
        let text = FREEZING_COLUMN.replace("EXPANSION", expansion);
        let fields = ["freeze_state", "stress", "displacement"];
        last_frame(dir.path(), &text, &fields)
    };
    // Ice formed in water: the column lengthens by the 9 % of the ice's volume, which pushed
    // the water ahead of it (Σ s V (ratio − 1)/A; the box's tets all have the cell's volume
    // over 6), to 0.5 % (measured 0.23 %; 0.08 % with the mean of the phases' moduli instead
    // of the series blend — the difference is not explained yet), and the ice holds no
    // stress worth the name: below 1 MPa (measured 0.09 MPa) against ice's strength of about
    // 1 MPa.
    let (rest, values) = run("displaces_water");
    let [state, stress, displacement] = &values[..] else {
        unreachable!()
    };
    let frozen = state.iter().sum::<f64>() / state.len() as f64;
    let expected = 0.09 * frozen * 0.03;
    let end: Vec<usize> = (0..rest.len() / 3)
        .filter(|&i| rest[3 * i] > 0.03 - 1e-9)
        .collect();
    let lengthened = end.iter().map(|&i| displacement[3 * i]).sum::<f64>() / end.len() as f64;
    assert!(
        (lengthened / expected - 1.0).abs() < 5e-3,
        "{lengthened:e} vs {expected:e} (frozen {frozen})"
    );
    assert!((0.6..0.8).contains(&frozen), "{frozen}");
    let in_ice = |stress: &[f64], state: &[f64]| {
        stress
            .chunks(6)
            .zip(state)
            .filter(|(_, s)| **s >= 0.999)
            .flat_map(|(s, _)| s.iter().map(|v| v.abs()))
            .fold(0.0f64, f64::max)
    };
    let largest = in_ice(stress, state);
    assert!(largest < 1e6, "{largest:e} Pa");
    // Each element expanding in every direction (the paper's): held across, its ice takes
    // E e_max / (1 − ν) = 391 MPa.
    let (_, values) = run("isotropic");
    let largest = in_ice(&values[1], &values[0]);
    assert!(largest > 3e8, "{largest:e} Pa");
    let dir = tempfile::tempdir().unwrap();
    let err = load(
        dir.path(),
        &FREEZING_COLUMN.replace("EXPANSION", "sideways"),
    )
    .unwrap_err();
    assert!(
        err.contains("freezing.expansion") && err.contains("displaces_water"),
        "{err}"
    );
}

#[test]
fn ice_formed_in_water_with_creep_resumes_bit_identically() {
    // The column, its ice creeping (Glen, in its own temperatures), cut at 30 min and
    // resumed: the inelastic strain (born ice, swollen water, creep) is the frames' plastic
    // strain, so the resumed run ends where the uninterrupted one does, bit for bit.
    let dir = tempfile::tempdir().unwrap();
    let text = FREEZING_COLUMN
        .replace("EXPANSION", "displaces_water")
        .replace("[time]", "[creep]\n[time]")
        .replace("output_every = 60", "output_every = 30");
    let scene = load(dir.path(), &text).unwrap();
    let never = std::sync::atomic::AtomicBool::new(false);
    let full = dir.path().join("full.h5");
    icefem::run::run(&scene, &options(&full, None, false), &never, |_| {}).unwrap();
    let half = dir.path().join("half.h5");
    icefem::run::run(&scene, &options(&half, Some(1800.0), false), &never, |_| {}).unwrap();
    icefem::run::run(&scene, &options(&half, None, true), &never, |_| {}).unwrap();
    let (p_full, s_full, t_full, _) = frames(&full);
    let (p_half, s_half, t_half, _) = frames(&half);
    assert_eq!(p_full, p_half, "positions");
    assert_eq!(s_full, s_half, "freeze states");
    assert_eq!(t_full, t_half, "temperatures");
}

/// The largest rise of the warmest and fall of the coldest temperature over a step (K) of
/// `heat` cooled for `steps` steps of `dt` (s) towards an ambient colder than every node
/// and warmer than none (no heat source of its own above or below the range), and how many
/// positive couplings the steps cancelled.
fn new_extremum(heat: &mut Heat, steps: usize, dt: f64, ambient: f64) -> (f64, usize) {
    let range = |t: &[f64]| {
        t.iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            })
    };
    let (mut worst, mut cancelled) = (0.0f64, 0);
    for k in 1..=steps {
        let (lo, hi) = range(heat.temperature());
        let s = heat.step(dt, k as f64 * dt).unwrap();
        cancelled += s.cancelled_edges;
        let (new_lo, new_hi) = range(heat.temperature());
        worst = worst.max(new_hi - hi).max(lo.min(ambient) - new_lo);
    }
    (worst, cancelled)
}

#[test]
fn heat_on_obtuse_meshes_makes_no_new_extremum() {
    // The gallery's Gmsh ball (969 tets) at 1 °C in −20 °C air, and a box of moved nodes with
    // a warm core.
    // A node whose couplings are all ≤ 0 ends a step within its start, its neighbours and its
    // air (lumped capacities, backward Euler); the heat step cancels the positive couplings
    // of nodes that would not, so nothing may get warmer than the warmest node or colder than
    // the coldest one or the air (by more than the extremum check's 1e-9 K).
    let scene = icefem::scene::Scene::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes/gallery/water_sphere_thermal.toml"),
    )
    .unwrap();
    let thermal = scene.thermal.as_ref().unwrap();
    let mesh = &scene.model.mesh;
    let mut ball = Heat::new(
        mesh,
        scene.model.mass.clone(),
        thermal.phases,
        &thermal.boundary,
        thermal.initial.clone(),
    )
    .unwrap();
    assert!(ball.obtuse_edges() > 0);
    // Plain P1 makes a new extremum of 2.3e-3 K in the first step (measured with every
    // coupling kept): the step cancels 10 couplings there and none after.
    let (worst, cancelled) = new_extremum(&mut ball, 30, 60.0, -20.0);
    assert!(cancelled > 0);
    assert!(
        worst <= EXTREMUM_TOLERANCE,
        "the ball: a new extremum by {worst:.3e} K"
    );

    // The box generator's tets are orthoschemes, never obtuse: its interior nodes moved
    // randomly by up to 0.15 of a cell make a mesh with obtuse angles.
    let flat = common::irregular_box([6, 6, 6], [0.03; 3], 0.15, 23);
    let convection = flat
        .boundary_faces()
        .iter()
        .map(|f| (f.nodes, 200.0, -20.0))
        .collect();
    let boundary = HeatBoundary {
        fixed: Vec::new(),
        convection,
    };
    // A warm core in cool water.
    let initial = flat
        .rest
        .iter()
        .map(|x| {
            if (x - nalgebra::Vector3::repeat(0.015)).norm() < 0.008 {
                5.0
            } else {
                0.5
            }
        })
        .collect();
    let mass = lumped_mass(&flat, 916.0);
    let mut moved_heat = Heat::new(&flat, mass, Phases::WATER_ICE, &boundary, initial).unwrap();
    assert!(moved_heat.obtuse_edges() > 0);
    let (worst, cancelled) = new_extremum(&mut moved_heat, 30, 2.0, -20.0);
    assert!(cancelled > 0);
    assert!(
        worst <= 1e-12,
        "the moved box: a new extremum by {worst:.3e} K"
    );
}
