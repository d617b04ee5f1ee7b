//! The acceleration of a state from its forces: where a scheme that carries an acceleration
//! (Newmark) starts.

use super::potential::{Share, StepPotential};
use super::terms::{solve_terms, ElasticInputs};
use super::Simulation;
use crate::physics::term::Solve;

impl Simulation {
    /// The acceleration of the current state from its forces, a = −M⁻¹ (∇Ψ(u) + D v) on the
    /// free dofs (Ψ: elasticity, dead loads and contact at the state's time; D the Rayleigh
    /// damping), 0 on the supported ones: what a scheme that carries an acceleration starts
    /// from.
    pub(super) fn acceleration_at_start(&mut self) -> Vec<f64> {
        let t = self.state.time;
        self.set_time(t);
        let offsets = self.state.history.offsets();
        let max_speed = self.max_speed();
        let model = &self.model;
        let solve = Solve {
            rest: &model.mesh.rest,
            previous: &self.state.u,
            velocity: &self.state.v,
            max_speed,
            earlier: &self.state.u,
            h: self.settings.dt,
            dynamic: true,
            times: (t, t),
        };
        let subset = self
            .shared
            .as_ref()
            .map(|s| (&s.elements, s.distribution.owned_dofs()));
        let elastic = ElasticInputs {
            history: &self.state.history,
            offsets: &offsets,
            element_energy: &mut self.element_energy,
            subset,
            // The acceleration of the state's stress: nothing creeps in no time.
            creep: None,
        };
        let (elastic, terms) = solve_terms(model, &self.assembly, elastic, &self.loads, &solve);
        let mut potential = StepPotential::new(elastic, terms);
        // Summed over the processes of a distributed run.
        potential.share = self.shared.as_ref().map(|s| Share {
            collective: s.distribution.collective(),
            owned: s.distribution.owned_dofs(),
            assembly: &self.assembly,
        });
        let mut gradient = vec![0.0; self.state.u.len()];
        crate::solver::Potential::gradient(&mut potential, &self.state.u, &mut gradient);
        drop(potential);
        let damping = model.damping.unwrap_or_default();
        for (d, g) in gradient.iter_mut().enumerate() {
            *g += damping.mass * model.mass[d / 3] * self.state.v[d];
        }
        if damping.stiffness > 0.0 {
            self.previous.copy_from_slice(&self.state.u);
            self.stiffness_at_previous(damping.stiffness);
            let dofs = self.assembly.dofs();
            let v: Vec<f64> = dofs.free_dofs().iter().map(|&d| self.state.v[d]).collect();
            let mut force = vec![0.0; v.len()];
            self.assembly
                .multiply(&self.damping_stiffness, &v, &mut force);
            // A process of a distributed run holds its share of β Kₙ: the processes' forces
            // at a node add up.
            let mut damping_force = vec![0.0; gradient.len()];
            for (f, &d) in force.iter().zip(dofs.free_dofs()) {
                damping_force[d] = *f;
            }
            self.exchange_sum(&mut damping_force);
            for (g, f) in gradient.iter_mut().zip(&damping_force) {
                *g += f;
            }
        }
        let model = &self.model;
        let dofs = self.assembly.dofs();
        // A process of a distributed run has the masses of its owned nodes (see
        // `Model::restrict`): the others' accelerations come from their owners.
        let mut a: Vec<f64> = (0..gradient.len())
            .map(|d| match dofs.free(d) {
                Some(_) if model.mass[d / 3] > 0.0 => -gradient[d] / model.mass[d / 3],
                _ => 0.0,
            })
            .collect();
        self.exchange_owned(&mut a);
        a
    }
}
