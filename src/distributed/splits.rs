//! Node splits made by processes that each hold a part of the mesh (see `fracture::patch`),
//! taking the decisions one process takes on the whole mesh (`fracture::driver`).
//!
//! The processes offer the nodes they own for a split and all of them put the offers in the
//! order one process tries them ([`candidates_in_order`]). For each, [`try_split`]: the
//! process that owns the node holds every element around it, so it reads the node's star and
//! the crack normal (continuing a crack the node is on) and tells the others; each process
//! gives the rows of the patch around the star that it evaluates, every process gathers all
//! of them and puts the same patch together, splits it the same way and puts the split into
//! its own part; the processes then find the smallest piece of the split mesh together, and
//! a split that cuts off too small a piece is refused on every process, leaving the parts as
//! they were. Checked on 3 processes against the whole mesh (`solver_tests/partition.rs`).
//! [`super::part_fracture`] drives them after each step (docs/distributed.md).

use super::agreed;
use super::components::connected_parts;
use super::ghosts::all_gathered;
use crate::fracture::cracks::OriginalBoundary;
use crate::fracture::driver::{continued, Refusal};
use crate::fracture::patch::{rows_from_words, rows_to_words, HeldMesh, Patch};
use crate::fracture::split::Fracturable;
use crate::fracture::split::NodeSplit;
use crate::fracture::NodeSeparation;
use crate::sim::part::Part;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use nalgebra::{Matrix3, Vector3};

/// What the owner of a node to split tells the other processes.
#[derive(Clone, Debug, PartialEq)]
struct SplitPlan {
    /// The nodes of the node's elements (the mesh's numbers, ascending).
    star: Vec<usize>,
    /// The crack normal (unit).
    normal: Vector3<f64>,
}

/// The plan of process `owner` (ignored elsewhere), on every process of `world`; `None` on
/// every process if the owner has none. Every process calls it.
fn plan_from_owner(
    world: &SimpleCommunicator,
    owner: u32,
    plan: Option<SplitPlan>,
) -> Option<SplitPlan> {
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
    let (normal, star) = words.split_at_checked(3)?;
    Some(SplitPlan {
        normal: Vector3::from_iterator(normal.iter().map(|&w| f64::from_bits(w))),
        star: star.iter().map(|&i| i as usize).collect(),
    })
}

/// The patch around `star` (the split node's star, [`SplitPlan::star`]) of the mesh the
/// processes of `world` hold, put together on every process from the rows each gives of the
/// elements of `held` it evaluates (`own`): the same patch on every process, and the one
/// `Patch::of` takes from the whole mesh. `node` is the split node and `whole` the mesh's
/// number of nodes and elements. Returns it with the node's number in it and the process of
/// each of its elements. Every process calls it.
fn gathered_patch(
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
fn smallest_piece(
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

/// A node offered for a split: its number in the mesh, the process owning it (which offered
/// it) and its separation.
pub type Candidate = (usize, u32, NodeSeparation);

/// The nodes each process offers for a split (`offered`: its owned nodes, as the whole mesh's
/// numbers, with their separations), on every process, in the order one process tries them:
/// the largest separation stress first, equal stresses by node; each with the process that
/// offered it. Every process calls it.
pub fn candidates_in_order(
    world: &SimpleCommunicator,
    offered: &[(usize, NodeSeparation)],
) -> Vec<Candidate> {
    let rank = world.rank() as u64;
    let words: Vec<u64> = (offered.iter())
        .flat_map(|(node, s)| {
            let values = (s.tensor.iter())
                .chain([&s.largest])
                .chain(s.normal.iter())
                .chain([&s.area]);
            [*node as u64, u64::from(s.eligible), rank]
                .into_iter()
                .chain(values.map(|x| x.to_bits()))
                .collect::<Vec<u64>>()
        })
        .collect();
    let mut all: Vec<Candidate> = (all_gathered(world, &words).chunks_exact(17))
        .map(|w| {
            let value = |k: usize| f64::from_bits(w[k]);
            let separation = NodeSeparation {
                tensor: Matrix3::from_iterator((3..12).map(value)),
                largest: value(12),
                normal: Vector3::new(value(13), value(14), value(15)),
                area: value(16),
                eligible: w[1] != 0,
            };
            (w[0] as usize, w[2] as u32, separation)
        })
        .collect();
    all.sort_by(|a, b| b.2.stress().total_cmp(&a.2.stress()).then(a.0.cmp(&b.0)));
    all
}

/// This process's part of a mesh that fracture splits.
#[derive(Clone, Debug)]
pub struct SplitPart {
    /// Its elements and nodes (the mesh's numbers) and which it evaluates and owns.
    pub part: Part,
    /// Its mesh and state, numbered in the part. After a split, `parent` and `node_parent`
    /// number the elements and nodes the part held before it (a copy of a node the part did
    /// not hold: `usize::MAX` − the mesh's number), which carry their data to the new mesh.
    pub mesh: Fracturable,
    /// The process owning each of its nodes.
    pub node_owner: Vec<u32>,
    /// The scene element each of its elements lies in.
    pub origin: Vec<usize>,
    /// The process evaluating each of its elements (a split element's children stay with
    /// its process).
    pub process: Vec<u32>,
}

/// A split the processes made.
#[derive(Clone, Debug, PartialEq)]
pub struct PartSplit {
    /// The split node's rest position (m).
    pub rest: Vector3<f64>,
    /// The crack normal used (unit).
    pub normal: Vector3<f64>,
    /// What the split did, in the mesh's numbers.
    pub split: NodeSplit,
    /// The nodes whose stars the split changed (the mesh's numbers, ascending).
    pub lapsed: Vec<usize>,
}

/// Splits `node` (the mesh's number), owned by process `owner` and separating along `normal`,
/// on the parts the processes of `world` hold (`held` on this one), as one process splits the
/// whole mesh (`fracture::driver`): the crack normal continued from a crack the node is on,
/// the split of its patch put into every part, refused if the plane misses the node's star
/// or the split cuts off a piece smaller than `min_piece` (m³), in which case `held` is left
/// as it was. `original` is the scene boundary's planes of the part's scene elements, and
/// `snap` and `min_quality` the split's [`crate::fracture::FractureSettings`]. Every process
/// calls it, and every process takes the same decision. Fails on every process if a part
/// cannot take the split (a part holding elements of every process's, see
/// `Patch::apply_to_part`).
pub fn try_split(
    world: &SimpleCommunicator,
    held: &mut SplitPart,
    original: &OriginalBoundary,
    (node, owner, normal): (usize, u32, Vector3<f64>),
    (snap, min_quality, min_piece): (f64, f64, f64),
) -> Result<Result<PartSplit, Refusal>, String> {
    let rank = world.rank() as u32;
    let mesh = HeldMesh {
        mesh: &held.mesh,
        elements: &held.part.elements,
        nodes: &held.part.nodes,
        origin: &held.origin,
    };
    let counts = (held.part.whole_nodes(), held.part.whole_elements());
    // The owner holds every element around the node: it reads the star and the normal.
    let plan = match held.part.local(node) {
        Some(k) if owner == rank => {
            let star: Vec<usize> = (Patch::star_nodes(&held.mesh.tets, k).iter())
                .map(|&k| held.part.nodes[k])
                .collect();
            let (elements, nodes) = mesh.patch_rows(|_| Some(rank), &star);
            let (around, local, _) = Patch::from_rows(elements, nodes, node, counts);
            Some(SplitPlan {
                normal: continued(original, &around, local, &normal),
                star,
            })
        }
        _ => None,
    };
    let plan = plan_from_owner(world, owner, plan).ok_or(format!(
        "process {owner} does not hold node {node}, which it owns"
    ))?;
    let own = &held.part.own_elements;
    let (mut patch, local, processes) =
        gathered_patch(world, &mesh, own, (&plan.star, node), counts);
    let Some(split) = (patch.mesh).split_node(local, &plan.normal, snap, min_quality) else {
        return Ok(Err(Refusal::PlaneMissesStar));
    };
    // The split numbers parents in the part before it, as a split of the whole mesh does.
    let (mut mesh, mut node_owner) = (held.mesh.clone(), held.node_owner.clone());
    mesh.parent = (0..mesh.tets.len()).collect();
    mesh.node_parent = (0..mesh.rest.len()).collect();
    let applied = patch.apply_to_part(&held.part, (&mut mesh, &mut node_owner), &processes, rank);
    let part = agreed(world, applied, || {
        "another process's part could not take the split".into()
    })?;
    if smallest_piece(world, &part, &mesh, &node_owner) < min_piece {
        return Ok(Err(Refusal::PieceTooSmall));
    }
    let mut touched = split.edge_nodes.clone();
    touched.extend(&split.pinched);
    touched.extend([local, split.new_node]);
    held.origin = mesh.parent.iter().map(|&e| held.origin[e]).collect();
    held.process = mesh.parent.iter().map(|&e| held.process[e]).collect();
    held.part = part;
    held.mesh = mesh;
    held.node_owner = node_owner;
    Ok(Ok(PartSplit {
        rest: patch.mesh.rest[local],
        normal: plan.normal,
        split: patch.numbered(&split),
        lapsed: patch.neighbours(&touched),
    }))
}
