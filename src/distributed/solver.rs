//! The linear solve of a distributed run: each process adds its part of the Hessian (the
//! columns where its elements and nodes write, on its part of the mesh) into a PETSc matrix
//! over all 3n dofs, whose rows the processes own by node; PETSc sums the parts, and
//! conjugate gradients with algebraic multigrid (hypre's BoomerAMG; PETSc's GAMG, with the
//! rigid-body modes as near-null space, on request) solve — or, where one process would
//! factorise (the scene's `linear = "cholesky"`, or `auto` on a small system), every process
//! factorises the whole matrix with MUMPS (see `Krylov::direct`). The constrained dofs are
//! rows of the diagonal only (their update is zero), which keeps every node's 3 × 3 block for
//! the multigrid. Each process gathers the solution on its part's dofs.

use super::partition::PartNumbering;
use super::petsc::{Divergence, Gather, Int, Krylov, Matrix, PetscError, Vector};
use super::traffic;
use crate::assembly::Assembly;
use crate::solver::{ExternalSolver, LinearError, LinearStats};
use nalgebra::Vector3;
use std::time::Instant;

impl From<PetscError> for LinearError {
    fn from(e: PetscError) -> Self {
        LinearError::External(e.to_string())
    }
}

/// PETSc's solver on one pattern.
pub struct PetscSolver {
    matrix: Matrix,
    krylov: Krylov,
    rhs: Vector,
    solution: Vector,
    gather: Gather,
    /// Free columns this process adds (the dofs of its elements' nodes and of the nodes its
    /// own nodes are coupled to), and for each its rows' PETSc indices
    /// (`rows[row_ptr[k]..row_ptr[k + 1]]`).
    columns: Vec<usize>,
    row_ptr: Vec<usize>,
    rows: Vec<Int>,
    /// PETSc index of each free dof.
    petsc_of_free: Vec<Int>,
    /// For each of this process's rows, its free dof (`None`: constrained).
    local_free: Vec<Option<usize>>,
    /// First PETSc row of this process.
    first_row: usize,
    n_free: usize,
    /// Entries a factorisation adds to other processes' rows.
    entries_sent: usize,
    /// Other processes' entries a product with the matrix reads (its off-process columns).
    halo: usize,
    /// Entries gathered from the others per solve.
    gathered: usize,
}

impl PetscSolver {
    /// The solver for `assembly`'s pattern on process `rank`, on its part of the mesh
    /// numbered by `numbering` (its nodes' PETSc numbers), its elements `tets`
    /// (those it evaluates marked in `owned_elements`), the nodes' rest positions `rest` (m);
    /// with `direct`, MUMPS factorises ([`Krylov::direct`]), else CG stops at the relative
    /// residual `rtol` or after `max_iterations`.
    pub fn new(
        assembly: &Assembly,
        numbering: &PartNumbering,
        (rank, owned_elements, tets): (u32, &[bool], &[[usize; 4]]),
        rest: &[Vector3<f64>],
        (direct, rtol, max_iterations): (bool, f64, usize),
    ) -> Result<Self, LinearError> {
        let n_nodes = rest.len();
        let global = 3 * numbering.whole_nodes();
        if global > Int::MAX as usize {
            return Err(LinearError::External(format!(
                "{global} dofs exceed PETSc's 32-bit indices"
            )));
        }
        let dofs = assembly.dofs();
        let petsc_dof = |d: usize| (3 * numbering.petsc_node[d / 3] + d % 3) as Int;
        let petsc_of_free: Vec<Int> = dofs.free_dofs().iter().map(|&d| petsc_dof(d)).collect();
        let r = rank as usize;
        let (start, end) = (numbering.node_start[r], numbering.node_start[r + 1]);
        let (first_row, local) = (3 * start, 3 * (end - start));
        // This process's rows in PETSc order: its nodes' dofs (all in its part).
        let mut node_of_row = vec![0usize; end - start];
        for (v, &i) in numbering.petsc_node.iter().enumerate() {
            if (start..end).contains(&i) {
                node_of_row[i - start] = v;
            }
        }
        let local_free: Vec<Option<usize>> = node_of_row
            .iter()
            .flat_map(|&v| (0..3).map(move |k| 3 * v + k))
            .map(|d| dofs.free(d))
            .collect();
        // Preallocation from the pattern: every entry any process adds is in it.
        let symbolic = assembly.symbolic();
        let in_range = |i: Int| (first_row..first_row + local).contains(&(i as usize));
        let mut diagonal = vec![1 as Int; local];
        let mut off = vec![0 as Int; local];
        for (i, f) in local_free.iter().enumerate() {
            if let Some(c) = *f {
                let rows = symbolic.row_idx_of_col_raw(c);
                let inside = rows.iter().filter(|&&r| in_range(petsc_of_free[r])).count();
                diagonal[i] = inside as Int;
                off[i] = (rows.len() - inside) as Int;
            }
        }
        let mut matrix = Matrix::new(local, global, 3, (&diagonal, &off))?;
        let coordinates: Vec<f64> = node_of_row
            .iter()
            .flat_map(|&v| [rest[v].x, rest[v].y, rest[v].z])
            .collect();
        matrix.set_rigid_body_modes(&coordinates, global)?;
        // The columns this process adds: the free dofs of its elements' nodes, and of the
        // nodes its own nodes are coupled to (a nodal volumetric energy's ring, a contact
        // pair), where its nodes' terms write.
        let mut touched = vec![false; n_nodes];
        for (tet, &own) in tets.iter().zip(owned_elements) {
            if own {
                for &v in tet {
                    touched[v] = true;
                }
            }
        }
        for &v in &node_of_row {
            for k in 0..3 {
                if let Some(c) = dofs.free(3 * v + k) {
                    for &r in symbolic.row_idx_of_col_raw(c) {
                        touched[dofs.free_dofs()[r] / 3] = true;
                    }
                }
            }
        }
        let columns: Vec<usize> = (0..dofs.num_free())
            .filter(|&c| touched[dofs.free_dofs()[c] / 3])
            .collect();
        let mut row_ptr = vec![0];
        let mut rows = Vec::new();
        for &c in &columns {
            rows.extend(
                symbolic
                    .row_idx_of_col_raw(c)
                    .iter()
                    .map(|&r| petsc_of_free[r]),
            );
            row_ptr.push(rows.len());
        }
        let entries_sent = columns
            .iter()
            .zip(row_ptr.windows(2))
            .filter(|(&c, _)| !in_range(petsc_of_free[c]))
            .map(|(_, w)| w[1] - w[0])
            .sum();
        let mut halo: Vec<Int> = local_free
            .iter()
            .flatten()
            .flat_map(|&c| {
                symbolic
                    .row_idx_of_col_raw(c)
                    .iter()
                    .map(|&r| petsc_of_free[r])
            })
            .filter(|&i| !in_range(i))
            .collect();
        halo.sort_unstable();
        halo.dedup();
        let rhs = Vector::new(local, global, 3)?;
        let solution = Vector::new(local, global, 3)?;
        let gather = Gather::new(&solution, &petsc_of_free)?;
        let gathered = petsc_of_free.iter().filter(|&&i| !in_range(i)).count();
        Ok(PetscSolver {
            matrix,
            krylov: if direct {
                Krylov::direct()?
            } else {
                Krylov::cg_amg(rtol, max_iterations)?
            },
            rhs,
            solution,
            gather,
            columns,
            row_ptr,
            rows,
            petsc_of_free,
            local_free,
            first_row,
            n_free: dofs.num_free(),
            entries_sent,
            halo: halo.len(),
            gathered,
        })
    }
}

impl ExternalSolver for PetscSolver {
    fn factorize(&mut self, assembly: &Assembly, values: &[f64]) -> Result<(), LinearError> {
        self.matrix.zero()?;
        let col_ptr = assembly.symbolic().col_ptr();
        let mut diagonal_sum = 0.0;
        let mut diagonal_count = 0usize;
        for (k, &c) in self.columns.iter().enumerate() {
            // The pattern and the values are symmetric: column c is row c.
            let column = &values[col_ptr[c]..col_ptr[c + 1]];
            let rows = &self.rows[self.row_ptr[k]..self.row_ptr[k + 1]];
            self.matrix.add_row(self.petsc_of_free[c], rows, column)?;
            diagonal_sum += values[assembly.diagonal_slot(c)].abs();
            diagonal_count += 1;
        }
        // A constrained dof's row is its diagonal alone, scaled like this process's part of
        // the others so as not to stand out in the multigrid's smoothing.
        let scale = if diagonal_sum > 0.0 {
            diagonal_sum / diagonal_count as f64
        } else {
            1.0
        };
        for (i, f) in self.local_free.iter().enumerate() {
            if f.is_none() {
                let row = (self.first_row + i) as Int;
                self.matrix.add_row(row, &[row], &[scale])?;
            }
        }
        self.matrix.assemble()?;
        traffic::add(&traffic::MATRIX_ENTRIES, self.entries_sent);
        self.krylov.set_matrix(&self.matrix)?;
        let count = self.krylov.non_positive_eigenvalues()?;
        if count > 0 {
            return Err(LinearError::NonPositiveEigenvalues {
                count,
                n: self.n_free,
            });
        }
        Ok(())
    }

    fn solve(&mut self, b: &[f64], x: &mut [f64]) -> Result<LinearStats, LinearError> {
        let start = Instant::now();
        let local_free = &self.local_free;
        self.rhs.write_local(|local| {
            for (entry, f) in local.iter_mut().zip(local_free) {
                *entry = f.map_or(0.0, |f| b[f]);
            }
        })?;
        let outcome = self.krylov.solve(&self.rhs, &mut self.solution)?;
        let iterations = match outcome {
            // One solve with the factor, counted as one iteration as one process's Cholesky.
            Ok(_) if self.krylov.is_direct() => 1,
            Ok(iterations) => iterations,
            Err((Divergence::Indefinite, iteration)) => {
                return Err(LinearError::NegativeCurvature {
                    iteration,
                    n: self.n_free,
                })
            }
            Err((Divergence::Iterations, iterations)) => {
                return Err(LinearError::CgNotConverged {
                    iterations,
                    residual: f64::NAN,
                })
            }
            Err((why, iterations)) => return Err(LinearError::External(why.message(iterations))),
        };
        traffic::add(&traffic::HALO, self.halo * iterations);
        traffic::add(&traffic::GATHERED, self.gathered);
        self.gather
            .gather(&self.solution, |mine| x.copy_from_slice(mine))?;
        Ok(LinearStats {
            t_solve: start.elapsed().as_secs_f64(),
            iterations,
            setups: 0,
            t_setup: 0.0,
        })
    }
}
