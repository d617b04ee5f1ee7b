//! Built-in mesh generators.

use super::{MeshError, TetMesh};
use nalgebra::Vector3;

/// A box `[origin, origin + size]` (m) split into `cells` hexahedral cells, each cut into
/// `tets_per_cell` tetrahedra: 6 (Kuhn/Freudenthal split along the main diagonal, every cell
/// alike) or 5 (four corner tets and a central one, alternating with cell parity so that the
/// face diagonals of neighbouring cells match).
pub fn box_mesh(
    origin: [f64; 3],
    size: [f64; 3],
    cells: [usize; 3],
    tets_per_cell: usize,
) -> Result<TetMesh, MeshError> {
    if cells.contains(&0) {
        return Err(MeshError::Generator(format!(
            "cells must be ≥ 1 per axis, got {cells:?}"
        )));
    }
    if size.iter().any(|&s| !(s.is_finite() && s > 0.0)) || origin.iter().any(|o| !o.is_finite()) {
        return Err(MeshError::Generator(format!(
            "size must be finite and positive and origin finite, got size {size:?}, origin {origin:?}"
        )));
    }
    if tets_per_cell != 5 && tets_per_cell != 6 {
        return Err(MeshError::Generator(format!(
            "tets_per_cell must be 5 or 6, got {tets_per_cell}"
        )));
    }
    let [nx, ny, nz] = cells;
    let node = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let mut rest = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                rest.push(Vector3::new(
                    origin[0] + size[0] * i as f64 / nx as f64,
                    origin[1] + size[1] * j as f64 / ny as f64,
                    origin[2] + size[2] * k as f64 / nz as f64,
                ));
            }
        }
    }
    // Cell corners are numbered by their bits: corner c = (c & 1, (c >> 1) & 1, (c >> 2) & 1).
    const KUHN: [[usize; 4]; 6] = [
        [0, 1, 3, 7],
        [0, 1, 5, 7],
        [0, 2, 3, 7],
        [0, 2, 6, 7],
        [0, 4, 5, 7],
        [0, 4, 6, 7],
    ];
    const FIVE_EVEN: [[usize; 4]; 5] = [
        [1, 2, 4, 7],
        [0, 1, 2, 4],
        [3, 1, 2, 7],
        [5, 1, 4, 7],
        [6, 2, 4, 7],
    ];
    const FIVE_ODD: [[usize; 4]; 5] = [
        [0, 3, 5, 6],
        [1, 0, 3, 5],
        [2, 0, 3, 6],
        [4, 0, 5, 6],
        [7, 3, 5, 6],
    ];
    let mut tets = Vec::with_capacity(nx * ny * nz * tets_per_cell);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let corner = |c: usize| node(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                let pattern: &[[usize; 4]] = match (tets_per_cell, (i + j + k) % 2) {
                    (6, _) => &KUHN,
                    (_, 0) => &FIVE_EVEN,
                    _ => &FIVE_ODD,
                };
                for local in pattern {
                    let mut tet = local.map(corner);
                    if TetMesh::edge_matrix(&rest, &tet).determinant() < 0.0 {
                        tet.swap(2, 3);
                    }
                    tets.push(tet);
                }
            }
        }
    }
    TetMesh::new(rest, tets)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_splits_fill_the_box_conformingly() {
        for tpc in [5, 6] {
            let mesh = box_mesh([0.0, -1.0, 2.0], [0.4, 0.1, 0.2], [4, 3, 2], tpc).unwrap();
            assert_eq!(mesh.num_tets(), 24 * tpc);
            assert!((mesh.volume() - 0.4 * 0.1 * 0.2).abs() < 1e-15);
            // A conforming mesh has exactly the box surface as boundary: 2 triangles per cell face.
            let expected = 2 * 2 * (4 * 3 + 3 * 2 + 4 * 2);
            assert_eq!(mesh.boundary_faces().len(), expected, "{tpc} tets per cell");
        }
    }

    #[test]
    fn bad_generator_input_is_an_error() {
        assert!(box_mesh([0.0; 3], [1.0; 3], [0, 1, 1], 6).is_err());
        assert!(box_mesh([0.0; 3], [1.0, -1.0, 1.0], [1, 1, 1], 6).is_err());
        assert!(box_mesh([0.0; 3], [1.0; 3], [1, 1, 1], 4).is_err());
    }
}
