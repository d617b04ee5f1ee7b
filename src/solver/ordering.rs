//! Fill-reducing orderings for the sparse Cholesky factorisation.
//!
//! faer's built-in approximate minimum degree (AMD) is excellent on small systems but on 3-D
//! meshes it fills about twice as much as nested dissection. Nested dissection comes from METIS
//! (`METIS_NodeND`, vendored C through `metis-sys`), applied to the *node* graph — one vertex
//! per mesh node with free dofs — and expanded to the dofs node by node, which keeps each
//! node's 3 × 3 block together (better supernodes, 9× fewer graph edges).

use crate::assembly::Assembly;

/// Which fill-reducing ordering the Cholesky factorisation uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FillOrdering {
    /// Nested dissection above [`AUTO_THRESHOLD`] free dofs, AMD below.
    Auto,
    /// Approximate minimum degree (faer).
    Amd,
    /// Nested dissection (METIS) on the node graph.
    Metis,
}

/// Free-dof count from which `Auto` picks nested dissection. Measured on ice cubes
/// (`icefem bench`): below ~5e3 dofs both orderings factor in milliseconds and AMD's cheaper
/// analysis wins; above, nested dissection fills less and factors faster.
pub const AUTO_THRESHOLD: usize = 5_000;

impl FillOrdering {
    /// Whether nested dissection is used for a system of `n` free dofs.
    pub fn uses_metis(self, n: usize) -> bool {
        match self {
            FillOrdering::Auto => n >= AUTO_THRESHOLD,
            FillOrdering::Amd => false,
            FillOrdering::Metis => true,
        }
    }
}

/// Nested-dissection permutation of the free dofs of `assembly`: `forward[new] = old`, and its
/// inverse. `None` if METIS fails (the caller then falls back to AMD).
pub fn nested_dissection(assembly: &Assembly) -> Option<(Vec<usize>, Vec<usize>)> {
    let dofs = assembly.dofs();
    let n = dofs.num_free();
    // Compact node index of every free dof; free dofs of one node are consecutive.
    let mut node_of = Vec::with_capacity(n);
    let mut first_dof = Vec::new(); // first free dof of each compact node
    let mut last_node = usize::MAX;
    for (f, &d) in dofs.free_dofs().iter().enumerate() {
        if d / 3 != last_node {
            last_node = d / 3;
            first_dof.push(f);
        }
        node_of.push(first_dof.len() - 1);
    }
    let nodes = first_dof.len();
    first_dof.push(n);
    // Node graph from the dof pattern, without self loops.
    let pattern = assembly.symbolic();
    let mut xadj: Vec<i32> = Vec::with_capacity(nodes + 1);
    let mut adjncy: Vec<i32> = Vec::new();
    xadj.push(0);
    let mut seen = vec![usize::MAX; nodes];
    for c in 0..nodes {
        for f in first_dof[c]..first_dof[c + 1] {
            for &r in pattern.row_idx_of_col_raw(f) {
                let m = node_of[r];
                if m != c && seen[m] != c {
                    seen[m] = c;
                    adjncy.push(i32::try_from(m).ok()?);
                }
            }
        }
        xadj.push(i32::try_from(adjncy.len()).ok()?);
    }
    let mut nvtxs = i32::try_from(nodes).ok()?;
    let mut perm = vec![0i32; nodes];
    let mut iperm = vec![0i32; nodes];
    // SAFETY: the arrays follow METIS's CSR graph contract (xadj has nvtxs + 1 entries,
    // adjncy holds valid, symmetric, loop-free neighbours) and perm/iperm have nvtxs entries;
    // null weights and options select METIS's defaults.
    let status = unsafe {
        metis_sys::METIS_NodeND(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            std::ptr::null_mut(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        return None;
    }
    // METIS: row i of the permuted matrix is row perm[i] of the original.
    let mut forward = Vec::with_capacity(n);
    for &c in &perm {
        let c = usize::try_from(c).ok()?;
        forward.extend(first_dof[c]..first_dof[c + 1]);
    }
    let mut inverse = vec![0usize; n];
    for (new, &old) in forward.iter().enumerate() {
        inverse[old] = new;
    }
    Some((forward, inverse))
}
