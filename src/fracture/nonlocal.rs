//! Nonlocal separation: the criterion read over a fixed length ℓ instead of one node.
//!
//! A node's separation v⁺/A(n) is a nodal force over a nodal area, so it resolves the stress
//! at the scale of the elements around the node. At a crack's front the stress grows like
//! 1/√r; a finer mesh puts its front node closer to the tip and reads a larger stress there,
//! so the same crack runs further on a finer mesh, and where the stress hovers near τ the
//! outcome turns on mesh-scale detail. Averaging over a fixed length ℓ (a material scale of
//! the criterion, not of the mesh) reads every mesh the same way once its elements are
//! smaller than ℓ:
//!
//! ```text
//! ς̄ᵢ = Σⱼ wᵢⱼ ςⱼ,   v̄⁺, n̄ = largest eigenpair of ς̄ᵢ,   Āᵢ = Σⱼ wᵢⱼ Aⱼ(n̄),
//! wᵢⱼ = (1 − (dᵢⱼ/ℓ)²)²  for dᵢⱼ < ℓ,
//! ```
//!
//! over the eligible nodes j, with dᵢⱼ the shortest path from i to j along the mesh's edges
//! (rest lengths). The path runs through the material: it goes around a crack, never across
//! it, so the two sides of a crack do not see each other's stress. The criterion is then
//! v̄⁺/Āᵢ > τ with the split plane normal to n̄. A uniform stress s reads s exactly (ςⱼ =
//! s Aⱼ(n) n nᵀ, so v̄⁺ = s Σ wᵢⱼ Aⱼ(n) = s Āᵢ); ℓ shorter than every edge is the local
//! criterion.

use super::{largest_eigen, NodeForces, NodeSeparation};
use crate::mesh::TetMesh;
use nalgebra::Vector3;
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// Each node's neighbours within the averaging length and their weights.
#[derive(Clone, Debug, Default)]
pub struct Averaging {
    /// Neighbours of node i (itself first): `neighbours[ptr[i]..ptr[i + 1]]`.
    ptr: Vec<usize>,
    neighbours: Vec<(u32, f64)>,
}

impl Averaging {
    /// The neighbourhoods of `mesh`'s nodes for the averaging length `length` (m, > 0).
    pub fn new(mesh: &TetMesh, length: f64) -> Self {
        Self::of(mesh, length, None)
    }

    /// As [`Averaging::new`], for the nodes `sources` marks only (every other node has no
    /// neighbours): on a process's part, the nodes it owns, whose neighbourhoods are whole
    /// when the part holds every element around the nodes within `length` of them (see
    /// [`within`]).
    pub fn of(mesh: &TetMesh, length: f64, sources: Option<&[bool]>) -> Self {
        Self::on(&Edges::of_mesh(&mesh.rest, &mesh.tets), length, sources)
    }

    /// As [`Averaging::of`], on the nodes and edges `edges` (the nodes a process's averages
    /// read, gathered from their owners).
    pub fn on(edges: &Edges, length: f64, sources: Option<&[bool]>) -> Self {
        let nodes = edges.rest.len();
        let mut averaging = Averaging {
            ptr: vec![0],
            neighbours: Vec::new(),
        };
        let mut search = BoundedSearch::new(nodes);
        for source in 0..nodes {
            if sources.is_none_or(|s| s[source]) {
                search.run(edges, &[source], length);
                for &j in &search.reached {
                    let r = search.distance[j as usize] / length;
                    averaging.neighbours.push((j, (1.0 - r * r).powi(2)));
                }
                search.clear();
            }
            averaging.ptr.push(averaging.neighbours.len());
        }
        averaging
    }

    /// The averaged separation of every node from the nodes' own (see the module docs);
    /// every Aⱼ is at least `area_floor` (m²).
    pub(crate) fn average(&self, nodes: &[NodeForces], area_floor: f64) -> Vec<NodeSeparation> {
        (0..nodes.len())
            .map(|i| {
                // An ineligible node is not averaged: it reads its own (zero next to water).
                if !nodes[i].eligible {
                    return nodes[i].local(area_floor);
                }
                let around = &self.neighbours[self.ptr[i]..self.ptr[i + 1]];
                let eligible = |j: &&(u32, f64)| nodes[j.0 as usize].eligible;
                let tensor = around
                    .iter()
                    .filter(eligible)
                    .map(|&(j, w)| w * nodes[j as usize].tensor)
                    .sum();
                let (largest, normal) = largest_eigen(&tensor);
                let area = around
                    .iter()
                    .filter(eligible)
                    .map(|&(j, w)| w * nodes[j as usize].area(&normal, area_floor))
                    .sum();
                NodeSeparation {
                    tensor,
                    largest,
                    normal,
                    area,
                    eligible: true,
                }
            })
            .collect()
    }
}

/// Whether each node of the mesh with rest positions `rest` (m) and elements `tets` lies
/// within `length` (m) of a node `sources` marks, along the mesh's edges (rest lengths): the
/// nodes whose separations the sources' averages read. A process whose part holds every
/// element around these nodes finds its owned nodes' neighbourhoods, and their separations,
/// as the whole mesh gives them.
pub fn within(
    rest: &[Vector3<f64>],
    tets: &[[usize; 4]],
    length: f64,
    sources: &[bool],
) -> Vec<bool> {
    Edges::of_mesh(rest, tets).within(length, sources)
}

/// Nodes (rest positions) and the edges between them, both ways, sorted: node a's neighbours
/// are `edges[start[a]..start[a + 1]]`. The searches walk a node's edges in this order, so
/// two graphs that number their nodes in the same order and give a node the same edges find
/// the same neighbourhoods, to the bit.
#[derive(Clone, Debug)]
pub struct Edges {
    rest: Vec<Vector3<f64>>,
    start: Vec<usize>,
    edges: Vec<(u32, u32)>,
}

impl Edges {
    /// The nodes at `rest` (m) and the edges of the elements `tets`.
    pub fn of_mesh(rest: &[Vector3<f64>], tets: &[[usize; 4]]) -> Self {
        let mut edges: Vec<(u32, u32)> = Vec::with_capacity(12 * tets.len());
        for tet in tets {
            for a in 0..4 {
                for b in a + 1..4 {
                    edges.push((tet[a] as u32, tet[b] as u32));
                }
            }
        }
        Self::new(rest.to_vec(), edges)
    }

    /// The nodes at `rest` (m) and the edges `edges` (each given one way or both, repeats
    /// allowed).
    pub fn new(rest: Vec<Vector3<f64>>, mut edges: Vec<(u32, u32)>) -> Self {
        let nodes = rest.len();
        let reversed: Vec<(u32, u32)> = edges.iter().map(|&(a, b)| (b, a)).collect();
        edges.extend(reversed);
        edges.sort_unstable();
        edges.dedup();
        let mut start = vec![0usize; nodes + 1];
        for &(a, _) in &edges {
            start[a as usize + 1] += 1;
        }
        for i in 0..nodes {
            start[i + 1] += start[i];
        }
        Edges { rest, start, edges }
    }

    /// Whether each node lies within `length` (m) of a node `sources` marks, along the edges.
    pub fn within(&self, length: f64, sources: &[bool]) -> Vec<bool> {
        let nodes = self.rest.len();
        let mut search = BoundedSearch::new(nodes);
        let from: Vec<usize> = (0..nodes).filter(|&i| sources[i]).collect();
        search.run(self, &from, length);
        let mut reached = vec![false; nodes];
        for &j in &search.reached {
            reached[j as usize] = true;
        }
        reached
    }

    /// Node `a`'s neighbours, ascending.
    pub fn neighbours(&self, a: usize) -> impl Iterator<Item = usize> + '_ {
        self.edges[self.start[a]..self.start[a + 1]]
            .iter()
            .map(|&(_, b)| b as usize)
    }
}

/// Dijkstra's search bounded by a length, its arrays kept from search to search.
struct BoundedSearch {
    /// Shortest path length from the sources (m; infinite where not reached).
    distance: Vec<f64>,
    /// Reached nodes, in the order first reached.
    reached: Vec<u32>,
}

impl BoundedSearch {
    fn new(nodes: usize) -> Self {
        BoundedSearch {
            distance: vec![f64::INFINITY; nodes],
            reached: Vec::new(),
        }
    }

    /// Finds every node closer than `length` to one of `sources` along the edges of `graph`
    /// (rest lengths). Distances are ordered as integer nanometres in the heap
    /// (exact enough for weights, and no float ordering to work around); ties go to the
    /// lower node.
    fn run(&mut self, graph: &Edges, sources: &[usize], length: f64) {
        let rest = &graph.rest;
        let mut heap = BinaryHeap::new();
        for &source in sources {
            self.distance[source] = 0.0;
            self.reached.push(source as u32);
            heap.push(Reverse((0u64, source as u32)));
        }
        while let Some(Reverse((_, a))) = heap.pop() {
            let a = a as usize;
            let da = self.distance[a];
            for &(_, b) in &graph.edges[graph.start[a]..graph.start[a + 1]] {
                let b = b as usize;
                let d = da + (rest[a] - rest[b]).norm();
                if d < length && d < self.distance[b] {
                    if self.distance[b].is_infinite() {
                        self.reached.push(b as u32);
                    }
                    self.distance[b] = d;
                    heap.push(Reverse(((d * 1e9) as u64, b as u32)));
                }
            }
        }
    }

    /// Forgets the last search.
    fn clear(&mut self) {
        for &j in &self.reached {
            self.distance[j as usize] = f64::INFINITY;
        }
        self.reached.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::tests::ICE;
    use crate::fem::ElasticModel;
    use crate::fracture::separation;
    use crate::mesh::box_mesh;
    use crate::physics::elasticity::Elasticity;
    use nalgebra::{Matrix3, Vector3};

    /// Local and averaged separations of a 6 cm cube of 1 cm cells (6 tets each) under the
    /// uniform uniaxial stress `s` along x (linear elasticity: exact nodal forces), averaged
    /// over `length`; and the index of the centre node.
    fn uniaxial(s: f64, length: f64) -> (Vec<NodeSeparation>, Vec<NodeSeparation>, usize) {
        let mesh = box_mesh([0.0; 3], [0.06; 3], [6, 6, 6], 6).unwrap();
        let el = Elasticity::new(&mesh, ICE, ElasticModel::Linear);
        let (e, nu) = (ICE.young(), ICE.poisson());
        let g = Matrix3::from_diagonal(&Vector3::new(s / e, -nu * s / e, -nu * s / e));
        let u: Vec<f64> = mesh.rest.iter().flat_map(|x| (g * x).data.0[0]).collect();
        let history = el.initial_history();
        let local = separation(&el, &history, &mesh.tets, &u, &[], 0.0, None);
        let averaging = Averaging::new(&mesh, length);
        let averaged = separation(&el, &history, &mesh.tets, &u, &[], 0.0, Some(&averaging));
        let centre = mesh
            .rest
            .iter()
            .position(|x| (x - Vector3::repeat(0.03)).norm() < 1e-12)
            .unwrap();
        (local, averaged, centre)
    }

    #[test]
    fn a_uniform_stress_reads_the_same_averaged() {
        // ℓ = 1.5 cm: the centre's neighbourhood (edges of 1 and 1.41 cm) stays inside the
        // cube, where every node's ς is s Aⱼ(n) n nᵀ; the average is then s exactly (round-off).
        let s = 3e6;
        let (local, averaged, centre) = uniaxial(s, 0.015);
        let a = &averaged[centre];
        assert!((a.stress() - s).abs() < 1e-9 * s, "{} Pa", a.stress());
        assert!(a.normal.x.abs() > 1.0 - 1e-12, "normal {}", a.normal);
        // It is an average: more area than the node's own.
        assert!(
            a.area > 2.0 * local[centre].area,
            "{} vs {}",
            a.area,
            local[centre].area
        );
    }

    #[test]
    fn a_length_below_every_edge_is_the_local_criterion() {
        let (local, averaged, _) = uniaxial(3e6, 0.005);
        assert_eq!(local, averaged);
    }

    #[test]
    fn the_average_does_not_reach_across_a_gap() {
        // Two cubes face to face (the two sides of a crack: coincident nodes, no shared
        // element): no node of one is a neighbour of the other, however long ℓ.
        let a = box_mesh([0.0; 3], [0.02; 3], [2, 2, 2], 6).unwrap();
        let b = box_mesh([0.02, 0.0, 0.0], [0.02; 3], [2, 2, 2], 6).unwrap();
        let first = a.num_nodes();
        let mesh = TetMesh::concat(vec![a, b]).unwrap();
        let averaging = Averaging::new(&mesh, 1.0);
        for i in 0..mesh.num_nodes() {
            let around = &averaging.neighbours[averaging.ptr[i]..averaging.ptr[i + 1]];
            assert_eq!(around.len(), first, "node {i}: the whole of its own cube");
            assert!(around
                .iter()
                .all(|&(j, _)| (j as usize >= first) == (i >= first)));
            assert_eq!(around[0], (i as u32, 1.0), "itself first, at full weight");
        }
    }

    #[test]
    fn a_graph_given_by_its_edges_averages_as_the_mesh_does() {
        // The edges of a 3 cm cube's elements given one way each, in reverse and repeated
        // (as a process gathers them from several owners): the same neighbourhoods, to the
        // bit, and every node's neighbours ascending.
        let mesh = box_mesh([0.0; 3], [0.03; 3], [3, 3, 3], 6).unwrap();
        let mut edges = Vec::new();
        for tet in mesh.tets.iter().rev() {
            for a in 0..4 {
                for b in 0..4 {
                    if a != b {
                        edges.push((tet[a] as u32, tet[b] as u32));
                    }
                }
            }
        }
        let given = Edges::new(mesh.rest.clone(), edges);
        let from_mesh = Edges::of_mesh(&mesh.rest, &mesh.tets);
        for a in 0..mesh.num_nodes() {
            let around: Vec<usize> = given.neighbours(a).collect();
            assert!(around.windows(2).all(|w| w[0] < w[1]));
            assert_eq!(around, from_mesh.neighbours(a).collect::<Vec<_>>());
        }
        let (x, y) = (
            Averaging::on(&given, 0.015, None),
            Averaging::new(&mesh, 0.015),
        );
        assert_eq!((x.ptr, x.neighbours), (y.ptr, y.neighbours));
    }

    #[test]
    fn the_nodes_within_reach_of_some_nodes_are_their_neighbourhoods() {
        // Every other node of a 4 cm cube of 1 cm cells, ℓ = 2.5 cm: `of` keeps their
        // neighbourhoods (and no other node's), and `within` is the union of them.
        let mesh = box_mesh([0.0; 3], [0.04; 3], [4, 4, 4], 6).unwrap();
        let sources: Vec<bool> = (0..mesh.num_nodes()).map(|i| i % 7 == 0).collect();
        let all = Averaging::new(&mesh, 0.025);
        let some = Averaging::of(&mesh, 0.025, Some(&sources));
        let reached = within(&mesh.rest, &mesh.tets, 0.025, &sources);
        let mut union = vec![false; mesh.num_nodes()];
        for (i, &source) in sources.iter().enumerate() {
            let got = &some.neighbours[some.ptr[i]..some.ptr[i + 1]];
            if source {
                assert_eq!(got, &all.neighbours[all.ptr[i]..all.ptr[i + 1]]);
                for &(j, _) in got {
                    union[j as usize] = true;
                }
            } else {
                assert!(got.is_empty());
            }
        }
        assert_eq!(reached, union);
        assert!(reached.iter().filter(|&&r| r).count() > sources.iter().filter(|&&s| s).count());
    }
}
