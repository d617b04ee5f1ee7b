//! The heat model on several processes (see `thermal::shared`): each process sets the rows
//! of the nodes it owns — whole on its part of the mesh — into a PETSc matrix over the whole
//! mesh's nodes, numbered as the mechanics' nodes are (a fixed-temperature node is a row of
//! its diagonal alone), solved by conjugate gradients with BoomerAMG; each process gathers
//! the solution on its part's free nodes. Sums, maxima and the union of the edges whose
//! couplings are cancelled go over MPI. With fracture the heat model stays on the part it was
//! set up on, and a split part reads it by position (`link_on_part`).

use super::partition::PartNumbering;
use super::petsc::{Gather, Int, Krylov, Matrix, Vector};
use crate::mesh::TetMesh;
use crate::sim::part::Part;
use crate::sim::SimError;
use crate::thermal::system::ScalarSystem;
use crate::thermal::HeatLink;
use crate::thermal::HeatShare;
use mpi::topology::SimpleCommunicator;

/// An owned free node's row: its PETSc index, its columns' PETSc indices and the slots of
/// its entries in the heat system's values.
struct Row {
    row: Int,
    columns: Vec<Int>,
    slots: Vec<usize>,
    /// Index of the diagonal entry in `columns`.
    diagonal: usize,
}

/// One process's share of a heat model.
pub struct HeatProcessShare {
    world: SimpleCommunicator,
    owned: Vec<bool>,
    whole_nodes: Vec<usize>,
    matrix: Matrix,
    krylov: Krylov,
    rhs: Vector,
    solution: Vector,
    gather: Gather,
    /// This process's owned free nodes' rows.
    rows: Vec<Row>,
    /// For each of this process's PETSc rows, its node's free number (`None`: fixed).
    row_free: Vec<Option<usize>>,
    /// The PETSc rows of this process's fixed nodes.
    fixed_rows: Vec<Int>,
    /// A row's values (scratch).
    values: Vec<f64>,
}

impl HeatProcessShare {
    /// The share of process `rank` whose part holds the whole mesh's nodes `nodes`
    /// (ascending, numbered by `numbering`), of which it owns those marked in `owned`, for
    /// the heat `system` on the part and each node's free number `free`; CG stops at the
    /// relative residual `rtol` or after `max_iterations`.
    pub fn new(
        (numbering, rank): (&PartNumbering, u32),
        (nodes, owned): (&[usize], &[bool]),
        (system, free): (&ScalarSystem, &[Option<usize>]),
        (rtol, max_iterations): (f64, usize),
    ) -> Result<Self, String> {
        let petsc = |k: usize| numbering.petsc_node[k] as Int;
        let r = rank as usize;
        let (start, end) = (numbering.node_start[r], numbering.node_start[r + 1]);
        let global = numbering.whole_nodes();
        let in_range = |i: Int| (start..end).contains(&(i as usize));
        let mut node_of_free = vec![0; system.rows()];
        let mut row_free = vec![None; end - start];
        for (k, f) in free.iter().enumerate() {
            if let Some(j) = *f {
                node_of_free[j] = k;
            }
            if owned[k] {
                row_free[petsc(k) as usize - start] = *f;
            }
        }
        let entries = system.row_entries();
        let rows: Vec<Row> = (entries.into_iter().enumerate())
            .filter(|(j, _)| owned[node_of_free[*j]])
            .map(|(j, row)| Row {
                row: petsc(node_of_free[j]),
                diagonal: row.iter().position(|&(c, _)| c == j).expect("a diagonal"),
                columns: row.iter().map(|&(c, _)| petsc(node_of_free[c])).collect(),
                slots: row.iter().map(|&(_, slot)| slot).collect(),
            })
            .collect();
        let (mut diagonal, mut off) = (vec![1 as Int; end - start], vec![0 as Int; end - start]);
        for row in &rows {
            let inside = row.columns.iter().filter(|&&c| in_range(c)).count();
            let local = row.row as usize - start;
            diagonal[local] = inside as Int;
            off[local] = (row.columns.len() - inside) as Int;
        }
        let fixed_rows = (row_free.iter().enumerate())
            .filter(|(_, f)| f.is_none())
            .map(|(i, _)| (start + i) as Int)
            .collect();
        let error = |e: super::petsc::PetscError| e.to_string();
        let matrix = Matrix::new(end - start, global, 1, (&diagonal, &off)).map_err(error)?;
        let rhs = Vector::new(end - start, global, 1).map_err(error)?;
        let solution = Vector::new(end - start, global, 1).map_err(error)?;
        let gathered: Vec<Int> = node_of_free.iter().map(|&k| petsc(k)).collect();
        let gather = Gather::new(&solution, &gathered).map_err(error)?;
        Ok(HeatProcessShare {
            world: SimpleCommunicator::world(),
            owned: owned.to_vec(),
            whole_nodes: nodes.to_vec(),
            matrix,
            krylov: Krylov::cg_amg(rtol, max_iterations).map_err(error)?,
            rhs,
            solution,
            gather,
            rows,
            row_free,
            fixed_rows,
            values: Vec::new(),
        })
    }
}

impl HeatShare for HeatProcessShare {
    fn owned(&self) -> &[bool] {
        &self.owned
    }

    fn whole_nodes(&self) -> &[usize] {
        &self.whole_nodes
    }

    fn sum(&self, x: f64) -> f64 {
        super::sum_in_order(&self.world, x)
    }

    fn max(&self, x: f64) -> f64 {
        super::largest(&self.world, x)
    }

    fn union(&self, edges: &[(usize, usize)]) -> Vec<(usize, usize)> {
        let mine: Vec<u64> = edges
            .iter()
            .flat_map(|&(a, b)| [a as u64, b as u64])
            .collect();
        let all = super::ghosts::all_gathered(&self.world, &mine);
        let mut union: Vec<(usize, usize)> = all
            .chunks_exact(2)
            .map(|p| (p[0] as usize, p[1] as usize))
            .collect();
        union.sort_unstable();
        union.dedup();
        union
    }

    fn set_matrix(&mut self, system: &ScalarSystem) -> Result<(), String> {
        let error = |e: super::petsc::PetscError| e.to_string();
        self.matrix.zero().map_err(error)?;
        let mut diagonal_sum = 0.0;
        for row in &self.rows {
            self.values.clear();
            self.values
                .extend(row.slots.iter().map(|&s| system.values[s]));
            diagonal_sum += self.values[row.diagonal].abs();
            self.matrix
                .add_row(row.row, &row.columns, &self.values)
                .map_err(error)?;
        }
        // A fixed node's row is its diagonal alone, scaled like the others (its update is
        // zero).
        let scale = if diagonal_sum > 0.0 {
            diagonal_sum / self.rows.len() as f64
        } else {
            1.0
        };
        for &row in &self.fixed_rows {
            self.matrix.add_row(row, &[row], &[scale]).map_err(error)?;
        }
        self.matrix.assemble().map_err(error)?;
        self.krylov.set_matrix(&self.matrix).map_err(error)
    }

    fn solve_in_place(&mut self, x: &mut [f64]) -> Result<(), String> {
        let error = |e: super::petsc::PetscError| e.to_string();
        let row_free = &self.row_free;
        self.rhs
            .write_local(|local| {
                for (entry, f) in local.iter_mut().zip(row_free) {
                    *entry = f.map_or(0.0, |j| x[j]);
                }
            })
            .map_err(error)?;
        if let Err((why, iterations)) = self
            .krylov
            .solve(&self.rhs, &mut self.solution)
            .map_err(error)?
        {
            return Err(why.message(iterations));
        }
        self.gather
            .gather(&self.solution, |mine| x.copy_from_slice(mine))
            .map_err(error)
    }
}

/// The heat model's `link` (on this process's part `heat_part` of the scene's mesh) to the
/// mechanics `mesh` of the part `part`, whose elements lie in the scene elements `origin`:
/// a node of the scene's mesh reads the heat model's node, another (a split's) its
/// position in the scene element of its first element. Every element lies in a scene
/// element of `heat_part`: a split part's element in its scene element, within the ring
/// around the part's own scene elements; a ghost-surface element stands in with an own one.
pub(super) fn link_on_part(
    link: HeatLink,
    (mesh, part, origin): (&TetMesh, &Part, &[usize]),
    heat_part: &Part,
) -> Result<HeatLink, SimError> {
    let element_source = (origin.iter())
        .map(|o| {
            heat_part.elements.binary_search(o).map_err(|_| {
                SimError::Setup(format!(
                    "split part: scene element {o} lies outside the heat model's part"
                ))
            })
        })
        .collect::<Result<Vec<usize>, SimError>>()?;
    let scene_nodes = heat_part.whole_nodes();
    let heat_node = |k: usize| {
        let i = part.nodes[k];
        (i < scene_nodes).then(|| heat_part.local(i)).flatten()
    };
    Ok(link.relinked((&mesh.rest, &mesh.tets), element_source, heat_node))
}
