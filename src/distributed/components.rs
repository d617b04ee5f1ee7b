//! The connected parts of the whole mesh (nodes joined by elements, as `mesh::parts`) found
//! by the processes together, each from its part of the mesh alone.
//!
//! Each process labels the connected pieces of its part by their lowest node (the whole
//! mesh's number). Two pieces on different processes are one part of the whole mesh exactly
//! when a chain of shared nodes joins them, and the owner of a shared node holds every
//! element around it: so each process tells the owner of each node it holds but does not own
//! its piece's label there, and the owner pairs it with its own. The pairs, a few per
//! neighbouring process, go to every process, which joins the labels; a part's label is then
//! its lowest node, and parts are numbered in the order of it, as on one process.

use super::ghosts::{all_gathered, exchange};
use crate::sim::part::Part;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use petgraph::unionfind::UnionFind;

/// The connected part of the whole mesh each node of this process's `part` is in, and the
/// number of parts: what `mesh::parts` gives on the whole mesh, at the part's nodes. `tets`
/// are the part's elements numbered in the part, and `node_owner` the process owning each of
/// its nodes. Every process calls it.
pub fn connected_parts(
    world: &SimpleCommunicator,
    part: &Part,
    tets: &[[usize; 4]],
    node_owner: &[u32],
) -> (Vec<u32>, usize) {
    let (size, rank) = (world.size() as usize, world.rank() as u32);
    let nodes = &part.nodes;
    // The part's pieces, each labelled by its lowest node (the part's nodes ascend).
    let (piece, pieces) = crate::mesh::parts_of(nodes.len(), tets);
    let mut lowest = vec![u64::MAX; pieces];
    for (k, &p) in piece.iter().enumerate() {
        lowest[p as usize] = lowest[p as usize].min(nodes[k] as u64);
    }
    let label = |k: usize| lowest[piece[k] as usize];
    // (node, this process's label there) to the node's owner.
    let mut told = vec![Vec::new(); size];
    for (k, &owner) in node_owner.iter().enumerate() {
        if owner != rank {
            told[owner as usize].extend([nodes[k] as u64, label(k)]);
        }
    }
    let mut pairs: Vec<[u64; 2]> = (exchange(world, told).0.chunks_exact(2))
        .map(|t| {
            let k = nodes
                .binary_search(&(t[0] as usize))
                .expect("an owned node");
            [label(k), t[1]]
        })
        .filter(|[a, b]| a != b)
        .collect();
    pairs.sort_unstable();
    pairs.dedup();
    let pairs = all_gathered(world, pairs.as_flattened());
    // Join the labels; each set's root its lowest label.
    let mut labels: Vec<u64> = pairs
        .iter()
        .copied()
        .chain(lowest.iter().copied())
        .collect();
    labels.sort_unstable();
    labels.dedup();
    let index = |l: u64| labels.binary_search(&l).expect("a label");
    let mut sets = UnionFind::<usize>::new(labels.len());
    for p in pairs.chunks_exact(2) {
        sets.union(index(p[0]), index(p[1]));
    }
    let mut set_lowest = vec![u64::MAX; labels.len()];
    for (i, &l) in labels.iter().enumerate() {
        let root = sets.find(i);
        set_lowest[root] = set_lowest[root].min(l);
    }
    let final_lowest: Vec<u64> = (lowest.iter())
        .map(|&l| set_lowest[sets.find(index(l))])
        .collect();
    // Every part's lowest node, from the processes holding it: the parts' numbering.
    let mut roots = final_lowest.clone();
    roots.sort_unstable();
    roots.dedup();
    let mut all = all_gathered(world, &roots);
    all.sort_unstable();
    all.dedup();
    let numbered = (0..nodes.len())
        .map(|k| {
            let root = final_lowest[piece[k] as usize];
            all.binary_search(&root).expect("a gathered root") as u32
        })
        .collect();
    (numbered, all.len())
}
