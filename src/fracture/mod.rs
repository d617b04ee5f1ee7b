//! Fracture criterion of O'Brien & Hodgins (1999) as the paper uses it (its §3; see
//! docs/numerics.md#fracture): the separation tensor of every node and its largest eigenvalue,
//! and the conforming node split along the crack plane.
//!
//! Per element, the stress is split by its eigen-decomposition into a tensile part
//! σ⁺ = Σ max(0, vᵢ) nᵢnᵢᵀ and a compressive part σ⁻ = Σ min(0, vᵢ) nᵢnᵢᵀ; each part exerts
//! nodal forces by the elastic force formula, f = −V R σ F*⁻ᵀ ∇Nᵢ in the world frame (σ the
//! corotated stress in the element's frame, R its rotation, F* the natural shape of its strain
//! offset (`fem::StrainOffset`); the linear model has R = I and no offset factor) — exactly
//! the forces the simulation balances, as the element's law gives them
//! (`fem::stress_forces`). The stress is the one the step converged to:
//! returned onto the yield surface, and with the nodal volumetric energy the deviatoric stress
//! plus the element pressure acting through its volume change. At node i, with F± = Σₑ f± and
//! m(a) = a aᵀ/|a| (0 for a = 0),
//!
//! ```text
//! ς = ½ ( −m(F⁺) + Σₑ m(f⁺) + m(F⁻) − Σₑ m(f⁻) )
//! ```
//!
//! Its largest eigenvalue v⁺ is a force (N); its eigenvector the crack normal n. Toughness is
//! given as a stress (Pa, the paper's 3.0e6 N/m² — ice's tensile strength): the node fractures
//! when v⁺ exceeds τ A(n), with A(n) = ½ Σₑ Vₑ |n · R F*⁻ᵀ∇Nᵢ| the node's share of the plane
//! through it with normal n, at least [`area_floor`]. For a uniform uniaxial stress s along n,
//! v⁺ = s A(n) exactly (tested), and on a grid A(n) is the node's cross-section h_y h_z: v⁺ is
//! the force the node's share of the plane carries, and the criterion v⁺/A > τ is mesh
//! independent, unlike a force threshold (see the calibration under "Toughness is a stress" in
//! docs/numerics.md#fracture). Only ice fractures: elements that hold ice (freeze state s > 0,
//! partly frozen ones with the stress the solve balanced) contribute, and a node touching an
//! element that is still all water gets ς = 0 — the water's pressure, which
//! balances the ice there, is not in the sums, and the unbalanced ice forces would otherwise
//! read as separation all along the freezing front. A node is thus eligible once the front
//! has passed it, whatever the element size; waiting for its whole star to finish freezing
//! would delay it by the time the front takes to cross an element.
//!
//! `driver` applies the criterion between time steps, `split` remeshes, `cracks` extracts the
//! crack surfaces.

pub mod cracks;
pub mod driver;
pub mod nonlocal;
pub mod patch;
pub mod split;

pub use driver::{Fracture, FractureEvent, FractureReport, FractureSettings};
pub use nonlocal::Averaging;

use crate::fem::{stress_forces, StrainOffset};
use crate::physics::elasticity::Elasticity;
use crate::physics::history::ElementHistory;
use crate::sim::Collective;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// The separation tensor of one node and what the criterion needs from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeSeparation {
    /// ς (N).
    pub tensor: Matrix3<f64>,
    /// Largest eigenvalue v⁺ (N).
    pub largest: f64,
    /// Its unit eigenvector: the crack normal.
    pub normal: Vector3<f64>,
    /// The node's share A(n) of the plane with that normal (m²), at least the area floor.
    pub area: f64,
    /// Whether the criterion applies: every element around the node holds ice (freeze state
    /// s > 0, however little frozen; `ElementHistory::holds_ice`).
    pub eligible: bool,
}

impl NodeSeparation {
    /// v⁺ / A(n) (Pa): compared against the toughness.
    pub fn stress(&self) -> f64 {
        if self.area > 0.0 {
            self.largest / self.area
        } else {
            0.0
        }
    }
}

/// The smallest area A(n) of a node (m²) for a mesh like `mesh`: ¼ h², with h = (6 V̄)^⅓ the
/// mesh's length scale from its mean element volume V̄ (the cell size of a box mesh of six
/// tets per cell).
///
/// A(n) is the node's share of the crack plane through it. Next to a small element (a sliver
/// left by an earlier split) or on a crack face it can be far below what a node of the scene's
/// mesh has (6e-7 m² against ~1e-3 m² in the paper's scene), and v⁺/A(n) then reads a modest
/// nodal force as a huge stress: one node read 5e8 Pa from 330 N. The floor is what a node on
/// an edge of a box mesh has for a plane across it (h²/4), and it stays tied to the scene's
/// mesh (evaluated once, before any split), so it scales with the mesh like A(n) does.
pub fn area_floor(mesh: &crate::mesh::TetMesh) -> f64 {
    area_floor_of(mesh.volume(), mesh.num_tets())
}

/// [`area_floor`] of a mesh of `elements` elements of rest volume `volume` (m³) in all.
pub fn area_floor_of(volume: f64, elements: usize) -> f64 {
    let h = (6.0 * volume / elements as f64).cbrt();
    0.25 * h * h
}

/// m(a) = a aᵀ / |a|, 0 for a = 0.
fn m(a: &Vector3<f64>) -> Matrix3<f64> {
    let n = a.norm();
    if n > 0.0 {
        a * a.transpose() / n
    } else {
        Matrix3::zeros()
    }
}

/// Tensile and compressive parts of a symmetric tensor.
fn split(sigma: &Matrix3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let eig = SymmetricEigen::new(*sigma);
    let (mut plus, mut minus) = (Matrix3::zeros(), Matrix3::zeros());
    for k in 0..3 {
        let n = eig.eigenvectors.column(k);
        let outer = n * n.transpose();
        let v = eig.eigenvalues[k];
        if v > 0.0 {
            plus += v * outer;
        } else {
            minus += v * outer;
        }
    }
    (plus, minus)
}

/// Separation tensors of every node of `tets` at displacements `u` (m), with `pressing` the
/// contact forces on the nodes (N, 3 per node, normal and friction; empty for none) and
/// `area_floor` the smallest A(n) (m², see [`area_floor`]); with `averaging`, each node's
/// separation is the nonlocal average over its neighbourhood (see [`nonlocal`]).
///
/// Contact forces push (and rub), and they are counted with the compressive forces (in F⁻ and
/// Σ m(f⁻)): a node on a closed crack or on a container wall is then judged like one inside
/// the ice, where the neighbouring material supplies that push. Leaving them out would read
/// the unbalanced compression of such a node as separation: m(F⁻) − Σ m(f⁻) is not negative
/// semi-definite when the f⁻ are not parallel (two unit forces at right angles leave +0.41
/// along their difference), and in the freezing container, where walls press the ice at
/// 1e9 Pa, it read as separation stresses of 1e9–1e10 Pa on the wall nodes.
pub fn separation(
    elasticity: &Elasticity,
    history: &ElementHistory,
    tets: &[[usize; 4]],
    u: &[f64],
    pressing: &[f64],
    area_floor: f64,
    averaging: Option<&Averaging>,
) -> Vec<NodeSeparation> {
    let offsets = history.offsets();
    let pressure = elasticity
        .nodal_pressures(tets, history, &offsets, u, None)
        .map(|(p, _)| p);
    let forces = node_forces(
        elasticity,
        history,
        (tets, u, pressing),
        (&offsets, pressure),
    );
    read(&forces, area_floor, averaging)
}

/// A process's part of the mesh, on which [`separation_on_part`] evaluates the criterion.
#[derive(Clone, Copy)]
pub struct OnPart<'a> {
    /// The sums across the processes: its exchange adds each node's parts at the node's owner
    /// and gives every process holding the node the sum.
    pub collective: &'a dyn Collective,
    /// Whether this process owns each node of its part.
    pub owned_nodes: &'a [bool],
}

impl OnPart<'_> {
    /// Gives every node of `values` (one per node of the part) its owner's value.
    fn owners_values(&self, values: &mut [f64]) {
        let mut dofs = vec![0.0; 3 * values.len()];
        for (a, &x) in values.iter().enumerate() {
            if self.owned_nodes[a] {
                dofs[3 * a] = x;
            }
        }
        // The owner's value plus the zeros of the other holders: the owner's value exactly.
        self.collective.exchange(&mut dofs);
        for (a, x) in values.iter_mut().enumerate() {
            *x = dofs[3 * a];
        }
    }
}

/// How a process's part averages the separations of its owned nodes (the nonlocal
/// criterion, see [`nonlocal`]) from the forces of its part's nodes.
pub trait PartAverages {
    /// The separations of the part's nodes from their forces `forces` (one per node of the
    /// part; whole at the nodes the process owns), A(n) at least `area_floor` (m²): averaged
    /// at the owned nodes, anything at the others (they are not eligible on this process).
    /// Every process calls it together (it may exchange forces).
    fn average(&self, forces: &[NodeForces], area_floor: f64) -> Vec<NodeSeparation>;
}

/// A part that holds every element around the nodes within the averaging length of its owned
/// nodes ([`nonlocal::within`]), averaged for its owned nodes ([`Averaging::of`]): their
/// neighbours' forces are whole on the part.
impl PartAverages for Averaging {
    fn average(&self, forces: &[NodeForces], area_floor: f64) -> Vec<NodeSeparation> {
        Averaging::average(self, forces, area_floor)
    }
}

/// [`separation`] on a process's part of the mesh (`tets`, `u` and `pressing` of its nodes,
/// `elasticity` and `history` of its elements), for the nodes it owns: they alone are
/// eligible in the result. The part must hold every element around its owned nodes, and
/// `averaging` must read each owned node's neighbours whole (a part holding the elements
/// around them, or their forces gathered from their owners). Each owned node's separation
/// then reads the elements the whole mesh's does, in the same order; the element pressures
/// of the nodal volumetric energy read the nodal pressures of the nodes' owners, which hold
/// their stars. So an owned node's separation is the whole mesh's, to the bit, when the
/// state is. Every process of `on_part` calls it (it exchanges the nodal pressures).
pub fn separation_on_part(
    elasticity: &Elasticity,
    history: &ElementHistory,
    (tets, u, pressing): (&[[usize; 4]], &[f64], &[f64]),
    area_floor: f64,
    averaging: Option<&dyn PartAverages>,
    on_part: &OnPart,
) -> Vec<NodeSeparation> {
    let from_owners = |p: &mut [f64]| on_part.owners_values(p);
    let offsets = history.offsets();
    let pressure =
        elasticity.element_pressures_from_owners(tets, history, &offsets, u, &from_owners);
    let forces = node_forces(
        elasticity,
        history,
        (tets, u, pressing),
        (&offsets, pressure),
    );
    let mut separations = match averaging {
        Some(averaging) => averaging.average(&forces, area_floor),
        None => read(&forces, area_floor, None),
    };
    // The averages read the neighbours' eligibility; only then are the owned nodes kept.
    for (node, &owned) in separations.iter_mut().zip(on_part.owned_nodes) {
        node.eligible &= owned;
    }
    separations
}

/// Each node's separation from its forces `nodes`, A(n) at least `area_floor` (m²), averaged
/// with `averaging`.
fn read(
    nodes: &[NodeForces],
    area_floor: f64,
    averaging: Option<&Averaging>,
) -> Vec<NodeSeparation> {
    match averaging {
        Some(averaging) => averaging.average(nodes, area_floor),
        None => nodes.iter().map(|n| n.local(area_floor)).collect(),
    }
}

/// What the criterion needs of every node of `tets` at displacements `u` with the contact
/// forces `pressing` (see [`separation`]), the elements' pressures of the nodal volumetric
/// energy `pressure` (Pa; `None` without it) and the strain `offsets` of `history`.
fn node_forces(
    elasticity: &Elasticity,
    history: &ElementHistory,
    (tets, u, pressing): (&[[usize; 4]], &[f64], &[f64]),
    (offsets, pressure): (&[StrainOffset], Option<Vec<f64>>),
) -> Vec<NodeForces> {
    let nodes = u.len() / 3;
    let mut f_plus = vec![Vector3::zeros(); nodes];
    let mut f_minus = vec![Vector3::zeros(); nodes];
    let mut s_plus = vec![Matrix3::zeros(); nodes];
    let mut s_minus = vec![Matrix3::zeros(); nodes];
    for (i, f) in pressing.chunks_exact(3).enumerate() {
        let f = Vector3::new(f[0], f[1], f[2]);
        f_minus[i] += f;
        s_minus[i] += m(&f);
    }
    // Rotated shape-function gradients scaled by the volume, per (element, vertex), for A(n).
    let mut weighted_grads: Vec<Vec<Vector3<f64>>> = vec![Vec::new(); nodes];
    let mut touches_water = vec![false; nodes];
    let mut has_ice = vec![false; nodes];
    for (e, tet) in tets.iter().enumerate() {
        if !history.holds_ice(e) {
            for &i in tet {
                touches_water[i] = true;
            }
            continue;
        }
        let rest = &elasticity.rest[e];
        let local = Elasticity::local(u, tet);
        // The stress as the solve balanced it (returned onto the yield surface; with the
        // nodal volumetric energy the elements' own laws are deviatoric, and their pressure p̄ₑ
        // acts through their volume change θₑ) and the simulation's nodal force
        // formula for a stress in the element's frame.
        let law = elasticity.law_of(history, e);
        let element = stress_forces(
            &law,
            rest,
            &local,
            &offsets[e],
            pressure.as_ref().map(|p| p[e]),
        );
        let (plus, minus) = split(&element.stress);
        let (f_p, f_m) = (element.forces(&plus), element.forces(&minus));
        for (k, &i) in tet.iter().enumerate() {
            let (fp, fm, g) = (f_p[k], f_m[k], element.weighted_grads[k]);
            f_plus[i] += fp;
            f_minus[i] += fm;
            s_plus[i] += m(&fp);
            s_minus[i] += m(&fm);
            weighted_grads[i].push(g);
            has_ice[i] = true;
        }
    }
    (0..nodes)
        .map(|i| NodeForces {
            tensor: if touches_water[i] {
                Matrix3::zeros()
            } else {
                0.5 * (-m(&f_plus[i]) + s_plus[i] + m(&f_minus[i]) - s_minus[i])
            },
            weighted_grads: std::mem::take(&mut weighted_grads[i]),
            eligible: has_ice[i] && !touches_water[i],
        })
        .collect()
}

/// What the criterion needs of one node before any averaging.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeForces {
    /// ς (N).
    pub tensor: Matrix3<f64>,
    /// Vₑ R F*⁻ᵀ∇Nᵢ of the node's ice elements (m², `fem::StressForces::weighted_grads`), for
    /// A(n).
    pub weighted_grads: Vec<Vector3<f64>>,
    /// Every element around the node holds ice (freeze state s > 0, however little frozen).
    pub eligible: bool,
}

impl NodeForces {
    /// The node's forces as words to send to another process (floating-point values by
    /// their bits), appended to `words`: eligibility, the number of gradients, ς's nine
    /// entries, the gradients. [`NodeForces::from_words`] reads them back.
    pub fn to_words(&self, words: &mut Vec<u64>) {
        words.push(self.eligible as u64);
        words.push(self.weighted_grads.len() as u64);
        words.extend(self.tensor.iter().map(|x| x.to_bits()));
        for g in &self.weighted_grads {
            words.extend(g.iter().map(|x| x.to_bits()));
        }
    }

    /// The forces [`NodeForces::to_words`] wrote at the start of `words`, and the words after
    /// them.
    pub fn from_words(words: &[u64]) -> (NodeForces, &[u64]) {
        let float = |w: &[u64]| w.iter().map(|&b| f64::from_bits(b)).collect::<Vec<_>>();
        let grads = words[1] as usize;
        let (head, rest) = words.split_at(11 + 3 * grads);
        let forces = NodeForces {
            eligible: head[0] != 0,
            tensor: Matrix3::from_column_slice(&float(&head[2..11])),
            weighted_grads: (float(&head[11..]).chunks_exact(3))
                .map(Vector3::from_column_slice)
                .collect(),
        };
        (forces, rest)
    }

    /// The node's own separation, A(n) at least `floor` (m²).
    pub fn local(&self, floor: f64) -> NodeSeparation {
        let (largest, normal) = largest_eigen(&self.tensor);
        NodeSeparation {
            tensor: self.tensor,
            largest,
            normal,
            area: self.area(&normal, floor),
            eligible: self.eligible,
        }
    }

    /// A(n) = ½ Σₑ Vₑ |n · R F*⁻ᵀ∇Nᵢ| (m²), at least `floor`.
    pub fn area(&self, normal: &Vector3<f64>, floor: f64) -> f64 {
        let area = 0.5
            * self
                .weighted_grads
                .iter()
                .map(|g| normal.dot(g).abs())
                .sum::<f64>();
        area.max(floor)
    }
}

/// The largest eigenvalue of a symmetric tensor and its unit eigenvector.
fn largest_eigen(tensor: &Matrix3<f64>) -> (f64, Vector3<f64>) {
    let eig = SymmetricEigen::new(*tensor);
    let k = eig.eigenvalues.imax();
    (eig.eigenvalues[k], eig.eigenvectors.column(k).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::tests::ICE;
    use crate::fem::ElasticModel;
    use crate::mesh::box_mesh;
    use crate::physics::elasticity::Volumetric;

    #[test]
    fn a_nodes_forces_come_back_from_their_words() {
        let forces = NodeForces {
            tensor: Matrix3::new(1.0, 2.0, 3.0, 2.0, -5.0, 6.0, 3.0, 6.0, 1e-300),
            weighted_grads: vec![
                Vector3::new(0.1, -0.2, 0.3),
                Vector3::new(f64::MIN, 0.0, -0.0),
            ],
            eligible: true,
        };
        let mut words = Vec::new();
        forces.to_words(&mut words);
        words.push(42);
        let (back, rest) = NodeForces::from_words(&words);
        assert_eq!(back, forces);
        assert_eq!(rest, [42]);
    }

    /// A 4 × 3 × 2 cm box of 4 × 3 × 2 cells (1 cm cubes) under the homogeneous displacement
    /// u = G x; returns the separation of the interior node at (2, 1, 1) cm and the stress.
    fn homogeneous(model: ElasticModel, g: Matrix3<f64>) -> (NodeSeparation, Matrix3<f64>) {
        homogeneous_with(model, g, Volumetric::Element)
    }

    /// As [`homogeneous`], with the volumetric discretisation `volumetric`.
    fn homogeneous_with(
        model: ElasticModel,
        g: Matrix3<f64>,
        volumetric: Volumetric,
    ) -> (NodeSeparation, Matrix3<f64>) {
        let mesh = box_mesh([0.0; 3], [0.04, 0.03, 0.02], [4, 3, 2], 6).unwrap();
        let mut el = Elasticity::new(&mesh, ICE, model);
        el.set_volumetric(&mesh, volumetric);
        let u: Vec<f64> = mesh
            .rest
            .iter()
            .flat_map(|x| (g * x).iter().copied().collect::<Vec<_>>())
            .collect();
        let history = el.initial_history();
        let sep = separation(&el, &history, &mesh.tets, &u, &[], 0.0, None);
        let node = mesh
            .rest
            .iter()
            .position(|x| (x - Vector3::new(0.02, 0.01, 0.01)).norm() < 1e-12)
            .unwrap();
        let eps = 0.5 * (g + g.transpose());
        (sep[node], ICE.hooke(&eps))
    }

    #[test]
    fn uniaxial_tension_gives_the_stress_times_the_node_cross_section() {
        // Uniaxial stress s along x: ε = diag(s/E, −ν s/E, −ν s/E).
        let s = 3e6;
        let (e, nu) = (ICE.young(), ICE.poisson());
        let g = Matrix3::from_diagonal(&Vector3::new(s / e, -nu * s / e, -nu * s / e));
        for model in [ElasticModel::Linear, ElasticModel::Corotated] {
            let (sep, sigma) = homogeneous(model, g);
            assert!((sigma[(0, 0)] - s).abs() < 1e-9 * s && sigma[(1, 1)].abs() < 1e-9 * s);
            // Crack normal along the load, v⁺/A = s, and A = the node's cross-section 1 cm².
            assert!(
                sep.normal.x.abs() > 1.0 - 1e-9,
                "{model:?}: normal {}",
                sep.normal
            );
            // Linear: exact; corotated: its stress differs from Hooke's at second order (s/E).
            let tol = if model == ElasticModel::Linear {
                1e-9
            } else {
                1e-4
            };
            assert!(
                (sep.stress() - s).abs() < tol * s,
                "{model:?}: {} Pa",
                sep.stress()
            );
            assert!(
                (sep.area - 1e-4).abs() < 1e-15,
                "{model:?}: area {}",
                sep.area
            );
            assert!((sep.largest - s * 1e-4).abs() < tol * s * 1e-4);
        }
    }

    #[test]
    fn nodal_volumetric_energy_gives_the_same_separation_stress() {
        // The element pressure of the averaged volume change enters the nodal forces: uniaxial
        // stress s still reads v⁺/A = s (linear: exactly; corotated: its J − 1 volume measure
        // differs from tr(S − I) at second order, s/E).
        let s = 3e6;
        let (e, nu) = (ICE.young(), ICE.poisson());
        let g = Matrix3::from_diagonal(&Vector3::new(s / e, -nu * s / e, -nu * s / e));
        for (model, tol) in [
            (ElasticModel::Linear, 1e-9),
            (ElasticModel::Corotated, 1e-4),
        ] {
            let (sep, _) = homogeneous_with(model, g, Volumetric::Nodal);
            assert!(
                (sep.stress() - s).abs() < tol * s,
                "{model:?}: {} Pa",
                sep.stress()
            );
        }
    }

    #[test]
    fn a_node_is_eligible_once_every_element_around_it_holds_ice() {
        // The front has passed a node when each element of its star has started to freeze:
        // one element around it still all water (s = 0) makes it ineligible, with ς = 0; the
        // same element a tenth frozen contributes its stress and the node is eligible.
        let mesh = box_mesh([0.0; 3], [0.04, 0.03, 0.02], [4, 3, 2], 6).unwrap();
        let el = Elasticity::new(&mesh, ICE, ElasticModel::Linear);
        let node = mesh
            .rest
            .iter()
            .position(|x| (x - Vector3::new(0.02, 0.01, 0.01)).norm() < 1e-12)
            .unwrap();
        let neighbour = mesh.tets.iter().position(|t| t.contains(&node)).unwrap();
        let u: Vec<f64> = mesh
            .rest
            .iter()
            .flat_map(|x| [1e-4 * x.x, 0.0, 0.0])
            .collect();
        let read = |state: f64| {
            let mut history = el.initial_history();
            history.freeze_state = vec![1.0; mesh.tets.len()];
            history.freeze_state[neighbour] = state;
            separation(&el, &history, &mesh.tets, &u, &[], 0.0, None)[node]
        };
        let water = read(0.0);
        assert!(!water.eligible && water.largest == 0.0);
        let freezing = read(0.1);
        assert!(freezing.eligible && freezing.largest > 0.0);
    }

    #[test]
    fn compression_never_separates() {
        // Hydrostatic and uniaxial compression: the largest eigenvalue is ≤ 0.
        for g in [
            Matrix3::identity() * -1e-3,
            Matrix3::from_diagonal(&Vector3::new(-1e-3, 0.0, 0.0)),
        ] {
            for model in [ElasticModel::Linear, ElasticModel::Corotated] {
                let (sep, _) = homogeneous(model, g);
                assert!(
                    sep.largest <= 1e-9 * 1e8 * 1e-4,
                    "{model:?}: v⁺ = {}",
                    sep.largest
                );
            }
        }
    }

    #[test]
    fn rigid_rotation_of_a_stressed_body_rotates_the_crack_normal() {
        // Corotated: stretch along x, then rotate by 90° about z: the crack normal turns to y.
        let s = 3e6;
        let (e, nu) = (ICE.young(), ICE.poisson());
        let stretch = Matrix3::from_diagonal(&Vector3::new(
            1.0 + s / e,
            1.0 - nu * s / e,
            1.0 - nu * s / e,
        ));
        let rot =
            nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
        let g = rot.into_inner() * stretch - Matrix3::identity();
        let (sep, _) = homogeneous(ElasticModel::Corotated, g);
        assert!(sep.normal.y.abs() > 1.0 - 1e-6, "normal {}", sep.normal);
        assert!((sep.stress() - s).abs() < 1e-4 * s, "{} Pa", sep.stress());
    }
}
