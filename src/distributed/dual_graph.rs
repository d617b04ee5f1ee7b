//! The elements' dual graph (two elements adjacent when they share a face) built by the
//! processes together, each from a contiguous range of the elements: a process sends each
//! face of its elements to the process the face's nodes hash to, which pairs the elements
//! that share a face and tells their processes. No process needs the other ranges'
//! elements; the graph feeds a partitioner that runs on every process (PT-Scotch, see
//! `partition`). A face no other element shares is on the whole mesh's boundary: each
//! process learns which of its elements' faces are, which no part of the mesh on its own
//! can tell from the faces a cut through the mesh makes.

use super::ghosts::{exchange, range_holder};
use super::petsc::Int;
use crate::mesh::TET_FACES;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// This process's rows of the dual graph, and which of its elements' faces are on the whole
/// mesh's boundary.
pub struct DualGraph {
    /// CSR offsets of the rows, from 0.
    pub offsets: Vec<Int>,
    /// The global numbers of each row's neighbours, ascending.
    pub neighbours: Vec<Int>,
    /// For each element of the range, bit `f` set when its face `TET_FACES[f]` is on the
    /// whole mesh's boundary (no other element has it).
    pub boundary: Vec<u8>,
}

/// This process's [`DualGraph`], for the elements `first .. first + tets.len()` (`tets`:
/// their nodes) when process `r` holds the elements `ranges[r] .. ranges[r + 1]`. Every
/// process calls it.
pub fn rows(world: &SimpleCommunicator, tets: &[[usize; 4]], ranges: &[usize]) -> DualGraph {
    let size = world.size() as usize;
    let first = ranges[world.rank() as usize];
    // Each face as (its nodes ascending, 4 × its element + its face), to the process its
    // nodes hash to.
    let mut faces = vec![Vec::new(); size];
    for (k, tet) in tets.iter().enumerate() {
        for (f, nodes) in TET_FACES.iter().enumerate() {
            let mut key = nodes.map(|a| tet[a] as u64);
            key.sort_unstable();
            let side = (4 * (first + k) + f) as u64;
            faces[hashed(&key, size)].extend([key[0], key[1], key[2], side]);
        }
    }
    let mut received: Vec<[u64; 4]> = (exchange(world, faces).0)
        .chunks_exact(4)
        .map(|r| [r[0], r[1], r[2], r[3]])
        .collect();
    received.sort_unstable();
    // Elements sharing a face, to the processes holding each: (4 × element + face, other
    // element).
    let mut pairs = vec![Vec::new(); size];
    for group in received.chunk_by(|a, b| a[..3] == b[..3]) {
        for a in group {
            let element = a[3] as usize / 4;
            for b in group.iter().filter(|b| b[3] / 4 != a[3] / 4) {
                pairs[range_holder(element, ranges)].extend([a[3], b[3] / 4]);
            }
        }
    }
    let sides: Vec<(u64, u64)> = (exchange(world, pairs).0)
        .chunks_exact(2)
        .map(|p| (p[0], p[1]))
        .collect();
    let mut boundary = vec![0b1111u8; tets.len()];
    for &(side, _) in &sides {
        boundary[side as usize / 4 - first] &= !(1 << (side % 4));
    }
    let mut mine: Vec<(u64, u64)> = sides.into_iter().map(|(s, b)| (s / 4, b)).collect();
    mine.sort_unstable();
    mine.dedup();
    let mut offsets = vec![0 as Int; tets.len() + 1];
    for &(a, _) in &mine {
        offsets[a as usize - first + 1] += 1;
    }
    for k in 0..tets.len() {
        offsets[k + 1] += offsets[k];
    }
    DualGraph {
        offsets,
        neighbours: mine.iter().map(|&(_, b)| b as Int).collect(),
        boundary,
    }
}

/// The process (of `size`) a face with ascending nodes `key` goes to.
fn hashed(key: &[u64; 3], size: usize) -> usize {
    let mixed = key[0].wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ key[1].wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ key[2].wrapping_mul(0x1656_67B1_9E37_79F9);
    ((mixed >> 32) % size as u64) as usize
}
