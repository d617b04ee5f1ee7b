//! Benchmark problems: an ice cube on box meshes of a chosen size, clamped at its base, under
//! gravity, stepped with backward Euler at dt = 1/30 s. Used by `icefem bench`.

use crate::fem::{ElasticModel, Material};
use crate::mesh::box_mesh;
use crate::physics::{Dirichlet, Elasticity, Model, Region};
use crate::sim::{Analysis, SimError, Simulation, StepSettings};
use crate::solver::{FillOrdering, LinearSolverKind, NewtonParams};
use nalgebra::Vector3;
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
}

/// Cells per axis of a cube box mesh with about `tets` tetrahedra (6 per cell).
pub fn cells_for(tets: usize) -> usize {
    ((tets as f64 / 6.0).cbrt().round() as usize).max(1)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Runs `steps` backward-Euler steps of a 10 cm corotated ice cube with ≈ `tets` tets and
/// reports median per-step timings.
pub fn run_size(
    tets: usize,
    steps: usize,
    linear: LinearSolverKind,
    ordering: FillOrdering,
) -> Result<BenchResult, SimError> {
    let start = Instant::now();
    let c = cells_for(tets);
    let mesh =
        box_mesh([0.0; 3], [0.1; 3], [c, c, c], 6).map_err(|e| SimError::Setup(e.to_string()))?;
    let material = Material {
        lambda: 8.64e10,
        mu: 3.70e10,
        density: 916.0,
    };
    let elasticity = Elasticity::new(&mesh, material, ElasticModel::Corotated);
    let base = Dirichlet {
        region: Region {
            min: Vector3::repeat(-1.0),
            max: Vector3::new(1.0, 1.0, 1e-9),
        },
        axes: [true; 3],
        displacement: Vector3::zeros(),
        velocity: Vector3::zeros(),
    };
    // A sideways component makes the problem non-trivial for the corotated rotations.
    let model = Model::new(
        mesh,
        elasticity,
        Vector3::new(3.0, 0.0, -9.81),
        &[],
        None,
        vec![base],
    )
    .map_err(|e| SimError::Setup(e.to_string()))?;
    let settings = StepSettings {
        analysis: Analysis::Dynamic,
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
    };
    let t_model = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let mut sim = Simulation::new(model, settings)?;
    let t_setup = start.elapsed().as_secs_f64();
    let t_symbolic = sim.linear_solver().symbolic_time();
    let mut per_step: Vec<[f64; 6]> = Vec::new();
    for _ in 0..steps {
        let r = sim.step()?;
        let n = r.newton;
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
    Ok(BenchResult {
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

/// Peak resident set size of this process (bytes), from /proc/self/status (Linux).
pub fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}
