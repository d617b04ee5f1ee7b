//! The benchmark problems, each run once in this process: an ice cube on box meshes of a
//! chosen size, clamped at its base, under gravity, stepped with backward Euler at dt = 1/30 s
//! ([`run_size`]); two such cubes stacked in a container, for the cost of contact
//! ([`contact_cost`]); a pulled cube that splits once, for the cost of fracture
//! ([`fracture_cost`]).

use super::median;
use crate::fem::{ElasticModel, Material};
use crate::mesh::surface::TriSurface;
use crate::mesh::{box_mesh, TetMesh};
use crate::physics::contact::{default_stiffness, Shape};
use crate::physics::ice_contact::IceContactTerm;
use crate::physics::obstacle_mesh::ObstacleSurface;
use crate::physics::{Contact, Dirichlet, Elasticity, Model, Obstacle, Region};
use crate::sim::{Analysis, SimError, Simulation, StepSettings};
use crate::solver::{FactorPrecision, FillOrdering, LinearSolverKind, NewtonParams};
use nalgebra::Vector3;
use std::sync::Arc;
use std::time::Instant;

/// Timings of one benchmark size (seconds unless noted).
#[derive(Clone, Debug, Default)]
pub struct BenchResult {
    /// Tetrahedra.
    pub tets: usize,
    /// Free dofs.
    pub dofs: usize,
    /// Stored entries of the free-system matrix.
    pub nnz: usize,
    /// Entries of the Cholesky factor (0 for CG).
    pub factor_nnz: usize,
    /// Mesh generation and model set-up.
    pub t_model: f64,
    /// Pattern, slot map, colouring.
    pub t_pattern: f64,
    /// Symbolic factorisation.
    pub t_symbolic: f64,
    /// Per step, median over the measured steps: assembly (incl. line search energies).
    pub t_assembly: f64,
    /// Per step, median: numeric factorisation (or preconditioner set-up).
    pub t_factorization: f64,
    /// Per step, median: triangular solves (or CG iterations).
    pub t_solve: f64,
    /// Per step, median: whole step.
    pub t_step: f64,
    /// Newton iterations per step (median).
    pub newton_iterations: usize,
    /// Linear iterations per step (median).
    pub linear_iterations: usize,
    /// Peak resident memory of the process (bytes), if the OS reports it.
    pub peak_memory: Option<u64>,
    /// First linear system of the run (the first Newton iteration of step 1, A = K + M/h²
    /// at rest, the system the peer solves): set-up — symbolic analysis plus numeric
    /// factorisation, or the multigrid hierarchy — (s).
    pub t_first_setup: f64,
    /// Its solve: triangular solves, or preconditioned CG to the tolerance (s).
    pub t_first_solve: f64,
    /// Its iterations (1 for Cholesky).
    pub first_iterations: usize,
    /// Multigrid levels (0 for the other solvers).
    pub levels: usize,
    /// Multigrid operator complexity Σ nnz(A_l) / nnz(A_0) (0 for the other solvers).
    pub operator_complexity: f64,
    /// Preconditioner or factor set-ups over the whole run.
    pub setups: usize,
}

/// Cells per axis of a cube box mesh with about `tets` tetrahedra (6 per cell).
pub fn cells_for(tets: usize) -> usize {
    ((tets as f64 / 6.0).cbrt().round() as usize).max(1)
}

/// A 10 cm corotated ice cube of `cells`³ box cells (6 tets each), its base (z = 0) clamped,
/// under gravity `g` (m/s²): the benchmark problem.
pub fn clamped_ice_cube(cells: usize, g: Vector3<f64>) -> Result<Model, SimError> {
    let c = cells;
    let mesh =
        box_mesh([0.0; 3], [0.1; 3], [c, c, c], 6).map_err(|e| SimError::Setup(e.to_string()))?;
    let elasticity = Elasticity::new(&mesh, ICE, ElasticModel::Corotated);
    let base = Dirichlet {
        amplitude: Default::default(),
        region: Region {
            min: Vector3::repeat(-1.0),
            max: Vector3::new(1.0, 1.0, 1e-9),
        }
        .into(),
        axes: [true; 3],
        displacement: Vector3::zeros(),
        velocity: Vector3::zeros(),
    };
    Model::new(mesh, elasticity, g, &[], None, vec![base])
        .map_err(|e| SimError::Setup(e.to_string()))
}

/// Runs `steps` backward-Euler steps of a 10 cm corotated ice cube with ≈ `tets` tets and
/// reports median per-step timings.
///
/// `amg_reuse`: multigrid-preconditioned CG keeps its hierarchy across Newton iterations and
/// steps (see [`StepSettings::amg_reuse`]).
pub fn run_size(
    tets: usize,
    steps: usize,
    linear: LinearSolverKind,
    ordering: FillOrdering,
    amg_reuse: bool,
) -> Result<BenchResult, SimError> {
    let start = Instant::now();
    // A sideways component makes the problem non-trivial for the corotated rotations.
    let model = clamped_ice_cube(cells_for(tets), Vector3::new(3.0, 0.0, -9.81))?;
    let settings = StepSettings {
        amg_reuse,
        ..frame_steps(linear, ordering)
    };
    let t_model = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let mut sim = Simulation::new(model, settings)?;
    let t_setup = start.elapsed().as_secs_f64();
    let t_symbolic = sim.linear_solver().symbolic_time();
    let mut per_step: Vec<[f64; 6]> = Vec::new();
    let mut setups = 0;
    let mut first = (0.0, 0.0, 0);
    for step in 0..steps {
        let r = sim.step()?;
        let n = r.newton;
        setups += n.factorizations;
        if step == 0 {
            let setup = n.t_factorization / n.factorizations.max(1) as f64;
            first = match sim.linear_solver().amg_stats() {
                Some(amg) => {
                    let (iterations, t) = amg.solves.first().copied().unwrap_or_default();
                    (setup, t, iterations)
                }
                None => (
                    t_symbolic + setup,
                    n.t_solve / n.linear_iterations.max(1) as f64,
                    1,
                ),
            };
        }
        per_step.push([
            n.t_assembly,
            n.t_factorization,
            n.t_solve,
            r.t_step,
            n.iterations as f64,
            n.linear_iterations as f64,
        ]);
    }
    let col = |k: usize| median(per_step.iter().map(|r| r[k]).collect());
    let hierarchy = sim.linear_solver().amg_stats().map(|a| a.hierarchy);
    Ok(BenchResult {
        t_first_setup: first.0,
        t_first_solve: first.1,
        first_iterations: first.2,
        levels: hierarchy.as_ref().map_or(0, |h| h.level_dofs.len()),
        operator_complexity: hierarchy.as_ref().map_or(0.0, |h| h.operator_complexity),
        setups,
        tets: sim.model.mesh.num_tets(),
        dofs: sim.assembly().dofs().num_free(),
        nnz: sim.assembly().nnz(),
        factor_nnz: sim.linear_solver().factor_nnz().unwrap_or(0),
        t_model,
        t_pattern: t_setup - t_symbolic,
        t_symbolic,
        t_assembly: col(0),
        t_factorization: col(1),
        t_solve: col(2),
        t_step: col(3),
        newton_iterations: col(4) as usize,
        linear_iterations: col(5) as usize,
        peak_memory: peak_memory(),
    })
}

/// The paper's ice (Lamé parameters in Pa, density in kg/m³).
const ICE: Material = Material {
    lambda: 8.64e10,
    mu: 3.70e10,
    density: 916.0,
};

/// Backward Euler at one step per frame (1/30 s) with a tight Newton tolerance.
fn frame_steps(linear: LinearSolverKind, ordering: FillOrdering) -> StepSettings {
    StepSettings {
        adaptive: None,
        analysis: Analysis::Dynamic,
        scheme: Default::default(),
        dt: 1.0 / 30.0,
        newton: NewtonParams {
            tolerance: 1e-9,
            step_tolerance: 1e-15 * 0.1 * 3f64.sqrt(),
            max_iterations: 50,
        },
        linear,
        ordering,
        cg_tolerance: 1e-10,
        cg_max_iterations: 100_000,
        amg_reuse: true,
        factor_reuse: false,
        factor_precision: FactorPrecision::Single,
    }
}

/// Per-step cost of contact against the elastic assembly (seconds, medians over the steps).
#[derive(Clone, Debug, Default)]
pub struct ContactCost {
    /// Tetrahedra.
    pub tets: usize,
    /// Boundary nodes tested against the obstacles.
    pub boundary_nodes: usize,
    /// Ice–ice candidate (node, triangle) pairs of the last step.
    pub candidates: usize,
    /// Newton iterations per step.
    pub newton_iterations: usize,
    /// Broad phase: ice–ice candidates and pattern update.
    pub t_broad: f64,
    /// Narrow phase: all contact gaps, forces and Jacobians (obstacles and ice–ice).
    pub t_narrow: f64,
    /// Elastic assembly (assembly time without the narrow phase).
    pub t_elastic: f64,
    /// Whole step.
    pub t_step: f64,
}

/// An open-top box of inner size `inner` as a triangle surface whose normals point into the
/// box (the side the ice is on): floor and four walls, two triangles each.
pub fn open_box_surface(inner: &Region) -> TriSurface {
    let (lo, hi) = (inner.min, inner.max);
    let corner = |i: usize| {
        Vector3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    // Quads (counter-clockwise seen from inside the box).
    let quads = [
        [0, 1, 3, 2],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 5, 7, 3],
    ];
    TriSurface {
        vertices: (0..8).map(corner).collect(),
        triangles: quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect(),
    }
}

/// Two 10 cm ice cubes of ≈ `tets`/2 tets each, the upper one resting on the lower, in a
/// container (five planes, or the same box as a triangle mesh when `mesh_container`), with
/// friction 0.3 everywhere; `steps` steps at 1/30 s.
pub fn contact_cost(
    tets: usize,
    steps: usize,
    mesh_container: bool,
) -> Result<ContactCost, SimError> {
    let setup = |e: crate::mesh::MeshError| SimError::Setup(e.to_string());
    let c = cells_for(tets / 2);
    let lower = box_mesh([0.0; 3], [0.1; 3], [c, c, c], 6).map_err(setup)?;
    let upper = box_mesh([0.02, 0.01, 0.1], [0.1; 3], [c, c, c], 6).map_err(setup)?;
    let mesh = TetMesh::concat(vec![lower, upper]).map_err(setup)?;
    let inner = Region {
        min: Vector3::new(-0.01, -0.01, 0.0),
        max: Vector3::new(0.13, 0.12, 0.3),
    };
    let stiffness = default_stiffness(&mesh, ICE.young());
    let shape = if mesh_container {
        Shape::Mesh {
            surface: Arc::new(ObstacleSurface::new(&open_box_surface(&inner))),
        }
    } else {
        Shape::Container { inner }
    };
    let container = Obstacle {
        shape,
        motion: Default::default(),
        stiffness,
        friction: 0.3,
    };
    let elasticity = Elasticity::new(&mesh, ICE, ElasticModel::Corotated);
    let contact = Contact::new(&mesh, vec![container], 1e-4);
    let mut model = Model::new(
        mesh,
        elasticity,
        Vector3::new(0.0, 0.0, -9.81),
        &[],
        None,
        vec![],
    )
    .map_err(setup)?;
    let young = model.elasticity.material.young();
    let ice = IceContactTerm::new(&model.mesh, stiffness, 0.3, 1e-4, &[], young);
    model.add_obstacles(contact);
    model.set_ice_contact(ice);
    let boundary_nodes = model.obstacle_contact().map_or(0, |c| c.nodes.len());
    let mut sim = Simulation::new(
        model,
        frame_steps(LinearSolverKind::Cholesky, FillOrdering::Auto),
    )?;
    let mut rows: Vec<[f64; 5]> = Vec::new();
    for _ in 0..steps {
        let r = sim.step()?;
        rows.push([
            r.t_contact_broad,
            r.t_contact_narrow,
            r.newton.t_assembly - r.t_contact_narrow,
            r.t_step,
            r.newton.iterations as f64,
        ]);
    }
    let col = |k: usize| median(rows.iter().map(|r| r[k]).collect());
    Ok(ContactCost {
        tets: sim.model.mesh.num_tets(),
        boundary_nodes,
        candidates: sim.ice_candidates(),
        newton_iterations: col(4) as usize,
        t_broad: col(0),
        t_narrow: col(1),
        t_elastic: col(2),
        t_step: col(3),
    })
}

/// Cost of fracture after one step (seconds): the check every step pays, and one split.
#[derive(Clone, Debug, Default)]
pub struct FractureCost {
    /// Tetrahedra before the split.
    pub tets: usize,
    /// The step itself.
    pub t_step: f64,
    /// Separation tensors of all nodes (every step pays this).
    pub t_check: f64,
    /// The split itself (conforming edge splits, pinch and piece checks).
    pub t_split: f64,
    /// Rebuilding the simulation on the split mesh (mass, contact, pattern, symbolic
    /// factorisation).
    pub t_remesh: f64,
    /// Taking the step again on the split mesh.
    pub t_resolve: f64,
}

/// A 10 cm ice cube of ≈ `tets` tets, its face x = 0 held in x and the face x = 10 cm pulled
/// to a strain of 1e-4 in one step of 1/30 s (σ ≈ 1e7 Pa > τ = 3e6 Pa), then one split.
pub fn fracture_cost(tets: usize) -> Result<FractureCost, SimError> {
    let setup = |e: crate::mesh::MeshError| SimError::Setup(e.to_string());
    let c = cells_for(tets);
    let mesh = box_mesh([0.0; 3], [0.1; 3], [c, c, c], 6).map_err(setup)?;
    let face = |x: f64, velocity: f64, axes: [bool; 3]| Dirichlet {
        amplitude: Default::default(),
        region: Region {
            min: Vector3::new(x - 1e-9, -1.0, -1.0),
            max: Vector3::new(x + 1e-9, 1.0, 1.0),
        }
        .into(),
        axes,
        displacement: Vector3::zeros(),
        velocity: Vector3::new(velocity, 0.0, 0.0),
    };
    let dt = 1.0 / 30.0;
    let dirichlet = vec![
        face(0.0, 0.0, [true; 3]),
        face(0.1, 1e-4 * 0.1 / dt, [true, false, false]),
    ];
    let elasticity = Elasticity::new(&mesh, ICE, ElasticModel::Corotated);
    let model =
        Model::new(mesh, elasticity, Vector3::zeros(), &[], None, dirichlet).map_err(setup)?;
    let settings = frame_steps(LinearSolverKind::Cholesky, FillOrdering::Auto);
    let mut sim = Simulation::new(model, settings)?;
    let tets = sim.model.mesh.num_tets();
    let t_step = sim.step()?.t_step;
    let mut fracture = crate::fracture::Fracture::new(
        crate::fracture::FractureSettings {
            toughness: 3e6,
            max_events_per_step: 1,
            snap: 0.2,
            min_quality: 0.1,
            render_gap: 0.0,
            nonlocal_length: 0.0,
        },
        &sim.model.mesh,
    );
    let r = fracture.after_step(&mut sim)?;
    if r.events.len() != 1 {
        return Err(SimError::Setup(format!(
            "expected one split, got {} (largest separation {:e} Pa)",
            r.events.len(),
            r.largest_stress
        )));
    }
    Ok(FractureCost {
        tets,
        t_step,
        t_check: r.t_check,
        t_split: r.t_split,
        t_remesh: r.t_remesh,
        t_resolve: r.t_resolve,
    })
}

/// Peak resident set size of this process (bytes), from /proc/self/status (Linux).
pub fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
