//! The mesh shared among processes: METIS splits the elements (by their dual graph, elements
//! that share a face adjacent), each node goes to the lowest-numbered process among its
//! elements', and PETSc's numbering lists each process's nodes contiguously.

use crate::mesh::TetMesh;

/// How the mesh is shared among `parts` processes.
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

/// Failure of the partitioner.
#[derive(Debug, thiserror::Error)]
#[error("METIS could not partition the mesh ({0})")]
pub struct PartitionError(pub String);

impl Partition {
    /// Splits `mesh` into `parts` (≥ 1) by METIS.
    pub fn new(mesh: &TetMesh, parts: usize) -> Result<Self, PartitionError> {
        let element_part = split_elements(mesh, parts)?;
        Ok(Self::from_element_parts(mesh, element_part, parts))
    }

    /// The partition given each element's process (`< parts`).
    pub fn from_element_parts(mesh: &TetMesh, element_part: Vec<u32>, parts: usize) -> Self {
        let n = mesh.num_nodes();
        // Nodes of no element (none in a valid mesh) go to process 0.
        let mut node_owner = vec![u32::MAX; n];
        for (tet, &p) in mesh.tets.iter().zip(&element_part) {
            for &v in tet {
                node_owner[v] = node_owner[v].min(p);
            }
        }
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

/// Each element's part, by METIS's k-way partition of the elements' dual graph (adjacent
/// through a face: 3 common nodes).
fn split_elements(mesh: &TetMesh, parts: usize) -> Result<Vec<u32>, PartitionError> {
    let ne = mesh.num_tets();
    if parts <= 1 || ne == 0 {
        return Ok(vec![0; ne]);
    }
    if parts > ne {
        return Err(PartitionError(format!(
            "{parts} processes for {ne} elements: at most one process per element"
        )));
    }
    let index = |x: usize| i32::try_from(x).map_err(|_| PartitionError(format!("{x} > i32")));
    let mut eptr: Vec<i32> = (0..=ne).map(|e| index(4 * e)).collect::<Result<_, _>>()?;
    let mut eind: Vec<i32> = mesh
        .tets
        .iter()
        .flatten()
        .map(|&v| index(v))
        .collect::<Result<_, _>>()?;
    let mut ne_i = index(ne)?;
    let mut nn_i = index(mesh.num_nodes())?;
    let mut ncommon = 3i32;
    let mut nparts = index(parts)?;
    let mut objval = 0i32;
    let mut epart = vec![0i32; ne];
    let mut npart = vec![0i32; mesh.num_nodes()];
    // SAFETY: eptr (ne + 1 entries) and eind (4 ne node indices < nn) follow METIS's mesh
    // contract; epart/npart have ne/nn entries; null weights and options select defaults.
    let status = unsafe {
        metis_sys::METIS_PartMeshDual(
            &mut ne_i,
            &mut nn_i,
            eptr.as_mut_ptr(),
            eind.as_mut_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            &mut ncommon,
            &mut nparts,
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            &mut objval,
            epart.as_mut_ptr(),
            npart.as_mut_ptr(),
        )
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        return Err(PartitionError(format!("status {status}")));
    }
    Ok(epart.into_iter().map(|p| p as u32).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::box_mesh;

    #[test]
    fn every_process_gets_elements_and_owned_nodes_are_numbered_contiguously() {
        let mesh = box_mesh([0.0; 3], [1.0; 3], [6, 4, 4], 5).unwrap();
        let p = Partition::new(&mesh, 3).unwrap();
        for part in 0..3 {
            let (elements, owned, ghosts) = p.counts(&mesh, part);
            // METIS balances to ~3 % by default: every part has about a third.
            assert!(
                elements as f64 > 0.25 * mesh.num_tets() as f64,
                "{elements}"
            );
            assert!(owned > 0 && ghosts > 0);
        }
        let mut seen = vec![false; mesh.num_nodes()];
        for (v, &i) in p.petsc_node.iter().enumerate() {
            let o = p.node_owner[v] as usize;
            assert!((p.node_start[o]..p.node_start[o + 1]).contains(&i));
            assert!(!std::mem::replace(&mut seen[i], true));
        }
    }
}
