//! A process's model, PETSc numbering and share of the run after a split made on the
//! processes' parts ([`super::splits::try_split`]), built from its part alone.
//!
//! The part holds every element around the nodes of its own elements (its *near* nodes), so
//! what lives on its elements and at its owned nodes comes out of `Model::remeshed_on` on the
//! part's mesh as the whole mesh's remesh gives it: masses, dead loads and obstacle contact
//! areas at the owned nodes, the elements' rest data, materials and freezing. A face of the
//! part's mesh through a near node is a face of the whole mesh's boundary (both its elements
//! would be held otherwise); the faces beyond are cut faces or faces the part cannot tell from
//! them, and are left out. What the part cannot tell alone comes from every process: the whole
//! boundary's perimeters (each face given by the process evaluating its element, ordered by
//! its nodes as `TetMesh::boundary_faces` orders a mesh's), the bounding box and the connected
//! pieces. Checked against the whole mesh's remesh restricted to each part on three processes,
//! and by a step taken on the parts (`solver_tests/partition.rs`).
//!
//! Ice–ice contact is rebuilt from the part's faces too, which is not the whole term: a
//! node's pairs reach faces and copies of split nodes beyond the part's ring (the other side
//! of a crack, another piece). [`super::ghost_surface`] gathers them; a part that also holds
//! the elements of its ghost faces finds the whole boundary's pairs with the restricted term
//! (tested by a step with contact); [`model_with_surface`] builds that term on a part holding
//! them. [`super::part_fracture`] drives these after each split (docs/distributed.md).

use super::components::connected_parts;
use super::ghost_surface::Surface;
use super::ghosts::gathered_by_key;
use super::largest;
use super::partition::PartNumbering;
use super::splits::SplitPart;
use super::{MpiCollective, ProcessShare};
use crate::fracture::cracks::{crack_faces, OriginalBoundary};
use crate::mesh::mean_edge;
use crate::mesh::{MeshError, TetMesh};
use crate::physics::contact::stiffness_for_edge;
use crate::physics::ice_contact::{IceContact, IceContactTerm};
use crate::physics::term::{NodeRestriction, WholeMesh};
use crate::physics::Model;
use crate::sim::part::Part;
use crate::sim::{Collective, Distribution};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::cell::Cell;
use std::rc::Rc;

/// This process's model after a split made on the parts: `before` (its model on its part
/// before the split) on the split part `held`, whose scene boundary's planes are `original`.
/// Every process of `world` calls it.
pub fn model_after_split(
    world: &SimpleCommunicator,
    held: &SplitPart,
    before: &Model,
    original: &OriginalBoundary,
) -> Result<Model, MeshError> {
    after_split(world, held, before, original).map(|(model, _)| model)
}

/// [`model_after_split`] on a part `held` that also holds the elements of this process's
/// ghost surface `surface` (gathered on the split parts, see [`super::ghost_surface`]), with
/// its ice–ice contact on that surface: the whole boundary's pairs with an owned node. The
/// surface's elements have no owned node and carry whatever `held`'s parents give them; the
/// part must hold every node of `surface`, and `pieces` is the whole mesh's number of pieces.
pub fn model_with_surface(
    world: &SimpleCommunicator,
    held: &SplitPart,
    before: &Model,
    (original, surface, pieces): (&OriginalBoundary, &Surface, usize),
) -> Result<Model, MeshError> {
    let (mut model, perimeters) = after_split(world, held, before, original)?;
    let Some(term) = model.term::<IceContactTerm>() else {
        return Ok(model);
    };
    // Every process has the term, also one whose part has no crack or other piece near it.
    let stiffness = match term.stiffness > 0.0 {
        true => term.stiffness,
        false => stiffness_for_edge(mean_edge(&perimeters), before.elasticity.material.young()),
    };
    let rank = world.rank() as u32;
    let part = &held.part;
    let restriction = NodeRestriction {
        local: (surface.nodes.iter())
            .map(|n| {
                part.local(n.node)
                    .expect("the part holds its surface's nodes")
            })
            .collect(),
        kept: surface.nodes.iter().map(|n| n.owner == rank).collect(),
        local_nodes: part.nodes.len(),
    };
    let contact = IceContact::on_surface(
        surface.contact_surface(rank, pieces),
        &perimeters,
        stiffness,
        (term.friction, term.smoothing_velocity),
    );
    let mut on_surface =
        IceContactTerm::inactive(term.stiffness, term.friction, term.smoothing_velocity);
    on_surface.active = Some(contact.restricted(&restriction));
    model.set_ice_contact(on_surface);
    Ok(model)
}

/// [`model_after_split`], and the whole boundary's perimeters (m) in
/// `TetMesh::boundary_faces`'s order.
fn after_split(
    world: &SimpleCommunicator,
    held: &SplitPart,
    before: &Model,
    original: &OriginalBoundary,
) -> Result<(Model, Vec<f64>), MeshError> {
    let (part, f) = (&held.part, &held.mesh);
    let mesh = TetMesh::new(f.rest.clone(), f.tets.clone())?;
    let (near, boundary) = part.whole_boundary_faces(&mesh);
    let touches_near = |nodes: &[usize; 3]| nodes.iter().any(|&i| near[i]);
    // Each whole-boundary face is given once, by the process evaluating its element.
    let own: Vec<_> = (boundary.iter())
        .filter(|face| part.own_elements[face.tet])
        .cloned()
        .collect();
    let perimeters = gathered_by_key(world, &part.keyed_perimeters(&mesh, &own));
    let (lo, hi) = mesh.bounding_box();
    let bounds = (
        lo.map(|x| -largest(world, -x)),
        hi.map(|x| largest(world, x)),
    );
    let (piece, pieces) = connected_parts(world, part, &mesh.tets, &held.node_owner);
    let cracks: Vec<[usize; 3]> = (crack_faces(&mesh, &held.origin, original).into_iter())
        .map(|face| face.nodes)
        .filter(|nodes| touches_near(nodes))
        .collect();
    let whole = WholeMesh {
        boundary: &boundary,
        perimeters: &perimeters,
        bounds,
        pieces: (&piece, pieces),
    };
    let mut model = before.remeshed_on(mesh, &f.parent, &cracks, &whole)?;
    let terms = std::mem::take(&mut model.terms);
    let owned = &part.owned_nodes;
    model.restrict(owned, &terms, &NodeRestriction::all(owned));
    Ok((model, perimeters))
}

/// This process's share of a run on its `part` of a mesh split on the parts, the part's mesh
/// being `mesh` (numbered in the part) and its PETSc numbering `numbering`
/// ([`numbering_after_split`]); CG stops at `solve`'s relative tolerance or iteration cap.
/// Every process calls it (it exchanges its ghosts' plan).
pub fn share_after_split(
    part: &Part,
    numbering: PartNumbering,
    mesh: &TetMesh,
    solve: (f64, usize),
) -> Box<dyn Distribution> {
    let rank = SimpleCommunicator::world().rank() as u32;
    let held = Rc::new(Cell::new([0; 2]));
    Box::new(ProcessShare::new(
        (part, numbering),
        mesh,
        rank,
        (solve, held),
    ))
}

/// The PETSc numbering of this process's `part` after a split made on the parts, whose nodes
/// are owned by `node_owner` and whose elements are evaluated by `element_part`: each
/// process's owned nodes numbered after the lower processes', in the mesh's order, as
/// `Partition` numbers the whole mesh; a ghost gets its owner's number. Every process of
/// `world` calls it.
pub fn numbering_after_split(
    world: &SimpleCommunicator,
    part: &Part,
    node_owner: &[u32],
    element_part: Vec<u32>,
) -> PartNumbering {
    let (size, rank) = (world.size() as usize, world.rank() as usize);
    let owned = part.owned_nodes.iter().filter(|&&o| o).count() as u64;
    let mut counts = vec![0u64; size];
    world.all_gather_into(&owned, &mut counts[..]);
    let node_start: Vec<usize> = std::iter::once(0)
        .chain(counts.iter().scan(0usize, |at, &n| {
            *at += n as usize;
            Some(*at)
        }))
        .collect();
    // The owner's number, and zeros from the other holders: every copy gets the owner's.
    let mut numbers = vec![0.0; 3 * part.nodes.len()];
    let owned = (part.owned_nodes.iter().enumerate()).filter(|(_, &o)| o);
    for (number, (k, _)) in (node_start[rank]..).zip(owned) {
        numbers[3 * k] = number as f64;
    }
    MpiCollective::new(part, node_owner).exchange(&mut numbers);
    PartNumbering {
        petsc_node: numbers.iter().step_by(3).map(|&x| x as usize).collect(),
        node_owner: node_owner.to_vec(),
        element_part,
        node_start,
    }
}
