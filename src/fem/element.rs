//! One element's rest data, its evaluation result, and the stiffness Bᵀ T B of a tangent.
#![allow(non_snake_case)]

use super::tensor::Tangent;
use crate::mesh::TetMesh;
use nalgebra::{Matrix3, Vector3};

/// Rest data of one tet.
#[derive(Clone, Copy, Debug)]
pub struct ElementRest {
    /// Rest volume (m³).
    pub volume: f64,
    /// Gradients of the four shape functions in the rest configuration (1/m).
    pub grads: [Vector3<f64>; 4],
}

impl ElementRest {
    /// Rest data of every tet of `mesh`.
    pub fn of_mesh(mesh: &TetMesh) -> Vec<ElementRest> {
        mesh.tets
            .iter()
            .map(|tet| {
                let Dm = TetMesh::edge_matrix(&mesh.rest, tet);
                // The mesh constructor rejected degenerate tets, so Dm is invertible.
                let inv = Dm.try_inverse().unwrap_or_else(Matrix3::zeros);
                let g1: Vector3<f64> = inv.row(0).transpose();
                let g2: Vector3<f64> = inv.row(1).transpose();
                let g3: Vector3<f64> = inv.row(2).transpose();
                ElementRest {
                    volume: Dm.determinant() / 6.0,
                    grads: [-(g1 + g2 + g3), g1, g2, g3],
                }
            })
            .collect()
    }

    /// Displacement gradient H = ∇u = Σᵢ uᵢ ⊗ ∇Nᵢ = F − I for the element's vertex
    /// displacements (m). Working with H rather than F keeps small strains accurate to round-off
    /// of the strain itself instead of round-off of the positions.
    #[inline]
    pub fn displacement_gradient(&self, u: &[Vector3<f64>; 4]) -> Matrix3<f64> {
        u.iter()
            .zip(&self.grads)
            .map(|(ui, gi)| ui * gi.transpose())
            .sum()
    }
}

/// Energy, gradient and (optionally) stiffness of one element.
#[derive(Clone, Debug)]
pub struct ElementEval {
    /// Elastic energy (J).
    pub energy: f64,
    /// dE/dx for the 12 vertex coordinates (N); the elastic force is its negative.
    pub gradient: [f64; 12],
    /// d²E/dx², row-major 12 × 12 (N/m), symmetric positive semi-definite.
    pub hessian: [f64; 144],
}

impl Default for ElementEval {
    fn default() -> Self {
        ElementEval {
            energy: 0.0,
            gradient: [0.0; 12],
            hessian: [0.0; 144],
        }
    }
}

/// The gradients Aᵀ∇Nᵢ through which the vertex displacements move He = H A + (A − I).
#[inline]
pub(super) fn offset_grads(A: &Matrix3<f64>, rest: &ElementRest) -> [Vector3<f64>; 4] {
    rest.grads.map(|g| A.tr_mul(&g))
}

/// Adds the element stiffness `v Bᵀ T B` (row-major 12 × 12) of the tangent `T` = dP/dF,
/// B mapping the 12 vertex displacements to vec(H) through the shape-function gradients
/// `grads` (B[a+3k, 3j+b] = δ_ab ∇N_j[k]): T B first (9 × 12), then Bᵀ (T B).
#[inline]
pub(super) fn add_stiffness(
    grads: &[Vector3<f64>; 4],
    v: f64,
    tangent: &Tangent,
    hessian: &mut [f64; 144],
) {
    let mut tb = [[0.0; 12]; 9];
    for (r, row) in tb.iter_mut().enumerate() {
        for (j, gj) in grads.iter().enumerate() {
            for b in 0..3 {
                row[3 * j + b] = tangent[(r, b)] * gj[0]
                    + tangent[(r, b + 3)] * gj[1]
                    + tangent[(r, b + 6)] * gj[2];
            }
        }
    }
    for (i, gi) in grads.iter().enumerate() {
        for a in 0..3 {
            let out = &mut hessian[(3 * i + a) * 12..(3 * i + a + 1) * 12];
            let (t0, t1, t2) = (&tb[a], &tb[a + 3], &tb[a + 6]);
            for c in 0..12 {
                out[c] += v * (gi[0] * t0[c] + gi[1] * t1[c] + gi[2] * t2[c]);
            }
        }
    }
}
