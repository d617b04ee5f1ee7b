//! The nodes a process's nonlocal averages read, gathered from their owners instead of held
//! as elements.
//!
//! The averaged separation of a node reads the forces of every node within the averaging
//! length ℓ along the mesh's edges (`fracture::nonlocal`). A process's part holds the
//! elements around its owned nodes and the ring around them; the nodes within ℓ reach further.
//! Holding every element around them (`part_mesh`'s halo) makes a fixed band of width ℓ on
//! each side of every cut between parts, which does not shrink as the mesh is refined: with
//! ℓ = 2 cm on the 10 cm container, two processes then hold 0.67–0.75 of the elements each.
//! What the averages read of a node is less: its rest position, its edges, and its forces
//! ([`NodeForces`]: ς, its elements' weighted gradients, its eligibility).
//!
//! So each process gathers the graph: round by round it finds the nodes within ℓ of its owned
//! nodes on the edges it knows, and asks the owners of those whose edges it does not all know
//! (the nodes of its own elements are whole on the part) for their neighbours, with their
//! rest positions and owners; the rounds end when no process asks. A path shorter than ℓ runs
//! through nodes within ℓ, whose edges are then all known, so the search on the gathered
//! graph finds each owned node's neighbourhood of the whole mesh. The graph numbers its nodes
//! in the whole mesh's order and a node's edges are sorted, so the search takes the same
//! steps and the averages add the same terms in the same order: an owned node's averaged
//! separation is the whole mesh's, to the bit (tested on three processes).
//!
//! At each evaluation, every node within ℓ that the process does not own gets its forces
//! from its owner (whose part holds its whole star), in one all-to-all exchange.

use super::ghosts::{exchange, FromOwners};
use crate::fracture::nonlocal::{Averaging, Edges};
use crate::fracture::{NodeForces, NodeSeparation, PartAverages};
use crate::sim::part::Part;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use nalgebra::Vector3;
use std::collections::BTreeMap;

/// What a process knows of a node of the gathered graph.
#[derive(Clone, Debug)]
struct Known {
    rest: Vector3<f64>,
    owner: u32,
    /// Whether all of its edges are known.
    whole: bool,
    /// Whether its owner was asked for its edges.
    asked: bool,
}

/// A process's gathered graph and the forces it exchanges at each evaluation.
pub struct NodeHalo {
    /// The gathered graph's nodes (the whole mesh's numbers, ascending).
    nodes: Vec<usize>,
    /// The owned nodes' neighbourhoods on the gathered graph.
    averaging: Averaging,
    /// The gathered node of each of the part's nodes.
    of_part: Vec<usize>,
    /// The part's node of each gathered node the process owns.
    owned: Vec<Option<usize>>,
    /// The gathered nodes within the averaging length this process does not own, whose
    /// forces come from their owners, and the plan that brings them.
    wanted: Vec<usize>,
    from_owners: FromOwners,
}

impl NodeHalo {
    /// The graph within `length` (m) of the owned nodes of this process's `part`, whose mesh
    /// has rest positions `rest` (m) and elements `tets` (numbered in the part) and whose
    /// nodes are owned by `node_owner`. Every process of `world` calls it.
    pub fn new(
        world: &SimpleCommunicator,
        part: &Part,
        (rest, tets): (&[Vector3<f64>], &[[usize; 4]]),
        node_owner: &[u32],
        length: f64,
    ) -> NodeHalo {
        let size = world.size() as usize;
        let part_edges = Edges::of_mesh(rest, tets);
        let whole = part.near_nodes(tets);
        let mut known: BTreeMap<usize, Known> = (part.nodes.iter().enumerate())
            .map(|(k, &i)| {
                let node = Known {
                    rest: rest[k],
                    owner: node_owner[k],
                    whole: whole[k],
                    asked: false,
                };
                (i, node)
            })
            .collect();
        let mut edges: Vec<(usize, usize)> = (0..rest.len())
            .flat_map(|a| part_edges.neighbours(a).map(move |b| (a, b)))
            .filter(|&(a, b)| a < b)
            .map(|(a, b)| (part.nodes[a], part.nodes[b]))
            .collect();
        let (nodes, reached) = loop {
            let (graph, nodes) = graph_of(&known, &edges);
            let sources: Vec<bool> = nodes.iter().map(|i| is_owned(part, *i)).collect();
            let reached = graph.within(length, &sources);
            let mut asks = vec![Vec::new(); size];
            for (k, &i) in nodes.iter().enumerate() {
                let node = known.get_mut(&i).expect("a known node");
                if reached[k] && !node.whole && !node.asked {
                    node.asked = true;
                    asks[node.owner as usize].push(i as u64);
                }
            }
            let mut asking = 0u64;
            let mine = asks.iter().map(Vec::len).sum::<usize>() as u64;
            world.all_reduce_into(&mine, &mut asking, SystemOperation::sum());
            if asking == 0 {
                break (nodes, reached);
            }
            let asked = exchange(world, asks);
            let answers = answer(world, part, (rest, node_owner), &part_edges, asked);
            read_answers(&answers, &mut known, &mut edges);
        };
        let (graph, _) = graph_of(&known, &edges);
        let owned_here: Vec<bool> = nodes.iter().map(|&i| is_owned(part, i)).collect();
        let averaging = Averaging::on(&graph, length, Some(&owned_here));
        let wanted: Vec<usize> = (0..nodes.len())
            .filter(|&k| reached[k] && !owned_here[k])
            .collect();
        let owners: Vec<(usize, u32)> = (wanted.iter())
            .map(|&k| (nodes[k], known[&nodes[k]].owner))
            .collect();
        let at = |i: &usize| nodes.binary_search(i).expect("a part's node is gathered");
        NodeHalo {
            of_part: part.nodes.iter().map(at).collect(),
            owned: (nodes.iter())
                .zip(&owned_here)
                .map(|(&i, &o)| o.then(|| part.local(i).expect("an owned node")))
                .collect(),
            nodes,
            averaging,
            from_owners: FromOwners::new(world, part, &owners),
            wanted,
        }
    }

    /// Number of nodes of the gathered graph beyond the part's (those held only for the
    /// averages).
    pub fn gathered_nodes(&self) -> usize {
        self.nodes.len() - self.of_part.len()
    }

    /// Number of nodes whose forces this process receives at each evaluation.
    pub fn received_nodes(&self) -> usize {
        self.from_owners.received()
    }
}

/// Whether `part` owns the whole mesh's node `i`.
fn is_owned(part: &Part, i: usize) -> bool {
    part.local(i).is_some_and(|k| part.owned_nodes[k])
}

/// The graph of the known nodes (numbered in the whole mesh's order) and edges, and the whole
/// mesh's number of each of its nodes.
fn graph_of(known: &BTreeMap<usize, Known>, edges: &[(usize, usize)]) -> (Edges, Vec<usize>) {
    let nodes: Vec<usize> = known.keys().copied().collect();
    let at = |i: usize| nodes.binary_search(&i).expect("an edge's node is known") as u32;
    let local = edges.iter().map(|&(a, b)| (at(a), at(b))).collect();
    let rest = known.values().map(|n| n.rest).collect();
    (Edges::new(rest, local), nodes)
}

/// The answers of this process (which owns the nodes asked of it: `asked`, in process order,
/// the whole mesh's numbers) to the processes that asked: per node, its number and its
/// neighbours' count, then each neighbour's number, owner and rest position (by its bits).
fn answer(
    world: &SimpleCommunicator,
    part: &Part,
    (rest, node_owner): (&[Vector3<f64>], &[u32]),
    edges: &Edges,
    (asked, counts): (Vec<u64>, Vec<mpi::Count>),
) -> Vec<u64> {
    let mut replies = vec![Vec::new(); counts.len()];
    let mut from = asked.iter();
    for (r, &count) in counts.iter().enumerate() {
        for &i in from.by_ref().take(count as usize) {
            let k = part.local(i as usize).expect("an owner holds its node");
            let reply = &mut replies[r];
            reply.push(i);
            let count_at = reply.len();
            reply.push(0);
            for b in edges.neighbours(k) {
                reply.extend([part.nodes[b] as u64, node_owner[b] as u64]);
                reply.extend(rest[b].iter().map(|x| x.to_bits()));
                reply[count_at] += 1;
            }
        }
    }
    exchange(world, replies).0
}

/// Adds the neighbours in `answers` ([`answer`]'s) to the known nodes and edges.
fn read_answers(
    answers: &[u64],
    known: &mut BTreeMap<usize, Known>,
    edges: &mut Vec<(usize, usize)>,
) {
    let mut words = answers;
    while let [node, count, rest @ ..] = words {
        let a = *node as usize;
        known.get_mut(&a).expect("an asked node").whole = true;
        let (neighbours, after) = rest.split_at(5 * *count as usize);
        for w in neighbours.chunks_exact(5) {
            let b = w[0] as usize;
            let x = Vector3::new(
                f64::from_bits(w[2]),
                f64::from_bits(w[3]),
                f64::from_bits(w[4]),
            );
            known.entry(b).or_insert(Known {
                rest: x,
                owner: w[1] as u32,
                whole: false,
                asked: false,
            });
            edges.push((a, b));
        }
        words = after;
    }
}

impl PartAverages for NodeHalo {
    fn average(&self, forces: &[NodeForces], area_floor: f64) -> Vec<NodeSeparation> {
        let nothing = NodeForces {
            tensor: Default::default(),
            weighted_grads: Vec::new(),
            eligible: false,
        };
        let mut gathered: Vec<NodeForces> = (self.owned.iter())
            .map(|o| o.map_or_else(|| nothing.clone(), |k| forces[k].clone()))
            .collect();
        let received =
            (self.from_owners).fetch(|k, words| forces[k].to_words(words), NodeForces::from_words);
        for (k, node) in received {
            gathered[self.wanted[k]] = node;
        }
        let averaged = self.averaging.average(&gathered, area_floor);
        self.of_part.iter().map(|&k| averaged[k]).collect()
    }
}
