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
    let grid = BoxGrid::new(origin, size, cells, tets_per_cell)?;
    TetMesh::new(
        (0..grid.num_nodes()).map(|v| grid.node(v)).collect(),
        (0..grid.num_tets()).map(|e| grid.tet(e)).collect(),
    )
}

/// The box of [`box_mesh`], whose every node and element follows from its index alone: each
/// process of a distributed run can make its own range of them without the rest of the mesh.
/// Nodes are numbered x fastest, then y, then z; elements cell by cell in the same order,
/// `tets_per_cell` to a cell.
#[derive(Clone, Copy, Debug)]
pub struct BoxGrid {
    origin: [f64; 3],
    size: [f64; 3],
    cells: [usize; 3],
    tets_per_cell: usize,
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

impl BoxGrid {
    /// The grid of [`box_mesh`]'s arguments, checked.
    pub fn new(
        origin: [f64; 3],
        size: [f64; 3],
        cells: [usize; 3],
        tets_per_cell: usize,
    ) -> Result<Self, MeshError> {
        if cells.contains(&0) {
            return Err(MeshError::Generator(format!(
                "cells must be ≥ 1 per axis, got {cells:?}"
            )));
        }
        if size.iter().any(|&s| !(s.is_finite() && s > 0.0))
            || origin.iter().any(|o| !o.is_finite())
        {
            return Err(MeshError::Generator(format!(
                "size must be finite and positive and origin finite, got size {size:?}, origin {origin:?}"
            )));
        }
        if tets_per_cell != 5 && tets_per_cell != 6 {
            return Err(MeshError::Generator(format!(
                "tets_per_cell must be 5 or 6, got {tets_per_cell}"
            )));
        }
        Ok(BoxGrid {
            origin,
            size,
            cells,
            tets_per_cell,
        })
    }

    /// Number of nodes.
    pub fn num_nodes(&self) -> usize {
        self.cells.iter().map(|n| n + 1).product()
    }

    /// Number of elements.
    pub fn num_tets(&self) -> usize {
        self.cells.iter().product::<usize>() * self.tets_per_cell
    }

    /// Rest position of node `v` (m).
    pub fn node(&self, v: usize) -> Vector3<f64> {
        let [nx, ny, nz] = self.cells;
        let ijk = [
            v % (nx + 1),
            v / (nx + 1) % (ny + 1),
            v / ((nx + 1) * (ny + 1)),
        ];
        let n = [nx, ny, nz];
        Vector3::from_fn(|a, _| self.origin[a] + self.size[a] * ijk[a] as f64 / n[a] as f64)
    }

    /// Nodes of element `e`, positively oriented.
    pub fn tet(&self, e: usize) -> [usize; 4] {
        let [nx, ny, _] = self.cells;
        let (cell, t) = (e / self.tets_per_cell, e % self.tets_per_cell);
        let (i, j, k) = (cell % nx, cell / nx % ny, cell / (nx * ny));
        let node = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
        let corner = |c: usize| node(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
        let pattern: &[[usize; 4]] = match (self.tets_per_cell, (i + j + k) % 2) {
            (6, _) => &KUHN,
            (_, 0) => &FIVE_EVEN,
            _ => &FIVE_ODD,
        };
        let mut tet = pattern[t].map(corner);
        let corners = tet.map(|v| self.node(v));
        if TetMesh::edge_matrix(&corners, &[0, 1, 2, 3]).determinant() < 0.0 {
            tet.swap(2, 3);
        }
        tet
    }
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
    fn the_grid_makes_each_element_from_its_index() {
        let grid = BoxGrid::new([1.0, 0.0, -1.0], [0.3, 0.2, 0.4], [3, 2, 4], 5).unwrap();
        assert_eq!(grid.node(0), Vector3::new(1.0, 0.0, -1.0));
        assert_eq!(
            grid.node(grid.num_nodes() - 1),
            Vector3::new(1.3, 0.2, -0.6)
        );
        // Element e lies in cell e / 5, numbered x fastest: its nodes are that cell's corners.
        for e in (0..grid.num_tets()).step_by(7) {
            let cell = e / 5;
            let low = Vector3::new(
                1.0 + 0.1 * (cell % 3) as f64,
                0.1 * (cell / 3 % 2) as f64,
                -1.0 + 0.1 * (cell / 6) as f64,
            );
            for v in grid.tet(e) {
                let offset = grid.node(v) - low;
                assert!(offset
                    .iter()
                    .all(|&d| d.abs() < 1e-12 || (d - 0.1).abs() < 1e-12));
            }
        }
    }

    #[test]
    fn bad_generator_input_is_an_error() {
        assert!(box_mesh([0.0; 3], [1.0; 3], [0, 1, 1], 6).is_err());
        assert!(box_mesh([0.0; 3], [1.0, -1.0, 1.0], [1, 1, 1], 6).is_err());
        assert!(box_mesh([0.0; 3], [1.0; 3], [1, 1, 1], 4).is_err());
    }
}
