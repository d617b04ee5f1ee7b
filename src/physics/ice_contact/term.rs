//! Ice–ice contact as a term of the model: built from a scene's mesh, carried through
//! splits and restricted to a process's part.

use super::{Candidate, IceContact, IceFriction, IceStep};
use crate::assembly::Assembly;
use crate::mesh::TetMesh;
use crate::physics::contact::{default_stiffness, stiffness_for_edge};
use crate::physics::contact_forces::SceneContact;
use crate::physics::crack_sides::CopyFrame;
use crate::physics::term::{
    NodeRestriction, Remesh, Solve, StepStartView, StepTerm, Term, TermHistory,
};
use nalgebra::Vector3;

/// Ice–ice contact as a term of the incremental potential: present in every model, active
/// while the mesh has several parts or cracks (`[physics] ice_stiffness`, `ice_friction`).
#[derive(Clone, Debug)]
pub struct IceContactTerm {
    /// Penalty stiffness (N/m³); 0 takes [`default_stiffness`] of each mesh.
    pub stiffness: f64,
    /// Coulomb friction coefficient between pieces.
    pub friction: f64,
    /// Friction smoothing velocity (m/s).
    pub smoothing_velocity: f64,
    /// The contact of the current mesh, if it has several parts or cracks.
    pub active: Option<IceContact>,
    /// Candidate pairs of the current step.
    candidates: Vec<Candidate>,
    /// CSC value indices of each candidate's 12 × 12 block (row-major), `u32::MAX` where a
    /// dof is constrained.
    candidate_slots: Vec<Vec<u32>>,
    /// The frames of the pairs of copies of the current step (see [`CrackSides::frames`]).
    copy_frames: Vec<CopyFrame>,
}

/// The name of the pairs' carried gaps in the state and in frames (see the module docs).
pub const CRACK_GAPS: &str = "crack_gaps";

/// The crack gaps `history` carries (rows p, q, g) with their nodes renumbered by `number`;
/// a pair with a node `number` does not give is dropped.
pub fn renumbered_gaps(
    history: &TermHistory,
    number: impl Fn(usize) -> Option<usize>,
) -> TermHistory {
    let rows: Vec<f64> = (history.get(CRACK_GAPS).chunks_exact(3))
        .filter_map(|r| {
            // Node numbers are whole numbers below 2^53, exact as f64.
            let at = |x: f64| number(x as usize).map(|k| k as f64);
            Some([at(r[0])?, at(r[1])?, r[2]])
        })
        .flatten()
        .collect();
    let mut renumbered = TermHistory::default();
    if !rows.is_empty() {
        renumbered.set(CRACK_GAPS, 3, rows);
    }
    renumbered
}

impl IceContactTerm {
    /// The term on `mesh` with crack faces `cracks`; `stiffness` 0 takes the default
    /// 10 E / h of the mesh with Young's modulus `young` (Pa).
    pub fn new(
        mesh: &TetMesh,
        stiffness: f64,
        friction: f64,
        smoothing_velocity: f64,
        cracks: &[[usize; 3]],
        young: f64,
    ) -> Self {
        let k = || {
            if stiffness > 0.0 {
                stiffness
            } else {
                default_stiffness(mesh, young)
            }
        };
        IceContactTerm {
            stiffness,
            friction,
            smoothing_velocity,
            active: IceContact::new(mesh, k, friction, smoothing_velocity, cracks),
            candidates: Vec::new(),
            candidate_slots: Vec::new(),
            copy_frames: Vec::new(),
        }
    }

    /// The term with the given parameters, inactive until a remesh gives its mesh several
    /// parts or cracks.
    pub fn inactive(stiffness: f64, friction: f64, smoothing_velocity: f64) -> Self {
        IceContactTerm {
            stiffness,
            friction,
            smoothing_velocity,
            active: None,
            candidates: Vec::new(),
            candidate_slots: Vec::new(),
            copy_frames: Vec::new(),
        }
    }

    /// Number of candidate pairs of the current step.
    pub fn num_candidates(&self) -> usize {
        self.candidates.len()
    }

    fn step<'a>(&'a self, rest: &'a [Vector3<f64>], slots: &'a [Vec<u32>]) -> Option<IceStep<'a>> {
        self.active.as_ref().map(|term| IceStep {
            term,
            rest,
            candidates: &self.candidates,
            slots,
            anticipated: Vec::new(),
            friction: None,
        })
    }
}

impl SceneContact for IceContactTerm {
    fn exerts_forces(&self) -> bool {
        self.active.is_some()
    }
    fn bookkeeping_len(&self) -> usize {
        self.candidate_slots.len()
    }
}

impl Term for IceContactTerm {
    fn name(&self) -> &'static str {
        "ice contact"
    }
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
    fn clone_box(&self) -> Box<dyn Term> {
        Box::new(self.clone())
    }
    /// Finds the candidate pairs of the coming step; the pattern must couple exactly their
    /// nodes. Keeping the pattern a function of the step's start state (never a
    /// history-dependent superset) keeps resumed runs bit-identical.
    fn start_step(&mut self, start: &StepStartView) -> Option<Vec<(usize, usize)>> {
        let term = self.active.as_ref()?;
        let sides = &term.copies;
        let normals = sides.normals(start.rest, start.u);
        let gaps = sides.gaps_of_rows(start.carried.get(CRACK_GAPS));
        // Kept for every pair, also those not facing each other this step: their gaps are
        // carried all the same.
        self.copy_frames = sides.frames(start.rest, start.u, &normals, &gaps);
        let at = (start.u, start.max_speed);
        self.candidates = term.candidates(start.rest, at, start.dt, &self.copy_frames);
        let mut couplings: Vec<(usize, usize)> = self
            .candidates
            .iter()
            .flat_map(|c| c.face.map(|f| (c.node.min(f), c.node.max(f))))
            .collect();
        couplings.sort_unstable();
        couplings.dedup();
        Some(couplings)
    }
    fn carried(&self) -> Option<(&'static str, usize)> {
        let term = self.active.as_ref()?;
        (!term.copies.is_empty()).then_some((CRACK_GAPS, 3))
    }
    fn carry(&self, rest: &[Vector3<f64>], u: &[f64]) -> Vec<f64> {
        self.active.as_ref().map_or(Vec::new(), |term| {
            let sides = &term.copies;
            sides.rows(&sides.gaps(rest, u, &self.copy_frames))
        })
    }
    fn inherit(&self, old: &[f64], node_parent: &[usize]) -> Vec<f64> {
        self.active.as_ref().map_or(Vec::new(), |term| {
            let sides = &term.copies;
            sides.rows(&sides.inherited_gaps(old, node_parent))
        })
    }
    fn pattern_ready(&mut self, assembly: &Assembly, _changed: bool) {
        if self.active.is_none() {
            return;
        }
        self.candidate_slots = self
            .candidates
            .iter()
            .map(|c| {
                let nodes = IceContact::pair_nodes(c);
                (0..144)
                    .map(|rc| {
                        let (r, col) = (rc / 12, rc % 12);
                        let (dr, dc) = (3 * nodes[r / 3] + r % 3, 3 * nodes[col / 3] + col % 3);
                        match (assembly.dofs().free(dr), assembly.dofs().free(dc)) {
                            (Some(fr), Some(fc)) => {
                                assembly.slot(fr, fc).map_or(u32::MAX, |s| s as u32)
                            }
                            _ => u32::MAX,
                        }
                    })
                    .collect()
            })
            .collect();
    }
    fn begin_solve<'a>(&'a self, solve: &Solve<'a>) -> Option<Box<dyn StepTerm + 'a>> {
        let mut ice = self.step(solve.rest, &self.candidate_slots)?;
        if solve.dynamic && ice.term.friction > 0.0 {
            let frames =
                ice.extrapolated_friction_frames(solve.rest, solve.previous, solve.earlier);
            ice.friction = Some(IceFriction {
                dt: solve.h,
                previous: solve.previous,
                frames,
            });
        }
        Some(Box::new(ice))
    }
    fn stored_energy(&self, rest: &[Vector3<f64>], u: &[f64], _t: f64) -> f64 {
        self.step(rest, &[])
            .map_or(0.0, |ice| ice.evaluate(u, None, None, None))
    }
    fn as_contact(&self) -> Option<&dyn SceneContact> {
        Some(self)
    }
    fn restricted(&self, part: &NodeRestriction) -> Box<dyn Term> {
        Box::new(IceContactTerm {
            active: self.active.as_ref().map(|c| c.restricted(part)),
            candidates: Vec::new(),
            candidate_slots: Vec::new(),
            copy_frames: Vec::new(),
            ..*self
        })
    }
    fn remeshed(&self, remesh: &Remesh) -> Box<dyn Term> {
        let w = remesh.whole;
        let (piece, pieces) = w.pieces;
        let active = (pieces >= 2 || !remesh.cracks.is_empty()).then(|| {
            let stiffness = match self.stiffness > 0.0 {
                true => self.stiffness,
                false => stiffness_for_edge(crate::mesh::mean_edge(w.perimeters), remesh.young),
            };
            IceContact::on_boundary(
                (remesh.mesh, w.boundary, w.perimeters),
                (piece.to_vec(), pieces),
                stiffness,
                (self.friction, self.smoothing_velocity),
                remesh.cracks,
            )
        });
        Box::new(IceContactTerm {
            active,
            ..IceContactTerm::inactive(self.stiffness, self.friction, self.smoothing_velocity)
        })
    }
}
