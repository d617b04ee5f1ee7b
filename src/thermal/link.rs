//! The heat model of a run and how the mechanics mesh reads it. The heat is solved on the
//! scene's mesh, which fracture never changes (its pattern and symbolic factorisation last
//! the run); a split mechanics mesh reads it by position: every node keeps the scene node it
//! is (nodes of the scene mesh keep their numbers through splits) or the scene element and
//! barycentric weights of its rest position. Cracks therefore conduct heat as if closed: a
//! modelling choice (docs/thermal.md), exact until the first split. On several processes
//! each holds the heat model of its part of the scene's mesh, and its part of the split mesh
//! reads it so (`distributed::part_fracture`).

use super::Heat;
use crate::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

/// The mean of `nodal` over each element's four nodes.
pub fn element_means(nodal: &[f64], tets: &[[usize; 4]]) -> Vec<f64> {
    tets.iter()
        .map(|tet| tet.iter().map(|&i| nodal[i]).sum::<f64>() / 4.0)
        .collect()
}

/// Where a mechanics node reads its temperature.
#[derive(Clone, Copy, Debug, PartialEq)]
enum NodeSource {
    /// The scene node of that number.
    Node(usize),
    /// Inside a scene element, with barycentric weights of its four nodes.
    Inside { element: usize, weights: [f64; 4] },
}

/// The heat model and the map from the (possibly split) mechanics mesh to its mesh.
pub struct HeatLink {
    /// The heat model on the scene's mesh.
    pub heat: Heat,
    scene_rest: Vec<Vector3<f64>>,
    scene_tets: Vec<[usize; 4]>,
    /// The scene element each mechanics element lies in.
    element_source: Vec<usize>,
    node_source: Vec<NodeSource>,
}

impl HeatLink {
    /// The link of `heat`, solved on `mesh`, to the same mesh.
    pub fn new(heat: Heat, mesh: &TetMesh) -> Self {
        HeatLink {
            heat,
            scene_rest: mesh.rest.clone(),
            scene_tets: mesh.tets.clone(),
            element_source: (0..mesh.num_tets()).collect(),
            node_source: (0..mesh.num_nodes()).map(NodeSource::Node).collect(),
        }
    }

    /// Temperature of every mechanics node (°C) for the scene-mesh temperatures `t`.
    pub fn node_temperatures(&self, t: &[f64]) -> Vec<f64> {
        self.node_source
            .iter()
            .map(|s| match *s {
                NodeSource::Node(i) => t[i],
                NodeSource::Inside { element, weights } => {
                    let nodes = self.scene_tets[element];
                    (0..4).map(|k| weights[k] * t[nodes[k]]).sum()
                }
            })
            .collect()
    }

    /// Ice fraction and temperature (°C) of every mechanics element (of nodes `tets`) at the
    /// scene-mesh temperatures `t`: the means of its nodes'. With lumped capacity each node
    /// holds a quarter of the mass of each of its elements and freezes it by giving up its
    /// latent heat, so the fraction is the share of the element's mass the heat model has
    /// frozen (on the unsplit mesh: exactly the heat model's element fraction).
    pub fn element_states(&self, t: &[f64], tets: &[[usize; 4]]) -> (Vec<f64>, Vec<f64>) {
        let phases = self.heat.phases();
        let nodal = self.node_temperatures(t);
        let ice: Vec<f64> = nodal.iter().map(|&x| phases.ice_fraction(x)).collect();
        (element_means(&ice, tets), element_means(&nodal, tets))
    }

    /// Temperature of every mechanics element (of nodes `tets`, °C) at the scene-mesh
    /// temperatures `t`: the mean of its nodes' (the temperature at its centroid).
    pub fn element_temperatures(&self, t: &[f64], tets: &[[usize; 4]]) -> Vec<f64> {
        element_means(&self.node_temperatures(t), tets)
    }

    /// The link to a mechanics mesh made by splitting the current one: element `e` of nodes
    /// `tets[e]` came from element `parent[e]`; nodes beyond the scene's are placed by their
    /// `rest` position in the scene element their element lies in.
    pub fn remeshed(self, rest: &[Vector3<f64>], tets: &[[usize; 4]], parent: &[usize]) -> Self {
        let element_source: Vec<usize> = parent.iter().map(|&p| self.element_source[p]).collect();
        let scene_nodes = self.scene_rest.len();
        self.relinked((rest, tets), element_source, |i| {
            (i < scene_nodes).then_some(i)
        })
    }

    /// The link to the mechanics mesh of rest positions `rest` (m) and elements `tets`,
    /// element `e` lying in element `element_source[e]` of the heat model's mesh: node `i` is
    /// the heat mesh's node `heat_node(i)` where that is one, else it is placed by its rest
    /// position in the heat element of the first element using it. (A process's part of a
    /// mesh split on the processes' parts reads the heat model on its part of the scene's
    /// mesh so.)
    pub fn relinked(
        mut self,
        (rest, tets): (&[Vector3<f64>], &[[usize; 4]]),
        element_source: Vec<usize>,
        heat_node: impl Fn(usize) -> Option<usize>,
    ) -> Self {
        let mut node_source: Vec<Option<NodeSource>> = (0..rest.len())
            .map(|i| heat_node(i).map(NodeSource::Node))
            .collect();
        for (tet, &element) in tets.iter().zip(&element_source) {
            for &i in tet {
                if node_source[i].is_none() {
                    node_source[i] = Some(NodeSource::Inside {
                        element,
                        weights: self.barycentric(element, rest[i]),
                    });
                }
            }
        }
        self.element_source = element_source;
        // A node in no element (none after a split) reads heat node 0: it is never drawn.
        self.node_source = node_source
            .into_iter()
            .map(|s| s.unwrap_or(NodeSource::Node(0)))
            .collect();
        self
    }

    /// Barycentric weights of `x` in scene element `e` (clamped to it and renormalised: a
    /// node of a split lies on its element up to round-off).
    fn barycentric(&self, e: usize, x: Vector3<f64>) -> [f64; 4] {
        let p = self.scene_tets[e].map(|i| self.scene_rest[i]);
        let d = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        let Some(inv) = d.try_inverse() else {
            return [0.25; 4];
        };
        let l = inv * (x - p[0]);
        let w = [1.0 - l.sum(), l.x, l.y, l.z].map(|v| v.clamp(0.0, 1.0));
        let sum: f64 = w.iter().sum();
        w.map(|v| v / sum)
    }
}
