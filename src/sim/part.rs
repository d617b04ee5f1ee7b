//! A process's part of a model in a distributed run.
//!
//! The elements are split into parts (one per process) and each node is owned by one process,
//! the lowest-numbered among its elements' (so an owned node is a node of the process's own
//! elements). A process holds its part's elements, every other element around their nodes,
//! and those elements' nodes: the nodes it owns and ghost nodes it holds copies of. Every node
//! of its own elements then has all of its elements on the process — an owned node's lumped
//! mass, loads and rows of the Hessian are whole there, and so is the nodal volume of every
//! node of its own elements, which their pressures need — and a process evaluates the
//! elastic energy of its part's elements only, and everything per node on its owned nodes
//! only (`Model::restrict`), so that the processes' parts add up to the whole potential.
//!
//! A term that couples nodes sharing no element (ice–ice contact: a boundary node with any
//! boundary face) has each process hold the elements of the boundary faces near its own
//! besides (its ghost surface, see `distributed::surface_hold`); they are ghosts like the
//! ring's. Where fracture splits
//! the mesh, or on one process, a part is the whole mesh: every element and node, each
//! process evaluating its own elements and owned nodes as above.

use crate::mesh::{BoundaryFace, MeshError, TetMesh};
use crate::physics::term::NodeRestriction;
use crate::physics::Model;
use nalgebra::Vector3;

/// Marks a node that is not in a part's mesh.
const NONE: usize = usize::MAX;

/// One process's part of a mesh: its elements and nodes, numbered as in the whole mesh's order.
#[derive(Clone, Debug, Default)]
pub struct Part {
    /// The part's elements, as elements of the whole mesh (ascending).
    pub elements: Vec<usize>,
    /// The part's nodes, as nodes of the whole mesh (ascending).
    pub nodes: Vec<usize>,
    /// Whether the process evaluates each of the part's elements (it is in its partition part).
    pub own_elements: Vec<bool>,
    /// Whether the process owns each of the part's nodes.
    pub owned_nodes: Vec<bool>,
    /// Number of nodes and elements of the whole mesh (the part keeps no array of the whole
    /// mesh's size: a process holds it for the whole run).
    whole_nodes: usize,
    whole_elements: usize,
}

/// The contiguous ranges of `items` (elements or nodes) that `processes` hold before a
/// partition: process `r` holds `starts[r] .. starts[r + 1]`.
pub fn ranges(items: usize, processes: usize) -> Vec<usize> {
    (0..=processes).map(|r| r * items / processes).collect()
}

/// Each of `nodes` nodes' owner when element `e` of `tets` is in partition part
/// `element_part[e]`: the lowest process among its elements' (`u32::MAX` for a node of no
/// element).
pub fn lowest_owners(tets: &[[usize; 4]], element_part: &[u32], nodes: usize) -> Vec<u32> {
    let mut owner = vec![u32::MAX; nodes];
    for (tet, &p) in tets.iter().zip(element_part) {
        for &v in tet {
            owner[v] = owner[v].min(p);
        }
    }
    owner
}

impl Part {
    /// The part of process `rank` when element `e` is in partition part `element_part[e]`
    /// and node `i` is owned by process `node_owner[i]` (one of its elements' processes): its
    /// elements, every element around their nodes, the elements `besides` (those every
    /// process holds, or a wider halo of the process's own), and those elements' nodes
    /// (`tets`: the whole mesh's elements). With `whole`, every element and node.
    pub fn new(
        tets: &[[usize; 4]],
        (element_part, node_owner): (&[u32], &[u32]),
        rank: u32,
        (besides, whole): (&[usize], bool),
    ) -> Part {
        let n = node_owner.len();
        let mut near = vec![whole; n];
        for (tet, &p) in tets.iter().zip(element_part) {
            if p == rank {
                for &v in tet {
                    near[v] = true;
                }
            }
        }
        let mut held = vec![false; tets.len()];
        for &e in besides {
            held[e] = true;
        }
        let elements: Vec<usize> = (0..tets.len())
            .filter(|&e| held[e] || tets[e].iter().any(|&v| near[v]))
            .collect();
        let mut in_part = vec![false; n];
        for &e in &elements {
            for &v in &tets[e] {
                in_part[v] = true;
            }
        }
        let nodes: Vec<usize> = (0..n).filter(|&i| in_part[i]).collect();
        Part {
            own_elements: elements.iter().map(|&e| element_part[e] == rank).collect(),
            owned_nodes: nodes.iter().map(|&i| node_owner[i] == rank).collect(),
            elements,
            nodes,
            whole_nodes: n,
            whole_elements: tets.len(),
        }
    }

    /// The part holding the whole mesh's `elements` and `nodes` (ascending), of which the
    /// process evaluates the elements marked in `own_elements` and owns the nodes marked in
    /// `owned_nodes`, in a mesh of `whole_nodes` nodes and `whole_elements` elements.
    pub fn from_lists(
        (elements, nodes): (Vec<usize>, Vec<usize>),
        (own_elements, owned_nodes): (Vec<bool>, Vec<bool>),
        (whole_nodes, whole_elements): (usize, usize),
    ) -> Part {
        debug_assert!(elements.is_sorted() && nodes.is_sorted());
        Part {
            elements,
            nodes,
            own_elements,
            owned_nodes,
            whole_nodes,
            whole_elements,
        }
    }

    /// The part's node of node `i` of the whole mesh, if the part holds it.
    pub fn local(&self, i: usize) -> Option<usize> {
        self.nodes.binary_search(&i).ok()
    }

    /// [`Part::local`] of every node of the whole mesh (`usize::MAX`: not in the part), for
    /// the set-up's passes over the whole mesh.
    fn local_nodes(&self) -> Vec<usize> {
        let mut local = vec![NONE; self.whole_nodes];
        for (k, &i) in self.nodes.iter().enumerate() {
            local[i] = k;
        }
        local
    }

    /// Whether the part is the whole mesh (every element of it, so every node).
    pub fn is_whole(&self) -> bool {
        self.elements.len() == self.whole_elements
    }

    /// Number of nodes of the whole mesh.
    pub fn whole_nodes(&self) -> usize {
        self.whole_nodes
    }

    /// Elements of the whole mesh.
    pub fn whole_elements(&self) -> usize {
        self.whole_elements
    }

    /// Whether the process owns each dof of the part (3 per node).
    pub fn owned_dofs(&self) -> Vec<bool> {
        self.owned_nodes.iter().flat_map(|&o| [o; 3]).collect()
    }

    /// The part's model: `whole` on the part's elements (their history, schedule and
    /// materials inherited), with masses, loads and per-node terms on the owned nodes only
    /// (see `Model::restrict`), and its initial displacement and velocity.
    pub fn model(&self, whole: &Model) -> Result<Model, MeshError> {
        if self.is_whole() {
            return Ok(self.whole_model(whole.clone()));
        }
        let rest: Vec<_> = self.nodes.iter().map(|&i| whole.mesh.rest[i]).collect();
        self.model_on(whole, rest, self.tets_of(&whole.mesh.tets))
    }

    /// [`Part::model`] of a part that is not the whole mesh, given its nodes' rest positions
    /// (m) and its elements numbered in the part.
    pub fn model_on(
        &self,
        whole: &Model,
        rest: Vec<Vector3<f64>>,
        tets: Vec<[usize; 4]>,
    ) -> Result<Model, MeshError> {
        let mut model = whole.remeshed(&rest, tets, &self.elements, &[])?;
        model.initial_displacement = self.dofs_of(&whole.initial_displacement);
        model.initial_velocity = self.dofs_of(&whole.initial_velocity);
        model.restrict(&self.owned_nodes, &whole.terms, &self.restriction());
        Ok(model)
    }

    /// [`Part::model`] of a part that is the whole mesh, from the whole `model` itself.
    pub fn whole_model(&self, mut model: Model) -> Model {
        debug_assert!(self.is_whole());
        let terms = std::mem::take(&mut model.terms);
        model.restrict(&self.owned_nodes, &terms, &self.restriction());
        model
    }

    /// The restriction of the whole mesh's per-node terms to the nodes this process owns.
    fn restriction(&self) -> NodeRestriction {
        let local = self.local_nodes();
        NodeRestriction {
            kept: local
                .iter()
                .map(|&k| k != NONE && self.owned_nodes[k])
                .collect(),
            local,
            local_nodes: self.nodes.len(),
        }
    }

    /// Whether each node of the part's elements `tets` (numbered in the part) is a node of an
    /// element the process evaluates: such a node has all its elements on the part.
    pub fn near_nodes(&self, tets: &[[usize; 4]]) -> Vec<bool> {
        let mut near = vec![false; self.nodes.len()];
        for (tet, _) in (tets.iter().zip(&self.own_elements)).filter(|(_, &o)| o) {
            tet.iter().for_each(|&i| near[i] = true);
        }
        near
    }

    /// The near nodes of the part's mesh `mesh` ([`Part::near_nodes`]) and its faces through
    /// them: faces of the whole mesh's boundary (both elements of an inner face through a
    /// near node are on the part), every one a near node has. Faces through no near node
    /// (the cut, and faces the part cannot tell from it) are left out.
    pub fn whole_boundary_faces(&self, mesh: &TetMesh) -> (Vec<bool>, Vec<BoundaryFace>) {
        let near = self.near_nodes(&mesh.tets);
        let mut faces = mesh.boundary_faces();
        faces.retain(|f| f.nodes.iter().any(|&i| near[i]));
        (near, faces)
    }

    /// The perimeters (m) of the faces `faces` of the part's mesh `mesh` (the whole mesh's
    /// boundary faces of the part's own elements, each given by one process), each keyed by
    /// its nodes' numbers in the whole mesh, ascending: sorted by key, all processes' give the
    /// whole boundary's in `TetMesh::boundary_faces` order.
    pub fn keyed_perimeters(
        &self,
        mesh: &TetMesh,
        faces: &[BoundaryFace],
    ) -> Vec<([usize; 3], f64)> {
        (faces.iter().zip(mesh.perimeters(faces)))
            .map(|(face, p)| {
                let mut key = face.nodes.map(|i| self.nodes[i]);
                key.sort_unstable();
                (key, p)
            })
            .collect()
    }

    /// The part's entries of a vector over the whole mesh's dofs (3 per node; empty stays
    /// empty).
    pub fn dofs_of(&self, whole: &[f64]) -> Vec<f64> {
        if whole.is_empty() {
            return Vec::new();
        }
        self.nodes
            .iter()
            .flat_map(|&i| [whole[3 * i], whole[3 * i + 1], whole[3 * i + 2]])
            .collect()
    }

    /// The part's elements, numbered in the part, from the whole mesh's elements `tets`.
    pub fn tets_of(&self, tets: &[[usize; 4]]) -> Vec<[usize; 4]> {
        let local = self.local_nodes();
        self.elements
            .iter()
            .map(|&e| tets[e].map(|v| local[v]))
            .collect()
    }

    /// The part's rows of a field of `columns` values per node (or per element if
    /// `per_element`) of the whole mesh.
    pub fn rows_of(&self, whole: &[f64], columns: usize, per_element: bool) -> Vec<f64> {
        let items = if per_element {
            &self.elements
        } else {
            &self.nodes
        };
        items
            .iter()
            .flat_map(|&i| &whole[columns * i..columns * (i + 1)])
            .copied()
            .collect()
    }

    /// The rows this process gives to a frame, in the whole mesh's order: its owned nodes
    /// (or, if `per_element`, its own elements) as (row of the whole mesh, row of the part).
    /// Every node and element is given by one process.
    pub fn given_rows(&self, per_element: bool) -> Vec<(usize, usize)> {
        let (items, mine) = match per_element {
            true => (&self.elements, &self.own_elements),
            false => (&self.nodes, &self.owned_nodes),
        };
        (items.iter().enumerate())
            .filter(|&(k, _)| mine[k])
            .map(|(k, &i)| (i, k))
            .collect()
    }

    /// The mesh's numbers of the process's own elements (`per_element`) or of its owned
    /// nodes, ascending.
    pub fn mine(&self, per_element: bool) -> Vec<usize> {
        (self.given_rows(per_element).into_iter())
            .map(|(i, _)| i)
            .collect()
    }

    /// The whole-mesh dof of each of the part's dofs (3 per node).
    pub fn whole_dofs(&self) -> impl Iterator<Item = usize> + '_ {
        self.nodes
            .iter()
            .flat_map(|&i| [3 * i, 3 * i + 1, 3 * i + 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_part_holds_every_element_around_its_elements_nodes() {
        // A chain of three tets sharing faces, and a fourth apart.
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4], [2, 3, 4, 5], [6, 7, 8, 9]];
        // Elements 0 | 1, 2, 3; a node belongs to the lowest part among its elements'.
        let element_part = [0, 1, 1, 1];
        let owner = [0, 0, 0, 0, 1, 1, 1, 1, 1, 1];
        let first = Part::new(&tets, (&element_part, &owner), 0, (&[], false));
        // Element 0's nodes 1, 2, 3 are in elements 1 and 2 too; element 3 is apart.
        assert_eq!(first.elements, vec![0, 1, 2]);
        assert_eq!(first.own_elements, vec![true, false, false]);
        assert_eq!(first.nodes, vec![0, 1, 2, 3, 4, 5]);
        assert_eq!(
            first.owned_nodes,
            vec![true, true, true, true, false, false]
        );
        assert!(!first.is_whole());
        let second = Part::new(&tets, (&element_part, &owner), 1, (&[], false));
        assert_eq!(second.elements, vec![0, 1, 2, 3]);
        assert!(second.is_whole());
        // Part 1 being element 3 alone: nodes 0 … 5 are not in it.
        let apart = Part::new(
            &tets,
            (&[0, 0, 0, 1], &[0, 0, 0, 0, 0, 0, 1, 1, 1, 1]),
            1,
            (&[], false),
        );
        assert_eq!(apart.elements, vec![3]);
        assert_eq!(apart.nodes, vec![6, 7, 8, 9]);
        assert_eq!((apart.local(7), apart.local(5)), (Some(1), None));
        assert_eq!(apart.tets_of(&tets), vec![[0, 1, 2, 3]]);
        assert_eq!(apart.whole_nodes(), 10);
        assert_eq!(apart.owned_dofs(), vec![true; 12]);
        let whole: Vec<f64> = (0..30).map(f64::from).collect();
        assert_eq!(apart.dofs_of(&whole)[..3], [18.0, 19.0, 20.0]);
        assert!(Part::new(&tets, (&element_part, &owner), 0, (&[], true)).is_whole());
        // Element 3 held by every process: on process 0 a ghost element with ghost nodes,
        // evaluated by process 1 alone.
        let with = Part::new(&tets, (&element_part, &owner), 0, (&[3], false));
        assert_eq!(with.elements, vec![0, 1, 2, 3]);
        assert!(with.is_whole());
        assert_eq!(with.own_elements, vec![true, false, false, false]);
        assert_eq!(with.nodes, (0..10).collect::<Vec<_>>());
        assert_eq!(with.owned_nodes.iter().filter(|&&o| o).count(), 4);
    }

    #[test]
    fn every_node_and_element_is_given_to_a_frame_by_one_process() {
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4], [2, 3, 4, 5], [6, 7, 8, 9]];
        let (element_part, owner) = ([0, 1, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1, 1, 1]);
        let parts =
            [0, 1].map(|rank| Part::new(&tets, (&element_part, &owner), rank, (&[], false)));
        for (per_element, count) in [(false, 10), (true, 4)] {
            let mut given: Vec<usize> = Vec::new();
            for part in &parts {
                let rows = part.given_rows(per_element);
                // In the whole mesh's order, each naming the part's row of the same item.
                assert!(rows.windows(2).all(|w| w[0].0 < w[1].0));
                let items = if per_element {
                    &part.elements
                } else {
                    &part.nodes
                };
                assert!(rows.iter().all(|&(i, k)| items[k] == i));
                given.extend(rows.iter().map(|&(i, _)| i));
            }
            given.sort_unstable();
            assert_eq!(given, (0..count).collect::<Vec<_>>());
        }
    }

    #[test]
    fn a_part_mesh_boundary_away_from_the_whole_boundary_touches_no_owned_node() {
        // A part's mesh on its own has faces where the ring ends (cut faces); what a scene
        // puts on the boundary at the nodes a process owns is whole on the part's mesh only
        // if no cut face touches an owned node. Three slabs of a 5-tet box, and parts made of
        // blocks of 2 cells in a pattern, each part touching the others along edges and
        // corners as well as faces.
        let mesh = crate::mesh::box_mesh([0.0; 3], [0.6, 0.5, 0.4], [6, 5, 4], 5).unwrap();
        let sorted = |f: [usize; 3]| {
            let mut f = f;
            f.sort_unstable();
            f
        };
        let whole: std::collections::HashSet<[usize; 3]> = mesh
            .boundary_faces()
            .iter()
            .map(|f| sorted(f.nodes))
            .collect();
        let slabs: Vec<u32> = (mesh.tets.iter())
            .map(|t| ((t.iter().map(|&v| mesh.rest[v].x).sum::<f64>() / 2.4 * 3.0) as u32).min(2))
            .collect();
        let blocks: Vec<u32> = (mesh.tets.iter())
            .map(|t| {
                let c = t.iter().fold(Vector3::zeros(), |c, &v| c + mesh.rest[v]) / 4.0;
                ((c.x / 0.2) as u32 + (c.y / 0.25) as u32 + (c.z / 0.2) as u32) % 3
            })
            .collect();
        for element_part in [slabs, blocks] {
            let mut owner = vec![u32::MAX; mesh.num_nodes()];
            for (t, &p) in mesh.tets.iter().zip(&element_part) {
                t.iter().for_each(|&v| owner[v] = owner[v].min(p));
            }
            let mut cut_faces = 0;
            for rank in 0..3 {
                let part = Part::new(&mesh.tets, (&element_part, &owner), rank, (&[], false));
                let rest = part.nodes.iter().map(|&i| mesh.rest[i]).collect();
                let sub = crate::mesh::TetMesh::new(rest, part.tets_of(&mesh.tets)).unwrap();
                for face in sub.boundary_faces() {
                    if !whole.contains(&sorted(face.nodes.map(|k| part.nodes[k]))) {
                        cut_faces += 1;
                        assert!(face.nodes.iter().all(|&k| !part.owned_nodes[k]));
                    }
                }
            }
            // The parts are cut: the check is not empty.
            assert!(cut_faces > 0);
        }
    }
}
