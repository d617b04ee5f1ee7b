//! Runs on several processes (the `mpi` feature): `mpirun -n N icefem run SCENE.toml`.
//!
//! PT-Scotch splits the elements ([`partition`]) and each process gathers its part of the mesh
//! from the ranges the processes hold ([`part_mesh`]); every process reads the scene and builds
//! its part of the model and state (`sim::part`: its elements and the ring of elements around
//! their nodes, or the whole mesh where a term needs it) and takes the same steps, with the same
//! decisions: Newton's residuals, line searches and step lengths are the same numbers on
//! every process. Each process evaluates the elastic energy, gradient and Hessian of its own
//! elements and the other terms on the nodes it owns; energies and dof sums are added across
//! the processes, gradients at the nodes several processes hold exchanged between them
//! ([`ghosts`]), and the Hessian's parts go into one PETSc matrix, solved by conjugate
//! gradients with algebraic multigrid ([`solver`]); the heat model is shared the same way
//! ([`heat`]). Process 0 gathers the processes' parts of
//! each frame, and of the header's mesh, and writes the same file a run on one process writes.
//!
//! A scene whose set-up needs no whole mesh is built on each process's part
//! (`scene::shared`, through [`MeshSharing`]); any other is read whole by every process,
//! which keeps the whole model as a description (materials, loads, terms; not the elements'
//! rest data) until it has built its part from it. Fracture splits the whole mesh, which
//! every process then holds: each makes the same splits and shares the split mesh out again
//! ([`Distribution::remeshed`]).

pub mod components;
pub mod dual_graph;
pub mod ghost_surface;
pub mod ghosts;
pub mod heat;
pub mod node_halo;
pub mod part_fracture;
pub mod part_mesh;
pub mod partition;
pub mod petsc;
pub mod rebuild;
pub mod run_fracture;
pub mod solver;
pub mod splits;
pub mod surface_hold;

use crate::assembly::Assembly;
use crate::mesh::TetMesh;
use crate::physics::Model;
use crate::run::Processes;
use crate::scene::{MeshRanges, MeshSharing, SharedMesh};
use crate::sim::part::Part;
use crate::sim::{Collective, Distribution, SimError, Simulation};
use crate::solver::{ExternalSolver, LinearError, LinearSolverKind};
use ghosts::Ghosts;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use partition::{PartNumbering, Partition};
use std::cell::{Cell, RefCell};
use std::rc::Rc;

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

/// What a process reports after a distributed run.
#[derive(Clone, Copy, Debug)]
pub struct ProcessReport {
    /// Values exchanged: sums, matrix entries, gathered values, halo values (see [`traffic`]).
    pub traffic: [u64; 4],
    /// Peak resident memory (bytes).
    pub peak_memory: u64,
    /// Peak resident memory before the solvers are set up (bytes): what reading the scene,
    /// partitioning the mesh and building the process's part took.
    pub set_up_memory: u64,
    /// Nodes and elements of the process's part of the mesh.
    pub held: [u64; 2],
}

/// MPI and PETSc, initialised for the life of this value; the processes of `mpirun`.
pub struct MpiProcesses {
    // Dropped in this order: PETSc before MPI.
    _petsc: petsc::Petsc,
    _universe: mpi::environment::Universe,
    world: SimpleCommunicator,
    /// The partition on this process's part, and the part, from [`Processes::part_model`]
    /// until [`Processes::distribute`].
    part: RefCell<Option<(PartNumbering, Part)>>,
    /// The ghost surface this process holds for ice–ice contact, where it holds one.
    surface: RefCell<Option<HeldSurface>>,
    /// Nodes and elements of this process's part (its share's, once the mesh is split).
    held: Rc<Cell<[u64; 2]>>,
    /// Whether every process holds the whole mesh even where parts would do.
    whole_mesh: Cell<bool>,
    /// Peak resident memory when the part was shared out (bytes; see
    /// [`ProcessReport::set_up_memory`]).
    set_up_memory: Cell<u64>,
    /// The owners of the nodes of the part last shared out, and its elements' processes.
    owners: RefCell<(Vec<u32>, Vec<u32>)>,
}

impl MpiProcesses {
    /// Initialises MPI (calls may come from any thread, one at a time: a test harness runs
    /// tests on threads of its own) and PETSc.
    pub fn init() -> Result<Self, DistributedError> {
        // PT-Scotch partitions on several threads in an order that changes from run to run;
        // on one thread (and from a fixed seed, see `petsc::ptscotch_parts`) every run gets
        // the same partition, which a resumed run needs to share the mesh out as the run it
        // resumes did. Set before MPI and PETSc start their threads.
        if std::env::var_os("SCOTCH_PTHREAD_NUMBER").is_none() {
            std::env::set_var("SCOTCH_PTHREAD_NUMBER", "1");
        }
        let (universe, _) = mpi::initialize_with_threading(mpi::Threading::Multiple)
            .ok_or(DistributedError::Mpi)?;
        let world = universe.world();
        let petsc = petsc::Petsc::init()?;
        Ok(MpiProcesses {
            _petsc: petsc,
            _universe: universe,
            world,
            part: RefCell::new(None),
            surface: RefCell::new(None),
            held: Rc::new(Cell::new([0; 2])),
            whole_mesh: Cell::new(false),
            set_up_memory: Cell::new(0),
            owners: RefCell::new((Vec::new(), Vec::new())),
        })
    }

    /// Makes every process hold the whole mesh, as a scene whose terms need it does (to
    /// measure what the parts save).
    pub fn hold_whole_mesh(&self) {
        self.whole_mesh.set(true);
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

    /// Each process's exchanged values (see [`traffic`]), peak resident memory (bytes) and
    /// the nodes and elements of its part, gathered onto process 0 (empty elsewhere).
    pub fn traffic_by_process(&self) -> Vec<ProcessReport> {
        let mine = traffic::read();
        let [nodes, elements] = self.held.get();
        let local = [
            mine[0],
            mine[1],
            mine[2],
            mine[3],
            peak_memory(),
            self.set_up_memory.get(),
            nodes,
            elements,
        ];
        let root = self.world.process_at_rank(0);
        if self.rank() == 0 {
            let mut all = vec![0u64; local.len() * self.size()];
            root.gather_into_root(&local[..], &mut all[..]);
            all.chunks(local.len())
                .map(|c| ProcessReport {
                    traffic: [c[0], c[1], c[2], c[3]],
                    peak_memory: c[4],
                    set_up_memory: c[5],
                    held: [c[6], c[7]],
                })
                .collect()
        } else {
            root.gather_into(&local[..]);
            Vec::new()
        }
    }

    /// The largest of `x` over the processes.
    pub fn max(&self, x: f64) -> f64 {
        largest(&self.world, x)
    }
}

/// The partition of the elements of the ranges a process holds (see [`MeshRanges`]): each
/// range element's process and its faces on the whole mesh's boundary (see
/// [`dual_graph::DualGraph::boundary`]).
#[derive(Clone)]
struct RangePartition {
    parts: Vec<u32>,
    boundary: Vec<u8>,
}

/// What a process holds of a ghost surface (ice–ice contact's, see [`surface_hold`]), while
/// the run goes on: the hold, its ranges' partition (kept, so that every gathering keeps the
/// parts) and its part's nodes' owners.
struct HeldSurface {
    hold: surface_hold::SurfaceHold,
    partition: RangePartition,
    node_owner: Vec<u32>,
}

impl MpiProcesses {
    /// The elements of the mesh the processes hold in `ranges` partitioned by PT-Scotch.
    /// Every process calls it.
    fn partitioned(
        &self,
        ranges: &MeshRanges,
    ) -> Result<RangePartition, partition::PartitionError> {
        let starts = ranges.element_starts;
        let graph = dual_graph::rows(&self.world, ranges.tets, starts);
        let parts = partition::parts_of_range(&graph, starts)?;
        Ok(RangePartition {
            parts,
            boundary: graph.boundary,
        })
    }

    /// This process's part of the mesh the processes hold in `ranges`, partitioned as
    /// `partition` says, with the elements `besides`; its partition is kept for
    /// [`Processes::distribute`]. Every process calls it.
    fn gather_part(
        &self,
        ranges: &MeshRanges,
        partition: &RangePartition,
        besides: part_mesh::Besides,
    ) -> SharedMesh {
        let gathered = part_mesh::part_mesh(
            &self.world,
            part_mesh::ElementRange {
                starts: ranges.element_starts,
                tets: ranges.tets,
                parts: &partition.parts,
                boundary: &partition.boundary,
            },
            part_mesh::NodeRange {
                starts: ranges.node_starts,
                rest: ranges.rest,
            },
            (besides, None),
        );
        *self.part.borrow_mut() = Some((gathered.numbering, gathered.part.clone()));
        SharedMesh {
            part: gathered.part,
            rest: gathered.rest,
            tets: gathered.tets,
            boundary: gathered.boundary,
        }
    }

    /// This process's part of `mesh` (the whole mesh, which every process holds) partitioned
    /// as `partition` says, with the elements of its ghost surface for `contact` at the state
    /// `at` of its part then, for steps of `h` seconds. Every process calls it.
    fn gather_with_surface(
        &self,
        (mesh, partition): (&TetMesh, RangePartition),
        contact: &crate::physics::ice_contact::IceContact,
        at: &PartState,
        h: f64,
    ) -> Result<SharedMesh, SimError> {
        let vmax = largest(&self.world, at.vmax);
        let hold = surface_hold::SurfaceHold::new(contact, (vmax, h), at.part, at.u);
        let elements = surface_hold::surface_elements(
            &self.world,
            at.part,
            at.mesh,
            (at.u, at.node_owner),
            hold.reach(),
        )
        .map_err(|e| SimError::Setup(e.to_string()))?;
        let starts = range_starts(mesh, self.size());
        let gathered = self.gather_part(
            &ranges_of(mesh, (&starts.0, &starts.1), self.rank() as usize),
            &partition,
            part_mesh::Besides::Asked(&elements),
        );
        let node_owner = self.node_owner();
        *self.surface.borrow_mut() = Some(HeldSurface {
            hold,
            partition,
            node_owner,
        });
        Ok(gathered)
    }

    /// The owners of the nodes of the part last gathered.
    fn node_owner(&self) -> Vec<u32> {
        let part = self.part.borrow();
        let (numbering, _) = part.as_ref().expect("a part gathered");
        numbering.node_owner.clone()
    }
}

/// A process's part and its state, from which its ghost surface is gathered.
struct PartState<'a> {
    part: &'a Part,
    /// The part's mesh: rest positions (m) and elements.
    mesh: (&'a [nalgebra::Vector3<f64>], &'a [[usize; 4]]),
    /// Each part node's owner.
    node_owner: &'a [u32],
    /// Displacements (m, 3 per node) and this process's largest velocity component (m/s).
    u: &'a [f64],
    vmax: f64,
}

/// Where each of `size` processes' ranges of `mesh`'s elements and of its nodes start (see
/// [`MeshRanges`]).
fn range_starts(mesh: &TetMesh, size: usize) -> (Vec<usize>, Vec<usize>) {
    (
        partition::ranges(mesh.num_tets(), size),
        partition::ranges(mesh.num_nodes(), size),
    )
}

/// This process's (`rank`) ranges of `mesh` where the ranges start at `starts` (elements,
/// nodes).
fn ranges_of<'a>(
    mesh: &'a TetMesh,
    (element_starts, node_starts): (&'a [usize], &'a [usize]),
    rank: usize,
) -> MeshRanges<'a> {
    MeshRanges {
        element_starts,
        tets: &mesh.tets[element_starts[rank]..element_starts[rank + 1]],
        node_starts,
        rest: &mesh.rest[node_starts[rank]..node_starts[rank + 1]],
    }
}

impl Processes for MpiProcesses {
    fn part_model(
        &self,
        model: &Model,
        (whole, h): (bool, f64),
    ) -> Result<(Part, Model), SimError> {
        let mesh = &model.mesh;
        let (size, rank) = (self.size(), self.rank() as usize);
        // Each process takes a range of the elements and one of the nodes to the partitioner
        // and the rendezvous that gathers its part (see `part_mesh`).
        let starts = range_starts(mesh, size);
        let ranges = ranges_of(mesh, (&starts.0, &starts.1), rank);
        let setup = |e: partition::PartitionError| SimError::Setup(e.to_string());
        let partition = self.partitioned(&ranges).map_err(setup)?;
        let gathered = match (whole || self.whole_mesh.get(), model.ice_contact()) {
            (true, _) => self.gather_part(&ranges, &partition, part_mesh::Besides::All),
            (false, None) => self.gather_part(&ranges, &partition, part_mesh::Besides::Asked(&[])),
            // Ice–ice contact: the part, then its ghost surface at the initial state.
            (false, Some(contact)) => {
                let ring = self.gather_part(&ranges, &partition, part_mesh::Besides::Asked(&[]));
                let initial = |whole: &[f64]| match whole.is_empty() {
                    true => vec![0.0; 3 * ring.part.nodes.len()],
                    false => ring.part.dofs_of(whole),
                };
                let u = initial(&model.initial_displacement);
                let at = PartState {
                    part: &ring.part,
                    mesh: (&ring.rest, &ring.tets),
                    node_owner: &self.node_owner(),
                    u: &u,
                    vmax: largest_component(&initial(&model.initial_velocity)),
                };
                self.gather_with_surface((mesh, partition), contact, &at, h)?
            }
        };
        part_and_model(gathered, model)
    }

    fn surface_outgrown(&self, sim: &Simulation, part: &Part) -> bool {
        let surface = self.surface.borrow();
        let (Some(held), Some(contact)) = (surface.as_ref(), sim.model.ice_contact()) else {
            return false;
        };
        let motion = (largest_component(&sim.state.v), sim.settings.dt);
        (held.hold).outgrown(&self.world, contact, (part, &sim.state.u), motion)
    }

    fn regathered(
        &self,
        model: &Model,
        sim: &Simulation,
        part: &Part,
    ) -> Result<(Part, Model), SimError> {
        let (Some(held), Some(contact)) = (self.surface.borrow_mut().take(), model.ice_contact())
        else {
            return Err(SimError::Setup(
                "this process holds no ghost surface to gather again".into(),
            ));
        };
        let mesh = &sim.model.mesh;
        let at = PartState {
            part,
            mesh: (&mesh.rest, &mesh.tets),
            node_owner: &held.node_owner,
            u: &sim.state.u,
            vmax: largest_component(&sim.state.v),
        };
        let h = sim.settings.dt;
        let gathered = self.gather_with_surface((&model.mesh, held.partition), contact, &at, h)?;
        part_and_model(gathered, model)
    }

    fn part_fracture(
        &self,
        settings: crate::fracture::FractureSettings,
        sim: &mut Simulation,
        part: &Part,
    ) -> Result<Box<dyn crate::run::FractureOnParts + '_>, SimError> {
        let owners = self.owners.borrow().clone();
        if owners.0.len() != part.nodes.len() || owners.1.len() != part.elements.len() {
            return Err(SimError::Setup(
                "fracture on a part other than the one shared out".into(),
            ));
        }
        let fracture = run_fracture::RunFracture::new(&self.world, settings, (sim, part), owners)?;
        Ok(Box::new(fracture))
    }

    fn mesh_sharing(&self) -> Option<&dyn MeshSharing> {
        (!self.whole_mesh.get()).then_some(self)
    }

    fn distribute(&self, sim: &mut Simulation) -> Result<(), SimError> {
        // The first share's (a ghost surface gathered again shares the run out anew).
        if self.set_up_memory.get() == 0 {
            self.set_up_memory.set(peak_memory());
        }
        let Some((numbering, part)) = self.part.borrow_mut().take() else {
            return Err(SimError::Setup(
                "the simulation was not built on this process's part".into(),
            ));
        };
        let iterative = sim.settings.iterative();
        let solve = (iterative.tolerance, iterative.max_iterations);
        *self.owners.borrow_mut() = (numbering.node_owner.clone(), numbering.element_part.clone());
        sim.distribute_heat(|system, free| {
            let share = heat::HeatProcessShare::new(
                (&numbering, self.rank()),
                (&part.nodes, &part.owned_nodes),
                (system, free),
                solve,
            )?;
            Ok(Box::new(share))
        })?;
        let share = ProcessShare::new(
            (&part, numbering),
            &sim.model.mesh,
            self.rank(),
            (solve, self.held.clone()),
        );
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

    fn gather_values(&self, values: Vec<f64>, take: &mut dyn FnMut(Vec<f64>)) {
        let root = self.world.process_at_rank(0);
        let count = values.len() as mpi::Count;
        if self.rank() != 0 {
            root.gather_into(&count);
            root.send(&values[..]);
            return;
        }
        let mut counts = vec![0 as mpi::Count; self.size()];
        root.gather_into_root(&count, &mut counts[..]);
        take(values);
        for (p, &count) in counts.iter().enumerate().skip(1) {
            let mut received = vec![0.0; count as usize];
            self.world
                .process_at_rank(p as mpi::Rank)
                .receive_into(&mut received[..]);
            take(received);
        }
    }

    fn any(&self, flag: bool) -> bool {
        let mut any = 0u8;
        self.world
            .all_reduce_into(&u8::from(flag), &mut any, SystemOperation::max());
        any != 0
    }
}

impl MeshSharing for MpiProcesses {
    fn rank_and_size(&self) -> (usize, usize) {
        (self.rank() as usize, self.size())
    }

    fn on_this_machine(&self) -> usize {
        self.world.split_shared(self.rank() as i32).size() as usize
    }

    fn share(&self, ranges: MeshRanges) -> Result<SharedMesh, String> {
        let partition = self.partitioned(&ranges).map_err(|e| e.to_string())?;
        Ok(self.gather_part(&ranges, &partition, part_mesh::Besides::Asked(&[])))
    }

    fn total(&self, n: usize) -> usize {
        let mut sum = 0u64;
        self.world
            .all_reduce_into(&(n as u64), &mut sum, SystemOperation::sum());
        sum as usize
    }

    fn largest(&self, x: f64) -> f64 {
        largest(&self.world, x)
    }

    fn gathered_by_key(&self, items: &[([usize; 3], f64)]) -> Vec<f64> {
        ghosts::gathered_by_key(&self.world, items)
    }

    fn copy_from_owners(&self, values: &mut [f64]) {
        let shared = self.part.borrow();
        let (numbering, part) = shared.as_ref().expect("a part shared out");
        for (k, &owned) in part.owned_nodes.iter().enumerate() {
            if !owned {
                values[3 * k..3 * k + 3].fill(0.0);
            }
        }
        let ghosts = Ghosts::new(
            SimpleCommunicator::world(),
            &part.nodes,
            &part.owned_nodes,
            &numbering.node_owner,
        );
        ghosts.exchange(values);
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
/// added in process order, vectors through the processes holding each node ([`Ghosts`]).
pub struct MpiCollective {
    world: SimpleCommunicator,
    ghosts: Ghosts,
}

impl MpiCollective {
    /// The sums of the processes of the world communicator, this process holding `part`,
    /// whose node `k` is owned by process `node_owner[k]`. Every process calls it.
    pub fn new(part: &Part, node_owner: &[u32]) -> Self {
        let ghosts = Ghosts::new(
            SimpleCommunicator::world(),
            &part.nodes,
            &part.owned_nodes,
            node_owner,
        );
        MpiCollective {
            world: SimpleCommunicator::world(),
            ghosts,
        }
    }
}

impl Collective for MpiCollective {
    fn sum(&self, x: f64) -> f64 {
        sum_in_order(&self.world, x)
    }

    fn exchange(&self, v: &mut [f64]) {
        self.ghosts.exchange(v);
    }

    fn max(&self, x: f64) -> f64 {
        largest(&self.world, x)
    }
}

/// Σ of `x` over the processes of `world`, gathered and added in process order: the same
/// bits on every process.
pub(crate) fn sum_in_order(world: &SimpleCommunicator, x: f64) -> f64 {
    let mut all = vec![0.0; world.size() as usize];
    world.all_gather_into(&x, &mut all[..]);
    traffic::add(&traffic::SUMS, 2 * (all.len() - 1));
    all.iter().sum()
}

/// The part `gathered` and its model, of the whole model `model`.
fn part_and_model(gathered: SharedMesh, model: &Model) -> Result<(Part, Model), SimError> {
    let part = gathered.part;
    let model = match part.is_whole() {
        true => Ok(part.whole_model(model.clone())),
        false => part.model_on(model, gathered.rest, gathered.tets),
    }
    .map_err(|e| SimError::Setup(e.to_string()))?;
    Ok((part, model))
}

/// The largest magnitude among `values` (0 if none).
fn largest_component(values: &[f64]) -> f64 {
    values.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// `result` where every process of `world` has a result; else this process's error, or
/// `elsewhere()` where only another process failed: the processes then go on or stop alike,
/// and none waits for the others in a collective that follows. Every process calls it.
pub(crate) fn agreed<T, E>(
    world: &SimpleCommunicator,
    result: Result<T, E>,
    elsewhere: impl FnOnce() -> E,
) -> Result<T, E> {
    let failed = largest(world, f64::from(u8::from(result.is_err()))) > 0.0;
    match (result, failed) {
        (Ok(value), false) => Ok(value),
        (Err(e), _) => Err(e),
        (Ok(_), true) => Err(elsewhere()),
    }
}

/// The largest `x` over the processes of `world`.
pub(crate) fn largest(world: &SimpleCommunicator, x: f64) -> f64 {
    let mut y = 0.0;
    world.all_reduce_into(&x, &mut y, SystemOperation::max());
    y
}

/// One process's share of a distributed simulation.
struct ProcessShare {
    collective: MpiCollective,
    owned_dofs: Vec<bool>,
    owned_elements: Vec<bool>,
    rank: u32,
    /// The partition on this process's part (its elements' processes: a remeshed share, with
    /// fracture, is the whole mesh's, so its elements are the whole mesh's).
    numbering: PartNumbering,
    tets: Vec<[usize; 4]>,
    rest: Vec<nalgebra::Vector3<f64>>,
    /// CG's relative tolerance and iteration cap.
    solve: (f64, usize),
    /// Nodes and elements of this process's part, for its report.
    held: Rc<Cell<[u64; 2]>>,
}

impl ProcessShare {
    /// The share of process `rank` holding `part` of `mesh`, numbered by `numbering`, CG
    /// stopping at `solve`'s relative tolerance or iteration cap, its part's size reported in
    /// `held`.
    fn new(
        (part, numbering): (&Part, PartNumbering),
        mesh: &TetMesh,
        rank: u32,
        (solve, held): ((f64, usize), Rc<Cell<[u64; 2]>>),
    ) -> Self {
        held.set([part.nodes.len() as u64, part.elements.len() as u64]);
        ProcessShare {
            collective: MpiCollective::new(part, &numbering.node_owner),
            owned_dofs: part.owned_dofs(),
            owned_elements: part.own_elements.clone(),
            rank,
            numbering,
            tets: mesh.tets.clone(),
            rest: mesh.rest.clone(),
            solve,
            held,
        }
    }
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

    fn solver(
        &self,
        assembly: &Assembly,
        linear: LinearSolverKind,
    ) -> Result<Box<dyn ExternalSolver>, LinearError> {
        let dofs = assembly.dofs();
        let owned_free = (0..dofs.num_dofs())
            .filter(|&d| self.owned_dofs[d] && dofs.free(d).is_some())
            .count();
        // The whole system's free dofs decide, as on one process (the same on every process).
        let free = self.collective.sum(owned_free as f64) as usize;
        let direct = linear.resolve(free) == LinearSolverKind::Cholesky;
        let (rtol, max_iterations) = self.solve;
        Ok(Box::new(solver::PetscSolver::new(
            assembly,
            &self.numbering,
            (self.rank, &self.owned_elements, &self.tets),
            &self.rest,
            (direct, rtol, max_iterations),
        )?))
    }

    fn remeshed(
        &self,
        model: &Model,
        parent: &[usize],
    ) -> Result<(Box<dyn Distribution>, Part), SimError> {
        let mesh = &model.mesh;
        let size = self.collective.world.size() as usize;
        let element_part = parent
            .iter()
            .map(|&p| self.numbering.element_part[p])
            .collect();
        let partition = Partition::from_element_parts(mesh, element_part, size);
        let part = Part::new(
            &mesh.tets,
            (&partition.element_part, &partition.node_owner),
            self.rank,
            (&[], true),
        );
        let share = ProcessShare::new(
            (&part, partition.of_part(&part)),
            mesh,
            self.rank,
            (self.solve, self.held.clone()),
        );
        Ok((Box::new(share), part))
    }
}
