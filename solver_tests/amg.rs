//! Smoothed-aggregation multigrid as the CG preconditioner: convergence rate on ~1e4 dofs,
//! near-constant iterations with size, agreement with Cholesky, and a simulation run that
//! follows the Cholesky trajectory.

mod common;

use common::ICE;
use icefem::assembly::{Assembly, DofMap};
use icefem::fem::ElasticModel;
use icefem::fem::Material;
use icefem::mesh::{box_mesh, TetMesh};
use icefem::physics::Elasticity;
use icefem::sim::{Analysis, Simulation};
use icefem::solver::{
    FactorPrecision, FillOrdering, IterativeSettings, LinearSolver, LinearSolverKind,
};
use nalgebra::Vector3;

/// Relative residual CG is asked for.
const TOLERANCE: f64 = 1e-8;

/// Constraint masks of the test cubes (10 cm, `cells` per axis, nodes at z = 0 constrained).
#[derive(Clone, Copy)]
enum Support {
    /// Base clamped in x, y and z.
    Clamped,
    /// Rollers as in the freezing container: the base holds z, the face x = 0 holds x, the
    /// face y = 0 holds y — nodes with one or two of three dofs constrained.
    Rollers,
}

fn constrained(mesh: &TetMesh, support: Support) -> Vec<bool> {
    let mut c = vec![false; 3 * mesh.num_nodes()];
    for (i, p) in mesh.rest.iter().enumerate() {
        match support {
            Support::Clamped => {
                if p.z <= 1e-9 {
                    c[3 * i..3 * i + 3].fill(true);
                }
            }
            Support::Rollers => {
                c[3 * i] = p.x <= 1e-9;
                c[3 * i + 1] = p.y <= 1e-9;
                c[3 * i + 2] = p.z <= 1e-9;
            }
        }
    }
    c
}

/// The stiffness of a linear-elastic ice cube (free system) and a load: gravity-like, plus a
/// sideways part so that every mode is excited.
fn cube_system(cells: usize, support: Support) -> (TetMesh, Assembly, Vec<f64>, Vec<f64>) {
    cube_system_of(cells, support, ICE)
}

fn cube_system_of(
    cells: usize,
    support: Support,
    material: Material,
) -> (TetMesh, Assembly, Vec<f64>, Vec<f64>) {
    let mesh = box_mesh([0.0; 3], [0.1; 3], [cells; 3], 6).expect("valid box");
    let elasticity = Elasticity::new(&mesh, material, ElasticModel::Linear);
    let assembly = Assembly::new(&mesh, DofMap::new(&constrained(&mesh, support)));
    let u = vec![0.0; 3 * mesh.num_nodes()];
    let mut values = vec![0.0; assembly.nnz()];
    let mut energies = vec![0.0; mesh.num_tets()];
    let mut gradient = vec![0.0; u.len()];
    let history = elasticity.initial_history();
    assembly.assemble(
        |e, h, out| elasticity.element(&mesh.tets, &history, &u, e, h, out),
        &mut energies,
        &mut gradient,
        Some(&mut values),
    );
    let b = assembly
        .dofs()
        .free_dofs()
        .iter()
        .map(|&d| [3.0, 1.0, -9.81][d % 3] * (1.0 + (d / 3) as f64 * 1e-3))
        .collect();
    (mesh, assembly, values, b)
}

/// Solves with `kind`; returns the solution, the iterations and the relative residual.
fn solve(
    kind: LinearSolverKind,
    mesh: &TetMesh,
    assembly: &Assembly,
    values: &[f64],
    b: &[f64],
) -> (Vec<f64>, usize, f64) {
    let (x, iterations, residual, _) = solve_with(kind, mesh, assembly, values, b);
    (x, iterations, residual)
}

/// As [`solve`], also returning the solver that was in use at the end.
fn solve_with(
    kind: LinearSolverKind,
    mesh: &TetMesh,
    assembly: &Assembly,
    values: &[f64],
    b: &[f64],
) -> (Vec<f64>, usize, f64, LinearSolverKind) {
    let mut solver = LinearSolver::new(
        kind,
        FillOrdering::Auto,
        assembly,
        &mesh.rest,
        &IterativeSettings {
            tolerance: TOLERANCE,
            max_iterations: 20_000,
            amg_reuse: true,
            factor_reuse: false,
            factor_precision: FactorPrecision::Single,
        },
    )
    .expect("solver set-up");
    solver.factorize(assembly, values).expect("set-up");
    let mut x = vec![0.0; b.len()];
    let stats = solver.solve(assembly, values, b, &mut x).expect("solve");
    let residual = relative_residual(assembly, values, &x, b);
    (x, stats.iterations, residual, solver.kind())
}

/// Euclidean norm.
fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// ‖b − A x‖ / ‖b‖ for the matrix with `values` on `assembly`'s pattern.
fn relative_residual(assembly: &Assembly, values: &[f64], x: &[f64], b: &[f64]) -> f64 {
    let mut ax = vec![0.0; b.len()];
    assembly.multiply(values, x, &mut ax);
    let r: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
    norm(&r) / norm(b)
}

/// Average residual reduction per iteration: (relative residual)^(1 / iterations).
fn rate(iterations: usize, relative_residual: f64) -> f64 {
    relative_residual.powf(1.0 / iterations as f64)
}

#[test]
fn amg_cg_converges_fast_on_1e4_dofs_where_jacobi_crawls() {
    // 16³ cells: 4913 nodes, 14 739 free dofs, static stiffness only (no mass: the hardest
    // case for a preconditioner, condition number ~ h⁻²).
    let (mesh, assembly, values, b) = cube_system(16, Support::Clamped);
    assert!(assembly.dofs().num_free() > 10_000);
    let (_, it_amg, res_amg) = solve(LinearSolverKind::Amg, &mesh, &assembly, &values, &b);
    let (_, it_jac, res_jac) = solve(LinearSolverKind::Cg, &mesh, &assembly, &values, &b);
    let (rate_amg, rate_jac) = (rate(it_amg, res_amg), rate(it_jac, res_jac));
    eprintln!(
        "AMG-CG {it_amg} it. (rate {rate_amg:.3}), Jacobi-CG {it_jac} it. (rate {rate_jac:.3})"
    );
    assert!(res_amg <= TOLERANCE);
    // Measured: 14 iterations, a reduction of 0.24 per iteration (pyamg's SA needs ~20 at
    // 1e4 dofs on a similar cube); Jacobi-CG needs 389 (0.954). The bounds — 20 iterations,
    // 0.4 per iteration (1e-8 in 20 iterations is 0.40) — leave room for round-off and
    // platform differences but fail if the hierarchy degrades towards a one-level method
    // (a wrong prolongator or smoother gives ≥ 50 iterations, a rate ≥ 0.7).
    assert!(it_amg <= 20, "AMG-CG took {it_amg} iterations");
    assert!(rate_amg <= 0.4, "AMG-CG reduction rate {rate_amg}");
    assert!(rate_jac > 0.9, "Jacobi-CG reduction rate {rate_jac}");
}

#[test]
fn amg_iterations_grow_little_with_size() {
    // 8³ cells (1 944 free dofs, two levels) against 20³ (26 460, three levels): 14× the
    // dofs, 2.5× finer. CG with an h-independent preconditioner keeps its iterations flat;
    // Jacobi's grow like h⁻¹ (2.5× here). Measured 14 → 20; allowing 1.6× catches a loss
    // of h-independence.
    let mut iterations = Vec::new();
    for cells in [8, 20] {
        let (mesh, assembly, values, b) = cube_system(cells, Support::Clamped);
        let (_, it, _) = solve(LinearSolverKind::Amg, &mesh, &assembly, &values, &b);
        iterations.push(it);
    }
    eprintln!("AMG-CG iterations 1 944 → 26 460 dofs: {iterations:?}");
    assert!(
        (iterations[1] as f64) <= 1.6 * iterations[0] as f64,
        "{iterations:?}"
    );
}

#[test]
fn amg_solution_matches_cholesky_with_partly_constrained_nodes() {
    // Rollers: nodes on the supported faces keep one or two free dofs, which the multigrid
    // pads with decoupled rows; the answer must not notice.
    let (mesh, assembly, values, b) = cube_system(10, Support::Rollers);
    let (x_amg, it, res) = solve(LinearSolverKind::Amg, &mesh, &assembly, &values, &b);
    let (x_chol, _, _) = solve(LinearSolverKind::Cholesky, &mesh, &assembly, &values, &b);
    let scale = x_chol.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = x_amg
        .iter()
        .zip(&x_chol)
        .fold(0.0f64, |m, (a, c)| m.max((a - c).abs()));
    eprintln!(
        "rollers: {it} it., relative residual {res:e}, max |Δx| / max |x| = {:e}",
        diff / scale
    );
    // A relative residual of 1e-8 bounds the relative error by κ(K) · 1e-8 in the worst case;
    // the error concentrates in the smooth modes, which multigrid resolves, and measures
    // ~1e-9. 1e-6 is a hundredfold margin that still catches a wrong answer (a preconditioner
    // that mishandles the padded dofs converges to the same system, but if the padding leaked
    // into the operator the solution would differ at O(1)).
    assert!(diff <= 1e-6 * scale, "max |Δx| = {diff:e} of {scale:e}");
    assert!(it <= 30, "{it} iterations");
}

#[test]
fn auto_falls_back_to_cholesky_on_a_nearly_incompressible_body() {
    // ν = 0.4999 (λ = 5000 μ): the volumetric near-null space of such a body is not spanned by
    // rigid-body modes, and smoothed aggregation needs hundreds of iterations (the unfrozen
    // water of the freezing container is this case). 20³ cells = 26 460 free dofs, above the
    // direct threshold, below the fallback limit: `Auto` starts with multigrid and must end
    // with Cholesky and the right answer.
    let soft = Material {
        lambda: 5000.0 * ICE.mu,
        ..ICE
    };
    let (mesh, assembly, values, b) = cube_system_of(20, Support::Clamped, soft);
    assert!(assembly.dofs().num_free() > icefem::solver::linear::AUTO_DIRECT_MAX_DOFS);
    let (_, _, res, kind) = solve_with(LinearSolverKind::Auto, &mesh, &assembly, &values, &b);
    assert_eq!(kind, LinearSolverKind::Cholesky);
    // A direct solve: round-off only (1e-8 is CG's tolerance, far above it).
    assert!(res <= TOLERANCE, "relative residual {res:e}");
}

/// A corotated ice cube, base clamped, gravity with a sideways part, 1/30 s steps.
fn falling_load_sim(linear: LinearSolverKind) -> Simulation {
    let model =
        icefem::bench::clamped_ice_cube(8, Vector3::new(300.0, 0.0, -981.0)).expect("valid model");
    let mut settings = common::settings(Analysis::Dynamic, 1.0 / 30.0);
    settings.linear = linear;
    Simulation::new(model, settings).expect("simulation")
}

#[test]
fn amg_simulation_follows_the_cholesky_trajectory() {
    let mut chol = falling_load_sim(LinearSolverKind::Cholesky);
    let mut amg = falling_load_sim(LinearSolverKind::Amg);
    let mut setups = 0;
    for step in 0..4 {
        chol.step().expect("Cholesky step");
        let report = amg.step().expect("AMG step");
        setups += report.newton.factorizations;
        let scale = chol.state.u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = chol
            .state
            .u
            .iter()
            .zip(&amg.state.u)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        eprintln!("step {step}: max |Δu| / max |u| = {:e}", diff / scale);
        // Both runs stop Newton at a residual of 1e-9 of the loads (`tolerance`), and CG
        // solves each Newton system to 1e-12: the states may differ by the Newton tolerance
        // times the conditioning of the step's system (measured: 3e-16, both Newton runs
        // land at round-off); 1e-7 leaves room while catching any systematic error.
        assert!(diff <= 1e-7 * scale, "step {step}: {diff:e} of {scale:e}");
    }
    // The hierarchy of the first step serves the next ones (the matrix barely changes).
    assert!(setups < 4, "{setups} multigrid set-ups in 4 steps");
}

#[test]
fn a_reused_factor_too_stale_to_converge_is_replaced_and_counted_as_a_set_up() {
    // Cholesky with `factor_reuse` (double precision, so that a fresh factor solves directly):
    // a later matrix is solved by CG preconditioned by the old factor. The same matrix scaled
    // by 1.5 has the old factor as an exact preconditioner (CG: one iteration, no set-up); the
    // nearly incompressible cube's matrix is far from it, the solve must factorise it itself —
    // and report that set-up, which /stats/factorizations counts.
    let (mesh, assembly, ice, b) = cube_system(8, Support::Clamped);
    let soft = Material {
        lambda: 5000.0 * ICE.mu,
        ..ICE
    };
    let (_, _, water, _) = cube_system_of(8, Support::Clamped, soft);
    let mut solver = reusing_cholesky(&assembly, &mesh, FactorPrecision::Double);
    let residual = |values: &[f64], x: &[f64]| relative_residual(&assembly, values, x, &b);
    let mut x = vec![0.0; b.len()];
    assert!(solver.factorize(&assembly, &ice).unwrap().is_some());

    let scaled: Vec<f64> = ice.iter().map(|v| 1.5 * v).collect();
    assert!(solver.factorize(&assembly, &scaled).unwrap().is_none());
    let stats = solver.solve(&assembly, &scaled, &b, &mut x).unwrap();
    assert_eq!((stats.setups, stats.t_setup), (0, 0.0));
    assert!(stats.iterations <= 2, "{} iterations", stats.iterations);
    assert!(residual(&scaled, &x) <= TOLERANCE);

    assert!(solver.factorize(&assembly, &water).unwrap().is_none());
    let stats = solver.solve(&assembly, &water, &b, &mut x).unwrap();
    assert_eq!(stats.setups, 1);
    assert!(stats.t_setup > 0.0 && stats.t_solve > 0.0);
    // The abandoned CG iterations were paid for and are counted, plus the direct solve.
    assert!(stats.iterations > 1);
    // A direct solve after the new factorisation: round-off, far below CG's tolerance.
    assert!(residual(&water, &x) <= 1e-10, "{:e}", residual(&water, &x));
}

/// A Cholesky solver that keeps its factor, in `precision`, as CG's preconditioner, with CG's
/// tolerance at [`TOLERANCE`].
fn reusing_cholesky(
    assembly: &Assembly,
    mesh: &TetMesh,
    precision: FactorPrecision,
) -> LinearSolver {
    LinearSolver::new(
        LinearSolverKind::Cholesky,
        FillOrdering::Auto,
        assembly,
        &mesh.rest,
        &IterativeSettings {
            tolerance: TOLERANCE,
            max_iterations: 1000,
            amg_reuse: true,
            factor_reuse: true,
            factor_precision: precision,
        },
    )
    .expect("solver set-up")
}

#[test]
fn a_reused_factor_solves_only_as_accurately_as_newton_asks() {
    // Newton's forcing term loosens CG preconditioned by a reused factor: asked for 1e-4 it
    // stops there, in fewer iterations than at CG's own tolerance (1e-8). The new matrix is
    // the ice cube's with λ 20 % larger: close enough for the old factor to be a useful
    // preconditioner, far enough to need several iterations.
    let (mesh, assembly, ice, b) = cube_system(8, Support::Clamped);
    let firmer = Material {
        lambda: 1.2 * ICE.lambda,
        ..ICE
    };
    let (_, _, mixed, _) = cube_system_of(8, Support::Clamped, firmer);
    let residual = |x: &[f64]| relative_residual(&assembly, &mixed, x, &b);
    let mut iterations = Vec::new();
    for forcing in [TOLERANCE, 1e-4] {
        let mut solver = reusing_cholesky(&assembly, &mesh, FactorPrecision::Single);
        assert!(solver.factorize(&assembly, &ice).unwrap().is_some());
        assert!(solver.factorize(&assembly, &mixed).unwrap().is_none());
        solver.set_forcing(forcing);
        let mut x = vec![0.0; b.len()];
        let stats = solver.solve(&assembly, &mixed, &b, &mut x).unwrap();
        assert_eq!(
            stats.setups, 0,
            "the old factor should do at {forcing:e}: {stats:?}"
        );
        assert!(residual(&x) <= forcing, "{:e} > {forcing:e}", residual(&x));
        iterations.push(stats.iterations);
    }
    eprintln!("CG iterations at 1e-8 / 1e-4: {iterations:?}");
    assert!(iterations[1] < iterations[0], "{iterations:?}");
    // Never looser than the caps, whatever Newton asks: FORCING_MAX for a first solve (no
    // convergence rate to go by, η = ∞), FORCING_LATER_MAX for later ones.
    use icefem::solver::linear::{FORCING_LATER_MAX, FORCING_MAX};
    for (asked, cap) in [(f64::INFINITY, FORCING_MAX), (0.5, FORCING_LATER_MAX)] {
        let mut solver = reusing_cholesky(&assembly, &mesh, FactorPrecision::Single);
        solver.factorize(&assembly, &ice).unwrap();
        solver.factorize(&assembly, &mixed).unwrap();
        solver.set_forcing(asked);
        let mut x = vec![0.0; b.len()];
        solver.solve(&assembly, &mixed, &b, &mut x).unwrap();
        assert!(
            residual(&x) <= cap,
            "asked {asked}: {:e} > {cap:e}",
            residual(&x)
        );
    }
}

#[test]
fn a_single_precision_factor_preconditions_cg_to_double_precision_accuracy() {
    // The kept factor in f32 (the default): a fresh one brings CG on the f64 matrix to 1e-8 in
    // a few iterations (its error is round-off of f32, ~1e-7 relative, times the conditioning
    // along a few directions), and the solution agrees with the double-precision direct
    // solve to CG's tolerance times the condition number (≤ 1e-5 relative: κ ≈ 1e3 here).
    let (mesh, assembly, ice, b) = cube_system(8, Support::Clamped);
    let mut single = reusing_cholesky(&assembly, &mesh, FactorPrecision::Single);
    let mut double = reusing_cholesky(&assembly, &mesh, FactorPrecision::Double);
    let (mut xs, mut xd) = (vec![0.0; b.len()], vec![0.0; b.len()]);
    for (solver, x) in [(&mut single, &mut xs), (&mut double, &mut xd)] {
        assert!(solver.factorize(&assembly, &ice).unwrap().is_some());
        let stats = solver.solve(&assembly, &ice, &b, x).unwrap();
        assert_eq!(stats.setups, 0);
        eprintln!(
            "{:?}: {} iterations",
            solver.factor_precision(),
            stats.iterations
        );
        assert!(stats.iterations <= 4, "{} iterations", stats.iterations);
    }
    assert_eq!(single.factor_precision(), Some(FactorPrecision::Single));
    assert_eq!(double.factor_precision(), Some(FactorPrecision::Double));
    let residual = relative_residual(&assembly, &ice, &xs, &b);
    assert!(residual <= TOLERANCE, "{residual:e}");
    let d: Vec<f64> = xs.iter().zip(&xd).map(|(s, d)| s - d).collect();
    assert!(norm(&d) <= 1e-5 * norm(&xd), "{:e}", norm(&d) / norm(&xd));
}

#[test]
fn single_precision_gives_way_to_double_where_f32_cannot_factor_the_matrix() {
    // A nearly incompressible cube (λ = 1e9 μ, ν = 0.5 − 5e-10): its stiffness spans ~12
    // decades, beyond f32's 7 digits — the f32 factorisation meets a non-positive pivot or
    // gives a preconditioner CG cannot converge with. The solver switches to double precision
    // for good and solves as the double-precision direct solver does.
    let (mesh, assembly, _, b) = cube_system(6, Support::Clamped);
    let locked = Material {
        lambda: 1e9 * ICE.mu,
        ..ICE
    };
    let (_, _, values, _) = cube_system_of(6, Support::Clamped, locked);
    let mut solver = reusing_cholesky(&assembly, &mesh, FactorPrecision::Single);
    solver.factorize(&assembly, &values).unwrap();
    let mut x = vec![0.0; b.len()];
    let stats = solver.solve(&assembly, &values, &b, &mut x).unwrap();
    eprintln!("{stats:?}");
    assert_eq!(solver.factor_precision(), Some(FactorPrecision::Double));
    // The answer is the double-precision direct solve's, bit for bit: the same factorisation
    // of the same matrix, the same triangular solves.
    let (expected, _, _) = solve(LinearSolverKind::Cholesky, &mesh, &assembly, &values, &b);
    assert_eq!(x, expected);
    // It stays in double precision: a later matrix (the same scaled, for which the kept
    // factor is exact up to scale) is solved by CG with the double-precision factor.
    let scaled: Vec<f64> = values.iter().map(|v| 2.0 * v).collect();
    solver.factorize(&assembly, &scaled).unwrap();
    let stats = solver.solve(&assembly, &scaled, &b, &mut x).unwrap();
    assert!(stats.iterations <= 2, "{stats:?}");
    assert_eq!(solver.factor_precision(), Some(FactorPrecision::Double));
}

#[test]
fn a_factor_that_failed_in_the_next_newton_solve_is_replaced_there_at_once() {
    // A factor kept into the next Newton solve (the next time step) that proved too stale
    // there is, from then on, replaced at the first refresh of a new solve without another
    // attempt — but tried again (a probe) after 1, then 2, 4, … up to STALE_PROBE_PERIOD such
    // replacements while the probes keep failing. Within a solve a factor is still kept.
    use icefem::solver::linear::STALE_PROBE_PERIOD;
    let (mesh, assembly, ice, b) = cube_system(8, Support::Clamped);
    let soft = Material {
        lambda: 5000.0 * ICE.mu,
        ..ICE
    };
    let (_, _, water, _) = cube_system_of(8, Support::Clamped, soft);
    // Double precision: a fresh factor is then a direct solve (one iteration).
    let mut solver = reusing_cholesky(&assembly, &mesh, FactorPrecision::Double);
    let mut x = vec![0.0; b.len()];
    solver.start_newton_solve();
    assert!(solver.factorize(&assembly, &ice).unwrap().is_some());
    // Next solve: the old factor is kept, fails on the water matrix and is replaced.
    solver.start_newton_solve();
    assert!(solver.factorize(&assembly, &water).unwrap().is_none());
    let stats = solver.solve(&assembly, &water, &b, &mut x).unwrap();
    assert_eq!(stats.setups, 1);
    // Each later solve alternates the two matrices, so every probe fails: replacements in
    // runs of 1, 2, 4, 8, 8, … between probes.
    let matrices = [&ice, &water];
    let mut period = 1;
    let mut solve = 0;
    for _probe in 0..5 {
        for _ in 0..period {
            solver.start_newton_solve();
            let values = matrices[solve % 2];
            solve += 1;
            assert!(
                solver.factorize(&assembly, values).unwrap().is_some(),
                "solve {solve}: the factor should have been replaced"
            );
            let stats = solver.solve(&assembly, values, &b, &mut x).unwrap();
            assert_eq!((stats.setups, stats.iterations), (0, 1), "a direct solve");
            // ...and keep the fresh factor for a refresh within the solve (an exact
            // preconditioner up to scale: CG in one or two iterations).
            let scaled: Vec<f64> = values.iter().map(|v| 1.5 * v).collect();
            assert!(solver.factorize(&assembly, &scaled).unwrap().is_none());
            let stats = solver.solve(&assembly, &scaled, &b, &mut x).unwrap();
            assert_eq!(stats.setups, 0);
            assert!(stats.iterations <= 2, "{} iterations", stats.iterations);
        }
        // The probe: the factor is tried once more, fails and is replaced inside the solve.
        solver.start_newton_solve();
        let values = matrices[solve % 2];
        solve += 1;
        assert!(
            solver.factorize(&assembly, values).unwrap().is_none(),
            "solve {solve}: a probe keeps the factor"
        );
        let stats = solver.solve(&assembly, values, &b, &mut x).unwrap();
        assert_eq!(stats.setups, 1, "solve {solve}: the probe fails");
        period = (2 * period).min(STALE_PROBE_PERIOD);
    }
}

#[test]
fn a_reused_factor_takes_a_few_large_diagonal_changes_exactly() {
    // Contacts switching on or off change a few diagonal entries by orders of magnitude; the
    // kept factor takes them exactly by a low-rank (Woodbury) correction, so CG needs no more
    // iterations than with a fresh factor. Here the change is on the diagonal only, so the
    // corrected preconditioner is the new matrix's exact inverse: in double precision one
    // iteration (measured without the correction: 12, one per changed entry plus one), in
    // single precision as many as a fresh f32 factor needs (≤ 4, see above).
    let (mesh, assembly, ice, b) = cube_system(8, Support::Clamped);
    let n = assembly.symbolic().nrows();
    // 11 dofs spread over the cube pressed by a penalty 1e3 × their stiffness (a contact's
    // k A against the ice around a node).
    let pressed: Vec<usize> = (0..11).map(|i| (i * 997 + 5) % n).collect();
    let mut contact = ice.clone();
    for &c in &pressed {
        contact[assembly.diagonal_slot(c)] *= 1e3;
    }
    let residual = |values: &[f64], x: &[f64]| relative_residual(&assembly, values, x, &b);
    // Both directions: contacts switching on (the factor of `ice` for `contact`) and off.
    for (precision, most) in [(FactorPrecision::Double, 1), (FactorPrecision::Single, 4)] {
        for (factored, current) in [(&ice, &contact), (&contact, &ice)] {
            let mut solver = reusing_cholesky(&assembly, &mesh, precision);
            assert!(solver.factorize(&assembly, factored).unwrap().is_some());
            assert!(solver.factorize(&assembly, current).unwrap().is_none());
            let mut x = vec![0.0; b.len()];
            let stats = solver.solve(&assembly, current, &b, &mut x).unwrap();
            eprintln!("{precision:?}: {stats:?}");
            assert_eq!(stats.setups, 0, "{stats:?}");
            assert!(stats.iterations <= most, "{precision:?}: {stats:?}");
            let r = residual(current, &x);
            assert!(r <= TOLERANCE, "{r:e}");
        }
    }
    // More changed entries than the correction takes (MAX_CORRECTED_DOFS): the rest are
    // outliers CG pays for (measured: 17 iterations for the 22 left over), or the factor is
    // replaced — either way the solve is right.
    use icefem::solver::low_rank::MAX_CORRECTED_DOFS;
    let mut many = ice.clone();
    for c in (0..n).step_by(n / (MAX_CORRECTED_DOFS + 20)) {
        many[assembly.diagonal_slot(c)] *= 1e3;
    }
    let mut solver = reusing_cholesky(&assembly, &mesh, FactorPrecision::Double);
    solver.factorize(&assembly, &ice).unwrap();
    solver.factorize(&assembly, &many).unwrap();
    let mut x = vec![0.0; b.len()];
    let stats = solver.solve(&assembly, &many, &b, &mut x).unwrap();
    eprintln!("{stats:?}");
    assert!(stats.iterations > 2, "{stats:?}");
    assert!(
        residual(&many, &x) <= TOLERANCE,
        "{:e}",
        residual(&many, &x)
    );
}
