//! Splitting the mesh at a fracturing node along the crack plane, conformingly.
//!
//! The crack plane passes through the node's current position with the separation tensor's
//! eigenvector as normal. Every edge of the node's tets that the plane crosses (and that does
//! not end at the node) is split at the crossing in *every* tet sharing it, so the mesh stays
//! conforming. A crossing closer to an edge end than `snap` × the edge length, or one whose
//! split would leave any child below the radius ratio `min_quality`, snaps to the edge instead
//! (the edge is not cut), so no sliver is created. Then the tets around the node on the negative
//! side of the plane (by centroid) take a copy of the node, and the faces between the two groups
//! become the two faces of the crack — where crossings snapped, the crack follows mesh faces.
//!
//! Edge splits keep the displacement field exactly (P1 fields are linear along edges), and with
//! it velocities and every element's state (children inherit their parent's plastic strain,
//! freeze state and eigenstrain through `parent`). Rest volume is preserved exactly, and so is
//! the lumped mass when it is recomputed from the rest volumes.

use crate::mesh::radius_ratio;
use crate::sim::part::Part;
use nalgebra::Vector3;
use std::collections::{HashMap, HashSet};

/// A tet mesh with the nodal state that must follow a split.
#[derive(Clone, Debug, PartialEq)]
pub struct Fracturable {
    /// Rest positions (m).
    pub rest: Vec<Vector3<f64>>,
    /// Tetrahedra (positively oriented at rest).
    pub tets: Vec<[usize; 4]>,
    /// Displacements (m), 3 per node.
    pub u: Vec<f64>,
    /// Velocities (m/s), 3 per node.
    pub v: Vec<f64>,
    /// For each tet, the element it came from (its own index before any split).
    pub parent: Vec<usize>,
    /// For each node, the node of the mesh this was made from that it is a copy of (a split
    /// node's copy, a pinched node's copy, through any number of splits), itself if none.
    pub node_parent: Vec<usize>,
    /// Further nodal vector fields (3 per node) carried like `u`, e.g. a step's start state.
    pub extra: Vec<Vec<f64>>,
    /// Smallest rest volume an edge split may create (m³; 0 by default): repeated splits in
    /// one place would otherwise shrink elements without bound.
    pub min_volume: f64,
}

/// What a node split did.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeSplit {
    /// The copy of the fractured node, taken by the tets on the negative side.
    pub new_node: usize,
    /// Nodes inserted on crossed edges.
    pub edge_nodes: Vec<usize>,
    /// Crack faces (node triples, as on the positive side) between the two groups.
    pub crack_faces: Vec<[usize; 3]>,
    /// Copies of nodes around the split where material was left joined at a point only.
    pub pinched: Vec<usize>,
}

impl Fracturable {
    /// The mesh and its state, every tet its own parent.
    pub fn new(rest: Vec<Vector3<f64>>, tets: Vec<[usize; 4]>, u: Vec<f64>, v: Vec<f64>) -> Self {
        let parent = (0..tets.len()).collect();
        let node_parent = (0..rest.len()).collect();
        Fracturable {
            rest,
            tets,
            u,
            v,
            parent,
            node_parent,
            extra: Vec::new(),
            min_volume: 0.0,
        }
    }

    /// The rows of this mesh and state that `part` holds, numbered in the part (each element
    /// its own parent, each node its own copy).
    pub fn rows_of(&self, part: &Part) -> Fracturable {
        let rows = |field: &[f64]| part.rows_of(field, 3, false);
        let mut f = Fracturable::new(
            part.nodes.iter().map(|&i| self.rest[i]).collect(),
            part.tets_of(&self.tets),
            rows(&self.u),
            rows(&self.v),
        );
        f.extra = self.extra.iter().map(|x| rows(x)).collect();
        f.min_volume = self.min_volume;
        f
    }

    /// Current position of node `i` (m).
    pub fn position(&self, i: usize) -> Vector3<f64> {
        self.rest[i] + Vector3::new(self.u[3 * i], self.u[3 * i + 1], self.u[3 * i + 2])
    }

    /// Adds a node interpolated at fraction `t` from `a` to `b` (rest position, displacement,
    /// velocity and the extra fields) and returns it.
    fn interpolated_node(&mut self, a: usize, b: usize, t: f64) -> usize {
        let n = self.rest.len();
        self.rest.push(self.rest[a] * (1.0 - t) + self.rest[b] * t);
        self.node_parent
            .push(if a == b { self.node_parent[a] } else { n });
        for k in 0..3 {
            let (ua, ub) = (self.u[3 * a + k], self.u[3 * b + k]);
            self.u.push(ua + t * (ub - ua));
            let (va, vb) = (self.v[3 * a + k], self.v[3 * b + k]);
            self.v.push(va + t * (vb - va));
            for field in &mut self.extra {
                let (xa, xb) = (field[3 * a + k], field[3 * b + k]);
                field.push(xa + t * (xb - xa));
            }
        }
        n
    }

    /// Splits edge (a, b) at fraction `t` in every tet that has it; returns the new node.
    fn split_edge(&mut self, a: usize, b: usize, t: f64) -> usize {
        let p = self.interpolated_node(a, b, t);
        for e in 0..self.tets.len() {
            let tet = self.tets[e];
            if tet.contains(&a) && tet.contains(&b) {
                // Substituting p for b keeps the orientation, likewise p for a.
                self.tets[e] = tet.map(|x| if x == b { p } else { x });
                self.tets.push(tet.map(|x| if x == a { p } else { x }));
                self.parent.push(self.parent[e]);
            }
        }
        p
    }

    /// Smallest rest radius ratio of the two children of every tet with edge (a, b) split at t;
    /// `None` if a child would be smaller than `min_volume`.
    fn split_quality(&self, a: usize, b: usize, t: f64) -> Option<f64> {
        let p = self.rest[a] * (1.0 - t) + self.rest[b] * t;
        let at =
            |tet: &[usize; 4], from: usize| tet.map(|i| if i == from { p } else { self.rest[i] });
        let quality = |x: [Vector3<f64>; 4]| {
            let volume = (x[1] - x[0]).cross(&(x[2] - x[0])).dot(&(x[3] - x[0])) / 6.0;
            (volume >= self.min_volume).then(|| radius_ratio(x))
        };
        let mut smallest = f64::INFINITY;
        for tet in self
            .tets
            .iter()
            .filter(|t| t.contains(&a) && t.contains(&b))
        {
            smallest = smallest.min(quality(at(tet, b))?.min(quality(at(tet, a))?));
        }
        Some(smallest)
    }

    /// Splits `node` along the plane through its current position with unit `normal` (see the
    /// module docs); `snap` in [0, 0.5) is the fraction of an edge within which a crossing snaps
    /// to the edge's end, `min_quality` the smallest radius ratio a split may create. Returns
    /// `None` (and changes nothing) if all of the node's tets lie on one side.
    pub fn split_node(
        &mut self,
        node: usize,
        normal: &Vector3<f64>,
        snap: f64,
        min_quality: f64,
    ) -> Option<NodeSplit> {
        let before = self.clone();
        let origin = self.position(node);
        let side = |f: &Self, i: usize| (f.position(i) - origin).dot(normal);
        let mut edge_nodes = Vec::new();
        let mut snapped: HashSet<(usize, usize)> = HashSet::new();
        // Split crossed edges until none of the node's tets straddles the plane.
        loop {
            let mut crossing = None;
            'search: for tet in self.tets.iter().filter(|t| t.contains(&node)) {
                for (x, y) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                    let (a, b) = (tet[x], tet[y]);
                    if a == node || b == node {
                        continue;
                    }
                    let (da, db) = (side(self, a), side(self, b));
                    if da * db < 0.0 && !snapped.contains(&(a.min(b), a.max(b))) {
                        let t = da / (da - db);
                        if t > snap && t < 1.0 - snap {
                            crossing = Some((a, b, t));
                            break 'search;
                        }
                    }
                }
            }
            let Some((a, b, t)) = crossing else { break };
            // Below the volume bound the crossing snaps whatever `min_quality` is: a cut's node
            // lies on the plane only up to round-off, so the edge between two cuts can cross
            // it again half way, and only this bound ends such cuts when `min_quality` is 0.
            if self.split_quality(a, b, t).is_none_or(|q| q < min_quality) {
                snapped.insert((a.min(b), a.max(b)));
                continue;
            }
            edge_nodes.push(self.split_edge(a, b, t));
        }
        // Sides by centroid; a crossing snapped to an end leaves a tet with vertices on both
        // sides but its centroid decides, and the faces it shares stay whole.
        let star: Vec<usize> = (0..self.tets.len())
            .filter(|&e| self.tets[e].contains(&node))
            .collect();
        let negative: Vec<bool> = star
            .iter()
            .map(|&e| {
                let c = self.tets[e]
                    .iter()
                    .map(|&i| self.position(i))
                    .sum::<Vector3<f64>>()
                    / 4.0;
                (c - origin).dot(normal) < 0.0
            })
            .collect();
        if negative.iter().all(|&n| n) || negative.iter().all(|&n| !n) {
            *self = before;
            return None;
        }
        // Crack faces: faces (through the node) shared by a positive and a negative tet.
        // Per face through the node (sorted key): its positive-side orientation, and whether a
        // positive / negative tet has it.
        type Sides = (Option<[usize; 3]>, bool, bool);
        let mut faces: HashMap<[usize; 3], Sides> = HashMap::new();
        for (&e, &neg) in star.iter().zip(&negative) {
            let t = self.tets[e];
            for f in [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
                let face = [t[f[0]], t[f[1]], t[f[2]]];
                if !face.contains(&node) {
                    continue;
                }
                let mut key = face;
                key.sort_unstable();
                let entry = faces.entry(key).or_insert((None, false, false));
                if neg {
                    entry.2 = true;
                } else {
                    entry.0 = Some(face);
                    entry.1 = true;
                }
            }
        }
        let mut crack_faces: Vec<[usize; 3]> = faces
            .values()
            .filter(|(_, pos, neg)| *pos && *neg)
            .filter_map(|(face, _, _)| *face)
            .collect();
        crack_faces.sort_unstable();
        // Duplicate the node for the negative side.
        let new_node = self.interpolated_node(node, node, 0.0);
        for (&e, &neg) in star.iter().zip(&negative) {
            if neg {
                self.tets[e] = self.tets[e].map(|x| if x == node { new_node } else { x });
            }
        }
        // The split may leave nodes around it where material meets only at the node (or along
        // an edge): give each such group its own copy.
        let mut around: Vec<usize> = self
            .tets
            .iter()
            .filter(|t| t.contains(&node) || t.contains(&new_node))
            .flatten()
            .copied()
            .collect();
        around.sort_unstable();
        around.dedup();
        let pinched = self.separate_pinched(&around);
        Some(NodeSplit {
            new_node,
            edge_nodes,
            crack_faces,
            pinched,
        })
    }

    /// Duplicates every node of `nodes` whose tets form several groups joined only at the
    /// node — not through a face containing it — giving each further group its own copy, and
    /// returns the copies. Such a joint has no area and carries no load; left in place, it
    /// would hold two pieces of a cut body together (and a node shared along an edge only has
    /// the same defect at both of the edge's nodes).
    pub fn separate_pinched(&mut self, nodes: &[usize]) -> Vec<usize> {
        let mut copies = Vec::new();
        for &node in nodes {
            let star: Vec<usize> = (0..self.tets.len())
                .filter(|&e| self.tets[e].contains(&node))
                .collect();
            // Components through faces at the node: two tets share such a face when they
            // share two nodes besides it.
            let mut group: Vec<usize> = (0..star.len()).collect();
            fn root(group: &mut [usize], mut i: usize) -> usize {
                while group[i] != i {
                    i = group[i];
                }
                i
            }
            for a in 0..star.len() {
                for b in a + 1..star.len() {
                    let (ta, tb) = (self.tets[star[a]], self.tets[star[b]]);
                    let shared = ta.iter().filter(|&&i| i != node && tb.contains(&i)).count();
                    if shared == 2 {
                        let (ra, rb) = (root(&mut group, a), root(&mut group, b));
                        group[ra.max(rb)] = ra.min(rb);
                    }
                }
            }
            let roots: Vec<usize> = (0..star.len()).map(|k| root(&mut group, k)).collect();
            let mut distinct = roots.clone();
            distinct.sort_unstable();
            distinct.dedup();
            // The group of the first tet keeps the node.
            for &r in distinct.iter().skip(1) {
                let copy = self.interpolated_node(node, node, 0.0);
                for (k, &e) in star.iter().enumerate() {
                    if roots[k] == r {
                        self.tets[e] = self.tets[e].map(|x| if x == node { copy } else { x });
                    }
                }
                copies.push(copy);
            }
        }
        copies
    }

    /// Rest volume of every tet (m³).
    pub fn volumes(&self) -> Vec<f64> {
        self.tets
            .iter()
            .map(|t| {
                let [a, b, c, d] = t.map(|i| self.rest[i]);
                (b - a).cross(&(c - a)).dot(&(d - a)) / 6.0
            })
            .collect()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::mesh::{box_mesh, TetMesh};

    /// A 4 cm cube of 1 cm cells stretched uniformly along x by 1e-3.
    fn stretched_bar() -> Fracturable {
        let mesh = box_mesh([0.0; 3], [0.04; 3], [4, 4, 4], 6).unwrap();
        let u: Vec<f64> = mesh
            .rest
            .iter()
            .flat_map(|x| [1e-3 * x.x, 0.0, 0.0])
            .collect();
        let v = vec![0.0; u.len()];
        Fracturable::new(mesh.rest.clone(), mesh.tets.clone(), u, v)
    }

    /// A 3 × 3 × 2 cm box of 1 cm cells, its interior nodes moved by up to a fifth of a cell
    /// (so its elements are of many shapes, as an unstructured mesh's), stretched along a
    /// skew direction, with one extra nodal field.
    pub(crate) fn skewed_block() -> Fracturable {
        let mesh = box_mesh([0.0; 3], [0.03, 0.03, 0.02], [3, 3, 2], 6).unwrap();
        let (lo, hi) = mesh.bounding_box();
        let mut state = 12345u64;
        let mut random = move || {
            // A linear congruential sequence: the same mesh in every run.
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let rest: Vec<Vector3<f64>> = (mesh.rest.iter())
            .map(|x| {
                let inside = (0..3).all(|k| x[k] > lo[k] + 1e-9 && x[k] < hi[k] - 1e-9);
                let shift = Vector3::new(random(), random(), random()) * 0.004;
                if inside {
                    x + shift
                } else {
                    *x
                }
            })
            .collect();
        let stretch = Vector3::new(1.0, 0.4, 0.2).normalize();
        let u: Vec<f64> = (rest.iter())
            .flat_map(|x| {
                (stretch * (1e-3 * stretch.dot(x)))
                    .iter()
                    .copied()
                    .collect::<Vec<_>>()
            })
            .collect();
        let v: Vec<f64> = (0..u.len()).map(|k| k as f64 * 1e-3).collect();
        let mut f = Fracturable::new(rest, mesh.tets, u, v);
        f.extra = vec![(0..f.u.len()).map(|k| (k as f64).sin()).collect()];
        f.min_volume = 1e-9;
        f
    }

    /// Every edge of the boundary surface is shared by an even number of boundary faces: no
    /// hanging nodes (their unmatched faces leave edges used once), and a crack inside the body
    /// is a closed slit (edges used twice).
    fn assert_watertight(f: &Fracturable) {
        let rest: Vec<[f64; 3]> = f.rest.iter().map(|x| [x.x, x.y, x.z]).collect();
        let mesh = TetMesh::from_arrays(&rest, f.tets.clone()).expect("valid mesh");
        let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
        for face in mesh.boundary_faces() {
            for k in 0..3 {
                let (a, b) = (face.nodes[k], face.nodes[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        assert!(
            edges.values().all(|&n| n == 2),
            "open or non-conforming boundary"
        );
    }

    #[test]
    fn oblique_split_cuts_edges_conformingly_and_keeps_volume_and_fields() {
        let mut f = stretched_bar();
        let volume: f64 = f.volumes().iter().sum();
        // The centre node, plane tilted so that it crosses edges.
        let node = f
            .rest
            .iter()
            .position(|x| (x - Vector3::new(0.02, 0.02, 0.02)).norm() < 1e-12)
            .unwrap();
        let normal = Vector3::new(1.0, 0.3, 0.2).normalize();
        let q0 = f
            .tets
            .iter()
            .map(|t| radius_ratio(t.map(|i| f.rest[i])))
            .fold(f64::INFINITY, f64::min);
        let split = f.split_node(node, &normal, 0.2, 0.2).expect("a split");
        assert!(
            !split.edge_nodes.is_empty(),
            "the tilted plane crosses edges"
        );
        assert!(!split.crack_faces.is_empty());
        let after: f64 = f.volumes().iter().sum();
        assert!(
            (after - volume).abs() < 1e-12 * volume,
            "volume {after} vs {volume}"
        );
        // No tet below the quality bound (or the mesh's own worst, if lower).
        let q_min = f
            .tets
            .iter()
            .map(|t| radius_ratio(t.map(|i| f.rest[i])))
            .fold(f64::INFINITY, f64::min);
        eprintln!("worst radius ratio after the split {q_min:.4} (mesh {q0:.4})");
        assert!(q_min >= 0.2f64.min(q0), "quality {q_min}");
        // The linear displacement field is kept exactly at the new nodes.
        for &p in split.edge_nodes.iter().chain([&split.new_node]) {
            assert!((f.u[3 * p] - 1e-3 * f.rest[p].x).abs() < 1e-18);
        }
        assert_eq!(f.rest[split.new_node], f.rest[node]);
        assert_eq!(f.parent.len(), f.tets.len());
        assert_watertight(&f);
    }

    #[test]
    fn a_plane_along_faces_splits_without_new_edge_nodes() {
        // The plane x = 2 cm through the node runs along mesh faces: nothing to cut.
        let mut f = stretched_bar();
        let node = f
            .rest
            .iter()
            .position(|x| (x - Vector3::new(0.02, 0.02, 0.02)).norm() < 1e-12)
            .unwrap();
        let split = f
            .split_node(node, &Vector3::x(), 0.1, 0.2)
            .expect("a split");
        assert!(split.edge_nodes.is_empty());
        // The negative side (x < 2 cm) uses the copy, the positive side the original.
        for t in &f.tets {
            let c = t.iter().map(|&i| f.rest[i]).sum::<Vector3<f64>>() / 4.0;
            if t.contains(&split.new_node) {
                assert!(c.x < 0.02);
            }
            if t.contains(&node) {
                assert!(c.x > 0.02);
            }
        }
        assert_watertight(&f);
    }

    #[test]
    fn a_plane_missing_the_star_changes_nothing() {
        // A corner node with a plane that leaves all its tets on one side.
        let mut f = stretched_bar();
        let before = f.clone();
        let corner = f.rest.iter().position(|x| x.norm() < 1e-12).unwrap();
        assert!(f
            .split_node(
                corner,
                &Vector3::new(-1.0, -1.0, -1.0).normalize(),
                0.1,
                0.2
            )
            .is_none());
        assert_eq!(f, before);
    }

    #[test]
    fn cuts_on_the_plane_end_without_a_quality_bound() {
        // A cut's node lies on the plane up to round-off (here ±2e-18 m, either side), so
        // the edge between two cuts "crosses" the plane half way; with no quality bound only
        // the smallest volume a split may create ends the cutting there: node 7 of the skewed
        // block and this normal cut such edges without end if it does not.
        let mut f = skewed_block();
        let volume: f64 = f.volumes().iter().sum();
        let normal = Vector3::new(1.0, 0.3, 0.2).normalize();
        let split = f.split_node(7, &normal, 0.05, 0.0).expect("a split");
        let smallest = f.volumes().into_iter().fold(f64::INFINITY, f64::min);
        eprintln!(
            "{} cuts, smallest element {smallest:.3e} m³",
            split.edge_nodes.len()
        );
        assert!(smallest >= f.min_volume, "an element below the bound");
        let after: f64 = f.volumes().iter().sum();
        // Summing a few hundred volumes of 1e-7 m³: round-off of 1e-15 relative at most.
        assert!((after - volume).abs() < 1e-12 * volume);
        assert_watertight(&f);
    }
}
