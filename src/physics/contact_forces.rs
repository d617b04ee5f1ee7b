//! What a contact term tells the step beyond its energy: the forces it exerts on the ice (for
//! output and the energy balance's friction work), the time it spends choosing contact
//! pairs, and what it holds. Side traits of [`super::term::StepTerm`] and
//! [`super::term::Term`], reached through their `as_contact`.

/// Per-node contact forces on the ice (N), for output.
#[derive(Clone, Debug, Default)]
pub struct ContactForces {
    /// Normal (penalty) force per node, 3 per node.
    pub normal: Vec<f64>,
    /// Friction force per node, 3 per node.
    pub friction: Vec<f64>,
}

/// A contact term during one solve.
pub trait SolveContact {
    /// Adds the term's contact forces on the ice at `u` (N, 3 per node).
    fn add_contact_forces(&self, u: &[f64], forces: &mut ContactForces);
    /// Wall time this term spent choosing its contact pairs during the solve (s).
    fn broad_phase_time(&self) -> f64 {
        0.0
    }
}

/// A contact term a scene enables.
pub trait SceneContact {
    /// Whether the term exerts contact forces on the ice (they are then written per frame).
    fn exerts_forces(&self) -> bool;
    /// Entries held for the term's bookkeeping (to show a term that is off costs nothing).
    fn bookkeeping_len(&self) -> usize;
}
