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
//!
//! The cracks (connected crack surfaces) are found alike ([`crack_ids`]): each process joins
//! its own elements' crack faces by their edges and labels each crack by its lowest face; the
//! edges go to home processes, which join the labels an edge carries.

use super::ghosts::{all_gathered, exchange};
use crate::sim::part::Part;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use nalgebra::Vector3;
use petgraph::unionfind::UnionFind;
use std::collections::HashMap;

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

/// A face's label: its nodes' numbers in the whole mesh, ascending.
type FaceKey = [u64; 3];

/// The crack (connected crack surface) of each of this process's crack faces `faces` (its
/// own elements', numbered in its part, whose nodes are at rest positions `rest` (m) and are
/// the whole mesh's nodes `numbers`), numbered as `fracture::cracks::crack_faces` numbers the
/// whole mesh's: faces sharing an edge, nodes identified by rest position (the copies of a
/// split node coincide at rest), are one crack, and cracks are numbered in the order of their
/// first face in the whole mesh's boundary (faces by their nodes' numbers). Every process of
/// `world` calls it.
pub fn crack_ids(
    world: &SimpleCommunicator,
    faces: &[[usize; 3]],
    (rest, numbers): (&[Vector3<f64>], &[usize]),
) -> Vec<usize> {
    let size = world.size() as usize;
    let at = |i: usize| rest[i].map(f64::to_bits);
    let edge_key = |f: &[usize; 3], j: usize| {
        let (a, b) = (at(f[j]), at(f[(j + 1) % 3]));
        let (a, b) = if a.as_slice() <= b.as_slice() {
            (a, b)
        } else {
            (b, a)
        };
        [a.x, a.y, a.z, b.x, b.y, b.z]
    };
    // This process's cracks: its faces joined by their edges.
    let mut sets = UnionFind::<usize>::new(faces.len());
    let mut first_with: HashMap<[u64; 6], usize> = HashMap::new();
    for (k, f) in faces.iter().enumerate() {
        for j in 0..3 {
            let first = *first_with.entry(edge_key(f, j)).or_insert(k);
            sets.union(first, k);
        }
    }
    let face_key = |f: &[usize; 3]| -> FaceKey {
        let mut key = f.map(|i| numbers[i] as u64);
        key.sort_unstable();
        key
    };
    let mut lowest: HashMap<usize, FaceKey> = HashMap::new();
    for (k, f) in faces.iter().enumerate() {
        let low = lowest.entry(sets.find(k)).or_insert([u64::MAX; 3]);
        *low = (*low).min(face_key(f));
    }
    let label = |k: usize| lowest[&sets.find(k)];
    // Each edge goes to a home process with its crack's label; the home joins the labels
    // an edge carries.
    let mut told = vec![Vec::new(); size];
    for (k, f) in faces.iter().enumerate() {
        for j in 0..3 {
            let key = edge_key(f, j);
            let home = key.iter().fold(0u64, |h, &w| h.rotate_left(7) ^ w) as usize % size;
            told[home].extend(key.iter().chain(&label(k)));
        }
    }
    let mut by_edge: HashMap<[u64; 6], FaceKey> = HashMap::new();
    let mut pairs: Vec<u64> = Vec::new();
    for w in exchange(world, told).0.chunks_exact(9) {
        let edge: [u64; 6] = w[..6].try_into().expect("six words");
        let label: FaceKey = w[6..].try_into().expect("three words");
        let first = *by_edge.entry(edge).or_insert(label);
        if first != label {
            pairs.extend(first.iter().chain(&label));
        }
    }
    // Every process joins all the labels alike; a crack's number is its lowest face's rank.
    let mine: Vec<u64> = lowest.values().flatten().copied().collect();
    let mut labels: Vec<FaceKey> = (all_gathered(world, &mine).chunks_exact(3))
        .map(|w| [w[0], w[1], w[2]])
        .collect();
    labels.sort_unstable();
    labels.dedup();
    let index = |l: &[u64]| labels.binary_search(&[l[0], l[1], l[2]]).expect("a label");
    let mut joined = UnionFind::<usize>::new(labels.len());
    for w in all_gathered(world, &pairs).chunks_exact(6) {
        joined.union(index(&w[..3]), index(&w[3..]));
    }
    // Labels ascend, so a set's first label met is its lowest: number the sets in that order.
    let mut number = vec![usize::MAX; labels.len()];
    let mut next = 0;
    for i in 0..labels.len() {
        let root = joined.find(i);
        if number[root] == usize::MAX {
            number[root] = next;
            next += 1;
        }
    }
    (0..faces.len())
        .map(|k| number[joined.find(index(&label(k)))])
        .collect()
}
