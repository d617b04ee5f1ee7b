//! Elastic energy of the mesh: per-element rest data, material, model and strain offsets.
//!
//! Each element's stress is σ = C : (ε − ε*) with the strain offset ε* = e I + ε_p: an
//! isotropic eigenstrain e (a scene's `[[eigenstrain]]` plus the freezing expansion) and, with
//! plasticity on, the element's plastic strain ε_p. While freezing, an element's material
//! blends from water to ice with its freeze state. The strain offsets and freeze states are
//! per-element history and live in the simulation state ([`ElementHistory`]).

use super::history::ElementHistory;
use super::term::StepTerm;
use crate::assembly::Assembly;
use crate::fem::{
    elastic_strain, element_eval, element_stress, ElasticModel, ElementEval, ElementRest, Material,
};
use crate::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

/// The elastic term: one ice material and model for all elements, their rest data, and the
/// scene's prescribed eigenstrain.
#[derive(Clone, Debug)]
pub struct Elasticity {
    /// Material constants of the ice (Pa, kg/m³).
    pub material: Material,
    /// Strain measure.
    pub model: ElasticModel,
    /// Rest data per element.
    pub rest: Vec<ElementRest>,
    /// Prescribed isotropic eigenstrain per element (dimensionless), the scene's
    /// `[[eigenstrain]]`: the initial value of the history's eigenstrain, to which freezing
    /// adds its expansion.
    pub eigenstrain: Vec<f64>,
    /// Bulk modulus of unfrozen water (Pa; 0 for inactive water); used only for elements
    /// whose freeze state is below 1.
    pub water_bulk: f64,
    /// Regularising shear modulus of unfrozen water (Pa), see `freezing`.
    pub water_shear: f64,
}

impl Elasticity {
    /// Elasticity of `mesh` with zero eigenstrain and no water.
    pub fn new(mesh: &TetMesh, material: Material, model: ElasticModel) -> Self {
        Elasticity {
            material,
            model,
            rest: ElementRest::of_mesh(mesh),
            eigenstrain: vec![0.0; mesh.num_tets()],
            water_bulk: 0.0,
            water_shear: 0.0,
        }
    }

    /// This elasticity on `mesh`, made from this one's mesh by splitting elements: new element
    /// `e` inherits the prescribed eigenstrain of element `parent[e]`.
    pub fn remeshed(&self, mesh: &TetMesh, parent: &[usize]) -> Self {
        Elasticity {
            rest: ElementRest::of_mesh(mesh),
            eigenstrain: parent.iter().map(|&p| self.eigenstrain[p]).collect(),
            ..*self
        }
    }

    /// The history of these elements at the start of a run without plasticity or freezing:
    /// the prescribed eigenstrain only.
    pub fn initial_history(&self) -> ElementHistory {
        ElementHistory::initial(&self.eigenstrain, false)
    }

    /// Displacements of the four vertices of `tet` from the global dof vector `u` (m).
    pub fn local(u: &[f64], tet: &[usize; 4]) -> [Vector3<f64>; 4] {
        tet.map(|v| Vector3::new(u[3 * v], u[3 * v + 1], u[3 * v + 2]))
    }

    /// Material of element `e` and the bulk modulus (Pa) of its water part: the ice and none,
    /// or, while it freezes at state s, s × the ice's Lamé constants (plus (1 − s) × the
    /// water's regularising shear modulus) and (1 − s) × the water's bulk modulus, so its
    /// stiffness changes continuously.
    pub fn material_of(&self, history: &ElementHistory, e: usize) -> (Material, f64) {
        match history.freeze_state.get(e) {
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

    /// Energy, gradient and optionally the exact stiffness of element `e` for displacements `u`.
    pub fn element(
        &self,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        u: &[f64],
        e: usize,
        with_hessian: bool,
        out: &mut ElementEval,
    ) {
        self.element_with(tets, history, u, e, with_hessian, false, out);
    }

    /// As [`Elasticity::element`]; with `project` the stiffness is made positive semi-definite
    /// (see `fem::constitutive`).
    // The element's inputs: mesh, history, state, which element and what to compute.
    #[allow(clippy::too_many_arguments)]
    pub fn element_with(
        &self,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        u: &[f64],
        e: usize,
        with_hessian: bool,
        project: bool,
        out: &mut ElementEval,
    ) {
        let (material, water_bulk) = self.material_of(history, e);
        element_eval(
            self.model,
            &material,
            water_bulk,
            &self.rest[e],
            &Self::local(u, &tets[e]),
            &history.offset_of(e),
            with_hessian,
            project,
            out,
        );
    }

    /// The largest nodal force (N) the strain offsets would exert on a clamped mesh,
    /// |V (C:ε*) ∇Nᵢ| over elements and nodes: the expansion and plastic strain act as loads,
    /// and Newton judges its residual against this scale like against dead loads.
    pub fn offset_force_scale(&self, history: &ElementHistory) -> f64 {
        (0..self.rest.len())
            .filter(|&e| history.eigenstrain[e] != 0.0 || !history.plastic_strain.is_empty())
            .map(|e| {
                let (material, water_bulk) = self.material_of(history, e);
                let offset = history.offset_of(e);
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
    pub fn elastic_strain(
        &self,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        u: &[f64],
        e: usize,
    ) -> Matrix3<f64> {
        elastic_strain(
            self.model,
            &self.rest[e],
            &Self::local(u, &tets[e]),
            &history.offset_of(e),
        )
        .0
    }

    /// Cauchy stress (Pa, Voigt xx yy zz yz xz xy) of every element.
    pub fn stresses(
        &self,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        u: &[f64],
    ) -> Vec<[f64; 6]> {
        use rayon::prelude::*;
        (0..tets.len())
            .into_par_iter()
            .map(|e| {
                let (material, water_bulk) = self.material_of(history, e);
                element_stress(
                    self.model,
                    &material,
                    water_bulk,
                    &self.rest[e],
                    &Self::local(u, &tets[e]),
                    &history.offset_of(e),
                )
            })
            .collect()
    }

    /// Elastic energy Σ Wₑ (J) at `u`, with each element's energy written to `element_energy`.
    pub fn energy(
        &self,
        assembly: &Assembly,
        tets: &[[usize; 4]],
        history: &ElementHistory,
        u: &[f64],
        element_energy: &mut [f64],
    ) -> f64 {
        assembly.energies(
            |e, out| self.element(tets, history, u, e, false, out),
            element_energy,
        );
        // Summed in order so the result does not depend on thread scheduling.
        element_energy.iter().sum()
    }
}

/// The elastic energy as a term of a solve: Σ Wₑ assembled element by element in parallel.
pub struct ElasticStep<'a> {
    /// The elasticity.
    pub elasticity: &'a Elasticity,
    /// Element connectivity.
    pub tets: &'a [[usize; 4]],
    /// The elements' history (strain offsets, freeze states).
    pub history: &'a ElementHistory,
    /// Pattern of the free system.
    pub assembly: &'a Assembly,
    /// Per-element energy buffer (J), one per element.
    pub element_energy: &'a mut [f64],
    /// Whether element stiffnesses are projected to be positive semi-definite.
    pub project: bool,
}

impl StepTerm for ElasticStep<'_> {
    fn add(
        &mut self,
        u: &[f64],
        energy: &mut f64,
        gradient: Option<&mut [f64]>,
        hessian: Option<&mut [f64]>,
    ) {
        let (el, tets, history) = (self.elasticity, self.tets, self.history);
        match gradient {
            Some(gradient) => {
                let project = self.project;
                self.assembly.assemble(
                    |e, with_h, out| el.element_with(tets, history, u, e, with_h, project, out),
                    self.element_energy,
                    gradient,
                    hessian,
                );
                *energy += self.element_energy.iter().sum::<f64>();
            }
            None => {
                *energy += el.energy(self.assembly, tets, history, u, self.element_energy);
            }
        }
    }

    fn project_hessian(&mut self) -> bool {
        !std::mem::replace(&mut self.project, true)
    }
}
