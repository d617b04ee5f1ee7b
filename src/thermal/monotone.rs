//! Conduction without new extrema on meshes with obtuse tetrahedra.
//!
//! The linear-element conduction matrix couples two nodes of an edge by
//! K_ab = Σ_e k_e V_e ∇λ_a·∇λ_b = −Σ_e k_e l_e cot θ_e / 6 over the elements around the edge
//! (l_e the length of the opposite edge, θ_e the dihedral angle there). Where the opposite
//! dihedral angles are obtuse, K_ab > 0: node a then cools when b warms, and a node can end a
//! step warmer than every node around it and than it was (the gallery's Gmsh ball). With
//! lumped capacities and backward Euler a node whose row has no positive coupling cannot: its
//! new temperature lies within its old one, its neighbours' new ones and its air's (a local
//! discrete maximum principle).
//!
//! Cancelling every positive coupling (K_ab (e_a − e_b)(e_a − e_b)ᵀ added: discrete upwinding)
//! guarantees that everywhere, but a Gmsh mesh has a positive coupling on about a quarter of
//! its edges, and the added conduction does not vanish as the mesh is refined: a ball cooled
//! in air then cools 7–9 % too fast on every mesh (`validation/heat_obtuse_ball.md`). So the
//! step is solved with the plain P1 matrix first; a node that ends it as a new local extremum
//! gets its positive couplings cancelled, and the step is solved again, until no node is one.
//! Rows only lose positive couplings, so this ends, at worst with every one cancelled; a step
//! that makes no new extremum — most steps on most meshes — is plain P1, second order. The
//! cancelling conductance keeps row sums zero (heat is conserved), symmetry and positive
//! definiteness.

use super::system::PAIRS;

/// An edge (a, b) that some element's geometry couples positively.
#[derive(Clone, Debug)]
struct ObtuseEdge {
    /// The edge's nodes.
    nodes: (usize, usize),
    /// Every (element, index into [`PAIRS`]) of the edge.
    parts: Vec<(usize, usize)>,
}

/// The edges of a mesh whose conduction coupling can be positive, and their nodes.
#[derive(Clone, Debug, Default)]
pub struct ObtuseEdges {
    edges: Vec<ObtuseEdge>,
    /// The nodes on such edges, each with its neighbours (the nodes it shares an element
    /// with) and the indices of its such edges.
    nodes: Vec<ObtuseNode>,
}

/// A node on an edge whose coupling can be positive.
#[derive(Clone, Debug)]
struct ObtuseNode {
    node: usize,
    neighbours: Vec<usize>,
    edges: Vec<usize>,
}

/// Temperatures (°C) past a node's bounds by more than this are a new extremum: far above the
/// heat Newton's tolerance, far below anything the front or the stresses resolve.
pub const EXTREMUM_TOLERANCE: f64 = 1e-9;

/// The cancelling conductance of one edge in one step: (a, b, K_ab > 0 in W/K), with the
/// (element, pair) whose matrix slot holds the edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeCorrection {
    /// The edge's nodes.
    pub nodes: (usize, usize),
    /// The assembled coupling it cancels (W/K).
    pub conductance: f64,
    /// An element of the edge and the edge's index into [`PAIRS`] there.
    pub part: (usize, usize),
}

impl ObtuseEdges {
    /// The edges of `tets` that some element couples positively, from each element's
    /// V ∇λ_a·∇λ_b for the [`PAIRS`] (`geometry`, m).
    pub fn new(tets: &[[usize; 4]], geometry: &[[f64; 10]]) -> Self {
        let off_diagonal = |p: usize| PAIRS[p].0 != PAIRS[p].1;
        let key = |e: usize, p: usize| {
            let (a, b) = (tets[e][PAIRS[p].0], tets[e][PAIRS[p].1]);
            (a.min(b), a.max(b))
        };
        let mut obtuse: Vec<(usize, usize)> = geometry
            .iter()
            .enumerate()
            .flat_map(|(e, g)| {
                (0..10)
                    .filter(move |&p| off_diagonal(p) && g[p] > 0.0)
                    .map(move |p| (e, p))
            })
            .map(|(e, p)| key(e, p))
            .collect();
        obtuse.sort_unstable();
        obtuse.dedup();
        let mut edges: Vec<ObtuseEdge> = obtuse
            .iter()
            .map(|&nodes| ObtuseEdge {
                nodes,
                parts: Vec::new(),
            })
            .collect();
        if edges.is_empty() {
            return ObtuseEdges::default();
        }
        for e in 0..tets.len() {
            for p in (0..10).filter(|&p| off_diagonal(p)) {
                if let Ok(i) = obtuse.binary_search(&key(e, p)) {
                    edges[i].parts.push((e, p));
                }
            }
        }
        let mut on_edges: Vec<usize> = obtuse.iter().flat_map(|&(a, b)| [a, b]).collect();
        on_edges.sort_unstable();
        on_edges.dedup();
        let mut nodes: Vec<ObtuseNode> = on_edges
            .iter()
            .map(|&node| ObtuseNode {
                node,
                neighbours: Vec::new(),
                edges: Vec::new(),
            })
            .collect();
        for t in tets {
            for &a in t {
                if let Ok(i) = on_edges.binary_search(&a) {
                    nodes[i].neighbours.extend(t.iter().filter(|&&b| b != a));
                }
            }
        }
        for (index, &(a, b)) in obtuse.iter().enumerate() {
            for n in [a, b] {
                let i = on_edges.binary_search(&n).expect("an edge's node");
                nodes[i].edges.push(index);
            }
        }
        for n in &mut nodes {
            n.neighbours.sort_unstable();
            n.neighbours.dedup();
        }
        ObtuseEdges { edges, nodes }
    }

    /// The nodes of each edge some element couples positively.
    pub fn edge_nodes(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.edges.iter().map(|e| e.nodes)
    }

    /// Number of edges some element couples positively.
    pub fn len(&self) -> usize {
        self.edges.len()
    }

    /// Whether no edge can couple positively.
    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// The corrections for element conductivities `k` (W/(m K)): the edges marked `cancel`
    /// whose assembled coupling Σ_e k_e g_e is positive.
    pub fn corrections(
        &self,
        k: &[f64],
        geometry: &[[f64; 10]],
        cancel: &[bool],
    ) -> Vec<EdgeCorrection> {
        self.edges
            .iter()
            .zip(cancel)
            .filter(|(_, &c)| c)
            .filter_map(|(edge, _)| {
                let coupling: f64 = edge.parts.iter().map(|&(e, p)| k[e] * geometry[e][p]).sum();
                (coupling > 0.0).then(|| EdgeCorrection {
                    nodes: edge.nodes,
                    conductance: coupling,
                    part: edge.parts[0],
                })
            })
            .collect()
    }
}

impl ObtuseEdges {
    /// Marks in `cancel` the edges of every node that ended a step as a new local extremum,
    /// and returns how many were newly marked. A node's bounds are its temperature at the
    /// step's start `before`, its neighbours' at the end `after` and, where it convects
    /// (`convects`), its air's `air` (°C); nodes not `free` are held and not checked.
    pub fn mark_extrema(
        &self,
        before: &[f64],
        after: &[f64],
        air: impl Fn(usize) -> Option<f64>,
        free: impl Fn(usize) -> bool,
        cancel: &mut [bool],
    ) -> usize {
        let mut marked = 0;
        for n in self.nodes.iter().filter(|n| free(n.node)) {
            let mut lo = before[n.node];
            let mut hi = lo;
            for &j in &n.neighbours {
                lo = lo.min(after[j]);
                hi = hi.max(after[j]);
            }
            if let Some(t) = air(n.node) {
                lo = lo.min(t);
                hi = hi.max(t);
            }
            let t = after[n.node];
            if t > hi + EXTREMUM_TOLERANCE || t < lo - EXTREMUM_TOLERANCE {
                for &e in &n.edges {
                    marked += usize::from(!cancel[e]);
                    cancel[e] = true;
                }
            }
        }
        marked
    }
}

/// Adds the corrections' conduction D T to `out` (W per node) for temperatures `t` (°C).
pub fn add_corrected_conduction(corrections: &[EdgeCorrection], t: &[f64], out: &mut [f64]) {
    for c in corrections {
        let (a, b) = c.nodes;
        let flow = c.conductance * (t[a] - t[b]);
        out[a] += flow;
        out[b] -= flow;
    }
}
