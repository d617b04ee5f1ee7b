//! A scene built on one process's part of its mesh, in a run shared among processes (see
//! `distributed`): no process builds the whole model, and with a `[mesh] box` no process
//! makes the whole mesh either.
//!
//! Each process makes (or, for a mesh file, reads and slices) a contiguous range of the
//! elements and one of the nodes; the processes partition the ranges together and each
//! gathers its part ([`MeshSharing::share`]). The scene is then built on the part's mesh by
//! the builders a one-process run uses. What a part cannot tell alone is asked of the
//! processes: the bounding box, whether a region selects anything anywhere (so that every
//! process gives the same error), which faces are on the whole mesh's boundary (a part's own
//! boundary also has the faces of its cut), sums over the whole boundary (gathered and added
//! in one process's order, so that penalties have its bits), and the owners' values at the
//! nodes a part holds but does not own (fixed temperatures, whole masses). Masses, dead loads
//! and contact nodes are kept at the nodes the process owns, all of whose elements its part
//! holds.
//!
//! Scenes with sections whose set-up needs the whole mesh — bodies, a freezing front
//! prescribed from a surface, an initial state read from a file, ice–ice contact between
//! several parts — are built whole on every process and shared out afterwards
//! ([`builds_on_parts`]). (A fractured run resumed on parts builds the whole scene again
//! to rebuild its split mesh from the frame: `run::restore`.)

use super::{SceneError, SceneFile, Validator};
use crate::mesh::{BoundaryFace, BoxGrid, TetMesh};
use crate::physics::contact::{Contact, WholeBoundary};
use crate::physics::Obstacle;
use crate::sim::part::Part;
use nalgebra::Vector3;

/// The ranges of a mesh one process holds before the partition: process `r` holds the
/// elements `element_starts[r] .. element_starts[r + 1]` and the nodes
/// `node_starts[r] .. node_starts[r + 1]`.
pub struct MeshRanges<'a> {
    /// Where each process's elements start; the number of elements last.
    pub element_starts: &'a [usize],
    /// This process's elements' nodes (the whole mesh's numbers).
    pub tets: &'a [[usize; 4]],
    /// Where each process's nodes start; the number of nodes last.
    pub node_starts: &'a [usize],
    /// This process's nodes' rest positions (m).
    pub rest: &'a [Vector3<f64>],
}

/// A process's part of a scene's mesh, gathered by [`MeshSharing::share`].
pub struct SharedMesh {
    /// Its elements and nodes as the whole mesh's, and which the process evaluates and owns.
    pub part: Part,
    /// The part's mesh: rest positions of its nodes (m) and its elements, numbered in the part.
    pub rest: Vec<Vector3<f64>>,
    pub tets: Vec<[usize; 4]>,
    /// For each of the part's elements, its faces on the whole mesh's boundary (bit `f`:
    /// `TET_FACES[f]`).
    pub boundary: Vec<u8>,
}

/// What the processes of a distributed run do together to build a scene on their parts.
/// Every process calls each method, in the same order.
pub trait MeshSharing {
    /// This process's number and the number of processes.
    fn rank_and_size(&self) -> (usize, usize);
    /// The number of processes on this process's machine (sharing its memory), this one
    /// included.
    fn on_this_machine(&self) -> usize;
    /// This process's part of the mesh the processes hold in `ranges`, partitioned among
    /// them.
    fn share(&self, ranges: MeshRanges) -> Result<SharedMesh, String>;
    /// The sum over the processes of `n`.
    fn total(&self, n: usize) -> usize;
    /// The largest `x` over the processes.
    fn largest(&self, x: f64) -> f64;
    /// Gives each node of this process's part (the last [`MeshSharing::share`]d) that it does
    /// not own the values its owner has in `values` (3 per node).
    fn copy_from_owners(&self, values: &mut [f64]);
    /// Every process's `items`, keyed by distinct node triples, on every process: their
    /// values in the order of their keys.
    fn gathered_by_key(&self, items: &[([usize; 3], f64)]) -> Vec<f64>;
}

/// Whether the scene `raw` is built on each process's part of its mesh: a single `[mesh]`
/// box or mesh file (of one connected part: checked once read) with materials, eigenstrains,
/// gravity, damping, supports, tractions, obstacles, plasticity, creep, heat with the
/// freezing it drives, fracture, or a freezing front from a box's faces. Other sections' set-up
/// needs the whole mesh (see the module docs).
pub fn builds_on_parts(raw: &SceneFile) -> bool {
    needs_whole_mesh(raw).is_none()
}

/// The first section of `raw` whose set-up needs the whole mesh on every process, if any.
pub(super) fn needs_whole_mesh(raw: &SceneFile) -> Option<&'static str> {
    let not_one_mesh = raw.mesh.as_ref().is_none_or(|m| {
        m.boxes.as_ref().is_some_and(|b| b.len() != 1) || (m.box_.is_some() == m.file.is_some())
    });
    [
        (!raw.body.is_empty(), "[[body]]"),
        (not_one_mesh, "[mesh] with several boxes"),
        (raw.initial.is_some(), "[initial]"),
        (
            raw.thermal.is_none() && !front_from_box_faces(raw),
            "[freezing]'s front from a surface",
        ),
        (raw.physics.ice_stiffness.is_some(), "physics.ice_stiffness"),
    ]
    .into_iter()
    .find_map(|(needs, section)| needs.then_some(section))
}

/// Whether `raw`'s prescribed freezing front (if any) comes from faces of a box only, which
/// each element's place alone decides: a `[mesh] box` cooled through box faces (a mesh file's
/// physical surface of a box face's name would take its place).
fn front_from_box_faces(raw: &SceneFile) -> bool {
    let Some(front) = &raw.freezing else {
        return true;
    };
    let box_mesh = raw.mesh.as_ref().is_some_and(|m| m.file.is_none());
    let box_faces =
        (front.cooling.iter().flatten()).all(|n| super::freezing::BOX_FACES.contains(&n.as_str()));
    box_mesh && box_faces
}

impl Validator<'_> {
    /// The part of the mesh of `grid` (a `[mesh] box`) this process holds, made from its
    /// ranges alone.
    pub(super) fn share_grid(&self, grid: &BoxGrid) -> Result<TetMesh, SceneError> {
        let sharing = self.sharing.get().expect("a shared scene");
        let (rank, size) = sharing.rank_and_size();
        let element_starts = crate::sim::part::ranges(grid.num_tets(), size);
        let node_starts = crate::sim::part::ranges(grid.num_nodes(), size);
        let tets: Vec<[usize; 4]> = (element_starts[rank]..element_starts[rank + 1])
            .map(|e| grid.tet(e))
            .collect();
        let rest: Vec<Vector3<f64>> = (node_starts[rank]..node_starts[rank + 1])
            .map(|v| grid.node(v))
            .collect();
        self.share(MeshRanges {
            element_starts: &element_starts,
            tets: &tets,
            node_starts: &node_starts,
            rest: &rest,
        })
    }

    /// The part of `mesh` (read whole) this process holds.
    pub(super) fn share_mesh(&self, mesh: TetMesh) -> Result<TetMesh, SceneError> {
        let sharing = self.sharing.get().expect("a shared scene");
        let (rank, size) = sharing.rank_and_size();
        let element_starts = crate::sim::part::ranges(mesh.num_tets(), size);
        let node_starts = crate::sim::part::ranges(mesh.num_nodes(), size);
        self.share(MeshRanges {
            tets: &mesh.tets[element_starts[rank]..element_starts[rank + 1]],
            rest: &mesh.rest[node_starts[rank]..node_starts[rank + 1]],
            element_starts: &element_starts,
            node_starts: &node_starts,
        })
    }

    fn share(&self, ranges: MeshRanges) -> Result<TetMesh, SceneError> {
        let sharing = self.sharing.get().expect("a shared scene");
        let shared = sharing.share(ranges).map_err(|e| self.invalid("mesh", e))?;
        let mesh = TetMesh::new(shared.rest, shared.tets).map_err(|source| SceneError::Mesh {
            path: self.path.into(),
            source,
        })?;
        *self.part.borrow_mut() = Some((shared.part, shared.boundary));
        Ok(mesh)
    }

    /// Notes that every process builds the whole scene, as `reason`'s set-up needs.
    pub(super) fn whole_on_every_process(&self, reason: &str) {
        self.notices.borrow_mut().push(format!(
            "every process builds the whole scene and then keeps its part: {reason} needs the whole mesh while setting up"
        ));
    }

    /// The bounding box of the whole mesh, of which `mesh` is this process's part or the
    /// whole (m).
    pub(super) fn bounding_box(&self, mesh: &TetMesh) -> (Vector3<f64>, Vector3<f64>) {
        let (lo, hi) = mesh.bounding_box();
        match self.sharing.get().filter(|_| self.part.borrow().is_some()) {
            Some(s) => (lo.map(|x| -s.largest(-x)), hi.map(|x| s.largest(x))),
            None => (lo, hi),
        }
    }

    /// The faces of `mesh` on the whole mesh's boundary.
    pub(super) fn whole_boundary(&self, mesh: &TetMesh) -> Vec<BoundaryFace> {
        match &*self.part.borrow() {
            Some((_, marks)) => mesh.faces_marked(marks),
            None => mesh.boundary_faces(),
        }
    }

    /// Gives each node of this process's part it does not own the values its owner has in
    /// `values` (3 per node); whether the scene is built on a part (else nothing changes).
    pub(super) fn copy_from_owners(&self, values: &mut [f64]) -> bool {
        match self.sharing.get().filter(|_| self.part.borrow().is_some()) {
            Some(s) => {
                s.copy_from_owners(values);
                true
            }
            None => false,
        }
    }

    /// Nodes and elements of the whole mesh, of which `mesh` is this process's part or the
    /// whole.
    pub(super) fn whole_counts(&self, mesh: &TetMesh) -> (usize, usize) {
        match &*self.part.borrow() {
            Some((part, _)) => (part.whole_nodes(), part.whole_elements()),
            None => (mesh.num_nodes(), mesh.num_tets()),
        }
    }

    /// Whether this process owns node `k` of `mesh` (every node, on the whole mesh).
    pub(super) fn owns_node(&self, k: usize) -> bool {
        (self.part.borrow().as_ref()).is_none_or(|(part, _)| part.owned_nodes[k])
    }

    /// The lowest node of each connected part of the whole mesh that this process holds
    /// (and owns, on a part: each is then checked by one process), numbered in `mesh`.
    pub(super) fn first_node_of_each_part(&self, mesh: &TetMesh) -> Vec<usize> {
        match &*self.part.borrow() {
            // A scene built on parts is one connected part (`builds_on_parts`).
            Some((part, _)) => (part.nodes.first() == Some(&0) && part.owned_nodes[0])
                .then_some(0)
                .into_iter()
                .collect(),
            None => {
                let (part, count) = crate::mesh::parts(mesh);
                let mut first = vec![usize::MAX; count];
                for (node, &p) in part.iter().enumerate().rev() {
                    first[p as usize] = node;
                }
                first
            }
        }
    }

    /// The deepest of the processes' `local` (depth, node of `mesh`) findings, of equally deep
    /// ones the highest-numbered node (as the last of one process's): its depth and position.
    pub(super) fn deepest(
        &self,
        mesh: &TetMesh,
        local: Option<(f64, usize)>,
    ) -> (f64, Vector3<f64>) {
        let part = self.part.borrow();
        let (Some(s), Some((part, _))) = (self.sharing.get(), part.as_ref()) else {
            let (depth, k) = local.expect("a finding on the only process");
            return (depth, mesh.rest[k]);
        };
        let depth = s.largest(local.map_or(f64::NEG_INFINITY, |(d, _)| d));
        let at = local.filter(|(d, _)| *d == depth).map(|(_, k)| k);
        let node = s.largest(at.map_or(-1.0, |k| part.nodes[k] as f64));
        let mine = at.filter(|&k| part.nodes[k] as f64 == node);
        let x =
            Vector3::from_fn(|a, _| s.largest(mine.map_or(f64::NEG_INFINITY, |k| mesh.rest[k][a])));
        (depth, x)
    }

    /// The perimeters of the whole mesh's boundary triangles (m), in the order of
    /// `TetMesh::boundary_faces` of the whole mesh: on a part, each process gives those of its
    /// own elements and every process gets all of them, so that sums over them have the bits
    /// of one process's.
    fn boundary_perimeters(&self, mesh: &TetMesh) -> Vec<f64> {
        match (self.sharing.get(), &*self.part.borrow()) {
            (Some(s), Some((part, marks))) => {
                let mut own = mesh.faces_marked(marks);
                own.retain(|f| part.own_elements[f.tet]);
                s.gathered_by_key(&part.keyed_perimeters(mesh, &own))
            }
            _ => mesh.perimeters(&mesh.boundary_faces()),
        }
    }

    /// The whole mesh's mean boundary edge (m), as `TetMesh::mean_boundary_edge` of it.
    pub(super) fn mean_boundary_edge(&self, mesh: &TetMesh) -> f64 {
        crate::mesh::mean_edge(&self.boundary_perimeters(mesh))
    }

    /// Contact of the whole mesh's boundary with `obstacles`, on `mesh` (its part or the
    /// whole).
    pub(super) fn contact(
        &self,
        mesh: &TetMesh,
        obstacles: Vec<Obstacle>,
        smoothing: f64,
    ) -> Contact {
        if self.part.borrow().is_none() {
            return Contact::new(mesh, obstacles, smoothing);
        }
        let whole = WholeBoundary::new(&self.boundary_perimeters(mesh), self.bounding_box(mesh));
        let faces = self.whole_boundary(mesh);
        Contact::on_boundary((mesh, &faces), whole, obstacles, smoothing)
    }

    /// `n` (items this process found) summed over the processes of a shared scene: what
    /// decides an error every process must give alike. Items a ring holds count on every
    /// process holding them.
    pub(super) fn found_anywhere(&self, n: usize) -> usize {
        match self.sharing.get().filter(|_| self.part.borrow().is_some()) {
            Some(s) => s.total(n),
            None => n,
        }
    }
}
