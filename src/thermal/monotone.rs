//! Conduction without new extrema on meshes with obtuse tetrahedra.
//!
//! The linear-element conduction matrix couples two nodes of an edge by
//! K_ab = Σ_e k_e V_e ∇λ_a·∇λ_b = −Σ_e k_e l_e cot θ_e / 6 over the elements around the edge
//! (l_e the length of the opposite edge, θ_e the dihedral angle there). Where the opposite
//! dihedral angles are obtuse, K_ab > 0: node a then cools when b warms, and a node can end a
//! step warmer than every node around it (the gallery's Gmsh ball: 0.32 → 0.48 °C). With
//! lumped capacities and backward Euler no temperature leaves the range of the step's start
//! and boundary values when every off-diagonal entry is ≤ 0 (an M-matrix).
//!
//! Where an assembled K_ab > 0, the edge gets the conductance that cancels it,
//! D = K_ab (e_a − e_b)(e_a − e_b)ᵀ (Kuzmin's discrete upwinding, applied to diffusion): row
//! sums stay zero (a uniform temperature stays uniform, heat is conserved), the matrix stays
//! symmetric positive semi-definite, and the edge conducts as if its obtuse angles were right
//! ones. Only edges with an obtuse angle in some element are looked at; a mesh without one
//! (the box generator's) is solved exactly as before.

use super::system::PAIRS;

/// An edge (a, b) that some element's geometry couples positively.
#[derive(Clone, Debug)]
struct ObtuseEdge {
    /// The edge's nodes.
    nodes: (usize, usize),
    /// Every (element, index into [`PAIRS`]) of the edge.
    parts: Vec<(usize, usize)>,
}

/// The edges of a mesh whose conduction coupling can be positive.
#[derive(Clone, Debug, Default)]
pub struct ObtuseEdges {
    edges: Vec<ObtuseEdge>,
}

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
        if !edges.is_empty() {
            for e in 0..tets.len() {
                for p in (0..10).filter(|&p| off_diagonal(p)) {
                    if let Ok(i) = obtuse.binary_search(&key(e, p)) {
                        edges[i].parts.push((e, p));
                    }
                }
            }
        }
        ObtuseEdges { edges }
    }

    /// Number of edges some element couples positively.
    pub fn len(&self) -> usize {
        self.edges.len()
    }

    /// Whether no edge can couple positively.
    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// The corrections for element conductivities `k` (W/(m K)): the edges whose assembled
    /// coupling Σ_e k_e g_e is positive.
    pub fn corrections(&self, k: &[f64], geometry: &[[f64; 10]]) -> Vec<EdgeCorrection> {
        self.edges
            .iter()
            .filter_map(|edge| {
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

/// Adds the corrections' conduction D T to `out` (W per node) for temperatures `t` (°C).
pub fn add_corrected_conduction(corrections: &[EdgeCorrection], t: &[f64], out: &mut [f64]) {
    for c in corrections {
        let (a, b) = c.nodes;
        let flow = c.conductance * (t[a] - t[b]);
        out[a] += flow;
        out[b] -= flow;
    }
}
