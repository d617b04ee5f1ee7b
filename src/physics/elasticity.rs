//! Elastic energy of the mesh: per-element rest data, material, model and strain offsets.

use crate::fem::{element_eval, element_stress, ElasticModel, ElementEval, ElementRest, Material};
use crate::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

/// The elastic term: one material and model for all elements, with a per-element isotropic
/// eigenstrain e (σ = C : (ε − e I)); zero unless a schedule (freezing) sets it.
#[derive(Clone, Debug)]
pub struct Elasticity {
    /// Material constants.
    pub material: Material,
    /// Strain measure.
    pub model: ElasticModel,
    /// Rest data per element.
    pub rest: Vec<ElementRest>,
    /// Isotropic eigenstrain per element (dimensionless).
    pub eigenstrain: Vec<f64>,
}

impl Elasticity {
    /// Elasticity of `mesh` with zero eigenstrain.
    pub fn new(mesh: &TetMesh, material: Material, model: ElasticModel) -> Self {
        Elasticity {
            material,
            model,
            rest: ElementRest::of_mesh(mesh),
            eigenstrain: vec![0.0; mesh.num_tets()],
        }
    }

    /// Displacements of the four vertices of `tet` from the global dof vector `u` (m).
    pub fn local(u: &[f64], tet: &[usize; 4]) -> [Vector3<f64>; 4] {
        tet.map(|v| Vector3::new(u[3 * v], u[3 * v + 1], u[3 * v + 2]))
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
        let offset = Matrix3::identity() * self.eigenstrain[e];
        let local = Self::local(u, &tets[e]);
        element_eval(
            self.model,
            &self.material,
            &self.rest[e],
            &local,
            &offset,
            with_hessian,
            project,
            out,
        );
    }

    /// Cauchy stress (Pa, Voigt xx yy zz yz xz xy) of every element.
    pub fn stresses(&self, tets: &[[usize; 4]], u: &[f64]) -> Vec<[f64; 6]> {
        use rayon::prelude::*;
        (0..tets.len())
            .into_par_iter()
            .map(|e| {
                let offset = Matrix3::identity() * self.eigenstrain[e];
                element_stress(
                    self.model,
                    &self.material,
                    &self.rest[e],
                    &Self::local(u, &tets[e]),
                    &offset,
                )
            })
            .collect()
    }
}
