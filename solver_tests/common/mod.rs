//! Helpers shared by the integration tests.
#![allow(dead_code)]

use icefem::fem::{ElasticModel, Material};
use icefem::mesh::TetMesh;
use icefem::physics::{Dirichlet, Elasticity, Model, Region};
use icefem::sim::{Analysis, Simulation, StepSettings};
use icefem::solver::{FactorPrecision, LinearSolverKind, NewtonParams};
use nalgebra::Vector3;
use std::path::Path;

/// A clamped ice bar sagging under sideways and downward gravity, damped: 60 tets, 10 steps of
/// 2 ms, a frame every 2 steps (the output and reliability tests' run).
pub const SAGGING_BAR: &str = r#"
[mesh]
box = { size = [0.2, 0.02, 0.02], cells = [10, 1, 1] }
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
[physics]
gravity = [0.0, -3.0, -9.81]
damping = { mass = 0.5, stiffness = 1e-5 }
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1e-9, 1.0, 1.0]
[time]
dt = 0.002
end_time = 0.02
output_every = 2
"#;

/// Ice, as in the paper: λ = 8.64e10 Pa, μ = 3.70e10 Pa, ρ = 916 kg/m³.
pub const ICE: Material = Material {
    lambda: 8.64e10,
    mu: 3.70e10,
    density: 916.0,
};

/// Settings with the scene defaults.
pub fn settings(analysis: Analysis, dt: f64) -> StepSettings {
    StepSettings {
        analysis,
        scheme: Default::default(),
        dt,
        adaptive: None,
        newton: NewtonParams {
            tolerance: 1e-9,
            step_tolerance: 1e-16,
            max_iterations: 50,
        },
        linear: LinearSolverKind::Cholesky,
        ordering: icefem::solver::FillOrdering::Auto,
        cg_tolerance: 1e-12,
        cg_max_iterations: 20_000,
        amg_reuse: true,
        factor_reuse: false,
        factor_precision: FactorPrecision::Single,
    }
}

/// Fixes every dof of the nodes with rest `x ≤ x_max`.
pub fn clamp_below_x(x_max: f64) -> Dirichlet {
    Dirichlet {
        amplitude: Default::default(),
        region: Region {
            min: Vector3::repeat(-1e30),
            max: Vector3::new(x_max, 1e30, 1e30),
        }
        .into(),
        axes: [true; 3],
        displacement: Vector3::zeros(),
        velocity: Vector3::zeros(),
    }
}

/// A simulation of `mesh` made of `material` with gravity `g` and the given supports.
pub fn simulation(
    mesh: TetMesh,
    material: Material,
    model: ElasticModel,
    gravity: [f64; 3],
    dirichlet: Vec<Dirichlet>,
    settings: StepSettings,
) -> Simulation {
    let elasticity = Elasticity::new(&mesh, material, model);
    let model = Model::new(
        mesh,
        elasticity,
        Vector3::from(gravity),
        &[],
        None,
        dirichlet,
    )
    .unwrap();
    Simulation::new(model, settings).unwrap()
}

/// Relative L2 difference ‖a − b‖ / ‖b‖.
pub fn rel_l2(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

/// Deterministic pseudo-random numbers in [−1, 1) (a 64-bit LCG), for irregular meshes.
pub struct Lcg(pub u64);
impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// A box mesh whose interior nodes are moved randomly by up to `jitter` × the cell size.
pub fn irregular_box(cells: [usize; 3], size: [f64; 3], jitter: f64, seed: u64) -> TetMesh {
    let mut mesh = icefem::mesh::box_mesh([0.0; 3], size, cells, 6).unwrap();
    let mut rng = Lcg(seed);
    let h: Vec<f64> = (0..3).map(|a| size[a] / cells[a] as f64).collect();
    for p in mesh.rest.iter_mut() {
        let interior = (0..3).all(|a| p[a] > 1e-12 && p[a] < size[a] - 1e-12);
        if interior {
            for a in 0..3 {
                p[a] += jitter * h[a] * rng.next();
            }
        }
    }
    TetMesh::new(mesh.rest, mesh.tets).unwrap()
}

/// Corotated ice clamped at x = 0 under gravity −z, backward Euler at one step per frame.
pub fn ice_cantilever(mesh: TetMesh) -> Simulation {
    simulation(
        mesh,
        ICE,
        ElasticModel::Corotated,
        [0.0, 0.0, -9.81],
        vec![clamp_below_x(1e-9)],
        settings(Analysis::Dynamic, 1.0 / 30.0),
    )
}

/// The files in `dir` (names), sorted: what a run or an export leaves behind.
pub fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A reference file of `validation/reference/` (`NAME.h5`) and its mesh (`mesh/nodes`,
/// `mesh/tets`, as make_references.py and make_heat_reference.py write them).
#[allow(dead_code)] // not every test binary reads references
pub fn reference_file(name: &str) -> (hdf5::File, TetMesh) {
    let path = format!(
        "{}/validation/reference/{name}.h5",
        env!("CARGO_MANIFEST_DIR")
    );
    let file = hdf5::File::open(&path).unwrap();
    let nodes = file
        .dataset("mesh/nodes")
        .unwrap()
        .read_2d::<f64>()
        .unwrap();
    let tets = file.dataset("mesh/tets").unwrap().read_2d::<i64>().unwrap();
    let nodes: Vec<[f64; 3]> = nodes
        .rows()
        .into_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect();
    let tets: Vec<[usize; 4]> = tets
        .rows()
        .into_iter()
        .map(|r| [0, 1, 2, 3].map(|k| r[k] as usize))
        .collect();
    let mesh = TetMesh::from_arrays(&nodes, tets).unwrap();
    (file, mesh)
}

/// Run options writing to `path`, optionally cut at `end` (s) or resuming it.
#[allow(dead_code)] // not every test binary runs scenes
pub fn run_options(
    path: &std::path::Path,
    end: Option<f64>,
    resume: bool,
) -> icefem::run::RunOptions {
    icefem::run::RunOptions {
        output: Some(path.to_path_buf()),
        end_time: end,
        resume,
        ..Default::default()
    }
}

/// The scene `text`, written to `dir/scene.toml` and loaded; the error's message otherwise.
#[allow(dead_code)] // not every test binary loads scenes
pub fn load_scene(dir: &std::path::Path, text: &str) -> Result<icefem::scene::Scene, String> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    icefem::scene::Scene::load(&path).map_err(|e| e.to_string())
}

/// The simulation of `model`, shared among the processes when the test runs under `mpirun`
/// with more than one (the `mpi` feature; `make test-mpi` runs the scikit-fem validation so),
/// each holding the whole mesh and state (the tests read them); else on this process.
pub fn shared(model: icefem::physics::Model, settings: icefem::sim::StepSettings) -> Simulation {
    #[cfg(feature = "mpi")]
    if let Some(processes) = mpi_processes::get() {
        use icefem::run::Processes;
        Simulation::check(&model, &settings).unwrap();
        let (_, part) = processes.part_model(&model, (true, settings.dt)).unwrap();
        let mut sim = Simulation::for_part(part, settings).unwrap();
        processes.distribute(&mut sim).unwrap();
        return sim;
    }
    Simulation::new(model, settings).unwrap()
}

/// The processes of `mpirun`, if the test runs under it with more than one (the `mpi`
/// feature), MPI and PETSc started.
#[cfg(feature = "mpi")]
pub fn mpi_launched() -> Option<&'static icefem::distributed::MpiProcesses> {
    mpi_processes::get()
}

#[cfg(feature = "mpi")]
mod mpi_processes {
    use icefem::distributed::MpiProcesses;
    use std::sync::OnceLock;

    /// The processes, initialised at the first use and finalised at exit.
    struct Global(MpiProcesses);
    // SAFETY: MPI is initialised with MPI_THREAD_MULTIPLE and the tests of a run under
    // `mpirun` go one at a time (`--test-threads=1`), so no two threads use it at once.
    unsafe impl Send for Global {}
    unsafe impl Sync for Global {}

    static PROCESSES: OnceLock<Option<Global>> = OnceLock::new();

    extern "C" fn finalize() {
        // SAFETY: at exit, after every test: MPI was initialised by `get`.
        unsafe {
            mpi::ffi::MPI_Finalize();
        }
    }

    /// The processes of `mpirun`, if more than one.
    pub fn get() -> Option<&'static MpiProcesses> {
        PROCESSES
            .get_or_init(|| {
                let launched = std::env::var("OMPI_COMM_WORLD_SIZE")
                    .ok()
                    .and_then(|n| n.parse::<usize>().ok())
                    .is_some_and(|n| n > 1);
                if !launched {
                    return None;
                }
                let processes = MpiProcesses::init().expect("MPI and PETSc start");
                // SAFETY: registering a plain function to run at exit.
                unsafe {
                    libc::atexit(finalize);
                }
                Some(Global(processes))
            })
            .as_ref()
            .map(|g| &g.0)
    }
}
