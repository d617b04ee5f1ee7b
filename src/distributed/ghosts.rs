//! The values at the nodes several processes hold: a process holds copies (ghosts) of nodes
//! other processes own (see `sim::part`). An exchange sends each ghost's part of a vector to
//! the node's owner, which adds the parts in process order to its own, and sends the sum back
//! to every process holding the node: afterwards every copy has the owner's bits.

use super::traffic;
use crate::sim::part::Part;
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use std::cell::RefCell;

/// Nodes of a part grouped by the process they go to or come from, in process order.
struct Groups {
    /// The nodes (the part's numbering).
    nodes: Vec<usize>,
    /// Values (3 per node) to or from each process, and where each process's values start.
    counts: Vec<Count>,
    starts: Vec<Count>,
}

impl Groups {
    /// `nodes`, of which the first `sizes[0]` go with process 0, the next `sizes[1]` with
    /// process 1, and so on.
    fn new(nodes: Vec<usize>, sizes: &[Count]) -> Self {
        let counts: Vec<Count> = sizes.iter().map(|n| 3 * n).collect();
        Groups {
            nodes,
            starts: starts(&counts),
            counts,
        }
    }
}

/// One process's ghosts and the processes holding copies of its nodes.
pub struct Ghosts {
    world: SimpleCommunicator,
    /// This process's ghost nodes, grouped by owner.
    ghosts: Groups,
    /// This process's nodes other processes hold, grouped by holder, each group in the order
    /// the holder lists them.
    held: Groups,
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

/// The process holding item `i` when process `r` holds the items `starts[r] .. starts[r + 1]`.
pub(super) fn range_holder(i: usize, starts: &[usize]) -> usize {
    starts.partition_point(|&s| s <= i) - 1
}

/// Sends `out[r]` to process `r` of `world`; returns what every process sent this one, in
/// process order, and how many values came from each.
pub(super) fn exchange(world: &SimpleCommunicator, out: Vec<Vec<u64>>) -> (Vec<u64>, Vec<Count>) {
    let counts: Vec<Count> = out.iter().map(|v| v.len() as Count).collect();
    let mut incoming = vec![0 as Count; out.len()];
    world.all_to_all_into(&counts[..], &mut incoming[..]);
    let send = out.concat();
    let mut received = vec![0u64; incoming.iter().sum::<Count>() as usize];
    world.all_to_all_varcount_into(
        &Partition::new(&send[..], &counts[..], &starts(&counts)[..]),
        &mut PartitionMut::new(&mut received[..], &incoming[..], &starts(&incoming)[..]),
    );
    (received, incoming)
}

/// Every process's `values`, in process order, on every process of `world`.
pub(super) fn all_gathered(world: &SimpleCommunicator, values: &[u64]) -> Vec<u64> {
    let mut counts = vec![0 as Count; world.size() as usize];
    world.all_gather_into(&(values.len() as Count), &mut counts[..]);
    let mut all = vec![0u64; counts.iter().sum::<Count>() as usize];
    world.all_gather_varcount_into(
        values,
        &mut PartitionMut::new(&mut all[..], &counts[..], &starts(&counts)[..]),
    );
    all
}

/// Every process's `items` on every process of `world`, ordered by their keys: the values
/// alone.
pub(super) fn gathered_by_key(world: &SimpleCommunicator, items: &[([usize; 3], f64)]) -> Vec<f64> {
    let mine: Vec<u64> = (items.iter())
        .flat_map(|(k, v)| [k[0] as u64, k[1] as u64, k[2] as u64, v.to_bits()])
        .collect();
    let all = all_gathered(world, &mine);
    let mut keyed: Vec<[u64; 4]> = (all.chunks_exact(4))
        .map(|r| [r[0], r[1], r[2], r[3]])
        .collect();
    keyed.sort_unstable();
    keyed.iter().map(|r| f64::from_bits(r[3])).collect()
}

/// A fixed plan by which a process gets, from their owners, values of nodes it holds beyond
/// its part's ghosts (the nodes a nonlocal average reads, a ghost surface's): each owner
/// sends the values of the nodes asked of it, in the order asked.
pub struct FromOwners {
    world: SimpleCommunicator,
    /// Per process, the part's nodes this process owns whose values it sends there.
    send: Vec<Vec<usize>>,
    /// Per process, the wanted nodes (indices into the list given to [`FromOwners::new`])
    /// whose values come from there.
    receive: Vec<Vec<usize>>,
}

impl FromOwners {
    /// The plan for the nodes `wanted` (the whole mesh's number and owner of each), this
    /// process holding `part` (whose owned nodes others may ask for). Every process of
    /// `world` calls it.
    pub fn new(world: &SimpleCommunicator, part: &Part, wanted: &[(usize, u32)]) -> Self {
        let size = world.size() as usize;
        let mut asks = vec![Vec::new(); size];
        let mut receive = vec![Vec::new(); size];
        for (k, &(node, owner)) in wanted.iter().enumerate() {
            asks[owner as usize].push(node as u64);
            receive[owner as usize].push(k);
        }
        let (asked, counts) = exchange(world, asks);
        let mut from = asked.iter();
        let send = (counts.iter())
            .map(|&count| {
                (from.by_ref().take(count as usize))
                    .map(|&i| part.local(i as usize).expect("an owner holds its node"))
                    .collect()
            })
            .collect();
        FromOwners {
            world: world.duplicate(),
            send,
            receive,
        }
    }

    /// Number of nodes whose values come from other processes.
    pub fn received(&self) -> usize {
        self.receive.iter().map(Vec::len).sum()
    }

    /// Each wanted node's value as its owner's `write(k, words)` writes it for its part's
    /// node `k`, read back by `read(words)` (which returns the value and the words after
    /// it): the wanted nodes' indices and values, grouped by owner. Every process calls it.
    pub fn fetch<T>(
        &self,
        write: impl Fn(usize, &mut Vec<u64>),
        read: impl Fn(&[u64]) -> (T, &[u64]),
    ) -> Vec<(usize, T)> {
        let outgoing = (self.send.iter())
            .map(|nodes| {
                let mut words = Vec::new();
                nodes.iter().for_each(|&k| write(k, &mut words));
                words
            })
            .collect();
        let (incoming, _) = exchange(&self.world, outgoing);
        let mut words = &incoming[..];
        let mut values = Vec::with_capacity(self.received());
        for &k in self.receive.iter().flatten() {
            let (value, after) = read(words);
            values.push((k, value));
            words = after;
        }
        values
    }
}

impl Ghosts {
    /// The ghosts of a part whose nodes are the whole mesh's `nodes` (ascending), of which
    /// this process owns those marked in `owned`, the part's node `k` being owned by process
    /// `node_owner[k]`.
    pub fn new(
        world: SimpleCommunicator,
        nodes: &[usize],
        owned: &[bool],
        node_owner: &[u32],
    ) -> Self {
        let size = world.size() as usize;
        let mut by_owner = vec![Vec::new(); size];
        for k in 0..nodes.len() {
            if !owned[k] {
                by_owner[node_owner[k] as usize].push(k);
            }
        }
        // Tell each owner which of its nodes this process holds.
        let wanted: Vec<Count> = by_owner.iter().map(|g| g.len() as Count).collect();
        let ids = (by_owner.iter())
            .map(|g| g.iter().map(|&k| nodes[k] as u64).collect())
            .collect();
        let (asked_ids, asked) = exchange(&world, ids);
        let ghosts: Vec<usize> = by_owner.concat();
        let held = asked_ids
            .iter()
            .map(|&i| {
                nodes
                    .binary_search(&(i as usize))
                    .expect("a process holds only nodes of its owner's part")
            })
            .collect();
        Ghosts {
            world,
            ghosts: Groups::new(ghosts, &wanted),
            held: Groups::new(held, &asked),
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
        // The ghosts' parts to their owners, added to the owners' in process order.
        self.send(v, (&self.ghosts, &self.held), (send, receive));
        for (j, &k) in self.held.nodes.iter().enumerate() {
            for a in 0..3 {
                v[3 * k + a] += receive[3 * j + a];
            }
        }
        // The sums back to every holder.
        self.send(v, (&self.held, &self.ghosts), (send, receive));
        for (j, &k) in self.ghosts.nodes.iter().enumerate() {
            v[3 * k..3 * k + 3].copy_from_slice(&receive[3 * j..3 * j + 3]);
        }
        traffic::add(
            &traffic::SUMS,
            3 * (self.ghosts.nodes.len() + self.held.nodes.len()),
        );
    }

    /// Sends the values of `v` at the nodes of `from` to the processes they go to, receiving
    /// theirs for the nodes of `to` into `receive`, in `to`'s order.
    fn send(
        &self,
        v: &[f64],
        (from, to): (&Groups, &Groups),
        (send, receive): (&mut Vec<f64>, &mut Vec<f64>),
    ) {
        send.clear();
        send.extend(from.nodes.iter().flat_map(|&k| &v[3 * k..3 * k + 3]));
        receive.resize(3 * to.nodes.len(), 0.0);
        self.world.all_to_all_varcount_into(
            &Partition::new(&send[..], &from.counts[..], &from.starts[..]),
            &mut PartitionMut::new(&mut receive[..], &to.counts[..], &to.starts[..]),
        );
    }
}
