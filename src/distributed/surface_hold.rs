//! Ice–ice contact on a process's part: the elements of its ghost surface held beside it, and
//! when to gather them again.
//!
//! Besides its part and ring, a process holds the elements of the boundary faces within a
//! reach of the boundary nodes it owns (its ghost surface, see [`super::ghost_surface`]),
//! gathered at the displacements of the moment. The reach is what the contact's next step
//! needs ([`IceContact::ghost_reach`], plus the step's motion) and an allowance of
//! [`ALLOWANCE_EDGES`] mean boundary edges. Before each step the processes check that what
//! the step needs is still held: a face within the step's reach of an owned node now was,
//! when the surface was gathered, within that reach plus twice the largest displacement
//! since (the node and the face each moved by at most that much). When it is not, the
//! processes gather their surfaces again and the run continues on the new parts (`run`).
//! The elements held for the surface have no node the process owns (an element around an
//! owned node is in its ring), so they are never evaluated there: they carry the positions
//! of the surface's nodes, which the ghost exchange keeps current.

use super::components::connected_parts;
use super::ghost_surface::{gathered, Surface};
use crate::mesh::{MeshError, TetMesh};
use crate::physics::ice_contact::IceContact;
use crate::sim::part::Part;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use nalgebra::Vector3;

/// Mean boundary edges of reach held beyond what the next step needs: the displacement a
/// run may gather before the surfaces are gathered again is half this many edges, less
/// the growth of the step's motion. More holds more elements on every process, less gathers
/// more often (a gathering rebuilds each process's simulation on its new part).
pub const ALLOWANCE_EDGES: f64 = 4.0;

/// The surface a process holds: how far it reaches, and from where.
#[derive(Clone, Debug)]
pub struct SurfaceHold {
    /// The reach (m) it was gathered with.
    reach: f64,
    /// The nodes the process owns (the whole mesh's numbers, ascending) and their
    /// displacements (m) when it was gathered.
    at: Vec<(usize, [f64; 3])>,
}

/// The reach (m) the ice–ice contact `contact` needs for a step of `h` seconds from the
/// current positions, with `vmax` the largest velocity component (m/s) and displacements of
/// up to `moved` (m) since the surface was gathered: the ghost reach, the step's motion and
/// twice `moved` (see the module docs).
fn needed(contact: &IceContact, (vmax, h): (f64, f64), moved: f64) -> f64 {
    contact.ghost_reach(vmax, h) + 2.0 * (2.0 * vmax * h + moved)
}

impl SurfaceHold {
    /// The hold of a surface gathered now, for a step of `h` seconds with `vmax` the largest
    /// velocity component (m/s, over the processes), by a process holding `part` at
    /// displacements `u` (m, 3 per part node).
    pub fn new(contact: &IceContact, (vmax, h): (f64, f64), part: &Part, u: &[f64]) -> Self {
        let reach = needed(contact, (vmax, h), 0.0) + ALLOWANCE_EDGES * contact.edge();
        Self::with_reach(reach, part, u)
    }

    /// The hold of a surface gathered now with `reach` (m), by a process holding `part` at
    /// displacements `u` (m, 3 per part node).
    pub fn with_reach(reach: f64, part: &Part, u: &[f64]) -> Self {
        let at = (part.nodes.iter().enumerate())
            .filter(|&(k, _)| part.owned_nodes[k])
            .map(|(k, &i)| (i, [u[3 * k], u[3 * k + 1], u[3 * k + 2]]))
            .collect();
        SurfaceHold { reach, at }
    }

    /// The reach (m) the surface was gathered with.
    pub fn reach(&self) -> f64 {
        self.reach
    }

    /// Whether the surface no longer holds what a step of `h` seconds of `contact` needs,
    /// the process holding `part` at displacements `u` (m, 3 per part node) with velocity
    /// components up to `vmax` (m/s, this process's): alike on every process of `world`,
    /// which all call it.
    pub fn outgrown(
        &self,
        world: &SimpleCommunicator,
        contact: &IceContact,
        (part, u): (&Part, &[f64]),
        (vmax, h): (f64, f64),
    ) -> bool {
        let mut moved = 0.0f64;
        for &(i, was) in &self.at {
            let k = part.local(i).expect("an owned node stays in the part");
            let now = Vector3::new(u[3 * k], u[3 * k + 1], u[3 * k + 2]);
            moved = moved.max((now - Vector3::from(was)).norm());
        }
        let mine = [moved, vmax];
        let mut largest = [0.0; 2];
        world.all_reduce_into(&mine[..], &mut largest[..], SystemOperation::max());
        needed(contact, (largest[1], h), largest[0]) > self.reach
    }
}

/// The elements of this process's ghost surface within `reach` (m) of its owned boundary
/// nodes (the whole mesh's numbers, ascending), the process holding `part` with mesh
/// (`rest`, `tets`) at displacements `u` (m, 3 per node) and its nodes owned by
/// `node_owner`. The mesh has no cracks (fracture on the parts gathers its own ghost
/// surface, `super::part_fracture`). Every
/// process of `world` calls it.
pub fn surface_elements(
    world: &SimpleCommunicator,
    part: &Part,
    (rest, tets): (&[Vector3<f64>], &[[usize; 4]]),
    (u, node_owner): (&[f64], &[u32]),
    reach: f64,
) -> Result<Vec<usize>, MeshError> {
    let (piece, _) = connected_parts(world, part, tets, node_owner);
    let mesh = TetMesh::new(rest.to_vec(), tets.to_vec())?;
    let given = Surface::given(part, &mesh, (u, node_owner, &piece), &[]);
    let surface = gathered(world, &given, reach);
    let mut elements: Vec<usize> = surface.elements.iter().map(|(e, _)| *e).collect();
    elements.sort_unstable();
    elements.dedup();
    Ok(elements)
}
