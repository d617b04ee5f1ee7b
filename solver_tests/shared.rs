//! A simulation shared among processes, without MPI: two threads play two processes, each
//! with its own `Simulation` on its part of the mesh (`sim::part`; or the whole mesh) sharing
//! the work as a distributed run does (`Simulation::distribute`), their sums exchanged
//! through memory and the Hessian's two parts added on the whole mesh's pattern and
//! factorised by Cholesky on both. This checks the split of the potential — elements per
//! process, masses, loads and contact on owned nodes, the nodal volumetric energy by owned
//! node, the ring of elements a part needs — in the default build; `distributed.rs` (feature
//! `mpi`) checks MPI and PETSc on top.

mod common;

use icefem::assembly::{Assembly, DofMap};
use icefem::physics::Model;
use icefem::sim::part::Part;
use icefem::sim::{Collective, Distribution, Scheme, SimError, Simulation};
use icefem::solver::linear::Cholesky;
use icefem::solver::{ExternalSolver, FillOrdering, LinearError, LinearSolverKind, LinearStats};
use std::sync::{Arc, Barrier, Mutex};

/// Two threads' meeting point: each puts its values, both read the other's.
struct Exchange {
    barrier: Barrier,
    slots: Mutex<[Vec<f64>; 2]>,
}

impl Exchange {
    /// Both processes' `mine`, in process order, on both.
    fn both(&self, rank: usize, mine: &[f64]) -> [Vec<f64>; 2] {
        self.slots.lock().unwrap()[rank] = mine.to_vec();
        self.barrier.wait();
        let both = self.slots.lock().unwrap().clone();
        // Nobody writes the next round before both have read this one.
        self.barrier.wait();
        both
    }
}

/// Process `rank`'s view of the exchange, for the dofs of its part (`whole_dofs`: the whole
/// mesh's dof of each, `total`: the whole mesh's count).
struct Sums {
    exchange: Arc<Exchange>,
    rank: usize,
    whole_dofs: Arc<Vec<usize>>,
    total: usize,
}

impl Collective for Sums {
    fn sum(&self, x: f64) -> f64 {
        let [a, b] = self.exchange.both(self.rank, &[x]);
        a[0] + b[0]
    }
    fn exchange(&self, v: &mut [f64]) {
        // On the whole mesh's dofs, each process's part added in process order.
        let mut mine = vec![0.0; self.total];
        for (&d, x) in self.whole_dofs.iter().zip(v.iter()) {
            mine[d] = *x;
        }
        let [a, b] = self.exchange.both(self.rank, &mine);
        for (&d, x) in self.whole_dofs.iter().zip(v.iter_mut()) {
            *x = a[d] + b[d];
        }
    }
    fn max(&self, x: f64) -> f64 {
        let [a, b] = self.exchange.both(self.rank, &[x]);
        a[0].max(b[0])
    }
}

/// The two Hessian parts added on the whole mesh's pattern, then Cholesky there: the same
/// factor on both processes, each solving for its part's free dofs.
struct SummedCholesky {
    sums: Sums,
    /// The whole mesh's pattern, and for each free dof of the part's, its free index there;
    /// `None` where the part is the whole mesh, whose pattern (with the couplings its terms
    /// add, such as ice–ice contact across a crack) is the part's.
    whole: Option<(Arc<Assembly>, Vec<usize>)>,
    cholesky: Cholesky,
}

impl SummedCholesky {
    /// The part's Hessian `values` on `assembly`'s pattern placed in the whole's.
    fn in_whole(&self, assembly: &Assembly, values: &[f64]) -> Vec<f64> {
        let Some((whole, free_in_whole)) = &self.whole else {
            return values.to_vec();
        };
        let mut in_whole = vec![0.0; whole.nnz()];
        let (col_ptr, row_idx) = (assembly.symbolic().col_ptr(), assembly.symbolic().row_idx());
        let whole_col_ptr = whole.symbolic().col_ptr();
        let whole_rows = whole.symbolic().row_idx();
        for c in 0..assembly.dofs().num_free() {
            let wc = free_in_whole[c];
            let rows = &whole_rows[whole_col_ptr[wc]..whole_col_ptr[wc + 1]];
            for k in col_ptr[c]..col_ptr[c + 1] {
                let wr = free_in_whole[row_idx[k]];
                let at = rows
                    .binary_search(&wr)
                    .expect("the part's entry is in the whole");
                in_whole[whole_col_ptr[wc] + at] = values[k];
            }
        }
        in_whole
    }
}

impl ExternalSolver for SummedCholesky {
    fn factorize(&mut self, assembly: &Assembly, values: &[f64]) -> Result<(), LinearError> {
        let mine = self.in_whole(assembly, values);
        let [a, b] = self.sums.exchange.both(self.sums.rank, &mine);
        let summed: Vec<f64> = a.iter().zip(&b).map(|(a, b)| a + b).collect();
        let whole = self.whole.as_ref().map_or(assembly, |(w, _)| w);
        self.cholesky.factorize(whole, &summed).map(|_| ())
    }
    fn solve(&mut self, b: &[f64], x: &mut [f64]) -> Result<LinearStats, LinearError> {
        let Some((whole, free_in_whole)) = &self.whole else {
            // The right-hand side is the same on both processes.
            return Ok(self.cholesky.solve(b, x));
        };
        // The right-hand side is the same on every process where a dof is held: put each
        // part's into the whole's (both give the same shared entries), solve, read back.
        let mut rhs = vec![f64::NAN; whole.dofs().num_free()];
        for (&w, v) in free_in_whole.iter().zip(b) {
            rhs[w] = *v;
        }
        let [p, q] = self.sums.exchange.both(self.sums.rank, &rhs);
        let rhs: Vec<f64> = p
            .iter()
            .zip(&q)
            .map(|(p, q)| if p.is_nan() { *q } else { *p })
            .collect();
        let mut whole_x = vec![0.0; rhs.len()];
        let stats = self.cholesky.solve(&rhs, &mut whole_x);
        for (&w, x) in free_in_whole.iter().zip(x.iter_mut()) {
            *x = whole_x[w];
        }
        Ok(stats)
    }
}

/// Process `rank` of two: the first half of the elements (by index) or the second; a node
/// belongs to the lower process among its elements'.
struct Half {
    part: Part,
    /// Process of each element of the whole mesh.
    element_part: Vec<u32>,
    exchange: Arc<Exchange>,
    rank: usize,
    sums: Sums,
    owned_dofs: Vec<bool>,
    whole: Arc<Assembly>,
}

impl Half {
    /// The part of process `rank` of `model`'s mesh: the whole mesh if `whole`.
    fn new(model: &Model, exchange: Arc<Exchange>, rank: usize, whole: bool) -> Self {
        let elements = model.mesh.num_tets();
        let element_part = (0..elements)
            .map(|e| u32::from(e >= elements / 2))
            .collect();
        Self::with_parts(model, exchange, rank, whole, element_part)
    }

    /// The part of process `rank` of `model`'s mesh when element `e` is process
    /// `element_part[e]`'s.
    fn with_parts(
        model: &Model,
        exchange: Arc<Exchange>,
        rank: usize,
        whole: bool,
        element_part: Vec<u32>,
    ) -> Self {
        let tets = &model.mesh.tets;
        let mut owner = vec![1u32; model.num_nodes()];
        for (tet, &p) in tets.iter().zip(&element_part) {
            for &v in tet {
                owner[v] = owner[v].min(p);
            }
        }
        let part = Part::new(tets, (&element_part, &owner), rank as u32, (&[], whole));
        let whole_dofs = Arc::new(part.whole_dofs().collect::<Vec<_>>());
        // The scene's model describes its elements; their couplings (the nodal volumetric
        // energy's stars) come with the rest data the whole mesh's solver builds.
        let mut elasticity = model.elasticity.clone();
        elasticity.build(&model.mesh);
        let couplings = elasticity.couplings();
        let constrained = model.constrained_dofs();
        let whole_assembly =
            Assembly::with_couplings(&model.mesh, DofMap::new(&constrained), &couplings);
        Half {
            sums: Sums {
                exchange: exchange.clone(),
                rank,
                whole_dofs,
                total: 3 * model.num_nodes(),
            },
            owned_dofs: part.owned_dofs(),
            part,
            element_part,
            exchange,
            rank,
            whole: Arc::new(whole_assembly),
        }
    }
}

impl Distribution for Half {
    fn collective(&self) -> &dyn Collective {
        &self.sums
    }
    fn owned_dofs(&self) -> &[bool] {
        &self.owned_dofs
    }
    fn owned_elements(&self) -> &[bool] {
        &self.part.own_elements
    }
    fn solver(
        &self,
        assembly: &Assembly,
        _: LinearSolverKind,
    ) -> Result<Box<dyn ExternalSolver>, LinearError> {
        // Always the summed Hessian's Cholesky: what these tests compare is the split of the
        // potential, not the solver.
        let sums = Sums {
            exchange: self.exchange.clone(),
            rank: self.rank,
            whole_dofs: self.sums.whole_dofs.clone(),
            total: self.sums.total,
        };
        if self.part.is_whole() {
            return Ok(Box::new(SummedCholesky {
                sums,
                whole: None,
                cholesky: Cholesky::new(FillOrdering::Auto, assembly)?,
            }));
        }
        let whole_dofs = &self.sums.whole_dofs;
        let free_in_whole = assembly
            .dofs()
            .free_dofs()
            .iter()
            .map(|&d| self.whole.dofs().free(whole_dofs[d]).expect("free in both"))
            .collect();
        Ok(Box::new(SummedCholesky {
            sums,
            whole: Some((self.whole.clone(), free_in_whole)),
            cholesky: Cholesky::new(FillOrdering::Auto, &self.whole)?,
        }))
    }
    fn remeshed(
        &self,
        model: &Model,
        parent: &[usize],
    ) -> Result<(Box<dyn Distribution>, Part), SimError> {
        let element_part = parent.iter().map(|&p| self.element_part[p]).collect();
        let whole = self.part.is_whole();
        let half = Half::with_parts(model, self.exchange.clone(), self.rank, whole, element_part);
        let part = half.part.clone();
        Ok((Box::new(half), part))
    }
}

/// The scene's displacements after `steps` steps (on the whole mesh's dofs, each from the
/// process owning it), and Newton's iterations per step; shared by two if `share` is given
/// (the whole mesh on each if its flag is set).
fn run(
    scene: &icefem::scene::Scene,
    steps: usize,
    share: Option<(Arc<Exchange>, usize, bool)>,
) -> (Vec<f64>, Vec<usize>) {
    let Some((exchange, rank, whole)) = share else {
        let mut sim = Simulation::new(scene.model.clone(), scene.settings).unwrap();
        let iterations = (0..steps)
            .map(|_| sim.step().unwrap().newton.iterations)
            .collect();
        return (sim.state.u.clone(), iterations);
    };
    let half = Half::new(&scene.model, exchange, rank, whole);
    let part = half.part.clone();
    let model = part.model(&scene.model).unwrap();
    let mut sim = Simulation::for_part(model, scene.settings).unwrap();
    sim.distribute(Box::new(half)).unwrap();
    let iterations = (0..steps)
        .map(|_| sim.step().unwrap().newton.iterations)
        .collect();
    let mut u = vec![0.0; 3 * part.whole_nodes()];
    for (k, d) in part.whole_dofs().enumerate() {
        if part.owned_nodes[k / 3] {
            u[d] = sim.state.u[k];
        }
    }
    (u, iterations)
}

/// `scene`'s first `steps` steps on two processes against one (each holding its part of the
/// mesh, or the whole mesh if `whole`): the same Newton iterations, displacements to
/// round-off.
fn two_match_one(scene: &icefem::scene::Scene, steps: usize, whole: bool) {
    let (serial, serial_iterations) = run(scene, steps, None);
    let exchange = Arc::new(Exchange {
        barrier: Barrier::new(2),
        slots: Mutex::new([Vec::new(), Vec::new()]),
    });
    let [(first, first_iterations), (second, second_iterations)] = std::thread::scope(|s| {
        let handles = [0, 1].map(|rank| {
            let exchange = exchange.clone();
            s.spawn(move || run(scene, steps, Some((exchange, rank, whole))))
        });
        handles.map(|h| h.join().unwrap())
    });
    assert_eq!(first_iterations, second_iterations);
    let both: Vec<f64> = first.iter().zip(&second).map(|(a, b)| a + b).collect();
    // Against one process: the same factorisation of the same matrix up to the order of
    // the sums (the two parts added, the gradient summed), so round-off only: ε times the
    // conditioning over the steps (measured below 1e-12 of the largest displacement).
    let scale = serial.iter().fold(0.0f64, |m, u| m.max(u.abs()));
    let diff = serial
        .iter()
        .zip(&both)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    eprintln!(
        "{}: shared by two (whole mesh on each: {whole}): max |Δu| / max |u| = {:.2e}",
        scene.path.display(),
        diff / scale
    );
    assert!(scale > 0.0 && diff <= 1e-9 * scale, "{diff:e} of {scale:e}");
    assert_eq!(serial_iterations, first_iterations);
}

/// The freezing container (freezing, the nodal volumetric energy, plasticity, the
/// container's walls): its first 90 steps (3 s), in which the ice front moves in and the
/// water is squeezed.
fn freezing_container() -> icefem::scene::Scene {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/freezing_container.toml");
    icefem::scene::Scene::load(&path).unwrap()
}

#[test]
fn the_freezing_container_shared_by_two_matches_one() {
    two_match_one(&freezing_container(), 90, true);
}

#[test]
fn the_freezing_container_in_two_parts_matches_one() {
    two_match_one(&freezing_container(), 90, false);
}

#[test]
fn stiffness_damping_in_two_parts_matches_one() {
    // Rayleigh's β Kₙ held by elements as the elastic energy is: with the nodal volumetric
    // energy, Kₙ's rows reach two rings of elements, beyond a part's ring.
    let mut scene = freezing_container();
    scene.model.damping = Some(icefem::physics::Rayleigh {
        mass: 0.0,
        stiffness: 1e-4,
    });
    two_match_one(&scene, 90, false);
    // The start from the acceleration of the state (Newmark's), with β Kₙ v in its forces.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sagging_bar.toml");
    std::fs::write(&path, common::SAGGING_BAR).unwrap();
    let mut bar = icefem::scene::Scene::load(&path).unwrap();
    for scheme in [Scheme::BackwardEuler, Scheme::Newmark] {
        bar.settings.scheme = scheme;
        bar.model.initial_velocity = vec![0.01; 3 * bar.model.num_nodes()];
        two_match_one(&bar, 10, false);
    }
}

/// What a run with fracture did: the splits of each step, the crack area at the end (m²) and
/// the displacements of every step before the first split.
struct Cracked {
    events: Vec<usize>,
    area: f64,
    before_first_split: Vec<Vec<f64>>,
}

/// `scene` (with `[fracture]`) to its end; shared by two processes, each holding the whole
/// mesh (as a run with fracture does), if `share` is given.
fn crack(scene: &icefem::scene::Scene, share: Option<(Arc<Exchange>, usize)>) -> Cracked {
    let mut sim = match share {
        None => Simulation::new(scene.model.clone(), scene.settings).unwrap(),
        Some((exchange, rank)) => {
            let half = Half::new(&scene.model, exchange, rank, true);
            let model = half.part.model(&scene.model).unwrap();
            let mut sim = Simulation::for_part(model, scene.settings).unwrap();
            sim.distribute(Box::new(half)).unwrap();
            sim
        }
    };
    let settings = scene.fracture.expect("a scene with [fracture]");
    let mut fracture = icefem::fracture::Fracture::new(settings, &sim.model.mesh);
    let steps = icefem::run::step_count(scene.end_time, scene.settings.dt);
    let mut cracked = Cracked {
        events: Vec::new(),
        area: 0.0,
        before_first_split: Vec::new(),
    };
    for _ in 0..steps {
        sim.step().unwrap();
        let report = fracture.after_step(&mut sim).unwrap();
        if report.events.is_empty() && cracked.events.iter().all(|&n| n == 0) {
            cracked.before_first_split.push(sim.state.u.clone());
        }
        cracked.events.push(report.events.len());
    }
    cracked.area = fracture.crack_area(&sim.model.mesh.rest);
    cracked
}

#[test]
fn a_pulled_bar_shared_by_two_cracks_as_on_one() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pulled_bar.toml");
    let scene = icefem::scene::Scene::load(&path).unwrap();
    let serial = crack(&scene, None);
    let exchange = Arc::new(Exchange {
        barrier: Barrier::new(2),
        slots: Mutex::new([Vec::new(), Vec::new()]),
    });
    let [first, second] = std::thread::scope(|s| {
        let handles = [0, 1].map(|rank| {
            let (scene, exchange) = (&scene, exchange.clone());
            s.spawn(move || crack(scene, Some((exchange, rank))))
        });
        handles.map(|h| h.join().unwrap())
    });
    // Both processes hold the whole mesh and take the same decisions: the same bits.
    assert_eq!(first.events, second.events);
    assert_eq!(first.area.to_bits(), second.area.to_bits());
    assert_eq!(first.before_first_split, second.before_first_split);
    let splits: usize = serial.events.iter().sum();
    assert!(splits > 0, "the bar cracks");
    // Until the first split, one process's displacements to round-off: the same matrix
    // factorised, its two halves added in another order (measured below 1e-12).
    assert_eq!(
        serial.before_first_split.len(),
        first.before_first_split.len()
    );
    for (a, b) in serial
        .before_first_split
        .iter()
        .zip(&first.before_first_split)
    {
        let scale = a.iter().fold(0.0f64, |m, u| m.max(u.abs()));
        let diff = a
            .iter()
            .zip(b)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(diff <= 1e-9 * scale, "{diff:e} of {scale:e}");
    }
    eprintln!(
        "pulled bar: {splits} splits, crack area {:.4e} m² on one process, {:.4e} m² shared by two",
        serial.area, first.area
    );
    assert_eq!(serial.events, first.events);
    assert!((serial.area - first.area).abs() <= 1e-9 * serial.area);
}
