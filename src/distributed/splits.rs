//! A node split made by processes that each hold a part of the mesh (see `fracture::patch`).
//!
//! The process that owns the split node holds every element around it: it finds the node's
//! star and the crack normal and tells the other processes ([`plan_from_owner`]). Each process
//! then gives the rows of the patch around the star that it evaluates, every process gathers
//! all of them, and each puts the same patch together ([`gathered_patch`]), splits it the same
//! way and puts the split into its own part (`Patch::apply_to_part`).

use super::components::connected_parts;
use super::ghosts::all_gathered;
use crate::fracture::patch::{rows_from_words, rows_to_words, HeldMesh, Patch};
use crate::fracture::split::Fracturable;
use crate::fracture::NodeSeparation;
use crate::sim::part::Part;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use nalgebra::{Matrix3, Vector3};

/// What the owner of a node to split tells the other processes.
#[derive(Clone, Debug, PartialEq)]
pub struct SplitPlan {
    /// The nodes of the node's elements (the mesh's numbers, ascending).
    pub star: Vec<usize>,
    /// The crack normal (unit).
    pub normal: Vector3<f64>,
}

/// The plan of process `owner` (`Some` there, ignored elsewhere), on every process of `world`.
/// Every process calls it.
pub fn plan_from_owner(
    world: &SimpleCommunicator,
    owner: u32,
    plan: Option<SplitPlan>,
) -> SplitPlan {
    let root = world.process_at_rank(owner as i32);
    let mut words: Vec<u64> = match plan {
        Some(plan) if world.rank() as u32 == owner => (plan.normal.iter())
            .map(|x| x.to_bits())
            .chain(plan.star.iter().map(|&i| i as u64))
            .collect(),
        _ => Vec::new(),
    };
    let mut len = words.len() as u64;
    root.broadcast_into(&mut len);
    words.resize(len as usize, 0);
    root.broadcast_into(&mut words[..]);
    let normal = Vector3::from_iterator(words.iter().take(3).map(|&w| f64::from_bits(w)));
    SplitPlan {
        star: words.iter().skip(3).map(|&i| i as usize).collect(),
        normal,
    }
}

/// The patch around `star` (the split node's star, [`SplitPlan::star`]) of the mesh the
/// processes of `world` hold, put together on every process from the rows each gives of the
/// elements of `held` it evaluates (`own`): the same patch on every process, and the one
/// `Patch::of` takes from the whole mesh. `node` is the split node and `whole` the mesh's
/// number of nodes and elements. Returns it with the node's number in it and the process of
/// each of its elements. Every process calls it.
pub fn gathered_patch(
    world: &SimpleCommunicator,
    held: &HeldMesh,
    own: &[bool],
    (star, node): (&[usize], usize),
    whole: (usize, usize),
) -> (Patch, usize, Vec<u32>) {
    let rank = world.rank() as u32;
    let (elements, nodes) = held.patch_rows(|e| own[e].then_some(rank), star);
    let words = all_gathered(world, &rows_to_words(&elements, &nodes));
    let (elements, nodes) = rows_from_words(&words);
    Patch::from_rows(elements, nodes, node, whole)
}

/// Rest volume (m³) of the smallest connected piece of the mesh the processes of `world` hold,
/// this process holding `part` with its mesh `mesh` (numbered in the part) and its nodes'
/// owners `node_owner`: each process adds up its own elements' volumes by piece, and the
/// pieces' sums are added over the processes (in another order than one process adds them:
/// the same to round-off). Every process calls it.
pub fn smallest_piece(
    world: &SimpleCommunicator,
    part: &Part,
    mesh: &Fracturable,
    node_owner: &[u32],
) -> f64 {
    let (piece, count) = connected_parts(world, part, &mesh.tets, node_owner);
    let mut volume = vec![0.0; count];
    for ((tet, v), _) in (mesh.tets.iter().zip(mesh.volumes()))
        .zip(&part.own_elements)
        .filter(|(_, &own)| own)
    {
        volume[piece[tet[0]] as usize] += v;
    }
    let mut total = vec![0.0; count];
    world.all_reduce_into(&volume[..], &mut total[..], SystemOperation::sum());
    total.into_iter().fold(f64::INFINITY, f64::min)
}

/// The nodes each process offers for a split (`offered`: its owned nodes, as the whole mesh's
/// numbers, with their separations), on every process, in the order one process tries them:
/// the largest separation stress first, equal stresses by node. Every process calls it.
pub fn candidates_in_order(
    world: &SimpleCommunicator,
    offered: &[(usize, NodeSeparation)],
) -> Vec<(usize, NodeSeparation)> {
    let words: Vec<u64> = (offered.iter())
        .flat_map(|(node, s)| {
            let values = (s.tensor.iter())
                .chain([&s.largest])
                .chain(s.normal.iter())
                .chain([&s.area]);
            [*node as u64, u64::from(s.eligible)]
                .into_iter()
                .chain(values.map(|x| x.to_bits()))
                .collect::<Vec<u64>>()
        })
        .collect();
    let mut all: Vec<(usize, NodeSeparation)> = (all_gathered(world, &words).chunks_exact(16))
        .map(|w| {
            let value = |k: usize| f64::from_bits(w[k]);
            let separation = NodeSeparation {
                tensor: Matrix3::from_iterator((2..11).map(value)),
                largest: value(11),
                normal: Vector3::new(value(12), value(13), value(14)),
                area: value(15),
                eligible: w[1] != 0,
            };
            (w[0] as usize, separation)
        })
        .collect();
    all.sort_by(|a, b| b.1.stress().total_cmp(&a.1.stress()).then(a.0.cmp(&b.0)));
    all
}
