//! Conjugate gradients preconditioned by one V-cycle of smoothed-aggregation multigrid
//! ([`crate::solver::amg`]), whose hierarchy is kept across Newton iterations and steps while
//! [`HierarchyReuse`] says it is still effective.

use super::error::{LinearError, LinearStats};
use super::reuse::HierarchyReuse;
use super::settings::IterativeSettings;
use crate::assembly::Assembly;
use crate::solver::amg::{Amg, AmgInfo};
use crate::solver::pcg::{pcg, MatrixOperators, PcgFailure, PcgWork, Preconditioner};
use nalgebra::Vector3;
use std::time::Instant;

/// CG preconditioned by a smoothed-aggregation hierarchy that is kept across Newton iterations
/// and steps: within a run the matrix changes slowly, and a hierarchy built for an earlier
/// matrix is still a good (symmetric positive-definite) preconditioner for the current one.
/// It is rebuilt on the next [`AmgCg::factorize`] once a solve needed more than
/// [`REFRESH_GROWTH`](super::reuse::REFRESH_GROWTH) times the iterations of the first solve
/// after the last set-up.
pub struct AmgCg {
    amg: Amg,
    tolerance: f64,
    max_iterations: usize,
    /// Iteration cap of a solve with a fresh hierarchy (or before its first count).
    fresh_cap: usize,
    /// When the hierarchy is rebuilt.
    reuse: HierarchyReuse,
    work: PcgWork,
    /// Set-ups so far.
    setups: usize,
    /// Set-up time so far (s).
    t_setup: f64,
    /// Iterations and time (s) of every solve so far, for statistics.
    history: Vec<(usize, f64)>,
}

/// What multigrid-preconditioned CG has done so far.
#[derive(Clone, Debug)]
pub struct AmgStats<'a> {
    /// The current hierarchy.
    pub hierarchy: AmgInfo,
    /// Set-ups so far.
    pub setups: usize,
    /// Their total time (s).
    pub t_setup: f64,
    /// Iterations and time (s) of every solve so far.
    pub solves: &'a [(usize, f64)],
}

impl AmgCg {
    /// A solver for `n` free dofs of a mesh whose nodes are at rest at `coords` (m, for the
    /// rigid-body modes), with CG's tolerance and cap and the reuse of hierarchies from
    /// `settings`; solves with a fresh hierarchy stop after `fresh_cap` iterations.
    pub fn new(
        coords: &[Vector3<f64>],
        n: usize,
        settings: &IterativeSettings,
        fresh_cap: usize,
    ) -> Self {
        AmgCg {
            amg: Amg::new(coords),
            tolerance: settings.tolerance,
            max_iterations: settings.max_iterations,
            fresh_cap,
            reuse: HierarchyReuse::new(settings.amg_reuse),
            work: PcgWork::new(n),
            setups: 0,
            t_setup: 0.0,
            history: Vec::new(),
        }
    }

    /// What the solver has done so far.
    pub fn stats(&self) -> AmgStats<'_> {
        AmgStats {
            hierarchy: self.amg.info(),
            setups: self.setups,
            t_setup: self.t_setup,
            solves: &self.history,
        }
    }

    /// Whether hierarchies are kept between refreshes (then the solves read the matrix
    /// values themselves).
    pub fn reuses(&self) -> bool {
        self.reuse.reuses()
    }

    /// The matrix values changed in place since the last set-up.
    pub fn matrix_changed(&mut self) {
        self.reuse.matrix_changed();
    }

    /// Prepares solves with the matrix of these values: keeps the hierarchy if
    /// [`HierarchyReuse`] says so, else sets one up. Returns whether it set one up.
    pub fn factorize(&mut self, assembly: &Assembly, values: &[f64]) -> Result<bool, LinearError> {
        if self.reuse.keeps_hierarchy(self.amg.is_built()) {
            return Ok(false);
        }
        self.setup(assembly, values)?;
        Ok(true)
    }

    /// Builds the hierarchy for these values; returns its time (s).
    fn setup(&mut self, assembly: &Assembly, values: &[f64]) -> Result<f64, LinearError> {
        let start = Instant::now();
        self.amg.setup(assembly, values)?;
        self.reuse.set_up();
        self.setups += 1;
        let t = start.elapsed().as_secs_f64();
        self.t_setup += t;
        Ok(t)
    }

    /// Solves `A x = b` by one PCG solve with the matrix `values`; a stale hierarchy that lets
    /// it fail is rebuilt once and the solve repeated (the abandoned iterations are counted:
    /// they were paid for, and the rebuild is the solve's set-up). `x` is overwritten.
    pub fn solve(
        &mut self,
        assembly: &Assembly,
        values: &[f64],
        b: &[f64],
        x: &mut [f64],
    ) -> Result<LinearStats, LinearError> {
        let start = Instant::now();
        let n = b.len();
        // Iterations of an attempt with a stale hierarchy that was abandoned, and the time (s)
        // of the rebuild that replaced it.
        let mut abandoned = 0;
        let mut rebuilt = None;
        loop {
            let mut ops = MatrixOperators {
                assembly,
                values,
                preconditioner: VCycle(&mut self.amg),
            };
            let cap = self
                .reuse
                .stale_cap(self.max_iterations)
                .unwrap_or(self.fresh_cap);
            let checkpoint = self.reuse.checkpoint(self.tolerance);
            let result = pcg(
                &mut ops,
                b,
                x,
                self.tolerance,
                cap,
                checkpoint,
                &mut self.work,
            );
            match result {
                Ok(iterations) => {
                    self.reuse.converged(iterations);
                    let iterations = iterations + abandoned;
                    let stats =
                        LinearStats::with_setup(start.elapsed().as_secs_f64(), iterations, rebuilt);
                    self.history.push((iterations, stats.t_solve));
                    return Ok(stats);
                }
                Err(PcgFailure::NegativeCurvature { iteration }) => {
                    return Err(LinearError::NegativeCurvature { iteration, n })
                }
                Err(failure) if self.reuse.is_stale() => {
                    abandoned += failure.iterations();
                    rebuilt = Some(self.setup(assembly, values)?);
                }
                Err(PcgFailure::NoConvergence { residual, .. }) => {
                    return Err(LinearError::CgNotConverged {
                        iterations: self.max_iterations,
                        residual,
                    })
                }
                // A V-cycle built on a positive-definite matrix is positive definite; one built
                // on an indefinite tangent (compressed corotated elements) is not, and CG sees
                // rᵀM⁻¹r ≤ 0 before it meets negative curvature: the same verdict.
                Err(PcgFailure::Breakdown { iteration }) => {
                    return Err(LinearError::NegativeCurvature { iteration, n })
                }
            }
        }
    }
}

/// One V-cycle of the hierarchy as a preconditioner.
struct VCycle<'a>(&'a mut Amg);

impl Preconditioner for VCycle<'_> {
    fn precondition(&mut self, r: &[f64], z: &mut [f64]) {
        self.0.apply(r, z);
    }
}
