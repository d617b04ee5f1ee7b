//! The mesh shared among processes: PT-Scotch splits the elements (by their dual graph,
//! elements that share a face adjacent; computed by all the processes, see `dual_graph`),
//! each node goes to the lowest-numbered process among its elements', and PETSc's numbering
//! lists each process's nodes contiguously.

use crate::mesh::TetMesh;
use crate::sim::part::Part;

/// How the mesh is shared among `parts` processes, over the whole mesh: what a process builds
/// where it holds the whole mesh (asked for with `ICEFEM_WHOLE_MESH=1`). A run on parts keeps
/// [`PartNumbering`] only, gathered without the whole mesh (`super::part_mesh`).
#[derive(Clone, Debug)]
pub struct Partition {
    /// Process of each element.
    pub element_part: Vec<u32>,
    /// Process that owns each node (its dofs' rows and entries).
    pub node_owner: Vec<u32>,
    /// PETSc's index of each node: the nodes of process 0, then of process 1, …, each in
    /// ascending order.
    pub petsc_node: Vec<usize>,
    /// For each process, its first PETSc node; one past the last node at the end.
    pub node_start: Vec<usize>,
}

/// The partition on one process's part only ([`Partition::of_part`]), which is what the
/// process keeps while it runs: no array of the whole mesh's size.
#[derive(Clone, Debug)]
pub struct PartNumbering {
    /// PETSc's index of each of the part's nodes.
    pub petsc_node: Vec<usize>,
    /// The process that owns each of the part's nodes.
    pub node_owner: Vec<u32>,
    /// The process of each of the part's elements.
    pub element_part: Vec<u32>,
    /// For each process, its first PETSc node; one past the last node at the end.
    pub node_start: Vec<usize>,
}

impl PartNumbering {
    /// Nodes of the whole mesh.
    pub fn whole_nodes(&self) -> usize {
        self.node_start.last().copied().unwrap_or(0)
    }
}

/// Failure of the partitioner.
#[derive(Debug, thiserror::Error)]
#[error("the mesh could not be partitioned ({0})")]
pub struct PartitionError(pub String);

pub use crate::sim::part::ranges;

/// The process each element of this process's range goes to, by PT-Scotch, every process
/// taking part: `graph` is the range's rows of the dual graph ([`super::dual_graph::rows`])
/// when process `r` holds the elements `starts[r] .. starts[r + 1]`.
pub fn parts_of_range(
    graph: &super::dual_graph::DualGraph,
    starts: &[usize],
) -> Result<Vec<u32>, PartitionError> {
    let size = starts.len() - 1;
    let ne = starts[size];
    if size > ne {
        return Err(PartitionError(format!(
            "{size} processes for {ne} elements: at most one process per element"
        )));
    }
    if ne > super::petsc::Int::MAX as usize {
        return Err(PartitionError(format!(
            "{ne} elements exceed PETSc's 32-bit indices"
        )));
    }
    super::petsc::ptscotch_parts(&graph.offsets, &graph.neighbours, ne)
        .map_err(|e| PartitionError(e.to_string()))
}

impl Partition {
    /// The partition given each element's process (`< parts`).
    pub fn from_element_parts(mesh: &TetMesh, element_part: Vec<u32>, parts: usize) -> Self {
        let n = mesh.num_nodes();
        let mut node_owner = crate::sim::part::lowest_owners(&mesh.tets, &element_part, n);
        // Nodes of no element (none in a valid mesh) go to process 0.
        for owner in &mut node_owner {
            if *owner == u32::MAX {
                *owner = 0;
            }
        }
        let mut node_start = vec![0usize; parts + 1];
        for &o in &node_owner {
            node_start[o as usize + 1] += 1;
        }
        for p in 0..parts {
            node_start[p + 1] += node_start[p];
        }
        let mut next = node_start.clone();
        let mut petsc_node = vec![0usize; n];
        for (v, &o) in node_owner.iter().enumerate() {
            petsc_node[v] = next[o as usize];
            next[o as usize] += 1;
        }
        Partition {
            element_part,
            node_owner,
            petsc_node,
            node_start,
        }
    }

    /// Number of processes.
    pub fn parts(&self) -> usize {
        self.node_start.len() - 1
    }

    /// What a process holding `part` keeps of the partition while it runs.
    pub fn of_part(&self, part: &Part) -> PartNumbering {
        PartNumbering {
            petsc_node: part.nodes.iter().map(|&i| self.petsc_node[i]).collect(),
            node_owner: part.nodes.iter().map(|&i| self.node_owner[i]).collect(),
            element_part: part
                .elements
                .iter()
                .map(|&e| self.element_part[e])
                .collect(),
            node_start: self.node_start.clone(),
        }
    }

    /// Element, node and interface counts of process `part`: its elements, the nodes it
    /// owns, and the nodes of its elements it does not own (its ghosts).
    pub fn counts(&self, mesh: &TetMesh, part: u32) -> (usize, usize, usize) {
        let mut touched = vec![false; mesh.num_nodes()];
        let mut elements = 0;
        for (tet, &p) in mesh.tets.iter().zip(&self.element_part) {
            if p == part {
                elements += 1;
                for &v in tet {
                    touched[v] = true;
                }
            }
        }
        let owned = self.node_owner.iter().filter(|&&o| o == part).count();
        let ghosts = touched
            .iter()
            .zip(&self.node_owner)
            .filter(|(&t, &o)| t && o != part)
            .count();
        (elements, owned, ghosts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::box_mesh;

    #[test]
    fn every_process_gets_elements_and_owned_nodes_are_numbered_contiguously() {
        let mesh = box_mesh([0.0; 3], [1.0; 3], [6, 4, 4], 5).unwrap();
        // Three slabs along x.
        let element_part = (mesh.tets.iter())
            .map(|t| (t.iter().map(|&v| mesh.rest[v].x).sum::<f64>() / 4.0 * 3.0) as u32)
            .collect();
        let p = Partition::from_element_parts(&mesh, element_part, 3);
        for part in 0..3 {
            let (elements, owned, ghosts) = p.counts(&mesh, part);
            assert_eq!(elements, mesh.num_tets() / 3);
            assert!(owned > 0);
            // A node on an interface belongs to the lower slab: the first has no ghosts.
            assert_eq!(ghosts > 0, part > 0, "{part}: {ghosts}");
        }
        // A process keeps the partition on its part: the same numbers at its nodes and
        // elements.
        let part = Part::new(
            &mesh.tets,
            (&p.element_part, &p.node_owner),
            1,
            (&[], false),
        );
        let numbering = p.of_part(&part);
        assert_eq!(numbering.whole_nodes(), mesh.num_nodes());
        for (k, &i) in part.nodes.iter().enumerate() {
            assert_eq!(numbering.petsc_node[k], p.petsc_node[i]);
            assert_eq!(numbering.node_owner[k], p.node_owner[i]);
        }
        for (k, &e) in part.elements.iter().enumerate() {
            assert_eq!(numbering.element_part[k], p.element_part[e]);
        }
        let mut seen = vec![false; mesh.num_nodes()];
        for (v, &i) in p.petsc_node.iter().enumerate() {
            let o = p.node_owner[v] as usize;
            assert!((p.node_start[o]..p.node_start[o + 1]).contains(&i));
            assert!(!std::mem::replace(&mut seen[i], true));
        }
    }
}
