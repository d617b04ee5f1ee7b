//! The energy balance of a solve: the energy after it may exceed the energy before it only by
//! the work done on the ice. Also the energies of a state, which the check and `/stats` use.
//!
//! For the backward-Euler incremental potential, with Ψ the stored energy of the solve (the
//! elastic energy with the step's eigenstrain and freeze state, the dead loads' potential and
//! the contact penalties at the step's end time) and x its minimiser under the supports' new
//! positions, the energy E = ½ vᵀM v + Ψ changes over the solve by exactly
//!
//!   E(xₙ₊₁) − E'(xₙ) = r·Δx_D + f_μ·Δx − ½ ΔvᵀM Δv − h vₙ₊₁ᵀC vₙ₊₁ − D_Ψ(xₙ, xₙ₊₁),
//!
//! where E'(xₙ) is the start state measured with the step's own loads (so the work of the
//! freezing expansion and of moving obstacles is in it), r the support reactions, Δx_D the
//! supports' motion, f_μ the friction forces, C the damping, and D_Ψ ≥ 0 the Bregman
//! divergence of Ψ (for convex Ψ). A static solve has the same bound without the kinetic
//! terms. Energy beyond the supports' and friction's work therefore means the solve is not a
//! minimiser of a consistent potential: Newton stopped at a round-off floor far from the
//! solution (a penalty stiffness 1e12 times the ice's), or a term's stored energy and the
//! potential it adds disagree. Non-convex elasticity and contact make D_Ψ slightly negative,
//! which [`EXCESS_TOLERANCE`] allows.

use super::terms::{elastic_term, ElasticInputs};
use super::{Energies, Simulation};
use crate::assembly::Assembly;
use crate::physics::term::StepTerm;
use crate::physics::Model;

/// Energy that may appear in a solve beyond the work done, as a fraction of the solve's
/// energy scale ([`Balance::scale`]). On the shipped scenes the largest excess measured is
/// 4.7e-7 of the scale; the margin is for the non-convex parts of corotated elasticity and
/// ice–ice contact, where D_Ψ can be slightly negative. A solve stopped at its round-off floor
/// by a 1e25 N/m³ wall gained about as much as the whole scale (19× this allowance).
pub const EXCESS_TOLERANCE: f64 = 0.05;

/// The energies of one solve and the work done on the ice during it (J).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Balance {
    /// The start state measured with the solve's loads, freeze state and obstacle positions.
    pub before: Energies,
    /// The solution, before the plastic strain is updated (which only releases energy).
    pub after: Energies,
    /// Work of the supports: reactions times their motion over the solve.
    pub supports: f64,
    /// Work of friction on the ice (negative unless an obstacle drags the ice along).
    pub friction: f64,
    /// Energy Newton's tolerance leaves undetermined: the residual force it accepts times
    /// the solve's Σ|Δu| over the free dofs (a bound on the residual's work, J).
    pub unresolved: f64,
}

impl Balance {
    /// Work done on the ice that can raise its energy (J): the supports', and friction's
    /// where it is positive.
    pub fn work(&self) -> f64 {
        self.supports + self.friction.max(0.0)
    }

    /// Energy the solve gained beyond the work done (J); ≤ 0 for a consistent solve.
    pub fn excess(&self) -> f64 {
        self.after.total() - self.before.total() - self.work()
    }

    /// The energy that moves in the solve (J): kinetic, elastic and contact energies before
    /// and after, the change of the loads' potential and the work — the yardstick for the
    /// excess (the loads' potential itself has an arbitrary zero).
    pub fn scale(&self) -> f64 {
        let stored = |e: &Energies| e.kinetic + e.elastic.abs() + e.contact;
        stored(&self.before)
            + stored(&self.after)
            + (self.after.potential - self.before.potential).abs()
            + self.supports.abs()
            + self.friction.abs()
    }

    /// Round-off in the totals (J): the load potential can be far larger than what moves.
    fn roundoff(&self) -> f64 {
        1e-12 * (self.before.potential.abs() + self.after.potential.abs() + self.scale())
    }

    /// The excess allowed (J): [`EXCESS_TOLERANCE`] of the scale, the energy Newton's
    /// tolerance leaves undetermined, and round-off.
    pub fn allowed(&self) -> f64 {
        EXCESS_TOLERANCE * self.scale() + self.unresolved + self.roundoff()
    }

    /// Whether the excess is within what is allowed.
    pub fn holds(&self) -> bool {
        self.excess() <= self.allowed()
    }
}

/// Energy appeared in a solve that no work accounts for.
#[derive(Clone, Debug, thiserror::Error)]
#[error(
    "the energy rose from {:.4e} J to {:.4e} J with {:.4e} J of work done by supports and friction: {:.3e} J more than the work, {:.1}× the {:.3e} J allowed ({:.0} % of the {:.3e} J that moved, and Newton's tolerance) — a penalty stiffness too large for the step, or a solve stopped at its round-off floor",
    .0.before.total(),
    .0.after.total(),
    .0.work(),
    .0.excess(),
    .0.excess() / .0.allowed(),
    .0.allowed(),
    100.0 * EXCESS_TOLERANCE,
    .0.scale()
)]
pub struct EnergyRise(pub Box<Balance>);

impl Simulation {
    /// Checks that the solution `u`, with energies `after`, holds no more energy
    /// than the solve's start — its energies `before`, measured at the state with the solve's
    /// loads, freeze state and obstacles — and the work done on the ice during the solve (see
    /// this module); `tolerance` is the residual force Newton accepts (N). Returns `after`.
    pub(super) fn check_balance(
        &mut self,
        before: Energies,
        after: Energies,
        u: &[f64],
        tolerance: f64,
    ) -> Result<Energies, EnergyRise> {
        let dofs = self.assembly.dofs();
        // The reactions are the gradient of the solve's potential on the constrained dofs.
        // Each dof counted on the process that owns it, in a distributed run.
        let reaction = self.workspace.gradient();
        let supports = (0..u.len())
            .filter(|&d| dofs.free(d).is_none() && self.counts(d))
            .map(|d| reaction[d] * (u[d] - self.previous[d]))
            .sum();
        let unresolved = tolerance
            * dofs
                .free_dofs()
                .iter()
                .filter(|&&d| self.counts(d))
                .map(|&d| (u[d] - self.previous[d]).abs())
                .sum::<f64>();
        let friction = (0..self.contact_forces.friction.len())
            .filter(|&d| self.counts(d))
            .map(|d| self.contact_forces.friction[d] * (u[d] - self.previous[d]))
            .sum();
        let supports = self.sum_over_processes(supports);
        let unresolved = self.sum_over_processes(unresolved);
        let friction = self.sum_over_processes(friction);
        let balance = Balance {
            before,
            after,
            supports,
            friction,
            unresolved,
        };
        if balance.holds() {
            Ok(after)
        } else {
            Err(EnergyRise(Box::new(balance)))
        }
    }
}

/// Energies of `model` at displacement and velocity `(u, v)` (m, m/s; 3 per node) and time
/// `t` (s) with the dead `loads` (N, 3 per node), the elastic energy from `elastic` (the
/// elements' history and strain offsets).
///
/// With a subset (a process's elements and owned dofs in a distributed run) the elastic
/// energy is that process's part of it, to be summed across the processes.
pub(super) fn energies_of(
    model: &Model,
    assembly: &Assembly,
    elastic: ElasticInputs,
    (u, v, t, loads): (&[f64], &[f64], f64, &[f64]),
) -> Energies {
    let mut energy = 0.0;
    elastic_term(model, assembly, elastic).add(u, &mut energy, None, None);
    energies_with(model, energy, (u, v), (t, loads))
}

/// Energies of `model` at `(u, v)`, time `t` and dead `loads` (N, 3 per node) with the elastic
/// energy `elastic` (J) known.
pub(super) fn energies_with(
    model: &Model,
    elastic: f64,
    (u, v): (&[f64], &[f64]),
    (t, loads): (f64, &[f64]),
) -> Energies {
    let kinetic = v
        .iter()
        .enumerate()
        .map(|(d, v)| 0.5 * model.mass[d / 3] * v * v)
        .sum();
    let potential = -loads.iter().zip(u).map(|(f, u)| f * u).sum::<f64>();
    // The model's terms in order (obstacles, then ice–ice contact): the total is their sum
    // in order.
    let contact = (model.terms.iter())
        .map(|term| term.stored_energy(&model.mesh.rest, u, t))
        .sum();
    Energies {
        kinetic,
        elastic,
        potential,
        contact,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn energies(kinetic: f64, elastic: f64, potential: f64) -> Energies {
        Energies {
            kinetic,
            elastic,
            potential,
            contact: 0.0,
        }
    }

    #[test]
    fn a_falling_body_trading_potential_for_kinetic_energy_balances() {
        // 1 kg falling 1 cm: 0.0981 J of potential becomes kinetic, less what damping takes.
        let b = Balance {
            before: energies(0.0, 0.0, 0.0),
            after: energies(0.0980, 0.0, -0.0981),
            ..Default::default()
        };
        assert!(b.excess() < 0.0);
        assert!(b.holds());
    }

    #[test]
    fn energy_from_nowhere_is_refused_and_work_done_is_allowed() {
        let gained = Balance {
            before: energies(0.001, 0.002, 0.0),
            after: energies(8.3, 0.002, 0.0),
            ..Default::default()
        };
        assert!(!gained.holds());
        let message = EnergyRise(Box::new(gained)).to_string();
        assert!(message.contains("more than the work"), "{message}");
        // The same rise with the supports doing that work is a balance.
        let pulled = Balance {
            supports: 8.299,
            ..gained
        };
        assert!(pulled.holds());
        // Friction removing energy does not make room for a rise elsewhere.
        let braked = Balance {
            friction: -8.3,
            ..gained
        };
        assert!(!braked.holds());
    }

    #[test]
    fn a_large_load_potential_leaves_room_only_for_round_off() {
        // A body far from its rest position: the load potential is 1e6 J, what moves 1e-3 J.
        let b = Balance {
            before: energies(0.0, 1e-3, -1e6),
            after: energies(0.0, 1e-3, -1e6 + 1e-9),
            ..Default::default()
        };
        assert!(b.holds());
        let rise = Balance {
            after: energies(1.0, 1e-3, -1e6),
            ..b
        };
        assert!(!rise.holds());
    }
}
