//! Runs on several processes (the `mpi` feature): `mpirun -n N icefem run SCENE.toml`.
//!
//! Every process reads the scene, builds the whole mesh and state and takes the same steps,
//! with the same decisions: Newton's iterates, residuals and line searches are the same
//! numbers on every process. What is shared out is the work of an iteration — METIS splits
//! the elements ([`partition`]); each process evaluates the elastic energy, gradient and
//! Hessian of its own elements and the other terms on the dofs it owns; energies and
//! gradients are summed across the processes (`sim::Collective`, over MPI), and the Hessian's
//! parts go into one PETSc matrix, solved by conjugate gradients with algebraic multigrid
//! ([`solver`]). Process 0 writes the output, the same file a run on one process writes.
//!
//! Not distributed: fracture (its remeshing) — a run that needs it is refused with a
//! message. Memory per process is that of the whole mesh and state plus its share of the
//! matrix.

pub mod partition;
pub mod petsc;
pub mod solver;

use crate::assembly::Assembly;
use crate::physics::Model;
use crate::run::Processes;
use crate::sim::part::Part;
use crate::sim::{Collective, Distribution, SimError, Simulation};
use crate::solver::{ExternalSolver, LinearError};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use partition::Partition;
use std::cell::RefCell;

/// What this process exchanged with the others so far, counted where it is sent (in values
/// of 8 bytes; a matrix entry also carries its two 4-byte indices): the measured side of the
/// communication volume (`docs/distributed.md`).
pub mod traffic {
    use std::sync::atomic::{AtomicU64, Ordering};

    /// Values of the energy and gradient sums (sent and received).
    pub static SUMS: AtomicU64 = AtomicU64::new(0);
    /// Matrix entries added to other processes' rows.
    pub static MATRIX_ENTRIES: AtomicU64 = AtomicU64::new(0);
    /// Values of the solutions gathered onto this process.
    pub static GATHERED: AtomicU64 = AtomicU64::new(0);
    /// Other processes' vector entries the conjugate gradients' products read (finest level,
    /// per iteration, summed over iterations).
    pub static HALO: AtomicU64 = AtomicU64::new(0);

    /// Adds `n` to `counter`.
    pub fn add(counter: &AtomicU64, n: usize) {
        counter.fetch_add(n as u64, Ordering::Relaxed);
    }

    /// The four counts: sums, matrix entries, gathered values, halo values.
    pub fn read() -> [u64; 4] {
        [&SUMS, &MATRIX_ENTRIES, &GATHERED, &HALO].map(|c| c.load(Ordering::Relaxed))
    }
}

/// Failure to start the processes' libraries.
#[derive(Debug, thiserror::Error)]
pub enum DistributedError {
    /// MPI could not be initialised (or was already).
    #[error("MPI could not be initialised")]
    Mpi,
    /// PETSc could not be initialised.
    #[error(transparent)]
    Petsc(#[from] petsc::PetscError),
}

/// MPI and PETSc, initialised for the life of this value; the processes of `mpirun`.
pub struct MpiProcesses {
    // Dropped in this order: PETSc before MPI.
    _petsc: petsc::Petsc,
    _universe: mpi::environment::Universe,
    world: SimpleCommunicator,
    /// The partition and this process's part, from [`Processes::part_model`] until
    /// [`Processes::distribute`].
    part: RefCell<Option<(Partition, Part)>>,
}

impl MpiProcesses {
    /// Initialises MPI (calls may come from any thread, one at a time: a test harness runs
    /// tests on threads of its own) and PETSc.
    pub fn init() -> Result<Self, DistributedError> {
        let (universe, _) = mpi::initialize_with_threading(mpi::Threading::Multiple)
            .ok_or(DistributedError::Mpi)?;
        let world = universe.world();
        let petsc = petsc::Petsc::init()?;
        Ok(MpiProcesses {
            _petsc: petsc,
            _universe: universe,
            world,
            part: RefCell::new(None),
        })
    }

    /// This process's number, from 0.
    pub fn rank(&self) -> u32 {
        self.world.rank() as u32
    }

    /// Number of processes.
    pub fn size(&self) -> usize {
        self.world.size() as usize
    }

    /// Ends every process of the run with `code` (after an error on any of them: the others
    /// may be waiting for it in a collective call).
    pub fn abort(&self, code: i32) -> ! {
        self.world.abort(code)
    }

    /// Each process's exchanged values (see [`traffic`]) and peak resident memory (bytes),
    /// gathered onto process 0 (empty elsewhere).
    pub fn traffic_by_process(&self) -> Vec<([u64; 4], u64)> {
        let mine = traffic::read();
        let local = [mine[0], mine[1], mine[2], mine[3], peak_memory()];
        let root = self.world.process_at_rank(0);
        if self.rank() == 0 {
            let mut all = vec![0u64; 5 * self.size()];
            root.gather_into_root(&local[..], &mut all[..]);
            all.chunks(5)
                .map(|c| ([c[0], c[1], c[2], c[3]], c[4]))
                .collect()
        } else {
            root.gather_into(&local[..]);
            Vec::new()
        }
    }

    /// The largest of `x` over the processes.
    pub fn max(&self, x: f64) -> f64 {
        let mut y = 0.0;
        self.world
            .all_reduce_into(&x, &mut y, SystemOperation::max());
        y
    }
}

impl Processes for MpiProcesses {
    fn part_model(&self, model: &Model, whole: bool) -> Result<Model, SimError> {
        let mesh = &model.mesh;
        let size = self.size();
        // Process 0 partitions; every process uses its partition.
        let mut element_part = match self.rank() {
            0 => {
                Partition::new(mesh, size)
                    .map_err(|e| SimError::Setup(e.to_string()))?
                    .element_part
            }
            _ => vec![0u32; mesh.num_tets()],
        };
        self.world
            .process_at_rank(0)
            .broadcast_into(&mut element_part[..]);
        let partition = Partition::from_element_parts(mesh, element_part, size);
        let part = Part::new(
            &mesh.tets,
            (&partition.element_part, &partition.node_owner),
            self.rank(),
            whole,
        );
        let model = part
            .model(model)
            .map_err(|e| SimError::Setup(e.to_string()))?;
        *self.part.borrow_mut() = Some((partition, part));
        Ok(model)
    }

    fn distribute(&self, sim: &mut Simulation) -> Result<(), SimError> {
        let Some((partition, part)) = self.part.borrow_mut().take() else {
            return Err(SimError::Setup(
                "the simulation was not built on this process's part".into(),
            ));
        };
        let mesh = &sim.model.mesh;
        let iterative = sim.settings.iterative();
        let share = ProcessShare {
            collective: MpiCollective {
                world: SimpleCommunicator::world(),
                scratch: RefCell::new(Vec::new()),
            },
            owned_dofs: part.owned_dofs(),
            owned_elements: part.own_elements,
            rank: self.rank(),
            partition,
            tets: mesh.tets.clone(),
            rest: mesh.rest.clone(),
            solve: (iterative.tolerance, iterative.max_iterations),
        };
        sim.distribute(Box::new(share))
    }

    fn count(&self) -> usize {
        self.size()
    }

    fn writes(&self) -> bool {
        self.rank() == 0
    }

    fn broadcast_bytes(&self, mut bytes: Vec<u8>) -> Vec<u8> {
        let root = self.world.process_at_rank(0);
        let mut len = bytes.len() as u64;
        root.broadcast_into(&mut len);
        bytes.resize(len as usize, 0);
        root.broadcast_into(&mut bytes[..]);
        bytes
    }

    fn any(&self, flag: bool) -> bool {
        let mut any = 0u8;
        self.world
            .all_reduce_into(&u8::from(flag), &mut any, SystemOperation::max());
        any != 0
    }
}

/// This process's peak resident memory (bytes).
fn peak_memory() -> u64 {
    // SAFETY: getrusage fills the struct it is given.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let ok = unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } == 0;
    // Linux reports kilobytes.
    if ok {
        usage.ru_maxrss.max(0) as u64 * 1024
    } else {
        0
    }
}

/// Sums across the processes over MPI, made the same on every process: scalars gathered and
/// added in process order, vectors reduced onto process 0 and broadcast from it.
struct MpiCollective {
    world: SimpleCommunicator,
    scratch: RefCell<Vec<f64>>,
}

impl Collective for MpiCollective {
    fn sum(&self, x: f64) -> f64 {
        let mut all = vec![0.0; self.world.size() as usize];
        self.world.all_gather_into(&x, &mut all[..]);
        traffic::add(&traffic::SUMS, 2 * (all.len() - 1));
        all.iter().sum()
    }

    fn exchange(&self, v: &mut [f64]) {
        let root = self.world.process_at_rank(0);
        if self.world.rank() == 0 {
            let mut total = self.scratch.borrow_mut();
            total.resize(v.len(), 0.0);
            root.reduce_into_root(v, &mut total[..], SystemOperation::sum());
            v.copy_from_slice(&total);
        } else {
            root.reduce_into(v, SystemOperation::sum());
        }
        root.broadcast_into(v);
        // Process 0 receives and sends every other's vector; the others one each way.
        let others = self.world.size() as usize - 1;
        let sent = if self.world.rank() == 0 {
            2 * others
        } else {
            2
        };
        traffic::add(&traffic::SUMS, sent * v.len());
    }

    fn max(&self, x: f64) -> f64 {
        let mut y = 0.0;
        self.world
            .all_reduce_into(&x, &mut y, SystemOperation::max());
        y
    }
}

/// One process's share of a distributed simulation.
struct ProcessShare {
    collective: MpiCollective,
    owned_dofs: Vec<bool>,
    owned_elements: Vec<bool>,
    rank: u32,
    partition: Partition,
    tets: Vec<[usize; 4]>,
    rest: Vec<nalgebra::Vector3<f64>>,
    /// CG's relative tolerance and iteration cap.
    solve: (f64, usize),
}

impl Distribution for ProcessShare {
    fn collective(&self) -> &dyn Collective {
        &self.collective
    }

    fn owned_dofs(&self) -> &[bool] {
        &self.owned_dofs
    }

    fn owned_elements(&self) -> &[bool] {
        &self.owned_elements
    }

    fn solver(&self, assembly: &Assembly) -> Result<Box<dyn ExternalSolver>, LinearError> {
        Ok(Box::new(solver::PetscSolver::new(
            assembly,
            &self.partition,
            (self.rank, &self.owned_elements, &self.tets),
            &self.rest,
            self.solve,
        )?))
    }
}
