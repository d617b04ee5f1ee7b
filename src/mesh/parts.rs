//! Connected parts of a tet mesh.

use petgraph::unionfind::UnionFind;

use super::TetMesh;

/// Connected components of the mesh (nodes joined by tets): part index per node and count.
pub fn parts(mesh: &TetMesh) -> (Vec<u32>, usize) {
    parts_of(mesh.num_nodes(), &mesh.tets)
}

/// [`parts`] of `nodes` nodes joined by `tets`.
pub fn parts_of(nodes: usize, tets: &[[usize; 4]]) -> (Vec<u32>, usize) {
    let n = nodes;
    let mut sets = UnionFind::<usize>::new(n);
    for tet in tets {
        for &v in &tet[1..] {
            sets.union(tet[0], v);
        }
    }
    // Parts numbered in the order of their first node.
    let mut label = vec![u32::MAX; n];
    let mut part = vec![0u32; n];
    let mut count = 0;
    for (i, p) in part.iter_mut().enumerate() {
        let r = sets.find_mut(i);
        if label[r] == u32::MAX {
            label[r] = count;
            count += 1;
        }
        *p = label[r];
    }
    (part, count as usize)
}
