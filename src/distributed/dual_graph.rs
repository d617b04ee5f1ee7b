//! The elements' dual graph (two elements adjacent when they share a face) built by the
//! processes together, each from a contiguous range of the elements: a process sends each
//! face of its elements to the process the face's nodes hash to, which pairs the elements
//! that share a face and tells their processes. No process needs the other ranges'
//! elements; the graph feeds a partitioner that runs on every process (PT-Scotch, see
//! `partition`).

use super::ghosts::{exchange, range_holder};
use super::petsc::Int;
use crate::mesh::TET_FACES;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// This process's rows of the dual graph, for the elements `first .. first + tets.len()`
/// (`tets`: their nodes) when process `r` holds the elements `ranges[r] .. ranges[r + 1]`:
/// CSR offsets from 0 and the global numbers of each row's neighbours, ascending. Every
/// process calls it.
pub fn rows(
    world: &SimpleCommunicator,
    tets: &[[usize; 4]],
    ranges: &[usize],
) -> (Vec<Int>, Vec<Int>) {
    let size = world.size() as usize;
    let first = ranges[world.rank() as usize];
    // Each face as (its nodes ascending, its element), to the process its nodes hash to.
    let mut faces = vec![Vec::new(); size];
    for (k, tet) in tets.iter().enumerate() {
        for f in TET_FACES {
            let mut key = f.map(|a| tet[a] as u64);
            key.sort_unstable();
            faces[hashed(&key, size)].extend([key[0], key[1], key[2], (first + k) as u64]);
        }
    }
    let mut received: Vec<[u64; 4]> = (exchange(world, faces).0)
        .chunks_exact(4)
        .map(|r| [r[0], r[1], r[2], r[3]])
        .collect();
    received.sort_unstable();
    // Elements sharing a face, to the processes holding each.
    let mut pairs = vec![Vec::new(); size];
    for group in received.chunk_by(|a, b| a[..3] == b[..3]) {
        for a in group {
            for b in group.iter().filter(|b| b[3] != a[3]) {
                pairs[range_holder(a[3] as usize, ranges)].extend([a[3], b[3]]);
            }
        }
    }
    let mut mine: Vec<(u64, u64)> = (exchange(world, pairs).0)
        .chunks_exact(2)
        .map(|p| (p[0], p[1]))
        .collect();
    mine.sort_unstable();
    mine.dedup();
    let mut offsets = vec![0 as Int; tets.len() + 1];
    for &(a, _) in &mine {
        offsets[a as usize - first + 1] += 1;
    }
    for k in 0..tets.len() {
        offsets[k + 1] += offsets[k];
    }
    (offsets, mine.iter().map(|&(_, b)| b as Int).collect())
}

/// The process (of `size`) a face with ascending nodes `key` goes to.
fn hashed(key: &[u64; 3], size: usize) -> usize {
    let mixed = key[0].wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ key[1].wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ key[2].wrapping_mul(0x1656_67B1_9E37_79F9);
    ((mixed >> 32) % size as u64) as usize
}
