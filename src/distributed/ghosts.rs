//! The values at the nodes several processes hold: a process holds copies (ghosts) of nodes
//! other processes own (see `sim::part`). An exchange sends each ghost's part of a vector to
//! the node's owner, which adds the parts in process order to its own, and sends the sum back
//! to every process holding the node: afterwards every copy has the owner's bits.

use super::traffic;
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use std::cell::RefCell;

/// One process's ghosts and the processes holding copies of its nodes.
pub struct Ghosts {
    world: SimpleCommunicator,
    /// This process's ghost nodes (its part's numbering), grouped by owner in process order.
    ghosts: Vec<usize>,
    /// Values (3 per node) to and from each process for the ghosts, and where they start.
    ghost_counts: Vec<Count>,
    ghost_starts: Vec<Count>,
    /// This process's nodes other processes hold, grouped by holder in process order, each
    /// group in the order the holder lists them.
    held: Vec<usize>,
    held_counts: Vec<Count>,
    held_starts: Vec<Count>,
    /// Send and receive buffers.
    scratch: RefCell<(Vec<f64>, Vec<f64>)>,
}

/// Where each group starts in a buffer of groups of `counts` values.
pub(super) fn starts(counts: &[Count]) -> Vec<Count> {
    counts
        .iter()
        .scan(0, |at, &c| {
            let start = *at;
            *at += c;
            Some(start)
        })
        .collect()
}

impl Ghosts {
    /// The ghosts of a part whose nodes are the whole mesh's `nodes` (ascending), of which
    /// this process owns those marked in `owned`, node `i` of the whole mesh being owned by
    /// process `node_owner[i]`.
    pub fn new(
        world: SimpleCommunicator,
        nodes: &[usize],
        owned: &[bool],
        node_owner: &[u32],
    ) -> Self {
        let size = world.size() as usize;
        let mut by_owner = vec![Vec::new(); size];
        for (k, &i) in nodes.iter().enumerate() {
            if !owned[k] {
                by_owner[node_owner[i] as usize].push(k);
            }
        }
        // Tell each owner which of its nodes this process holds.
        let wanted: Vec<Count> = by_owner.iter().map(|g| g.len() as Count).collect();
        let mut asked = vec![0 as Count; size];
        world.all_to_all_into(&wanted[..], &mut asked[..]);
        let ghosts: Vec<usize> = by_owner.concat();
        let ids: Vec<u64> = ghosts.iter().map(|&k| nodes[k] as u64).collect();
        let mut asked_ids = vec![0u64; asked.iter().sum::<Count>() as usize];
        world.all_to_all_varcount_into(
            &Partition::new(&ids[..], &wanted[..], &starts(&wanted)[..]),
            &mut PartitionMut::new(&mut asked_ids[..], &asked[..], &starts(&asked)[..]),
        );
        let held = asked_ids
            .iter()
            .map(|&i| {
                nodes
                    .binary_search(&(i as usize))
                    .expect("a process holds only nodes of its owner's part")
            })
            .collect();
        let values = |c: &[Count]| c.iter().map(|n| 3 * n).collect::<Vec<Count>>();
        let (ghost_counts, held_counts) = (values(&wanted), values(&asked));
        Ghosts {
            world,
            ghosts,
            ghost_starts: starts(&ghost_counts),
            ghost_counts,
            held,
            held_starts: starts(&held_counts),
            held_counts,
            scratch: RefCell::new((Vec::new(), Vec::new())),
        }
    }

    /// Sums the parts of `v` (3 per node of the part) at each node across the processes
    /// holding it, in place, the same bits on each.
    pub fn exchange(&self, v: &mut [f64]) {
        if v.is_empty() {
            // Nothing held (contact forces of a model without contact): empty everywhere.
            return;
        }
        let mut scratch = self.scratch.borrow_mut();
        let (send, receive) = &mut *scratch;
        let node = |v: &[f64], k: usize| [v[3 * k], v[3 * k + 1], v[3 * k + 2]];
        // The ghosts' parts to their owners, added to the owners' in process order.
        send.clear();
        send.extend(self.ghosts.iter().flat_map(|&k| node(v, k)));
        receive.resize(self.held.len() * 3, 0.0);
        self.world.all_to_all_varcount_into(
            &Partition::new(&send[..], &self.ghost_counts[..], &self.ghost_starts[..]),
            &mut PartitionMut::new(
                &mut receive[..],
                &self.held_counts[..],
                &self.held_starts[..],
            ),
        );
        for (j, &k) in self.held.iter().enumerate() {
            for a in 0..3 {
                v[3 * k + a] += receive[3 * j + a];
            }
        }
        // The sums back to every holder.
        send.clear();
        send.extend(self.held.iter().flat_map(|&k| node(v, k)));
        receive.resize(self.ghosts.len() * 3, 0.0);
        self.world.all_to_all_varcount_into(
            &Partition::new(&send[..], &self.held_counts[..], &self.held_starts[..]),
            &mut PartitionMut::new(
                &mut receive[..],
                &self.ghost_counts[..],
                &self.ghost_starts[..],
            ),
        );
        for (j, &k) in self.ghosts.iter().enumerate() {
            v[3 * k..3 * k + 3].copy_from_slice(&receive[3 * j..3 * j + 3]);
        }
        traffic::add(&traffic::SUMS, 3 * (self.ghosts.len() + self.held.len()));
    }
}
