//! Finite-difference checks of every term of the incremental potential, through the `StepTerm`
//! interface Newton sees: the gradient against central differences of the energy (along random
//! directions and per dof) and the Hessian, mapped back from the CSC values of the free
//! system, against central differences of the gradient (along random directions and column
//! by column over the free dofs, which also checks that the pattern holds every coupling).
//!
//! Central differences with step ε have a truncation error O(ε²) (relative (ε/ℓ)² for a term
//! that changes on a length ℓ) and a round-off error O(δ/ε) (δ the absolute round-off of the
//! energy or gradient). Each test picks ε from the shortest length on which its term changes
//! (element size, penetration depth, slip, the friction smoothing length ε_v h) and keeps every
//! kink outside the stencil: contact gaps stay ≥ 2e-7 m (obstacles) and ≥ 2e-6 m (ice, also
//! from the penalty's onset δ) from gap 0, against stencils of 1e-9 m or less, and slips are
//! either ≥ 100 ε_v h (sliding) or ≈ 0.02 ε_v h (sticking), far from the profile's switch at
//! |y| = ε_v h. The tolerances sit an order or two above the measured errors (printed with
//! `--nocapture`). A sign or a 1 % factor wrong in a gradient or Hessian gives errors of 1e-2
//! to 1 in the term it touches; friction is also checked alone (the contact term minus its
//! frictionless copy), because beside the penalty's stiffness a sliding friction's Hessian is
//! only ~5e-4 of the largest entry.
//!
//! What is exact: the step terms hold lagged quantities fixed for a solve (friction's normal
//! force, friction frames, the plane a node meets a mesh obstacle on, the inertia predictor,
//! βKₙ), so their derivatives are those of the fixed-lag energy; that is what is checked.
//! Contact anticipation is off (no `anticipate` call). The projected elastic stiffness is
//! exact only where the projection changes nothing (tension); in compression it is shown to
//! differ. The ice–ice penalty's Hessian k A φ″ ∇g ∇gᵀ leaves out k A φ′ ∇²g (the curvature of
//! the triangle's normal and foot point), so it is exact only up to O(|φ′|/ℓ): its tests bound
//! that part and check that it scales with |φ′|, check the crack-copy pairs (constant ∇g)
//! exactly, and check ice friction alone exactly.

mod common;
use common::*;
use icefem::assembly::{Assembly, DofMap};
use icefem::fem::ElasticModel;
use icefem::mesh::TetMesh;
use icefem::physics::contact::{default_stiffness, ContactForces, ObstacleContact, Shape};
use icefem::physics::elasticity::{ElasticStep, Volumetric};
use icefem::physics::history::ElementHistory;
use icefem::physics::ice_contact::IceContactTerm;
use icefem::physics::inertia::{Inertia, StiffnessDamping};
use icefem::physics::loads::{lumped_mass, DeadLoads};
use icefem::physics::plasticity::Plasticity;
use icefem::physics::term::{Solve, StepStartView, StepTerm, Term};
use icefem::physics::{Contact, Elasticity, Model, Obstacle, Region, Traction};
use icefem::scene::Scene;
use icefem::sim::part::Part;
use nalgebra::{Matrix3, Rotation3, Vector3};
use std::path::Path;

/// Random directions per check.
const DIRECTIONS: usize = 4;

/// Relative errors of one finite-difference check.
#[derive(Clone, Copy, Debug)]
struct Errors {
    /// Energy vs gradient along random directions d: max |ΔE/2ε − g·d| / Σ |gᵢ dᵢ| (the sum of
    /// magnitudes, so that a g·d small by cancellation does not inflate it).
    energy_directions: f64,
    /// Energy vs gradient per dof: max |ΔE/2ε − gᵢ| / max |g|.
    energy_dofs: f64,
    /// Gradient vs Hessian along random directions d: max ‖Δg/2ε − H d‖ / ‖|H| |d|‖.
    hessian_directions: f64,
    /// Gradient vs Hessian per free dof: max |Δg/2ε − Hᵢⱼ| / max |H| over all entries.
    hessian_columns: f64,
}

impl Errors {
    fn gradient(&self) -> f64 {
        self.energy_directions.max(self.energy_dofs)
    }
    fn hessian(&self) -> f64 {
        self.hessian_directions.max(self.hessian_columns)
    }
    /// Prints the errors and asserts the gradient's below `tol_g` and the Hessian's below
    /// `tol_h`.
    fn assert_below(&self, what: &str, tol_g: f64, tol_h: f64) {
        eprintln!(
            "{what}: gradient {:.1e} (directions {:.1e}, dofs {:.1e}) ≤ {tol_g:.0e}; \
             Hessian {:.1e} (directions {:.1e}, columns {:.1e}) ≤ {tol_h:.0e}",
            self.gradient(),
            self.energy_directions,
            self.energy_dofs,
            self.hessian(),
            self.hessian_directions,
            self.hessian_columns
        );
        assert!(
            self.gradient() <= tol_g,
            "{what}: gradient vs energy differences {self:?}"
        );
        assert!(
            self.hessian() <= tol_h,
            "{what}: Hessian vs gradient differences {self:?}"
        );
    }
}

fn energy_at(term: &mut dyn StepTerm, u: &[f64]) -> f64 {
    let mut e = 0.0;
    term.add(u, &mut e, None, None);
    e
}

fn gradient_at(term: &mut dyn StepTerm, u: &[f64]) -> Vec<f64> {
    let mut e = 0.0;
    let mut g = vec![0.0; u.len()];
    term.add(u, &mut e, Some(&mut g), None);
    g
}

/// The free-system matrix with CSC `values` as a dense column-major nf × nf array.
fn dense(assembly: &Assembly, values: &[f64]) -> Vec<f64> {
    let s = assembly.symbolic();
    let nf = assembly.dofs().num_free();
    let mut out = vec![0.0; nf * nf];
    for c in 0..nf {
        for (r, v) in s.row_idx_of_col_raw(c).iter().zip(&values[s.col_range(c)]) {
            out[c * nf + r] = *v;
        }
    }
    out
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn axpy(u: &[f64], s: f64, d: &[f64]) -> Vec<f64> {
    u.iter().zip(d).map(|(u, d)| u + s * d).collect()
}

/// Checks `term`'s gradient and Hessian at `u0` by central differences of step `step` (m);
/// `seed` picks the random directions. The energy of the energy-only call must equal the one
/// that comes with the gradient and Hessian (Newton's line search uses the former).
fn check(term: &mut dyn StepTerm, assembly: &Assembly, u0: &[f64], step: f64, seed: u64) -> Errors {
    let n = u0.len();
    let dofs = assembly.dofs();
    let nf = dofs.num_free();
    let mut e0 = 0.0;
    let mut g0 = vec![0.0; n];
    let mut h0 = vec![0.0; assembly.nnz()];
    term.add(u0, &mut e0, Some(&mut g0), Some(&mut h0));
    let e_only = energy_at(term, u0);
    assert!(
        (e_only - e0).abs() <= 1e-12 * e0.abs(),
        "energy {e_only} alone vs {e0} with derivatives"
    );
    let h = dense(assembly, &h0);
    let h_abs: Vec<f64> = h0.iter().map(|x| x.abs()).collect();
    let (g_scale, h_scale) = (max_abs(&g0), max_abs(&h));
    assert!(g_scale > 0.0 && h_scale > 0.0, "the term is inactive here");
    let mut rng = Lcg(seed);
    let free = |g: &[f64]| -> Vec<f64> { dofs.free_dofs().iter().map(|&d| g[d]).collect() };

    let mut energy_directions = 0.0f64;
    let mut hessian_directions = 0.0f64;
    for _ in 0..DIRECTIONS {
        // Energy along a direction over all dofs (the gradient covers all 3n).
        let d: Vec<f64> = (0..n).map(|_| rng.next()).collect();
        let fd = (energy_at(term, &axpy(u0, step, &d)) - energy_at(term, &axpy(u0, -step, &d)))
            / (2.0 * step);
        let exact: f64 = g0.iter().zip(&d).map(|(g, d)| g * d).sum();
        let magnitude: f64 = g0.iter().zip(&d).map(|(g, d)| (g * d).abs()).sum();
        energy_directions = energy_directions.max((fd - exact).abs() / magnitude);
        // Gradient along a direction over the free dofs (the Hessian covers those).
        let mut d_free = vec![0.0; n];
        for &dof in dofs.free_dofs() {
            d_free[dof] = rng.next();
        }
        let gp = free(&gradient_at(term, &axpy(u0, step, &d_free)));
        let gm = free(&gradient_at(term, &axpy(u0, -step, &d_free)));
        let fd: Vec<f64> = gp
            .iter()
            .zip(&gm)
            .map(|(p, m)| (p - m) / (2.0 * step))
            .collect();
        let mut hd = vec![0.0; nf];
        assembly.multiply(&h0, &free(&d_free), &mut hd);
        let mut magnitude = vec![0.0; nf];
        let d_abs: Vec<f64> = free(&d_free).iter().map(|x| x.abs()).collect();
        assembly.multiply(&h_abs, &d_abs, &mut magnitude);
        let diff: Vec<f64> = fd.iter().zip(&hd).map(|(a, b)| a - b).collect();
        hessian_directions = hessian_directions.max(norm(&diff) / norm(&magnitude));
    }

    let mut energy_dofs = 0.0f64;
    let mut u = u0.to_vec();
    for d in 0..n {
        u[d] = u0[d] + step;
        let ep = energy_at(term, &u);
        u[d] = u0[d] - step;
        let em = energy_at(term, &u);
        u[d] = u0[d];
        energy_dofs = energy_dofs.max(((ep - em) / (2.0 * step) - g0[d]).abs() / g_scale);
    }

    let mut hessian_columns = 0.0f64;
    for (c, &d) in dofs.free_dofs().iter().enumerate() {
        u[d] = u0[d] + step;
        let gp = free(&gradient_at(term, &u));
        u[d] = u0[d] - step;
        let gm = free(&gradient_at(term, &u));
        u[d] = u0[d];
        for r in 0..nf {
            let fd = (gp[r] - gm[r]) / (2.0 * step);
            hessian_columns = hessian_columns.max((fd - h[c * nf + r]).abs() / h_scale);
        }
    }
    Errors {
        energy_directions,
        energy_dofs,
        hessian_directions,
        hessian_columns,
    }
}

/// A step term minus another on the same pattern: isolates what the first adds (friction
/// on top of the contact penalty).
struct Minus<'a>(Box<dyn StepTerm + 'a>, Box<dyn StepTerm + 'a>);

impl StepTerm for Minus<'_> {
    fn name(&self) -> &'static str {
        "minus"
    }

    fn add(
        &mut self,
        u: &[f64],
        energy: &mut f64,
        gradient: Option<&mut [f64]>,
        hessian: Option<&mut [f64]>,
    ) {
        let mut e = 0.0;
        let mut g = gradient.as_ref().map(|g| vec![0.0; g.len()]);
        let mut h = hessian.as_ref().map(|h| vec![0.0; h.len()]);
        self.1.add(u, &mut e, g.as_deref_mut(), h.as_deref_mut());
        let (mut gradient, mut hessian) = (gradient, hessian);
        for (x, y) in [(gradient.as_deref_mut(), &g), (hessian.as_deref_mut(), &h)] {
            if let (Some(x), Some(y)) = (x, y) {
                for (x, y) in x.iter_mut().zip(y) {
                    *x -= y;
                }
            }
        }
        self.0.add(u, energy, gradient, hessian);
        *energy -= e;
    }
}

/// Node displacements `u` (3 per node) of positions `x(X)`.
fn displacement_of(mesh: &TetMesh, x: impl Fn(&Vector3<f64>) -> Vector3<f64>) -> Vec<f64> {
    mesh.rest
        .iter()
        .flat_map(|p| {
            let d = x(p) - p;
            [d.x, d.y, d.z]
        })
        .collect()
}

/// Adds a random vector of amplitude `a` (m) to each node's displacement, with its component
/// along `normal` removed if given.
fn jitter(mesh: &TetMesh, u: &mut [f64], a: f64, normal: Option<Vector3<f64>>, seed: u64) {
    let mut rng = Lcg(seed);
    for i in 0..mesh.num_nodes() {
        let mut r = Vector3::new(rng.next(), rng.next(), rng.next()) * a;
        if let Some(n) = normal {
            r -= r.dot(&n) * n;
        }
        for k in 0..3 {
            u[3 * i + k] += r[k];
        }
    }
}

/// Free dofs everywhere except those of the nodes with rest x = 0.
fn clamped_at_x0(mesh: &TetMesh) -> Vec<bool> {
    (0..3 * mesh.num_nodes())
        .map(|d| mesh.rest[d / 3].x < 1e-12)
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Elasticity

/// A homogeneous deformation gradient I + G of strain `strain` (positive: stretch, negative:
/// compression; the symmetric part of G is definite), turned by a large rotation, with a
/// non-affine jitter of 5 % of the strain on each node so every element differs.
fn deformed(mesh: &TetMesh, strain: f64, seed: u64) -> Vec<f64> {
    let g = Matrix3::new(1.0, 0.3, 0.1, 0.2, 0.8, -0.2, 0.1, 0.1, 1.2) * strain;
    let r = Rotation3::from_euler_angles(0.3, -0.5, 0.9).into_inner();
    let mut u = displacement_of(mesh, |p| r * (p + g * p));
    jitter(mesh, &mut u, 0.05 * strain.abs() * 0.04, None, seed);
    u
}

/// The elastic term of an irregular 10 × 8 × 6 cm ice box (2 × 2 × 2 cells, clamped at x = 0)
/// with eigenstrain `eigenstrain` in the elements of x < 5 cm, checked at a rotated strain of
/// `strain`.
fn check_elasticity(
    model: ElasticModel,
    strain: f64,
    eigenstrain: f64,
    project: bool,
    seed: u64,
) -> Errors {
    check_elasticity_with(
        model,
        strain,
        eigenstrain,
        project,
        seed,
        Volumetric::Element,
        None,
    )
}

/// As [`check_elasticity`], with the volumetric discretisation `volumetric` and, if
/// `yield_limit` is given, plasticity with that elastic limit and a plastic strain of 5 × it
/// already in the elements of y < 4 cm.
fn check_elasticity_with(
    model: ElasticModel,
    strain: f64,
    eigenstrain: f64,
    project: bool,
    seed: u64,
    volumetric: Volumetric,
    yield_limit: Option<f64>,
) -> Errors {
    let mesh = irregular_box([2, 2, 2], [0.1, 0.08, 0.06], 0.2, seed);
    let mut elasticity = Elasticity::new(&mesh, ICE, model);
    elasticity.set_volumetric(&mesh, volumetric);
    elasticity.plasticity = yield_limit.map(|elastic_limit| Plasticity {
        elastic_limit,
        cap: None,
    });
    let offsets: Vec<f64> = mesh
        .tets
        .iter()
        .map(|t| {
            let centroid: Vector3<f64> =
                t.iter().map(|&v| mesh.rest[v]).sum::<Vector3<f64>>() / 4.0;
            if centroid.x < 0.05 {
                eigenstrain
            } else {
                0.0
            }
        })
        .collect();
    let mut history = ElementHistory::initial(&offsets, yield_limit.is_some());
    if let Some(gamma) = yield_limit {
        let shear = Matrix3::new(1.0, 0.5, 0.0, 0.5, -0.4, 0.2, 0.0, 0.2, -0.6) * (5.0 * gamma);
        for (e, t) in mesh.tets.iter().enumerate() {
            if t.iter().map(|&v| mesh.rest[v].y).sum::<f64>() / 4.0 < 0.04 {
                history.plastic_strain[e] = shear;
            }
        }
    }
    let assembly = Assembly::with_couplings(
        &mesh,
        DofMap::new(&clamped_at_x0(&mesh)),
        &elasticity.couplings(),
    );
    elasticity.pattern_ready(&assembly);
    let mut element_energy = vec![0.0; mesh.num_tets()];
    let offsets = history.offsets();
    let mut term = ElasticStep::new(
        &elasticity,
        (&mesh.tets, &history, &offsets),
        &assembly,
        &mut element_energy,
        project,
    );
    let u = deformed(&mesh, strain, seed + 1);
    // Strains s = 1 % on elements of ℓ ≈ 4 cm: the energy's curvature is C and its gradient only
    // C s, so the truncation relative to the gradient is ~ (ε/ℓ)² / s: 2e-9 at ε = 5e-7 m,
    // measured, falling as ε². The round-off of the energy (~1e3 J, summed over 48 elements)
    // against ε × forces of ~1e5 N grows as 1/ε: 1.5e-9 at ε = 5e-9 m (6e-9 linear). ε = 5e-8 m
    // sits between: 1e-10 (1e-9 linear).
    check(&mut term, &assembly, &u, 5e-8, seed + 2)
}

#[test]
fn elasticity_corotated_in_tension() {
    // Stretched by 1 % and turned: every twist eigenvalue is positive, so the tangent is the
    // exact Hessian, projected or not.
    check_elasticity(ElasticModel::Corotated, 0.01, 0.0, false, 1).assert_below(
        "elasticity, corotated, tension",
        1e-8,
        1e-8,
    );
    check_elasticity(ElasticModel::Corotated, 0.01, 0.0, true, 1).assert_below(
        "elasticity, corotated, tension, projected",
        1e-8,
        1e-8,
    );
}

#[test]
fn elasticity_corotated_in_compression() {
    // Compressed by 1 % and turned: the twist eigenvalues (ψᵢ + ψⱼ)/(sᵢ + sⱼ) are negative.
    // The unprojected tangent is still the exact Hessian; the projected one (|·| of those
    // eigenvalues, for Newton's descent) is deliberately not, and must differ.
    check_elasticity(ElasticModel::Corotated, -0.01, 0.0, false, 3).assert_below(
        "elasticity, corotated, compression",
        1e-8,
        1e-8,
    );
    let projected = check_elasticity(ElasticModel::Corotated, -0.01, 0.0, true, 3);
    eprintln!(
        "projected in compression: Hessian error {:.1e}",
        projected.hessian()
    );
    assert!(projected.gradient() <= 1e-8, "{projected:?}");
    assert!(
        projected.hessian() > 1e-4,
        "the projection changed nothing: {projected:?}"
    );
}

#[test]
fn elasticity_with_eigenstrain_linear_and_corotated() {
    // A 2 % eigenstrain in half the elements (the multiplicative offset Fe = F (I + ε*)⁻¹ of
    // the corotated model, the additive one of the linear model), stretched by 1 %.
    check_elasticity(ElasticModel::Corotated, 0.01, 0.02, false, 5).assert_below(
        "elasticity, corotated, eigenstrain",
        1e-8,
        1e-8,
    );
    check_elasticity(ElasticModel::Linear, 0.01, 0.02, false, 7).assert_below(
        "elasticity, linear, eigenstrain",
        1e-8,
        1e-8,
    );
}

#[test]
fn elasticity_with_nodal_volumetric_energy() {
    // The averaged nodal pressure: its energy couples each node's star, so the Hessian also
    // checks that the pattern holds those pairs. With eigenstrain, in tension and compression.
    for (model, strain, seed) in [
        (ElasticModel::Linear, 0.01, 11),
        (ElasticModel::Corotated, 0.01, 13),
        (ElasticModel::Corotated, -0.01, 15),
    ] {
        check_elasticity_with(model, strain, 0.02, false, seed, Volumetric::Nodal, None)
            .assert_below(
                &format!("elasticity, nodal volume, {model:?}, {strain}"),
                1e-8,
                1e-8,
            );
    }
}

#[test]
fn elasticity_yielding_inside_the_solve() {
    // Plasticity's incremental potential (consistent tangent) at strains 10 × the elastic
    // limit, with plastic strain already in half the elements, per element and with the
    // nodal volumetric energy. The yielding tangent 2μγ/r changes on the scale of the
    // deviatoric strain r ≈ 1e-2 rather than 1, so the Hessian's truncation error is
    // (ε / (ℓ r))² ≈ 2e-8 at ε = 5e-8 m, ℓ = 4 cm (measured 0.6–1.3e-8): 5e-8 for the Hessian.
    for volumetric in [Volumetric::Element, Volumetric::Nodal] {
        for (model, seed) in [(ElasticModel::Linear, 17), (ElasticModel::Corotated, 19)] {
            check_elasticity_with(model, 0.01, 0.02, false, seed, volumetric, Some(1e-3))
                .assert_below(
                    &format!("elasticity, yielding, {model:?}, {volumetric:?}"),
                    1e-8,
                    5e-8,
                );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Dead loads, inertia, damping

#[test]
fn dead_loads_gravity_and_traction() {
    let mesh = irregular_box([2, 2, 2], [0.1, 0.08, 0.06], 0.2, 9);
    let elasticity = Elasticity::new(&mesh, ICE, ElasticModel::Corotated);
    let traction = Traction {
        amplitude: Default::default(),
        region: Region {
            min: Vector3::new(0.1 - 1e-9, -1.0, -1.0),
            max: Vector3::new(1.0, 1.0, 1.0),
        }
        .into(),
        traction: Vector3::new(2e5, -1e5, 3e5),
    };
    let model = Model::new(
        mesh,
        elasticity,
        Vector3::new(0.0, 0.0, -9.81),
        &[traction],
        None,
        vec![],
    )
    .unwrap();
    let mesh = &model.mesh;
    let assembly = Assembly::new(mesh, DofMap::new(&clamped_at_x0(mesh)));
    let external_force = model.dead_loads_at(0.0);
    let mut term = DeadLoads {
        force: &external_force,
    };
    let u = deformed(mesh, 0.01, 10);
    // −f·u is linear: its gradient is −f, its Hessian zero, and central differences are exact
    // up to the round-off of the sum f·u against ε × forces of ~1e2 N: 1e-10 at ε = 1e-7 m.
    let mut e = 0.0;
    let mut g = vec![0.0; u.len()];
    let mut h = vec![0.0; assembly.nnz()];
    term.add(&u, &mut e, Some(&mut g), Some(&mut h));
    assert!(h.iter().all(|v| *v == 0.0), "dead loads have no Hessian");
    assert!(g.iter().zip(&external_force).all(|(g, f)| *g == -f));
    let step = 1e-7;
    let mut rng = Lcg(11);
    let (mut err_dir, mut err_dof) = (0.0f64, 0.0f64);
    for _ in 0..DIRECTIONS {
        let d: Vec<f64> = (0..u.len()).map(|_| rng.next()).collect();
        let fd = (energy_at(&mut term, &axpy(&u, step, &d))
            - energy_at(&mut term, &axpy(&u, -step, &d)))
            / (2.0 * step);
        let exact: f64 = g.iter().zip(&d).map(|(g, d)| g * d).sum();
        let magnitude: f64 = g.iter().zip(&d).map(|(g, d)| (g * d).abs()).sum();
        err_dir = err_dir.max((fd - exact).abs() / magnitude);
    }
    let scale = max_abs(&g);
    let mut up = u.clone();
    for d in 0..u.len() {
        up[d] = u[d] + step;
        let ep = energy_at(&mut term, &up);
        up[d] = u[d] - step;
        let em = energy_at(&mut term, &up);
        up[d] = u[d];
        err_dof = err_dof.max(((ep - em) / (2.0 * step) - g[d]).abs() / scale);
        // The gradient does not move.
        up[d] = u[d] + step;
        assert_eq!(gradient_at(&mut term, &up), g);
        up[d] = u[d];
    }
    eprintln!("dead loads: gradient {err_dir:.1e} (directions), {err_dof:.1e} (dofs) ≤ 1e-9");
    assert!(
        err_dir <= 1e-9 && err_dof <= 1e-9,
        "{err_dir:e} {err_dof:e}"
    );
}

#[test]
fn inertia_with_mass_damping() {
    let mesh = irregular_box([2, 2, 2], [0.1, 0.08, 0.06], 0.2, 13);
    let mass = lumped_mass(&mesh, |_| ICE.density);
    let assembly = Assembly::new(&mesh, DofMap::new(&clamped_at_x0(&mesh)));
    let n = 3 * mesh.num_nodes();
    let mut rng = Lcg(14);
    let previous: Vec<f64> = (0..n).map(|_| 1e-3 * rng.next()).collect();
    let predictor: Vec<f64> = previous.iter().map(|p| p + 1e-3 * rng.next()).collect();
    let u: Vec<f64> = predictor.iter().map(|p| p + 1e-4 * rng.next()).collect();
    let mut term = Inertia {
        dt: 1e-2,
        mass: &mass,
        predictor: &predictor,
        velocity_form: (1e-2, &previous),
        alpha: 3.0,
        assembly: &assembly,
    };
    // A quadratic: central differences are exact up to round-off, 1e-16 × 1e-2 J / ε against
    // forces of 0.1 N, 1e-11 at ε = 1e-6 m.
    check(&mut term, &assembly, &u, 1e-6, 15).assert_below("inertia + α damping", 1e-10, 1e-10);
}

#[test]
fn stiffness_damping() {
    let mesh = irregular_box([2, 2, 2], [0.1, 0.08, 0.06], 0.2, 17);
    let elasticity = Elasticity::new(&mesh, ICE, ElasticModel::Corotated);
    let history = elasticity.initial_history();
    let assembly = Assembly::new(&mesh, DofMap::new(&clamped_at_x0(&mesh)));
    let previous = deformed(&mesh, -0.005, 18);
    // β Kₙ as the simulation makes it: the projected elastic Hessian at the start of the step.
    let beta = 2e-4;
    let mut beta_k = vec![0.0; assembly.nnz()];
    let mut element_energy = vec![0.0; mesh.num_tets()];
    ElasticStep::new(
        &elasticity,
        (&mesh.tets, &history, &history.offsets()),
        &assembly,
        &mut element_energy,
        true,
    )
    .add(
        &previous,
        &mut 0.0,
        Some(&mut vec![0.0; previous.len()]),
        Some(&mut beta_k),
    );
    beta_k.iter_mut().for_each(|k| *k *= beta);
    let mut rng = Lcg(19);
    let u: Vec<f64> = previous.iter().map(|p| p + 1e-5 * rng.next()).collect();
    let mut scratch = vec![0.0; 2 * assembly.dofs().num_free()];
    let mut term = StiffnessDamping {
        velocity_form: (1e-2, &previous),
        beta_stiffness: &beta_k,
        assembly: &assembly,
        scratch: &mut scratch,
    };
    // A quadratic in Δu = u − uₙ ~ 1e-5 m: central differences have no truncation error, and
    // the round-off of βKₙΔu (entries of 1e6 N s/m cancelling across a row) falls as 1/ε:
    // 3e-11 at ε = 1e-7 m, 1e-12 at ε = 1e-6 m, which is used.
    check(&mut term, &assembly, &u, 1e-6, 20).assert_below("β stiffness damping", 1e-10, 1e-10);
}

// ---------------------------------------------------------------------------------------------
// Obstacle contact

/// The block the obstacle tests press: 6 × 6 × 4 cm, 3 × 3 × 2 cells, interior jittered.
fn block() -> TetMesh {
    irregular_box([3, 3, 2], [0.06, 0.06, 0.04], 0.2, 21)
}

/// What a solve starts from: displacement, velocity, step.
struct Start {
    previous: Vec<f64>,
    velocity: Vec<f64>,
    h: f64,
    dynamic: bool,
}

impl Start {
    /// A static solve of step `h` (s) from `u` at rest.
    fn at_rest(u: &[f64], h: f64) -> Self {
        Start {
            previous: u.to_vec(),
            velocity: vec![0.0; u.len()],
            h,
            dynamic: false,
        }
    }
}

/// Starts `terms` on `mesh` as the simulation does (start of step, pattern, solve) and hands
/// their step terms and the pattern to `f`. The terms must ask for the same couplings (the
/// same term with and without friction do: friction does not enter the broad phase).
fn with_step_terms<R>(
    terms: Vec<&mut (dyn Term + 'static)>,
    mesh: &TetMesh,
    start: &Start,
    f: impl FnOnce(Vec<Box<dyn StepTerm + '_>>, &Assembly) -> R,
) -> R {
    let view = StepStartView {
        rest: &mesh.rest,
        u: &start.previous,
        v: &start.velocity,
        max_speed: start.velocity.iter().fold(0.0f64, |m, x| m.max(x.abs())),
        dt: start.h,
        carried: &Default::default(),
    };
    let mut terms = terms;
    let couplings: Vec<_> = terms.iter_mut().map(|t| t.start_step(&view)).collect();
    assert!(couplings.iter().all(|c| *c == couplings[0]));
    let constrained = vec![false; 3 * mesh.num_nodes()];
    let pairs = couplings[0].clone().unwrap_or_default();
    let assembly = Assembly::with_couplings(mesh, DofMap::new(&constrained), &pairs);
    for t in terms.iter_mut() {
        t.pattern_ready(&assembly, true);
    }
    // Friction's normal force is extrapolated from uₙ − h vₙ, as in the simulation.
    let earlier: Vec<f64> = if start.dynamic {
        axpy(&start.previous, -start.h, &start.velocity)
    } else {
        Vec::new()
    };
    let solve = Solve {
        rest: &mesh.rest,
        previous: &start.previous,
        velocity: &start.velocity,
        max_speed: start.velocity.iter().fold(0.0, |m: f64, v| m.max(v.abs())),
        earlier: &earlier,
        h: start.h,
        dynamic: start.dynamic,
        times: (0.0, start.h),
    };
    let steps = terms
        .iter()
        .map(|t| t.begin_solve(&solve).expect("the term is active"))
        .collect();
    f(steps, &assembly)
}

/// [`with_step_terms`] for one term.
fn with_step_term<R>(
    term: &mut (dyn Term + 'static),
    mesh: &TetMesh,
    start: &Start,
    f: impl FnOnce(&mut dyn StepTerm, &Assembly) -> R,
) -> R {
    with_step_terms(vec![term], mesh, start, |mut steps, asm| {
        f(steps[0].as_mut(), asm)
    })
}

/// The same obstacle contact without friction.
fn frictionless(term: &ObstacleContact) -> ObstacleContact {
    let mut t = term.clone();
    for o in &mut t.contact.obstacles {
        o.friction = 0.0;
    }
    t
}

/// What a friction check measures: the errors of the whole contact term, those of friction
/// alone (the term minus a frictionless copy on the same pairs: beside the penalty's k A ~ 1e10
/// N/m, a sliding friction's Hessian α λ / |y| ~ 1e7 N/m is too small to judge in the sum), and
/// the friction forces at the evaluation point.
struct FrictionCheck {
    all: Errors,
    alone: Errors,
    forces: ContactForces,
}

impl FrictionCheck {
    fn assert_below(&self, what: &str, tol: f64, tol_all_h: f64) {
        self.alone
            .assert_below(&format!("{what}, friction alone"), tol, tol);
        self.all
            .assert_below(&format!("{what}, whole term"), tol, tol_all_h);
    }
}

/// Checks obstacle `term` with its friction, alone and in the whole term, started from `start`
/// and evaluated at `u` with central-difference step `step`.
fn check_friction(
    term: &ObstacleContact,
    mesh: &TetMesh,
    start: &Start,
    u: &[f64],
    step: f64,
    seed: u64,
) -> FrictionCheck {
    let (mut with, mut without) = (term.clone(), frictionless(term));
    with_step_terms(vec![&mut with, &mut without], mesh, start, |steps, asm| {
        let mut steps = steps.into_iter();
        let (mut whole, rest) = (steps.next().unwrap(), steps.next().unwrap());
        let forces = contact_forces(whole.as_ref(), u);
        let all = check(whole.as_mut(), asm, u, step, seed);
        let alone = check(&mut Minus(whole, rest), asm, u, step, seed + 1);
        FrictionCheck { all, alone, forces }
    })
}

/// The contact forces (normal, friction; N, 3 per node) of `term` at `u`.
fn contact_forces(term: &dyn StepTerm, u: &[f64]) -> ContactForces {
    let mut forces = ContactForces {
        normal: vec![0.0; u.len()],
        friction: vec![0.0; u.len()],
    };
    let contact = term.as_contact().expect("a contact term");
    contact.add_contact_forces(u, &mut forces);
    forces
}

/// Nodes pressed by a contact term at `u` (a normal force on them).
fn pressed_nodes(term: &dyn StepTerm, u: &[f64]) -> usize {
    let forces = contact_forces(term, u);
    forces
        .normal
        .chunks(3)
        .filter(|f| f.iter().any(|x| *x != 0.0))
        .count()
}

fn node_vec(v: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2])
}

/// Penetration pattern of the block's bottom nodes along the plane (m, gap): by the node's
/// column along rest x, −d, −0.2 d, 0.6 d, 1.4 d: two columns pressed in, two lifted off, every
/// gap at least 0.2 d from zero.
fn gap_pattern(rest: &Vector3<f64>, d: f64) -> f64 {
    let column = (rest.x / 0.02).round();
    d * (-1.0 + 0.8 * column)
}

/// The tilted plane the block meets and the rotation taking the block's bottom (normal −z) onto
/// it.
fn tilted_plane() -> (Vector3<f64>, Rotation3<f64>) {
    let normal = Vector3::new(0.15, -0.25, 1.0).normalize();
    let rotation = Rotation3::rotation_between(&Vector3::z(), &normal).unwrap();
    (normal, rotation)
}

/// The block turned onto the tilted half-space through the origin, its bottom nodes at the
/// gaps of [`gap_pattern`] with depth `d`, every node jittered by 0.05 d.
fn block_on_tilted_plane(mesh: &TetMesh, d: f64) -> Vec<f64> {
    let (normal, rotation) = tilted_plane();
    let mut u = displacement_of(mesh, |p| {
        let bottom = p.z < 1e-12;
        rotation * p + normal * if bottom { gap_pattern(p, d) } else { 0.0 }
    });
    jitter(mesh, &mut u, 0.05 * d, None, 22);
    u
}

fn tilted_half_space(mesh: &TetMesh, friction: f64, velocity: Vector3<f64>) -> ObstacleContact {
    let (normal, _) = tilted_plane();
    let obstacle = Obstacle {
        shape: Shape::HalfSpace {
            point: Vector3::zeros(),
            normal,
        },
        motion: icefem::physics::Motion::translating(velocity),
        stiffness: default_stiffness(mesh, ICE.young()),
        friction,
    };
    ObstacleContact::new(Contact::new(mesh, vec![obstacle], 1e-4), mesh.num_nodes())
}

/// Penetration depth of the obstacle tests (m): k A d ≈ 1e4 N per node at the default
/// stiffness; gaps are ≥ 2e-7 m from zero, so ε ≤ 1e-9 m keeps every stencil on one side.
const DEPTH: f64 = 1e-6;

#[test]
fn obstacle_penalty_compression_and_separation() {
    let mesh = block();
    let mut term = tilted_half_space(&mesh, 0.0, Vector3::zeros());
    let u = block_on_tilted_plane(&mesh, DEPTH);
    let start = Start::at_rest(&u, 1.0);
    // The penalty ½ k A g² is piecewise quadratic: central differences are exact on one side
    // of g = 0, up to round-off (gaps to 1e-17 m of 1e-6 m, energy ~ 1e-2 J): at ε = 1e-9 m,
    // 1e-17 / 1e-9 relative to the force, 1e-8.
    let errors = with_step_term(&mut term, &mesh, &start, |t, asm| {
        let pressed = pressed_nodes(t, &u);
        // Two of the four columns of 4 bottom nodes are in.
        assert_eq!(pressed, 8, "pressed nodes");
        check(t, asm, &u, 1e-9, 23)
    });
    errors.assert_below(
        "obstacle, tilted plane, compression + separation",
        1e-7,
        1e-7,
    );
}

#[test]
fn obstacle_separated_contributes_nothing() {
    // The tilted-plane state lifted by 2.5 µm, so that the lowest node is 1.5 µm off, in a
    // dynamic step with friction: no energy, gradient or Hessian, and none appears within the
    // stencil.
    let mesh = block();
    let mut term = tilted_half_space(&mesh, 0.3, Vector3::zeros());
    let (normal, _) = tilted_plane();
    let mut u = block_on_tilted_plane(&mesh, DEPTH);
    for i in 0..mesh.num_nodes() {
        for k in 0..3 {
            u[3 * i + k] += 2.5 * DEPTH * normal[k];
        }
    }
    let start = Start {
        previous: u.clone(),
        velocity: vec![0.0; u.len()],
        h: 1e-2,
        dynamic: true,
    };
    with_step_term(&mut term, &mesh, &start, |t, asm| {
        let mut e = 0.0;
        let mut g = vec![0.0; u.len()];
        let mut h = vec![0.0; asm.nnz()];
        t.add(&u, &mut e, Some(&mut g), Some(&mut h));
        assert_eq!(e, 0.0);
        assert!(g.iter().all(|x| *x == 0.0) && h.iter().all(|x| *x == 0.0));
        let mut rng = Lcg(24);
        for _ in 0..DIRECTIONS {
            let d: Vec<f64> = (0..u.len()).map(|_| rng.next()).collect();
            for s in [1e-9, -1e-9] {
                let up = axpy(&u, s, &d);
                assert_eq!(energy_at(t, &up), 0.0);
                assert!(gradient_at(t, &up).iter().all(|x| *x == 0.0));
            }
        }
    });
    eprintln!("obstacle, separated: energy, gradient and Hessian exactly 0");
}

#[test]
fn obstacle_container_corner_compression() {
    // The block pushed into a corner of the container (floor and two walls): edge nodes meet
    // two planes, the corner node three; each plane counts only the node's faces facing it.
    let mesh = block();
    let obstacle = Obstacle {
        shape: Shape::Container {
            inner: Region {
                min: Vector3::zeros(),
                max: Vector3::new(0.2, 0.2, 0.2),
            },
        },
        motion: Default::default(),
        stiffness: default_stiffness(&mesh, ICE.young()),
        friction: 0.0,
    };
    let mut term =
        ObstacleContact::new(Contact::new(&mesh, vec![obstacle], 1e-4), mesh.num_nodes());
    let mut u = displacement_of(&mesh, |p| p - Vector3::repeat(DEPTH));
    jitter(&mesh, &mut u, 0.05 * DEPTH, None, 25);
    let start = Start::at_rest(&u, 1.0);
    // As for the tilted plane: piecewise quadratic, gaps 1e-6 ± 5e-8 m, ε = 1e-9 m.
    with_step_term(&mut term, &mesh, &start, |t, asm| {
        check(t, asm, &u, 1e-9, 26)
    })
    .assert_below("obstacle, container corner, compression", 1e-7, 1e-7);
}

/// Over the nodes the obstacle presses, the range of |friction force| / (α |normal force|):
/// f₁(|y|/ε) when the lagged normal force is the one at the evaluation point, 1 while sliding,
/// 2r − r² ≈ 2r for r = |y|/ε ≪ 1 sticking; and the number of those nodes. Also checks that
/// each normal force pushes along `normal`.
fn friction_ratios(forces: &ContactForces, alpha: f64, normal: &Vector3<f64>) -> (f64, f64, usize) {
    let (mut lo, mut hi, mut pressed) = (f64::INFINITY, 0.0f64, 0);
    for i in 0..forces.normal.len() / 3 {
        let f_n = node_vec(&forces.normal, i);
        if f_n.norm() > 0.0 {
            assert!(
                f_n.normalize().dot(normal) > 1.0 - 1e-12,
                "normal force off the normal"
            );
            let ratio = node_vec(&forces.friction, i).norm() / (alpha * f_n.norm());
            lo = lo.min(ratio);
            hi = hi.max(ratio);
            pressed += 1;
        }
    }
    (lo, hi, pressed)
}

/// Checks friction on the tilted plane (α = 0.5, moving along the plane at `v_obstacle`) in a
/// dynamic step of h = 10 ms: the block starts pressed as in [`block_on_tilted_plane`] with
/// velocity `v_block` and is evaluated at uₙ + h v_block + `slip` (all tangential, with a
/// tangential jitter of `jitter_amplitude`), so every node keeps its gap and its lagged normal
/// force. Returns the check and the range of [`friction_ratios`].
fn check_plane_friction(
    v_block: Vector3<f64>,
    v_obstacle: Vector3<f64>,
    slip: Vector3<f64>,
    jitter_amplitude: f64,
    step: f64,
) -> (FrictionCheck, f64, f64) {
    let mesh = block();
    let alpha = 0.5;
    let term = tilted_half_space(&mesh, alpha, v_obstacle);
    let (normal, _) = tilted_plane();
    let previous = block_on_tilted_plane(&mesh, DEPTH);
    let h = 1e-2;
    let velocity: Vec<f64> = (0..mesh.num_nodes())
        .flat_map(|_| [v_block.x, v_block.y, v_block.z])
        .collect();
    let mut u: Vec<f64> = (0..previous.len())
        .map(|d| previous[d] + h * velocity[d] + slip[d % 3])
        .collect();
    jitter(&mesh, &mut u, jitter_amplitude, Some(normal), 27);
    let start = Start {
        previous,
        velocity,
        h,
        dynamic: true,
    };
    let result = check_friction(&term, &mesh, &start, &u, step, 28);
    let (lo, hi, pressed) = friction_ratios(&result.forces, alpha, &normal);
    assert_eq!(pressed, 8, "two columns of the bottom are in");
    (result, lo, hi)
}

#[test]
fn obstacle_friction_sliding() {
    // The block slides at 10 cm/s down the plane while the plane moves 5 cm/s across: slips of
    // ~1 mm against ε = ε_v h = 1e-6 m, so the friction force is α λ (f₁ = 1) and its energy the
    // cone α λ |y|, which curves on the length |y|. ε_fd = 1e-9 m (the penalty's limit, see
    // [`DEPTH`]) gives truncation (1e-9 / 1e-3)² and round-off as for the penalty.
    let (normal, rotation) = tilted_plane();
    let down = rotation * Vector3::new(0.6, 0.8, 0.0);
    let across = normal.cross(&down);
    let (result, lo, hi) =
        check_plane_friction(0.1 * down, 0.05 * across, Vector3::zeros(), 5e-8, 1e-9);
    eprintln!("sliding: |f_friction| / (α |f_normal|) in [{lo}, {hi}]");
    assert!(
        (lo - 1.0).abs() < 1e-9 && (hi - 1.0).abs() < 1e-9,
        "not sliding"
    );
    result.assert_below("obstacle friction, sliding on a moving plane", 1e-7, 1e-7);
}

#[test]
fn obstacle_friction_sticking() {
    // The block moves with the plane (5 cm/s across it) and creeps 2e-8 m relative to it, with
    // a 2e-9 m jitter: slips of ~0.02 ε (ε = ε_v h = 1e-6 m), where the friction potential is
    // α λ ε (r² − r³/3 + 1/3), r = |y|/ε. Its Hessian αλ/ε [(2 − r) T − r ŷŷᵀ] turns with ŷ
    // on the length |y|, so the truncation is ~ (r/2) (ε_fd/|y|)²: 6e-6 of the friction at
    // ε_fd = 1e-9 m, measured, falling as ε_fd². The penalty's round-off (gaps to 1e-17 m of
    // 5 cm positions, against the stencil) grows as 1/ε_fd: 1e-7 of the whole term at 3e-11 m
    // in the ramp test. ε_fd = 1e-10 m (1/200 of the slip) keeps both below 1.5e-7 in every
    // sticking test.
    let (normal, rotation) = tilted_plane();
    let across = normal.cross(&(rotation * Vector3::x()));
    let creep = rotation * Vector3::new(2e-8, 1e-8, 0.0);
    let v = 0.05 * across;
    let (result, lo, hi) = check_plane_friction(v, v, creep, 2e-9, 1e-10);
    eprintln!("sticking: |f_friction| / (α |f_normal|) in [{lo:.3}, {hi:.3}]");
    assert!(lo > 0.0 && hi < 0.1, "not sticking");
    result.assert_below("obstacle friction, sticking", 2e-6, 2e-6);
}

// ---------------------------------------------------------------------------------------------
// Mesh obstacle

#[test]
fn mesh_obstacle_ramp_scene_sliding_and_sticking() {
    // scenes/slide_down_ramp.toml: the 4 cm cube and the ramp read from ramp.obj (a closed
    // triangle prism; its 26.6° slope is two triangles) inside a container. The cube is laid
    // on the slope (turned by atan ½ about y) with its bottom nodes at the gaps of
    // [`gap_pattern`] and jittered; each node within reach gets the plane through its closest
    // ramp point at uₙ, frozen for the step, so the penalty and friction are those of planes
    // and exact. The container's planes are all far (zero).
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/slide_down_ramp.toml");
    let scene = Scene::load(&path).unwrap();
    let mesh = &scene.model.mesh;
    let term = scene.model.term::<ObstacleContact>().unwrap();
    let contact = &term.contact;
    assert!(
        contact.obstacles[0].surface().is_some(),
        "obstacle 0 is the ramp mesh"
    );
    let alpha = contact.obstacles[0].friction;
    let eps = contact.smoothing_velocity * scene.settings.dt;
    let theta = 0.5f64.atan();
    let rotation = Rotation3::from_axis_angle(&Vector3::y_axis(), theta);
    let normal = rotation * Vector3::z();
    let down = rotation * Vector3::x();
    // Bottom centre of the cube at rest, and the point of the slope z = 0.1 − x / 2 it goes to
    // (inside one of the slope's two triangles, away from their shared diagonal x + y = 0.2).
    let centre = Vector3::new(0.03, 0.1, 0.1);
    let target = Vector3::new(0.1, 0.05, 0.05);
    let h = scene.settings.dt;
    let cases = [
        // Sliding down the slope at 10 cm/s: slips of 1 mm against ε = 1e-6 m.
        (
            "sliding",
            0.1 * down + Vector3::new(0.0, 0.02, 0.0),
            Vector3::zeros(),
            5e-8,
            1e-9,
        ),
        // At rest, creeping 2e-8 m: r = |y|/ε ≈ 0.02 (see the sticking plane test for ε_fd).
        (
            "sticking",
            Vector3::zeros(),
            rotation * Vector3::new(2e-8, 1e-8, 0.0),
            2e-9,
            1e-10,
        ),
    ];
    for (name, v, creep, jitter_amplitude, step) in cases {
        let mut u = displacement_of(mesh, |p| {
            let q = p - centre;
            let column = ((q.x + 0.02) / (0.04 / 3.0)).round();
            let bottom = q.z.abs() < 1e-12;
            let gap = if bottom {
                DEPTH * (-1.0 + 0.8 * column)
            } else {
                0.0
            };
            target + rotation * q + gap * normal
        });
        jitter(mesh, &mut u, 0.05 * DEPTH, None, 31);
        let velocity: Vec<f64> = (0..mesh.num_nodes())
            .flat_map(|_| [v.x, v.y, v.z])
            .collect();
        let mut at: Vec<f64> = (0..u.len())
            .map(|d| u[d] + h * velocity[d] + creep[d % 3])
            .collect();
        jitter(mesh, &mut at, jitter_amplitude, Some(normal), 32);
        let start = Start {
            previous: u,
            velocity,
            h,
            dynamic: true,
        };
        let result = check_friction(term, mesh, &start, &at, step, 33);
        let (lo, hi, pressed) = friction_ratios(&result.forces, alpha, &normal);
        eprintln!(
            "ramp {name} (ε = {eps:.1e} m): {pressed} nodes in, |f_t| / (α |f_n|) in \
             [{lo:.3}, {hi:.3}]"
        );
        assert_eq!(pressed, 8, "two columns of the bottom are in");
        let tol = match name {
            "sliding" => {
                assert!((lo - 1.0).abs() < 1e-9 && (hi - 1.0).abs() < 1e-9);
                1e-7
            }
            _ => {
                assert!(lo > 0.0 && hi < 0.1);
                2e-6
            }
        };
        result.assert_below(&format!("mesh obstacle (ramp.obj), {name}"), tol, tol);
    }
}

// ---------------------------------------------------------------------------------------------
// Ice–ice contact

/// scenes/stacked_cubes.toml (two 4 cm cubes, the upper one on the lower, shifted 5 mm in x
/// and y), with ice friction `friction`.
fn stacked_cubes(friction: f64) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/stacked_cubes.toml");
    let text = std::fs::read_to_string(&path).unwrap().replace(
        "[physics]\n",
        &format!("[physics]\nice_friction = {friction}\n"),
    );
    Scene::parse(&text, &path).unwrap()
}

/// Depth (m) the upper cube is pressed into the lower one: 2 × the penalty onset δ = 1e-4 ×
/// the mean edge (1.5e-6 m), so every pair is past the onset (φ″ = 1) with the 10 % jitter.
const ICE_DEPTH: f64 = 3e-6;

/// The stacked cubes pressed together by `depth` (m), the upper one also shifted 2 mm in x (in
/// the scene every node's foot point lies on a face diagonal of the other cube; 2 mm puts them
/// 1.4 mm off any triangle edge), every node jittered by 0.1 × the depth.
fn pressed_cubes(scene: &Scene, depth: f64) -> Vec<f64> {
    let mesh = &scene.model.mesh;
    let ice = scene
        .model
        .ice_contact()
        .expect("two parts: ice contact on");
    assert_eq!(ice.parts, 2);
    let upper = ice.part[mesh.num_nodes() - 1];
    let mut u = vec![0.0; 3 * mesh.num_nodes()];
    for i in 0..mesh.num_nodes() {
        if ice.part[i] == upper {
            u[3 * i] += 2e-3;
            u[3 * i + 2] -= depth;
        }
    }
    jitter(mesh, &mut u, 0.1 * depth, None, 41);
    u
}

fn ice_term(scene: &Scene) -> Box<dyn Term> {
    scene
        .model
        .terms
        .iter()
        .find(|t| t.as_any().is::<IceContactTerm>())
        .unwrap()
        .clone()
}

#[test]
fn ice_contact_pressed_cubes() {
    // Node–triangle pairs of the two parts, both ways (upper bottom nodes on the lower top
    // faces and the reverse), pressed past the onset. The gap's gradient ∇g = (n, −β n) is
    // exact, so the gradient is; the Hessian k A φ″ ∇g ∇gᵀ leaves out k A φ′ ∇²g, whose entries
    // are ~ k A |φ′| / ℓ with ℓ the triangles' height (9 mm): relative to k A, |φ′| / ℓ ≈
    // (3.3e-6 + δ/2) / 9e-3 ≈ 4e-4 at 3 µm. That part is checked by its scaling: pressed twice
    // as deep, |φ′| = |g| + δ/2 grows by (6.6 + 0.75) / (3.3 + 0.75) ≈ 1.8, and so must the
    // Hessian's error; a wrong sign or factor in k A φ″ ∇g ∇gᵀ would instead give an error of
    // order 1 at any depth. ε = 1e-9 m: gaps stay ≥ 2e-6 m from 0 and δ, the round-off of gaps (1e-17 m
    // at 4 cm positions) is 1e-8 of the force, and the truncation (ε/ℓ)² negligible.
    let scene = stacked_cubes(0.0);
    let mesh = &scene.model.mesh;
    let mut errors = Vec::new();
    for depth in [ICE_DEPTH, 2.0 * ICE_DEPTH] {
        let u = pressed_cubes(&scene, depth);
        let start = Start::at_rest(&u, scene.settings.dt);
        let e = with_step_term(ice_term(&scene).as_mut(), mesh, &start, |t, asm| {
            check(t, asm, &u, 1e-9, 42)
        });
        e.assert_below(
            &format!("ice contact, pressed {depth:e} m (penalty)"),
            1e-7,
            2e-3 * depth / ICE_DEPTH,
        );
        errors.push(e);
    }
    let growth = errors[1].hessian() / errors[0].hessian();
    eprintln!("ice contact: Hessian error × {growth:.2} at twice the depth (|φ′| × 1.8)");
    assert!((1.6..2.0).contains(&growth), "{growth}");
}

/// Checks ice friction (α = 0.3) on the pressed cubes in a dynamic step of the scene's h =
/// 1/60 s: the upper cube starts with velocity `v_upper` and is evaluated at uₙ + h v_upper +
/// `creep` (tangential, xy) with an xy jitter of `jitter_amplitude` on every node. Returns the
/// errors of the whole term (penalty and friction), those of friction alone (the term minus a
/// frictionless copy on the same pairs) and how the friction force on the upper cube grows
/// when the step's motion uₙ₊₁ − uₙ is doubled: 1 while sliding (f₁ = 1), f₁(2r)/f₁(r) ≈ 2
/// sticking.
fn check_ice_friction(
    v_upper: Vector3<f64>,
    creep: Vector3<f64>,
    jitter_amplitude: f64,
    step: f64,
) -> (FrictionCheck, f64) {
    let scene = stacked_cubes(0.3);
    let mesh = &scene.model.mesh;
    let part = scene.model.ice_contact().unwrap().part.clone();
    let upper = part[mesh.num_nodes() - 1];
    let previous = pressed_cubes(&scene, ICE_DEPTH);
    let h = scene.settings.dt;
    let moving = |d: usize, v: &Vector3<f64>| if part[d / 3] == upper { v[d % 3] } else { 0.0 };
    let velocity: Vec<f64> = (0..previous.len()).map(|d| moving(d, &v_upper)).collect();
    let mut u: Vec<f64> = (0..previous.len())
        .map(|d| previous[d] + h * velocity[d] + moving(d, &creep))
        .collect();
    jitter(mesh, &mut u, jitter_amplitude, Some(Vector3::z()), 43);
    let doubled: Vec<f64> = (0..u.len()).map(|d| 2.0 * u[d] - previous[d]).collect();
    let start = Start {
        previous,
        velocity,
        h,
        dynamic: true,
    };
    let (mut with, mut without) = (ice_term(&scene), ice_term(&stacked_cubes(0.0)));
    let terms = vec![with.as_mut(), without.as_mut()];
    with_step_terms(terms, mesh, &start, |steps, asm| {
        let mut steps = steps.into_iter();
        let (mut whole, rest) = (steps.next().unwrap(), steps.next().unwrap());
        let friction_on_upper = |u: &[f64]| -> Vector3<f64> {
            let f = contact_forces(whole.as_ref(), u).friction;
            (0..mesh.num_nodes())
                .filter(|&i| part[i] == upper)
                .map(|i| node_vec(&f, i))
                .sum()
        };
        let growth = friction_on_upper(&doubled).norm() / friction_on_upper(&u).norm();
        let forces = contact_forces(whole.as_ref(), &u);
        let all = check(whole.as_mut(), asm, &u, step, 44);
        let alone = check(&mut Minus(whole, rest), asm, &u, step, 45);
        (FrictionCheck { all, alone, forces }, growth)
    })
}

#[test]
fn ice_contact_on_two_parts_adds_up_to_the_whole() {
    // Each cube (5 × 5 × 5 cells) is one process's part; each process holds the boundary of
    // both besides (more than its ghost surface), numbered in its part, and evaluates the
    // pairs with a node it owns, keeping their gradient entries and Hessian columns on its
    // owned nodes (as a distributed solve does) and counting the energy of the pairs whose
    // node it owns. Friction included (the upper cube slides). An owned node then gets its
    // pairs' contributions in the order of one process: the gradient entries and Hessian
    // columns are the whole term's bit for bit; the energies, summed in another order, add
    // up to the whole's to round-off (1e-12, against 1e-16 per addition).
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/stacked_cubes.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("cells = [3, 3, 3]", "cells = [5, 5, 5]")
        .replace("[physics]\n", "[physics]\nice_friction = 0.3\n");
    let scene = Scene::parse(&text, &path).unwrap();
    let model = &scene.model;
    let previous = pressed_cubes(&scene, ICE_DEPTH);
    let part_of = model.ice_contact().unwrap().part.clone();
    let upper = part_of[model.num_nodes() - 1];
    let h = scene.settings.dt;
    let velocity: Vec<f64> = (0..previous.len())
        .map(|d| match (part_of[d / 3] == upper, d % 3) {
            (true, 0) => 0.012,
            (true, 1) => 0.006,
            _ => 0.0,
        })
        .collect();
    let u = axpy(&previous, h, &velocity);
    let start = Start {
        previous,
        velocity,
        h,
        dynamic: true,
    };
    // Energy, gradient and dense Hessian of a model's ice contact at the start's `u`.
    let evaluate = |model: &Model, start: &Start, u: &[f64]| {
        let mut term = model
            .terms
            .iter()
            .find(|t| t.as_any().is::<IceContactTerm>())
            .unwrap()
            .clone();
        with_step_term(term.as_mut(), &model.mesh, start, |t, asm| {
            let (mut e, mut g) = (0.0, vec![0.0; u.len()]);
            let mut hessian = vec![0.0; asm.nnz()];
            t.add(u, &mut e, Some(&mut g), Some(&mut hessian));
            (e, g, dense(asm, &hessian))
        })
    };
    let (energy, gradient, hessian) = evaluate(model, &start, &u);
    let n = u.len();
    // The elements of the lower cube come first.
    let tets = &model.mesh.tets;
    let element_part: Vec<u32> = (0..tets.len())
        .map(|e| u32::from(part_of[tets[e][0]] == upper))
        .collect();
    let mut owner = vec![1u32; model.num_nodes()];
    for (tet, &p) in tets.iter().zip(&element_part) {
        for &v in tet {
            owner[v] = owner[v].min(p);
        }
    }
    assert!(model.ice_contact().is_some());
    let everywhere: Vec<usize> = (model.mesh.boundary_marks().iter().enumerate())
        .filter(|(_, &faces)| faces != 0)
        .map(|(e, _)| e)
        .collect();
    let (mut energies, mut g_sum, mut h_sum) = (Vec::new(), vec![0.0; n], vec![0.0; n * n]);
    for rank in 0..2 {
        let part = Part::new(tets, (&element_part, &owner), rank, (&everywhere, false));
        assert!(!part.is_whole(), "the other cube's inside is not held");
        let local = part.model(model).unwrap();
        let of = |v: &[f64]| part.dofs_of(v);
        let at = Start {
            previous: of(&start.previous),
            velocity: of(&start.velocity),
            h,
            dynamic: true,
        };
        let (e, g, hl) = evaluate(&local, &at, &of(&u));
        let whole: Vec<usize> = part.whole_dofs().collect();
        let owned = part.owned_dofs();
        for (l, &c) in whole.iter().enumerate().filter(|&(l, _)| owned[l]) {
            g_sum[c] += g[l];
            for (k, &d) in whole.iter().enumerate() {
                h_sum[c * n + d] += hl[l * whole.len() + k];
            }
        }
        energies.push(e);
    }
    assert!(energies.iter().all(|&e| e > 0.0), "{energies:?}");
    assert!(g_sum == gradient, "gradients differ");
    assert!(h_sum == hessian, "Hessians differ");
    let e_sum: f64 = energies.iter().sum();
    let error = (e_sum - energy).abs() / energy;
    eprintln!("ice contact on two parts: energies {energies:?} add up to {energy:.3e} J ({error:.1e} apart)");
    assert!(error < 1e-12, "{error:e}");
}

#[test]
fn ice_friction_sliding() {
    // The upper cube slides at (12, 6) mm/s over the lower one: 0.2 mm of slip in the step
    // against ε = ε_v h = 1.7e-6 m, and no foot point leaves its triangle (1.4 mm margin).
    // Friction holds the pairs' normals, foot-point weights and normal forces fixed for the
    // step, so its slip is linear in u and its Hessian exact: checked alone to the penalty's
    // round-off, and with the penalty to the penalty's Hessian bound (see
    // ice_contact_pressed_cubes). ε = 1e-9 m as there; the cone's truncation (1e-9/2e-4)².
    let (result, growth) = check_ice_friction(
        Vector3::new(0.012, 0.006, 0.0),
        Vector3::zeros(),
        5e-8,
        1e-9,
    );
    eprintln!("ice sliding: friction × {growth:.4} for twice the motion");
    assert!((growth - 1.0).abs() < 1e-3, "not sliding: {growth}");
    result.assert_below("ice contact, sliding", 1e-7, 2e-3);
}

#[test]
fn ice_friction_sticking() {
    // At rest, the upper cube creeping (2, 1) × 1e-8 m with a 2e-9 m jitter: r = |y| / ε ≈
    // 0.013. ε_fd = 1e-10 m, as for the sticking obstacle.
    let (result, growth) =
        check_ice_friction(Vector3::zeros(), Vector3::new(2e-8, 1e-8, 0.0), 2e-9, 1e-10);
    eprintln!("ice sticking: friction × {growth:.4} for twice the motion");
    assert!((1.9..2.0).contains(&growth), "not sticking: {growth}");
    result.assert_below("ice contact, sticking", 2e-6, 2e-3);
}

#[test]
fn ice_friction_normal_force_at_rest_extrapolates_to_itself() {
    // With uₙ₋₁ = uₙ, λ = max(0, 2 λ(uₙ) − λ(uₙ₋₁)) must be λ(uₙ) for every pair.
    use icefem::physics::ice_contact::IceStep;
    let scene = stacked_cubes(0.3);
    let mesh = &scene.model.mesh;
    let ice = scene.model.ice_contact().unwrap();
    let u = pressed_cubes(&scene, ICE_DEPTH);
    let normals = ice.crack_sides().normals(&mesh.rest, &u);
    let frames = ice.crack_sides().frames(&mesh.rest, &u, &normals, &[]);
    let candidates = ice.candidates(&mesh.rest, (&u, 0.0), scene.settings.dt, &frames);
    let step = IceStep {
        term: ice,
        rest: &mesh.rest,
        candidates: &candidates,
        slots: &[],
        anticipated: Vec::new(),
        friction: None,
    };
    let now = step.friction_frames(&mesh.rest, &u);
    let extrapolated = step.extrapolated_friction_frames(&mesh.rest, &u, &u);
    for (a, b) in now.iter().zip(&extrapolated) {
        let (a, b) = (a.map(|f| f.2), b.map(|f| f.2));
        assert_eq!(a, b, "λ(uₙ) {a:?}, extrapolated {b:?}");
    }
}

#[test]
fn ice_contact_crack_copies_pressed() {
    // Two 4 cm boxes meeting at z = 4 cm whose touching faces are crack faces: the copies of
    // each split node are paired, with the gap g = (p − q)·m along the frozen normal m of the
    // crack, so ∇g is constant and the Hessian k A φ″ ∇g ∇gᵀ exact. Pressed by 3e-6 m (past
    // the onset) with a 3e-7 m jitter; ε = 1e-9 m as for the node–triangle pairs.
    let lower = icefem::mesh::box_mesh([0.0; 3], [0.04; 3], [2, 2, 2], 6).unwrap();
    let upper = icefem::mesh::box_mesh([0.0, 0.0, 0.04], [0.04; 3], [2, 2, 2], 6).unwrap();
    let mesh = TetMesh::concat(vec![lower, upper]).unwrap();
    let cracks: Vec<[usize; 3]> = mesh
        .boundary_faces()
        .iter()
        .filter(|f| {
            f.nodes
                .iter()
                .all(|&i| (mesh.rest[i].z - 0.04).abs() < 1e-12)
        })
        .map(|f| f.nodes)
        .collect();
    assert_eq!(cracks.len(), 16, "8 triangles on each side");
    let mut term = IceContactTerm::new(&mesh, 0.0, 0.0, 1e-4, &cracks, ICE.young());
    let half = mesh.num_nodes() / 2;
    let mut u = vec![0.0; 3 * mesh.num_nodes()];
    for i in half..mesh.num_nodes() {
        u[3 * i + 2] = -ICE_DEPTH;
    }
    jitter(&mesh, &mut u, 0.1 * ICE_DEPTH, None, 51);
    let start = Start::at_rest(&u, 1e-2);
    let errors = with_step_term(&mut term, &mesh, &start, |t, asm| {
        let pressed = pressed_nodes(t, &u);
        assert_eq!(pressed, 18, "9 copies a side");
        check(t, asm, &u, 1e-9, 52)
    });
    errors.assert_below("ice contact, crack copies pressed", 1e-7, 1e-7);
}
