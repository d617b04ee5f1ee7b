//! A process's part of the mesh gathered from the ranges the processes hold, with no array
//! of the whole mesh's size on any process.
//!
//! Before the partition, process `r` holds a contiguous range of the elements and one of the
//! nodes (their rest positions). Each node's *home* is the process holding it in its range of
//! nodes. The processes meet at the homes (a rendezvous, four all-to-all exchanges): each
//! element's nodes go home with the element and its process; a home finds each node's owner
//! (the lowest process among its elements', as in `sim::part`) and the processes of the
//! node's elements, each of which holds all of them in its ring; the holders of the elements'
//! ranges send every element to the processes that hold it; owners number their nodes for
//! PETSc; and each process asks its nodes' homes for their owners, PETSc numbers and rest
//! positions. The result is what `Part::new` and `Partition::of_part` give from the whole
//! mesh, to the bit (tested on three processes in `solver_tests/partition.rs`).

use super::ghosts::{exchange, range_holder};
use super::partition::PartNumbering;
use crate::sim::part::Part;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use nalgebra::Vector3;

/// The elements a process holds before the partition: a contiguous range of the whole
/// mesh's.
pub struct ElementRange<'a> {
    /// Where each process's range starts, the number of elements of the whole mesh last.
    pub starts: &'a [usize],
    /// The range's elements' nodes, as nodes of the whole mesh.
    pub tets: &'a [[usize; 4]],
    /// The process each of the range's elements goes to (the partitioner's answer).
    pub parts: &'a [u32],
    /// The range's elements' faces on the whole mesh's boundary (see
    /// [`super::dual_graph::DualGraph::boundary`]).
    pub boundary: &'a [u8],
}

/// The nodes a process holds before the partition: a contiguous range of the whole mesh's.
pub struct NodeRange<'a> {
    /// Where each process's range starts, the number of nodes of the whole mesh last.
    pub starts: &'a [usize],
    /// The range's rest positions (m).
    pub rest: &'a [Vector3<f64>],
}

/// Which elements a process holds besides its part and ring.
#[derive(Clone, Copy)]
pub enum Besides<'a> {
    /// These elements of the whole mesh (ascending), which this process asks for (the
    /// elements of its ghost surface, see `super::ghost_surface`): the holders of their
    /// ranges send them.
    Asked(&'a [usize]),
    /// Every element: each process holds the whole mesh (`ICEFEM_WHOLE_MESH=1`, and tests
    /// that read the whole state).
    All,
}

/// A process's part of the mesh.
#[derive(Clone, Debug)]
pub struct PartMesh {
    /// Its elements and nodes, and which of them the process evaluates and owns.
    pub part: Part,
    /// The partition on its nodes and elements.
    pub numbering: PartNumbering,
    /// Rest positions of the part's nodes (m).
    pub rest: Vec<Vector3<f64>>,
    /// The part's elements, numbered in the part.
    pub tets: Vec<[usize; 4]>,
    /// The part's elements' faces on the whole mesh's boundary (bit `f`: face
    /// `TET_FACES[f]`): the part's own mesh cannot tell them from the faces of its cut.
    pub boundary: Vec<u8>,
}

/// This process's part of the mesh whose elements and nodes the processes of `world` hold in
/// `elements` and `nodes` ranges, with the elements `besides` it asks for, and with
/// `halo` (m) every element around the nodes within that distance of its owned nodes along
/// the mesh's edges (the nonlocal separation's reach, see `fracture::nonlocal::within`; the
/// averages need only those nodes' forces, which [`super::node_halo`] gathers for much less).
/// Every process calls it.
pub fn part_mesh(
    world: &SimpleCommunicator,
    elements: ElementRange,
    nodes: NodeRange,
    (besides, halo): (Besides, Option<f64>),
) -> PartMesh {
    let (size, rank) = (world.size() as usize, world.rank() as u32);
    let first_element = elements.starts[rank as usize];
    let first_node = nodes.starts[rank as usize];
    // Each element's nodes go home, with the element and its process.
    let mut incidences = vec![Vec::new(); size];
    for (k, (tet, &p)) in elements.tets.iter().zip(elements.parts).enumerate() {
        for &v in tet {
            let e = (first_element + k) as u64;
            incidences[range_holder(v, nodes.starts)].extend([v as u64, e, p as u64]);
        }
    }
    let mut home = Home::new(
        exchange(world, incidences).0,
        (first_node, nodes.rest.len()),
        (elements.starts, size),
    );
    let held = held_elements(world, &elements, std::mem::take(&mut home.rings), besides);
    let (node_start, petsc_numbers) =
        petsc_numbering(world, std::mem::take(&mut home.owned), nodes.starts);
    let numbers = (&home.owner[..], &petsc_numbers[..]);
    let held = match halo {
        Some(length) => grown(world, held, &elements, (&home, &nodes, numbers), length),
        None => held,
    };
    let part_nodes = {
        let mut v: Vec<usize> = held.iter().flat_map(|h| h.tet).collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let facts = node_facts(world, &part_nodes, (nodes.starts, nodes.rest), numbers);
    let tets = held
        .iter()
        .map(|h| {
            h.tet
                .map(|v| part_nodes.binary_search(&v).expect("a held node"))
        })
        .collect();
    let part = Part::from_lists(
        (held.iter().map(|h| h.element).collect(), part_nodes),
        (
            held.iter().map(|h| h.part == rank).collect(),
            facts.iter().map(|f| f.owner == rank).collect(),
        ),
        (
            *nodes.starts.last().expect("a range per process"),
            *elements.starts.last().expect("a range per process"),
        ),
    );
    PartMesh {
        numbering: PartNumbering {
            petsc_node: facts.iter().map(|f| f.petsc).collect(),
            node_owner: facts.iter().map(|f| f.owner).collect(),
            element_part: held.iter().map(|h| h.part).collect(),
            node_start,
        },
        rest: facts.iter().map(|f| f.rest).collect(),
        boundary: held.iter().map(|h| h.boundary).collect(),
        tets,
        part,
    }
}

/// What a home learns of its nodes from their elements.
struct Home {
    /// Owner of each of the home's nodes.
    owner: Vec<u32>,
    /// For each process, the home's nodes it owns (ascending).
    owned: Vec<Vec<u64>>,
    /// For each process, pairs (element of its range, another process that holds the element
    /// in its ring).
    rings: Vec<Vec<u64>>,
    /// The home's (node, element, element's process), ascending.
    incidences: Vec<[u64; 3]>,
}

impl Home {
    /// From the triples (node, element, element's process) received at the home of the nodes
    /// `first .. first + count`, the elements held by processes `element_starts` (`size`
    /// processes).
    fn new(
        triples: Vec<u64>,
        (first, count): (usize, usize),
        (element_starts, size): (&[usize], usize),
    ) -> Self {
        let mut triples: Vec<[u64; 3]> = (triples.chunks_exact(3))
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        triples.sort_unstable();
        let (mut owner, mut rings) = (vec![u32::MAX; count], vec![Vec::new(); size]);
        let mut processes = Vec::new();
        for node in triples.chunk_by(|a, b| a[0] == b[0]) {
            processes.clear();
            processes.extend(node.iter().map(|t| t[2]));
            processes.sort_unstable();
            processes.dedup();
            owner[node[0][0] as usize - first] = processes[0] as u32;
            // A node with elements of several processes: each holds all of its elements.
            for &[_, e, p] in node.iter().filter(|_| processes.len() > 1) {
                let holder = range_holder(e as usize, element_starts);
                for &q in processes.iter().filter(|&&q| q != p) {
                    rings[holder].extend([e, q]);
                }
            }
        }
        // A node of no element (none in a valid mesh) goes to process 0, as in `Partition`.
        let mut owned = vec![Vec::new(); size];
        for (k, o) in owner.iter_mut().enumerate() {
            if *o == u32::MAX {
                *o = 0;
            }
            owned[*o as usize].push((first + k) as u64);
        }
        Home {
            owner,
            owned,
            rings,
            incidences: triples,
        }
    }
}

/// An element a process holds.
struct HeldElement {
    element: usize,
    /// The process it goes to.
    part: u32,
    /// Its nodes (the whole mesh's numbers).
    tet: [usize; 4],
    /// Its faces on the whole mesh's boundary.
    boundary: u8,
}

/// The elements this process holds, ascending: the holders of the ranges send each element to
/// its process, to the processes holding it in their rings (`rings`, from the homes) and to
/// those asking for it `besides` (every process, for `Besides::All`).
fn held_elements(
    world: &SimpleCommunicator,
    elements: &ElementRange,
    rings: Vec<Vec<u64>>,
    besides: Besides,
) -> Vec<HeldElement> {
    let size = world.size() as usize;
    let first = elements.starts[world.rank() as usize];
    let ring_pairs = exchange(world, rings).0;
    let mut destinations: Vec<(usize, u32)> = (ring_pairs.chunks_exact(2))
        .map(|p| (p[0] as usize - first, p[1] as u32))
        .collect();
    let mut asks = vec![Vec::new(); size];
    if let Besides::Asked(wanted) = besides {
        for &e in wanted {
            asks[range_holder(e, elements.starts)].push(e as u64);
        }
    }
    let (asked, from) = exchange(world, asks);
    let mut asked = asked.into_iter();
    for (q, &n) in from.iter().enumerate() {
        destinations.extend(
            asked
                .by_ref()
                .take(n as usize)
                .map(|e| (e as usize - first, q as u32)),
        );
    }
    for (k, &p) in elements.parts.iter().enumerate() {
        match besides {
            Besides::All => destinations.extend((0..size as u32).map(|q| (k, q))),
            Besides::Asked(_) => destinations.push((k, p)),
        }
    }
    send_elements(world, elements, destinations)
}

/// The elements of this process's range `elements` sent to the processes `destinations`
/// (element of the range, process) asks for, and what the others sent this one: its held
/// elements, ascending. Every process calls it.
fn send_elements(
    world: &SimpleCommunicator,
    elements: &ElementRange,
    mut destinations: Vec<(usize, u32)>,
) -> Vec<HeldElement> {
    let size = world.size() as usize;
    let first = elements.starts[world.rank() as usize];
    destinations.sort_unstable();
    destinations.dedup();
    let mut out = vec![Vec::new(); size];
    for (k, q) in destinations {
        let t = elements.tets[k];
        out[q as usize].extend([(first + k) as u64, elements.parts[k] as u64]);
        out[q as usize].extend(t.map(|v| v as u64));
        out[q as usize].push(elements.boundary[k] as u64);
    }
    let mut held: Vec<HeldElement> = (exchange(world, out).0.chunks_exact(7))
        .map(|h| HeldElement {
            element: h[0] as usize,
            part: h[1] as u32,
            tet: [h[2], h[3], h[4], h[5]].map(|v| v as usize),
            boundary: h[6] as u8,
        })
        .collect();
    held.sort_unstable_by_key(|h| h.element);
    held
}

/// `held` grown by every element around the nodes within `length` (m) of this process's owned
/// nodes along the mesh's edges. A node is known to have all its elements held when it is a
/// node of an element of the process's own, or once they were asked for; each round asks the
/// homes of the nodes found within reach that are not (the homes tell the holders of their
/// elements' ranges to send them), until no process finds any. Paths shorter than `length`
/// from an owned node run through nodes within reach, so a node found short of it on the held
/// elements is so on the whole mesh, and the rounds end with every node within reach found.
/// Every process calls it.
fn grown(
    world: &SimpleCommunicator,
    mut held: Vec<HeldElement>,
    elements: &ElementRange,
    (home, nodes, numbers): (&Home, &NodeRange, (&[u32], &[u64])),
    length: f64,
) -> Vec<HeldElement> {
    let (size, rank) = (world.size() as usize, world.rank() as u32);
    let mut complete: Vec<usize> = (held.iter())
        .filter(|h| h.part == rank)
        .flat_map(|h| h.tet)
        .collect();
    complete.sort_unstable();
    complete.dedup();
    // The held nodes' owners and rest positions, asked of their homes once each.
    let mut known: Vec<(usize, u32, Vector3<f64>)> = Vec::new();
    loop {
        let mut part_nodes: Vec<usize> = held.iter().flat_map(|h| h.tet).collect();
        part_nodes.sort_unstable();
        part_nodes.dedup();
        let new: Vec<usize> = (part_nodes.iter().copied())
            .filter(|v| known.binary_search_by_key(v, |k| k.0).is_err())
            .collect();
        let facts = node_facts(world, &new, (nodes.starts, nodes.rest), numbers);
        known.extend(new.iter().zip(facts).map(|(&v, f)| (v, f.owner, f.rest)));
        known.sort_unstable_by_key(|k| k.0);
        // `known` holds exactly the held nodes: held elements are never dropped.
        let rest: Vec<Vector3<f64>> = known.iter().map(|k| k.2).collect();
        let owned: Vec<bool> = known.iter().map(|k| k.1 == rank).collect();
        let local = |v: usize| part_nodes.binary_search(&v).expect("a held node");
        let tets: Vec<[usize; 4]> = held.iter().map(|h| h.tet.map(local)).collect();
        let reached = crate::fracture::nonlocal::within(&rest, &tets, length, &owned);
        let wanted: Vec<usize> = (part_nodes.iter().zip(&reached))
            .filter(|&(v, &r)| r && complete.binary_search(v).is_err())
            .map(|(&v, _)| v)
            .collect();
        let mut any = 0u64;
        world.all_reduce_into(
            &(wanted.len() as u64),
            &mut any,
            mpi::collective::SystemOperation::max(),
        );
        if any == 0 {
            return held;
        }
        complete.extend(&wanted);
        complete.sort_unstable();
        // Each home tells the holders of its nodes' elements' ranges who wants them.
        let mut asks = vec![Vec::new(); size];
        for &v in &wanted {
            asks[range_holder(v, nodes.starts)].push(v as u64);
        }
        let (asked, from) = exchange(world, asks);
        let mut tell = vec![Vec::new(); size];
        let mut asked = asked.into_iter();
        for (q, &n) in from.iter().enumerate() {
            for v in asked.by_ref().take(n as usize) {
                let start = home.incidences.partition_point(|t| t[0] < v);
                for t in home.incidences[start..].iter().take_while(|t| t[0] == v) {
                    tell[range_holder(t[1] as usize, elements.starts)].extend([t[1], q as u64]);
                }
            }
        }
        let first = elements.starts[rank as usize];
        let destinations = (exchange(world, tell).0.chunks_exact(2))
            .map(|p| (p[0] as usize - first, p[1] as u32))
            .collect();
        let mut more = send_elements(world, elements, destinations);
        more.retain(|m| {
            held.binary_search_by_key(&m.element, |h| h.element)
                .is_err()
        });
        held.extend(more);
        held.sort_unstable_by_key(|h| h.element);
    }
}

/// PETSc's numbering: where each process's nodes start (the number of nodes last), and the
/// PETSc number of each node of this home. Each process numbers the nodes it owns — which
/// their homes tell it (`owned`: for each process, nodes of this home, ascending) — in
/// ascending order from its start, and tells their homes.
fn petsc_numbering(
    world: &SimpleCommunicator,
    owned: Vec<Vec<u64>>,
    node_starts: &[usize],
) -> (Vec<usize>, Vec<u64>) {
    let (size, rank) = (world.size() as usize, world.rank() as usize);
    // In process order, and homes hold ascending ranges: ascending.
    let (mine, _) = exchange(world, owned);
    let mut counts = vec![0u64; size];
    world.all_gather_into(&(mine.len() as u64), &mut counts[..]);
    let node_start: Vec<usize> = std::iter::once(0)
        .chain(counts.iter().scan(0usize, |at, &c| {
            *at += c as usize;
            Some(*at)
        }))
        .collect();
    let mut answers = vec![Vec::new(); size];
    for (k, &v) in mine.iter().enumerate() {
        let petsc = (node_start[rank] + k) as u64;
        answers[range_holder(v as usize, node_starts)].extend([v, petsc]);
    }
    let first = node_starts[rank];
    let mut petsc = vec![0u64; node_starts[rank + 1] - first];
    for pair in exchange(world, answers).0.chunks_exact(2) {
        petsc[pair[0] as usize - first] = pair[1];
    }
    (node_start, petsc)
}

/// What a process learns of one of its nodes from the node's home.
struct NodeFacts {
    owner: u32,
    petsc: usize,
    rest: Vector3<f64>,
}

/// The owner, PETSc number and rest position of each of `wanted` (ascending), asked of their
/// homes: the processes holding `starts` ranges of `rest`, whose owners and PETSc numbers are
/// `numbers`.
fn node_facts(
    world: &SimpleCommunicator,
    wanted: &[usize],
    (starts, rest): (&[usize], &[Vector3<f64>]),
    (owner, petsc): (&[u32], &[u64]),
) -> Vec<NodeFacts> {
    let size = world.size() as usize;
    let first = starts[world.rank() as usize];
    let mut asks = vec![Vec::new(); size];
    for &v in wanted {
        asks[range_holder(v, starts)].push(v as u64);
    }
    let (asked, from): (Vec<u64>, Vec<Count>) = exchange(world, asks);
    let mut replies = vec![Vec::new(); size];
    let mut asked = asked.into_iter();
    for (q, &n) in from.iter().enumerate() {
        for v in asked.by_ref().take(n as usize) {
            let k = v as usize - first;
            let x = rest[k];
            replies[q].extend([owner[k] as u64, petsc[k], x.x.to_bits(), x.y.to_bits()]);
            replies[q].push(x.z.to_bits());
        }
    }
    // The replies come in process order, each in the order asked: `wanted`'s order.
    (exchange(world, replies).0.chunks_exact(5))
        .map(|r| NodeFacts {
            owner: r[0] as u32,
            petsc: r[1] as usize,
            rest: Vector3::new(
                f64::from_bits(r[2]),
                f64::from_bits(r[3]),
                f64::from_bits(r[4]),
            ),
        })
        .collect()
}
