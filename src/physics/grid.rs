//! A uniform hash grid of axis-aligned boxes (triangles' bounding boxes), the broad phase of
//! both contact searches.

use nalgebra::Vector3;
use std::collections::HashMap;

/// Boxes registered in every grid cell they overlap.
#[derive(Clone, Debug, Default)]
pub struct BoxGrid {
    /// Cell edge (m).
    cell: f64,
    /// Ids of the boxes overlapping each non-empty cell.
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl BoxGrid {
    /// An empty grid of cubic cells of edge `cell` (m, > 0).
    pub fn new(cell: f64) -> Self {
        BoxGrid {
            cell,
            cells: HashMap::new(),
        }
    }

    fn key(&self, p: &Vector3<f64>) -> [i64; 3] {
        [0, 1, 2].map(|a| (p[a] / self.cell).floor() as i64)
    }

    /// Registers box `id` spanning `lo`…`hi` (m).
    pub fn insert(&mut self, lo: &Vector3<f64>, hi: &Vector3<f64>, id: u32) {
        let (klo, khi) = (self.key(lo), self.key(hi));
        for x in klo[0]..=khi[0] {
            for y in klo[1]..=khi[1] {
                for z in klo[2]..=khi[2] {
                    self.cells.entry([x, y, z]).or_default().push(id);
                }
            }
        }
    }

    /// Ids of the boxes registered in the cell holding `p`.
    pub fn at(&self, p: &Vector3<f64>) -> &[u32] {
        self.cells.get(&self.key(p)).map_or(&[], Vec::as_slice)
    }

    /// Calls `f` with the ids of the boxes registered in the cells overlapping `lo`…`hi` (an
    /// id may come more than once), cell by cell in (x, y, z) order and in insertion order
    /// within a cell — the same order whatever the path. A query box spanning more cells than
    /// the grid has non-empty ones walks those instead, so a long reach (a fast body) never
    /// visits millions of empty cells.
    pub fn overlapping(&self, lo: &Vector3<f64>, hi: &Vector3<f64>, mut f: impl FnMut(u32)) {
        let (klo, khi) = (self.key(lo), self.key(hi));
        let span = (0..3).fold(1.0, |n, a| n * (khi[a] - klo[a] + 1) as f64);
        if span > self.cells.len() as f64 {
            let mut hit: Vec<(&[i64; 3], &Vec<u32>)> = self
                .cells
                .iter()
                .filter(|(k, _)| (0..3).all(|a| k[a] >= klo[a] && k[a] <= khi[a]))
                .collect();
            hit.sort_unstable_by_key(|(k, _)| **k);
            for (_, ids) in hit {
                ids.iter().for_each(|&id| f(id));
            }
            return;
        }
        for x in klo[0]..=khi[0] {
            for y in klo[1]..=khi[1] {
                for z in klo[2]..=khi[2] {
                    for &id in self.cells.get(&[x, y, z]).into_iter().flatten() {
                        f(id);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_and_sparse_queries_find_the_same_boxes() {
        let mut grid = BoxGrid::new(0.1);
        grid.insert(
            &Vector3::new(0.0, 0.0, 0.0),
            &Vector3::new(0.05, 0.05, 0.05),
            0,
        );
        grid.insert(
            &Vector3::new(0.95, 0.0, 0.0),
            &Vector3::new(1.25, 0.05, 0.05),
            1,
        );
        assert_eq!(grid.at(&Vector3::new(1.1, 0.0, 0.0)), &[1]);
        assert!(grid.at(&Vector3::new(0.5, 0.5, 0.5)).is_empty());
        let found = |lo: Vector3<f64>, hi: Vector3<f64>| {
            let mut ids = Vec::new();
            grid.overlapping(&lo, &hi, |id| ids.push(id));
            ids.dedup();
            ids
        };
        // A small query walks cells; a huge one walks the non-empty cells: same answer.
        assert_eq!(
            found(Vector3::repeat(-0.01), Vector3::repeat(0.01)),
            vec![0]
        );
        assert_eq!(
            found(Vector3::repeat(-100.0), Vector3::repeat(100.0)),
            vec![0, 1]
        );
        assert_eq!(
            found(Vector3::new(0.5, -1.0, -1.0), Vector3::repeat(100.0)),
            vec![1]
        );
    }
}
