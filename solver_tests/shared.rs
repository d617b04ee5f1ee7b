//! A simulation shared among processes, without MPI: two threads play two processes, each
//! with its own `Simulation` sharing the work as a distributed run does (`Simulation::
//! distribute`), their sums exchanged through memory and the Hessian's two parts added and
//! factorised by Cholesky on both. This checks the split of the potential — elements per
//! process, the other terms kept on owned dofs, the nodal volumetric energy by owned node —
//! in the default build; `distributed.rs` (feature `mpi`) checks MPI and PETSc on top.

use icefem::assembly::Assembly;
use icefem::sim::{Collective, Distribution, Simulation};
use icefem::solver::linear::Cholesky;
use icefem::solver::{ExternalSolver, FillOrdering, LinearError, LinearStats};
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

/// Process `rank`'s view of the exchange.
struct Sums {
    exchange: Arc<Exchange>,
    rank: usize,
}

impl Collective for Sums {
    fn sum(&self, x: f64) -> f64 {
        let [a, b] = self.exchange.both(self.rank, &[x]);
        a[0] + b[0]
    }
    fn sum_in_place(&self, v: &mut [f64]) {
        let [a, b] = self.exchange.both(self.rank, v);
        for ((v, a), b) in v.iter_mut().zip(&a).zip(&b) {
            *v = a + b;
        }
    }
    fn max(&self, x: f64) -> f64 {
        let [a, b] = self.exchange.both(self.rank, &[x]);
        a[0].max(b[0])
    }
}

/// The two Hessian parts added, then Cholesky: the same factor on both processes.
struct SummedCholesky {
    sums: Sums,
    cholesky: Cholesky,
}

impl ExternalSolver for SummedCholesky {
    fn factorize(&mut self, assembly: &Assembly, values: &[f64]) -> Result<(), LinearError> {
        let mut whole = values.to_vec();
        self.sums.sum_in_place(&mut whole);
        self.cholesky.factorize(assembly, &whole).map(|_| ())
    }
    fn solve(&mut self, b: &[f64], x: &mut [f64]) -> Result<LinearStats, LinearError> {
        Ok(self.cholesky.solve(b, x))
    }
}

/// Process `rank` of two: the first half of the elements (by index) or the second; a node
/// belongs to the lower process among its elements'.
struct Half {
    exchange: Arc<Exchange>,
    rank: usize,
    sums: Sums,
    owned_elements: Vec<bool>,
    owned_dofs: Vec<bool>,
}

impl Half {
    fn new(sim: &Simulation, exchange: Arc<Exchange>, rank: usize) -> Self {
        let tets = &sim.model.mesh.tets;
        let part = |e: usize| usize::from(e >= tets.len() / 2);
        let mut owner = vec![1usize; sim.model.num_nodes()];
        for (e, tet) in tets.iter().enumerate() {
            for &v in tet {
                owner[v] = owner[v].min(part(e));
            }
        }
        Half {
            sums: Sums {
                exchange: exchange.clone(),
                rank,
            },
            exchange,
            rank,
            owned_elements: (0..tets.len()).map(|e| part(e) == rank).collect(),
            owned_dofs: owner.iter().flat_map(|&o| [o == rank; 3]).collect(),
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
        &self.owned_elements
    }
    fn solver(&self, assembly: &Assembly) -> Result<Box<dyn ExternalSolver>, LinearError> {
        Ok(Box::new(SummedCholesky {
            sums: Sums {
                exchange: self.exchange.clone(),
                rank: self.rank,
            },
            cholesky: Cholesky::new(FillOrdering::Auto, assembly)?,
        }))
    }
}

/// The scene's displacements after `steps` steps, and Newton's iterations per step.
fn run(
    scene: &icefem::scene::Scene,
    steps: usize,
    share: Option<(Arc<Exchange>, usize)>,
) -> (Vec<f64>, Vec<usize>) {
    let mut sim = Simulation::new(scene.model.clone(), scene.settings).unwrap();
    if let Some((exchange, rank)) = share {
        let half = Half::new(&sim, exchange, rank);
        sim.distribute(Box::new(half)).unwrap();
    }
    let iterations = (0..steps)
        .map(|_| sim.step().unwrap().newton.iterations)
        .collect();
    (sim.state.u.clone(), iterations)
}

#[test]
fn the_freezing_container_shared_by_two_matches_one() {
    // Freezing, the nodal volumetric energy, plasticity, the container's walls: the first
    // 90 steps (3 s), in which the ice front moves in and the water is squeezed.
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/freezing_container.toml");
    let scene = icefem::scene::Scene::load(&path).unwrap();
    let steps = 90;
    let (serial, serial_iterations) = run(&scene, steps, None);
    let exchange = Arc::new(Exchange {
        barrier: Barrier::new(2),
        slots: Mutex::new([Vec::new(), Vec::new()]),
    });
    let [(first, first_iterations), (second, _)] = std::thread::scope(|s| {
        let handles = [0, 1].map(|rank| {
            let (scene, exchange) = (&scene, exchange.clone());
            s.spawn(move || run(scene, steps, Some((exchange, rank))))
        });
        handles.map(|h| h.join().unwrap())
    });
    // Both processes hold the same state, bit for bit.
    assert_eq!(first, second);
    // Against one process: the same factorisation of the same matrix up to the order of
    // the sums (the two parts added, the gradient summed), so round-off only: ε times the
    // conditioning over 90 steps (measured below 1e-12 of the largest displacement).
    let scale = serial.iter().fold(0.0f64, |m, u| m.max(u.abs()));
    let diff = serial
        .iter()
        .zip(&first)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    eprintln!("shared by two: max |Δu| / max |u| = {:.2e}", diff / scale);
    assert!(scale > 0.0 && diff <= 1e-9 * scale, "{diff:e} of {scale:e}");
    assert_eq!(serial_iterations, first_iterations);
}
