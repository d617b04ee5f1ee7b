//! Elastic energy of the mesh: per-element rest data, material, model and strain offsets.
//!
//! Each element's stress is σ = C : (ε − ε*) with the strain offset ε* = e I + ε_p: an
//! isotropic eigenstrain e (a scene's `[[eigenstrain]]` plus the freezing expansion) and, with
//! plasticity on, the element's plastic strain ε_p. While freezing, an element's material
//! blends from water to ice with its freeze state.

use crate::fem::{
    elastic_strain, element_eval, element_stress, ElasticModel, ElementEval, ElementRest, Material,
};
use crate::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

/// The elastic term: one ice material and model for all elements, per-element strain offsets
/// and, while freezing, per-element freeze states.
#[derive(Clone, Debug)]
pub struct Elasticity {
    /// Material constants of the ice (Pa, kg/m³).
    pub material: Material,
    /// Strain measure.
    pub model: ElasticModel,
    /// Rest data per element.
    pub rest: Vec<ElementRest>,
    /// Isotropic eigenstrain per element (dimensionless).
    pub eigenstrain: Vec<f64>,
    /// Plastic strain per element (symmetric, dimensionless); empty without plasticity.
    pub plastic_strain: Vec<Matrix3<f64>>,
    /// Freeze state per element, 0 (water) … 1 (ice); empty without freezing (all ice).
    pub freeze_state: Vec<f64>,
    /// Bulk modulus of unfrozen water (Pa; 0 for inactive water); used only while
    /// `freeze_state` is set.
    pub water_bulk: f64,
    /// Regularising shear modulus of unfrozen water (Pa), see `freezing`.
    pub water_shear: f64,
}

impl Elasticity {
    /// Elasticity of `mesh` with zero eigenstrain, no plasticity and no freezing.
    pub fn new(mesh: &TetMesh, material: Material, model: ElasticModel) -> Self {
        Elasticity {
            material,
            model,
            rest: ElementRest::of_mesh(mesh),
            eigenstrain: vec![0.0; mesh.num_tets()],
            plastic_strain: Vec::new(),
            freeze_state: Vec::new(),
            water_bulk: 0.0,
            water_shear: 0.0,
        }
    }

    /// This elasticity on `mesh`, made from this one's mesh by splitting elements: new element
    /// `e` inherits the eigenstrain, plastic strain and freeze state of element `parent[e]`.
    pub fn remeshed(&self, mesh: &TetMesh, parent: &[usize]) -> Self {
        let inherit = |v: &[f64]| parent.iter().map(|&p| v[p]).collect::<Vec<f64>>();
        Elasticity {
            rest: ElementRest::of_mesh(mesh),
            eigenstrain: inherit(&self.eigenstrain),
            freeze_state: if self.freeze_state.is_empty() {
                Vec::new()
            } else {
                inherit(&self.freeze_state)
            },
            plastic_strain: if self.plastic_strain.is_empty() {
                Vec::new()
            } else {
                parent.iter().map(|&p| self.plastic_strain[p]).collect()
            },
            ..*self
        }
    }

    /// Displacements of the four vertices of `tet` from the global dof vector `u` (m).
    pub fn local(u: &[f64], tet: &[usize; 4]) -> [Vector3<f64>; 4] {
        tet.map(|v| Vector3::new(u[3 * v], u[3 * v + 1], u[3 * v + 2]))
    }

    /// Material of element `e` and the bulk modulus (Pa) of its water part: the ice and none,
    /// or, while it freezes at state s, s × the ice's Lamé constants (plus (1 − s) × the
    /// water's regularising shear modulus) and (1 − s) × the water's bulk modulus, so its
    /// stiffness changes continuously.
    pub fn material_of(&self, e: usize) -> (Material, f64) {
        match self.freeze_state.get(e) {
            Some(&s) if s < 1.0 => (
                Material {
                    lambda: s * self.material.lambda,
                    mu: s * self.material.mu + (1.0 - s) * self.water_shear,
                    density: self.material.density,
                },
                (1.0 - s) * self.water_bulk,
            ),
            _ => (self.material, 0.0),
        }
    }

    /// Strain offset ε* = e I + ε_p of element `e`.
    pub fn offset_of(&self, e: usize) -> Matrix3<f64> {
        let iso = Matrix3::identity() * self.eigenstrain[e];
        match self.plastic_strain.get(e) {
            Some(p) => iso + p,
            None => iso,
        }
    }

    /// Energy, gradient and optionally the exact stiffness of element `e` for displacements `u`.
    pub fn element(
        &self,
        tets: &[[usize; 4]],
        u: &[f64],
        e: usize,
        with_hessian: bool,
        out: &mut ElementEval,
    ) {
        self.element_with(tets, u, e, with_hessian, false, out);
    }

    /// As [`Elasticity::element`]; with `project` the stiffness is made positive semi-definite
    /// (see `fem::constitutive`).
    pub fn element_with(
        &self,
        tets: &[[usize; 4]],
        u: &[f64],
        e: usize,
        with_hessian: bool,
        project: bool,
        out: &mut ElementEval,
    ) {
        let (material, water_bulk) = self.material_of(e);
        element_eval(
            self.model,
            &material,
            water_bulk,
            &self.rest[e],
            &Self::local(u, &tets[e]),
            &self.offset_of(e),
            with_hessian,
            project,
            out,
        );
    }

    /// The largest nodal force (N) the strain offsets would exert on a clamped mesh,
    /// |V (C:ε*) ∇Nᵢ| over elements and nodes: the expansion and plastic strain act as loads,
    /// and Newton judges its residual against this scale like against dead loads.
    pub fn offset_force_scale(&self) -> f64 {
        (0..self.rest.len())
            .filter(|&e| self.eigenstrain[e] != 0.0 || !self.plastic_strain.is_empty())
            .map(|e| {
                let (material, water_bulk) = self.material_of(e);
                let offset = self.offset_of(e);
                let stress =
                    material.hooke(&offset) + Matrix3::identity() * (water_bulk * offset.trace());
                let r = &self.rest[e];
                r.grads
                    .iter()
                    .map(|g| (r.volume * stress * g).norm())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max)
    }

    /// Elastic strain of element `e` in its own frame (see `fem::elastic_strain`).
    pub fn elastic_strain(&self, tets: &[[usize; 4]], u: &[f64], e: usize) -> Matrix3<f64> {
        elastic_strain(
            self.model,
            &self.rest[e],
            &Self::local(u, &tets[e]),
            &self.offset_of(e),
        )
        .0
    }

    /// Cauchy stress (Pa, Voigt xx yy zz yz xz xy) of every element.
    pub fn stresses(&self, tets: &[[usize; 4]], u: &[f64]) -> Vec<[f64; 6]> {
        use rayon::prelude::*;
        (0..tets.len())
            .into_par_iter()
            .map(|e| {
                let (material, water_bulk) = self.material_of(e);
                element_stress(
                    self.model,
                    &material,
                    water_bulk,
                    &self.rest[e],
                    &Self::local(u, &tets[e]),
                    &self.offset_of(e),
                )
            })
            .collect()
    }
}
