//! Heat conduction with freezing on a tet mesh: ρ c ∂T/∂t = ∇·(k ∇T) with the latent heat of
//! water ↔ ice through an enthalpy formulation ([`Phases`]).
//!
//! Discretisation: P1 temperatures at the nodes, lumped capacity (each node carries the mass
//! m_i = Σ ρ V_e / 4 of its elements and the specific enthalpy h(T_i)), backward Euler in
//! time. Per step, for every free node i,
//!
//! r_i = m_i (h(T_i) − h(T_iⁿ)) / Δt + (K T)_i + H_i (T_i − T_air,i) = 0,
//!
//! K the P1 conductivity matrix with each element's conductivity from its ice fraction at the
//! step's start (lagged: the step's only explicit part), H_i the lumped convection
//! coefficient Σ h A / 3 of the node's convecting boundary triangles. Fixed-temperature nodes
//! are eliminated; insulated boundaries need nothing. r is the gradient of the convex
//! potential Σ m_i/Δt (Ĥ(T_i) − h(T_iⁿ) T_i) + ½ Tᵀ K T + Σ H_i (½ T_i² − T_air,i T_i)
//! (Ĥ' = h, h increasing), so Newton with a backtracking line search on it converges from any
//! start, whatever the mushy range; the Jacobian diag(m_i h'(T_i)/Δt + H_i) + K is symmetric
//! positive definite, factorised by sparse Cholesky on a pattern analysed once
//! ([`system::ScalarSystem`]).
//!
//! Energy: K's columns sum to zero, so at the solution the change of the nodes' enthalpy
//! Σ m_i (h(T_i) − h(T_iⁿ)) equals the heat that came in over the step, Δt (Σ H_i (T_air,i −
//! T_i) + Σ_fixed (K T)_d), up to Δt Σ r_i: every step reports both ([`HeatStep`]).

pub mod enthalpy;
pub mod link;
pub mod monotone;
pub mod neumann;
pub mod shared;
pub mod system;

pub use enthalpy::{Phase, Phases};
pub use link::HeatLink;
pub use shared::HeatShare;

use crate::mesh::TetMesh;
use monotone::{add_corrected_conduction, EdgeCorrection, ObtuseEdges};
use nalgebra::Matrix3;
use system::{ScalarSystem, PAIRS};

/// Failures of the heat model.
#[derive(Debug, thiserror::Error)]
pub enum ThermalError {
    /// Inputs that do not define a heat problem.
    #[error("heat model: {0}")]
    Setup(String),
    /// A step whose Newton iteration did not converge.
    #[error("heat step to t = {time} s: {reason}")]
    Step {
        /// Time the step was to reach (s).
        time: f64,
        /// What went wrong.
        reason: String,
    },
}

/// The boundary conditions of the heat model (nodes and triangles of the mesh).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HeatBoundary {
    /// Nodes held at a temperature (°C).
    pub fixed: Vec<(usize, f64)>,
    /// Boundary triangles exchanging heat with a fluid: nodes, heat transfer coefficient h
    /// (W/(m² K)) and the fluid's temperature (°C).
    pub convection: Vec<([usize; 3], f64, f64)>,
}

impl HeatBoundary {
    /// The boundary on a part of the mesh, whose node `local(i)` is node `i` of the whole
    /// mesh (`None`: not in the part): the fixed nodes and convecting triangles it holds.
    pub fn restricted(&self, local: impl Fn(usize) -> Option<usize>) -> HeatBoundary {
        HeatBoundary {
            fixed: (self.fixed.iter())
                .filter_map(|&(i, t)| Some((local(i)?, t)))
                .collect(),
            convection: (self.convection.iter())
                .filter_map(|&(tri, h, t)| {
                    let [a, b, c] = tri.map(&local);
                    Some(([a?, b?, c?], h, t))
                })
                .collect(),
        }
    }
}

/// What a heat step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HeatStep {
    /// Newton iterations (each a solve).
    pub newton_iterations: usize,
    /// Numeric factorisations: one per iteration, less those whose matrix was the one already
    /// factored (no node changed its segment of h, same step and conductivities).
    pub factorizations: usize,
    /// Solves of the step: 1, plus one for each round of cancelled couplings (see
    /// `monotone`).
    pub passes: usize,
    /// Edges whose positive coupling the step cancelled.
    pub cancelled_edges: usize,
    /// Heat that came in through the boundary over the step (J): convection and the
    /// fixed-temperature nodes.
    pub heat_in: f64,
    /// Change of the nodes' enthalpy over the step (J): sensible and latent.
    pub enthalpy_change: f64,
    /// Latent part of the change (J): L × the change of the frozen mass, released heat
    /// negative.
    pub latent_change: f64,
    /// Wall time of the step (s).
    pub t_step: f64,
}

impl HeatStep {
    /// |enthalpy change − heat in| (J): zero at the exact solution of the step.
    pub fn imbalance(&self) -> f64 {
        (self.enthalpy_change - self.heat_in).abs()
    }
}

/// The heat model of a mesh and its nodal temperatures.
pub struct Heat {
    phases: Phases,
    /// Nodal mass m_i (kg).
    mass: Vec<f64>,
    tets: Vec<[usize; 4]>,
    /// V ∇λ_a · ∇λ_b per element for the [`PAIRS`] (m).
    geometry: Vec<[f64; 10]>,
    /// The edges whose coupling can be positive (see `monotone`).
    obtuse: ObtuseEdges,
    /// Free number of each node (`None`: fixed temperature).
    free: Vec<Option<usize>>,
    /// Lumped convection coefficient H_i (W/K) and H_i T_air,i (W) per node.
    convection: Vec<(f64, f64)>,
    /// Nodal temperature (°C).
    temperature: Vec<f64>,
    system: ScalarSystem,
    /// Whether this process counts each free node in sums and maxima: it owns it (every node
    /// on one process).
    counted: Vec<bool>,
    /// This process's share of a distributed run.
    share: Option<Box<dyn HeatShare>>,
}

/// Newton stops when the largest residual is this fraction of the largest diagonal of the
/// Jacobian times 1 K (the heat flow a 1 K change of the stiffest node would cause): far below
/// what the front's position resolves, and above round-off for any mesh.
const RELATIVE_TOLERANCE: f64 = 1e-10;
/// Newton iterations before a step is declared failed.
const MAX_ITERATIONS: usize = 50;

impl Heat {
    /// The heat model of `mesh` with nodal masses `mass` (kg), the `phases`, `boundary` and the
    /// `initial` nodal temperatures (°C; fixed nodes take their fixed value).
    pub fn new(
        mesh: &TetMesh,
        mass: Vec<f64>,
        phases: Phases,
        boundary: &HeatBoundary,
        initial: Vec<f64>,
    ) -> Result<Self, ThermalError> {
        let setup = |m: String| ThermalError::Setup(m);
        phases.check().map_err(setup)?;
        let n = mesh.num_nodes();
        if mass.len() != n || initial.len() != n {
            return Err(setup(format!(
                "{} masses and {} initial temperatures for {n} nodes",
                mass.len(),
                initial.len()
            )));
        }
        if let Some(t) = initial.iter().find(|t| !t.is_finite()) {
            return Err(setup(format!("initial temperature {t} is not finite")));
        }
        let mut temperature = initial;
        let mut fixed = vec![false; n];
        for &(i, t) in &boundary.fixed {
            if i >= n || !t.is_finite() {
                return Err(setup(format!("fixed temperature {t} at node {i} of {n}")));
            }
            fixed[i] = true;
            temperature[i] = t;
        }
        let mut count = 0;
        let free = fixed
            .iter()
            .map(|&f| {
                (!f).then(|| {
                    count += 1;
                    count - 1
                })
            })
            .collect::<Vec<_>>();
        let mut convection = vec![(0.0, 0.0); n];
        for &(tri, h, t_air) in &boundary.convection {
            if !(h.is_finite() && h >= 0.0 && t_air.is_finite()) || tri.iter().any(|&i| i >= n) {
                return Err(setup(format!(
                    "convection h = {h} W/(m² K) to {t_air} °C on triangle {tri:?}"
                )));
            }
            let x = tri.map(|i| mesh.rest[i]);
            let area = 0.5 * (x[1] - x[0]).cross(&(x[2] - x[0])).norm();
            for i in tri {
                convection[i].0 += h * area / 3.0;
                convection[i].1 += h * area / 3.0 * t_air;
            }
        }
        let geometry: Vec<[f64; 10]> = mesh
            .tets
            .iter()
            .map(|t| {
                let x = t.map(|i| mesh.rest[i]);
                let d = Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[3] - x[0]]);
                let volume = d.determinant().abs() / 6.0;
                // Rows of D⁻¹ are ∇λ1, ∇λ2, ∇λ3; ∇λ0 = −their sum.
                let inv = d.try_inverse().unwrap_or_else(Matrix3::zeros);
                let g1 = inv.row(0).transpose();
                let g2 = inv.row(1).transpose();
                let g3 = inv.row(2).transpose();
                let g = [-(g1 + g2 + g3), g1, g2, g3];
                PAIRS.map(|(a, b)| volume * g[a].dot(&g[b]))
            })
            .collect();
        let system = ScalarSystem::new(&mesh.tets, &free, count).map_err(setup)?;
        let obtuse = ObtuseEdges::new(&mesh.tets, &geometry);
        Ok(Heat {
            phases,
            mass,
            tets: mesh.tets.clone(),
            geometry,
            obtuse,
            free,
            convection,
            temperature,
            system,
            counted: vec![true; count],
            share: None,
        })
    }

    /// Shares the heat model among the processes of a distributed run: this model is a
    /// process's part (see [`shared`]), `make` builds its share from the heat system's
    /// pattern and each node's free number.
    pub fn distribute(
        &mut self,
        make: impl FnOnce(&ScalarSystem, &[Option<usize>]) -> Result<Box<dyn HeatShare>, String>,
    ) -> Result<(), ThermalError> {
        let share = make(&self.system, &self.free).map_err(ThermalError::Setup)?;
        for (i, free) in self.free.iter().enumerate() {
            if let Some(j) = free {
                self.counted[*j] = share.owned()[i];
            }
        }
        self.share = Some(share);
        Ok(())
    }

    /// Whether this process counts node `i` in sums over the nodes: it owns it.
    fn counts(&self, i: usize) -> bool {
        self.share.as_ref().is_none_or(|s| s.owned()[i])
    }

    /// Σ of `x` over the processes (`x` on one).
    fn sum(&self, x: f64) -> f64 {
        self.share.as_ref().map_or(x, |s| s.sum(x))
    }

    /// Largest `x` over the processes (`x` on one).
    fn max(&self, x: f64) -> f64 {
        self.share.as_ref().map_or(x, |s| s.max(x))
    }

    /// Σ_i m_i f(T_i) over the nodes this process counts, for the nodes' values `f` (summed
    /// over the processes).
    fn mass_sum(&self, f: impl Fn(usize, f64) -> f64) -> f64 {
        let local = (self.mass.iter().enumerate())
            .filter(|(i, _)| self.counts(*i))
            .map(|(i, m)| m * f(i, self.temperature[i]))
            .sum();
        self.sum(local)
    }

    /// Σ a_j b_j over the free nodes this process counts, summed over the processes.
    fn dot(&self, a: &[f64], b: &[f64]) -> f64 {
        let local = (a.iter().zip(b).zip(&self.counted))
            .filter(|(_, &c)| c)
            .map(|((a, b), _)| a * b)
            .sum();
        self.sum(local)
    }

    /// Nodal temperatures (°C).
    pub fn temperature(&self) -> &[f64] {
        &self.temperature
    }

    /// Sets the nodal temperatures (°C), e.g. from a stored frame; fixed nodes keep theirs.
    pub fn set_temperature(&mut self, t: &[f64]) {
        for ((dst, &src), free) in self.temperature.iter_mut().zip(t).zip(&self.free) {
            if free.is_some() {
                *dst = src;
            }
        }
    }

    /// The phases.
    pub fn phases(&self) -> &Phases {
        &self.phases
    }

    /// Ice fraction of each node, 0 … 1.
    pub fn nodal_ice_fraction(&self) -> Vec<f64> {
        let p = &self.phases;
        self.temperature
            .iter()
            .map(|&t| p.ice_fraction(t))
            .collect()
    }

    /// Ice fraction of each element: the mean of its nodes' (the lumped nodes' share of it).
    pub fn element_ice_fraction(&self) -> Vec<f64> {
        let f = self.nodal_ice_fraction();
        self.tets
            .iter()
            .map(|t| t.iter().map(|&i| f[i]).sum::<f64>() / 4.0)
            .collect()
    }

    /// Total enthalpy Σ m_i h(T_i) (J, relative to ice at the mushy range's lower end); in a
    /// distributed run, over the whole mesh (every process calls it).
    pub fn enthalpy(&self) -> f64 {
        self.mass_sum(|_, t| self.phases.enthalpy(t))
    }

    /// Frozen mass Σ m_i f(T_i) (kg); in a distributed run, over the whole mesh (every
    /// process calls it).
    pub fn frozen_mass(&self) -> f64 {
        self.mass_sum(|_, t| self.phases.ice_fraction(t))
    }

    /// Element conductivities (W/(m K)) from the current ice fractions.
    fn conductivities(&self) -> Vec<f64> {
        self.element_ice_fraction()
            .into_iter()
            .map(|f| self.phases.conductivity(f))
            .collect()
    }

    /// Number of edges whose conduction coupling can be positive (obtuse angles), which get
    /// a cancelling conductance where it is (see `monotone`).
    pub fn obtuse_edges(&self) -> usize {
        self.obtuse.len()
    }

    /// (K T) per node for element conductivities `k`, with the step's edge `corrections`.
    fn conduction(&self, k: &[f64], corrections: &[EdgeCorrection], t: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; t.len()];
        add_corrected_conduction(corrections, t, &mut out);
        for ((tet, g), ke) in self.tets.iter().zip(&self.geometry).zip(k) {
            for (p, &(a, b)) in PAIRS.iter().enumerate() {
                let v = ke * g[p];
                out[tet[a]] += v * t[tet[b]];
                if a != b {
                    out[tet[b]] += v * t[tet[a]];
                }
            }
        }
        out
    }

    /// Advances the temperatures by one backward-Euler step of `dt` (s), to time `time` (s,
    /// for messages).
    pub fn step(&mut self, dt: f64, time: f64) -> Result<HeatStep, ThermalError> {
        let start = std::time::Instant::now();
        let p = self.phases;
        let h0: Vec<f64> = self.temperature.iter().map(|&t| p.enthalpy(t)).collect();
        let frozen0 = self.frozen_mass();
        let k = self.conductivities();
        // Plain P1 first; nodes that end the step as new extrema get their positive couplings
        // cancelled and the step is solved again (see `monotone`).
        let mut cancel = vec![false; self.obtuse.len()];
        let (mut iterations, mut factorizations, mut passes) = (0, 0, 0);
        let n_free = self.free.iter().flatten().count();
        let (t, heat_in, cancelled_edges) = loop {
            let corrections = self.obtuse.corrections(&k, &self.geometry, &cancel);
            let residual = StepResidual {
                k: &k,
                corrections: &corrections,
                h0: &h0,
                dt,
                n_free,
            };
            let solve = self.solve_step(&residual, time)?;
            iterations += solve.iterations;
            factorizations += solve.factorizations;
            passes += 1;
            if self.mark_extrema(&solve.temperature, &mut cancel) == 0 {
                let heat_in = self.heat_in(&residual, &solve.temperature);
                // Each edge counted by the process owning its first node, which holds it
                // whole.
                let counted = (corrections.iter())
                    .filter(|c| self.counts(c.nodes.0))
                    .count();
                break (
                    solve.temperature,
                    heat_in,
                    self.sum(counted as f64) as usize,
                );
            }
        };
        let enthalpy_change = self.mass_sum(|i, _| p.enthalpy(t[i]) - h0[i]);
        self.temperature = t;
        let latent_change = -p.latent_heat * (self.frozen_mass() - frozen0);
        Ok(HeatStep {
            newton_iterations: iterations,
            factorizations,
            passes,
            cancelled_edges,
            heat_in,
            enthalpy_change,
            latent_change,
            t_step: start.elapsed().as_secs_f64(),
        })
    }

    /// Marks in `cancel` the positive couplings of the nodes that end the step at
    /// temperatures `t` as new local extrema (against the step's start, their neighbours and
    /// their air); how many were newly marked.
    fn mark_extrema(&self, t: &[f64], cancel: &mut [bool]) -> usize {
        let air = |i: usize| {
            let (h, ht) = self.convection[i];
            (h > 0.0).then(|| ht / h)
        };
        // Each process judges the nodes it owns, whose neighbours are all on it.
        let free = |i: usize| self.free[i].is_some() && self.counts(i);
        let Some(share) = &self.share else {
            return self
                .obtuse
                .mark_extrema(&self.temperature, t, air, free, cancel);
        };
        let before = cancel.to_vec();
        self.obtuse
            .mark_extrema(&self.temperature, t, air, free, cancel);
        // The edges any process marked, marked on every process holding them.
        let whole = share.whole_nodes();
        let key = |(a, b): (usize, usize)| (whole[a].min(whole[b]), whole[a].max(whole[b]));
        let mine: Vec<(usize, usize)> = (self.obtuse.edge_nodes().enumerate())
            .filter(|(e, _)| cancel[*e] && !before[*e])
            .map(|(_, nodes)| key(nodes))
            .collect();
        let marked = share.union(&mine);
        for (e, nodes) in self.obtuse.edge_nodes().enumerate() {
            if marked.binary_search(&key(nodes)).is_ok() {
                cancel[e] = true;
            }
        }
        marked.len()
    }

    /// Newton on the step's `residual` from the current temperatures, with an exact line
    /// search; `time` (s) is for messages.
    fn solve_step(
        &mut self,
        residual: &StepResidual,
        time: f64,
    ) -> Result<HeatSolve, ThermalError> {
        let mut t = self.temperature.clone();
        let (mut iterations, mut factorizations) = (0, 0);
        let mut r = residual.of(self, &t);
        loop {
            // The Jacobian, its scale and the convergence test.
            self.assemble_jacobian(residual, &t);
            let largest_diagonal = self.max(self.system.largest_diagonal(&self.counted));
            let worst = (r.iter().zip(&self.counted))
                .filter(|(_, &c)| c)
                .fold(0.0f64, |m, (v, _)| m.max(v.abs()));
            let worst = self.max(worst);
            // No free node on any process: the largest diagonal is 0.
            if worst <= RELATIVE_TOLERANCE * largest_diagonal || largest_diagonal == 0.0 {
                break;
            }
            if iterations == MAX_ITERATIONS {
                return Err(ThermalError::Step {
                    time,
                    reason: format!(
                        "Newton did not converge in {MAX_ITERATIONS} iterations (largest residual {worst:.3e} W)"
                    ),
                });
            }
            iterations += 1;
            let failed = |reason| ThermalError::Step { time, reason };
            factorizations += usize::from(self.factor().map_err(failed)?);
            let mut step: Vec<f64> = r.iter().map(|v| -v).collect();
            self.solve_in_place(&mut step).map_err(failed)?;
            t = self.line_search(residual, &t, &r, &step);
            r = residual.of(self, &t);
        }
        Ok(HeatSolve {
            temperature: t,
            iterations,
            factorizations,
        })
    }

    /// The Jacobian diag(m_i h'(T_i)/Δt + H_i) + K of the step's residual at temperatures `t`
    /// into the system.
    fn assemble_jacobian(&mut self, residual: &StepResidual, t: &[f64]) {
        let (k, dt) = (residual.k, residual.dt);
        self.system.clear();
        for (e, g) in self.geometry.iter().enumerate() {
            self.system.add_element(e, &g.map(|v| k[e] * v));
        }
        for c in residual.corrections {
            let (a, b) = c.nodes;
            let (e, pair) = c.part;
            for i in [a, b] {
                if let Some(j) = self.free[i] {
                    self.system.add_diagonal(j, c.conductance);
                }
            }
            self.system.add_element_entry(e, pair, -c.conductance);
        }
        for (i, free) in self.free.iter().enumerate() {
            if let Some(j) = free {
                let d = self.mass[i] / dt * self.phases.capacity(t[i]) + self.convection[i].0;
                self.system.add_diagonal(*j, d);
            }
        }
    }

    /// The temperatures `t` + α `step` (`step` over the free nodes) where the potential is
    /// least along `step`, α in (0, 1], for the residual `r` at `t`.
    fn line_search(&self, residual: &StepResidual, t: &[f64], r: &[f64], step: &[f64]) -> Vec<f64> {
        // Exact line search: the potential is convex and piecewise quadratic along the
        // step, so its slope φ'(α) = r(T + α δ) · δ increases; find where it crosses 0 in
        // (0, 1] (α = 1 when it is still negative there). Backtracking alone stalls when
        // nodes keep stepping across the steep mushy range and back.
        let trial = |alpha: f64| -> Vec<f64> {
            let mut x = t.to_vec();
            for (i, free) in self.free.iter().enumerate() {
                if let Some(j) = free {
                    x[i] += alpha * step[*j];
                }
            }
            x
        };
        let slope = |x: &[f64]| -> f64 { self.dot(&residual.of(self, x), step) };
        let mut alpha = 1.0;
        let mut next = trial(alpha);
        let slope_at_one = slope(&next);
        if slope_at_one > 0.0 {
            // Regula falsi with the Illinois modification on [0, 1].
            let (mut a, mut fa) = (0.0, self.dot(r, step));
            let (mut b, mut fb) = (1.0, slope_at_one);
            let mut side = 0;
            for _ in 0..60 {
                alpha = (a * fb - b * fa) / (fb - fa);
                let x = trial(alpha);
                let f = slope(&x);
                if f > 0.0 {
                    (b, fb) = (alpha, f);
                    if side == -1 {
                        fa *= 0.5;
                    }
                    side = -1;
                } else {
                    (a, fa) = (alpha, f);
                    if side == 1 {
                        fb *= 0.5;
                    }
                    side = 1;
                }
                next = x;
                if f.abs() <= 1e-12 * fa.abs().max(fb.abs()) || b - a <= 1e-12 {
                    break;
                }
            }
        }
        next
    }

    /// Heat that came in over the step of `residual` ending at temperatures `t` (J):
    /// convection at the free nodes, (K T) at the fixed ones.
    fn heat_in(&self, residual: &StepResidual, t: &[f64]) -> f64 {
        let dt = residual.dt;
        let kt = self.conduction(residual.k, residual.corrections, t);
        let local = (0..t.len())
            .filter(|&i| self.counts(i))
            .map(|i| match self.free[i] {
                Some(_) => self.convection[i].1 - self.convection[i].0 * t[i],
                None => kt[i],
            })
            .sum::<f64>();
        dt * self.sum(local)
    }

    /// Factorises the Jacobian (sets the processes' solver up), unless it is the one already
    /// factorised on every process; returns whether it did.
    fn factor(&mut self) -> Result<bool, String> {
        let Some(share) = &mut self.share else {
            return self.system.factor();
        };
        // The same decision on every process: the set-up is collective.
        let changed = f64::from(u8::from(!self.system.holds_factored()));
        if share.max(changed) == 0.0 {
            return Ok(false);
        }
        share.set_matrix(&self.system)?;
        self.system.remember_factored();
        Ok(true)
    }

    /// x ← J⁻¹ x with the last factorisation (`x` by free number).
    fn solve_in_place(&mut self, x: &mut [f64]) -> Result<(), String> {
        match &mut self.share {
            Some(share) => share.solve_in_place(x),
            None => {
                self.system.solve_in_place(x);
                Ok(())
            }
        }
    }
}

/// The residual of one heat step, r_i = m_i (h(T_i) − h(T_iⁿ)) / Δt + (K T)_i + H_i (T_i −
/// T_air,i) over the free nodes, with what it holds fixed over the step.
struct StepResidual<'a> {
    /// Element conductivities at the step's start (W/(m K)).
    k: &'a [f64],
    /// The conductances that cancel positive couplings (see `monotone`).
    corrections: &'a [EdgeCorrection],
    /// Each node's specific enthalpy at the step's start, h(T_iⁿ) (J/kg).
    h0: &'a [f64],
    /// Step (s).
    dt: f64,
    /// Number of free nodes.
    n_free: usize,
}

impl StepResidual<'_> {
    /// r (W) of `heat`'s nodes at temperatures `t`, by free number.
    fn of(&self, heat: &Heat, t: &[f64]) -> Vec<f64> {
        let (p, dt, h0) = (heat.phases, self.dt, self.h0);
        let kt = heat.conduction(self.k, self.corrections, t);
        let mut r = vec![0.0; self.n_free];
        for (i, free) in heat.free.iter().enumerate() {
            if let Some(j) = free {
                let (hc, hct) = heat.convection[i];
                r[*j] = heat.mass[i] / dt * (p.enthalpy(t[i]) - h0[i]) + kt[i] + hc * t[i] - hct;
            }
        }
        r
    }
}

/// What a step's Newton solve reached.
struct HeatSolve {
    /// Nodal temperatures at the step's end (°C).
    temperature: Vec<f64>,
    /// Newton iterations.
    iterations: usize,
    /// Numeric factorisations.
    factorizations: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_part_keeps_the_fixed_nodes_and_convecting_triangles_it_holds() {
        let boundary = HeatBoundary {
            fixed: vec![(0, -10.0), (5, -5.0)],
            convection: vec![([0, 1, 2], 500.0, -10.0), ([2, 3, 5], 10.0, -20.0)],
        };
        // The part holds whole-mesh nodes 0, 1, 2, 3 as its nodes 0 … 3.
        let local = |i: usize| (i < 4).then_some(i);
        let part = boundary.restricted(local);
        assert_eq!(part.fixed, vec![(0, -10.0)]);
        assert_eq!(part.convection, vec![([0, 1, 2], 500.0, -10.0)]);
        // Renumbered: whole node i is the part's node 3 − i.
        let part = boundary.restricted(|i: usize| (i < 4).then(|| 3 - i));
        assert_eq!(part.convection, vec![([3, 2, 1], 500.0, -10.0)]);
    }
}
