//! A run whose processes hold ghost surfaces for ice–ice contact (see
//! `distributed::surface_hold`): gathering them again as the ice moves.

use super::{attach_heat, Run, RunError};
use crate::sim::handover::PartMap;
use crate::sim::{SimError, Simulation};

impl Run<'_> {
    /// Gathers the processes' ghost surfaces (see `distributed::surface_hold`) again where the
    /// next step needs more than they hold, or after a `restarted` point, and continues on the
    /// new parts from the state reached; if it did, whether the surfaces were outgrown and
    /// the time it took (s). Every process calls it.
    ///
    /// A run resumed from a restart point gathers its surfaces there, so the uninterrupted
    /// run does too: the two then hold the same elements and gather at the same steps after,
    /// and a gathering there changes nothing else (the solver starts without memory at a
    /// restart point, as on the new parts): a resumed run is the uninterrupted one bit for bit.
    pub(super) fn hold_surfaces(
        &mut self,
        restarted: bool,
    ) -> Result<Option<(bool, f64)>, RunError> {
        if let Some(fracture) = &mut self.on_parts {
            // Fracture on the parts holds its own ghost surface, gathered again as the ice
            // moves; at a restart point on the part a run resumed there makes (see
            // `FractureOnParts::restart`).
            let outgrown = fracture.surface_outgrown(&self.sim);
            let start = std::time::Instant::now();
            match (restarted, outgrown) {
                (true, _) => fracture.restart(&mut self.sim)?,
                (false, true) => fracture.gather_surface_again(&mut self.sim)?,
                (false, false) => return Ok(None),
            }
            return Ok(Some((outgrown, start.elapsed().as_secs_f64())));
        }
        let (Some((processes, part)), Some(scene)) = (&self.shared, &self.whole) else {
            return Ok(None);
        };
        let outgrown = processes.surface_outgrown(&self.sim, part);
        if !(restarted || outgrown) {
            return Ok(None);
        }
        let start = std::time::Instant::now();
        let setup = |error| RunError::Setup {
            path: scene.path.clone(),
            error,
        };
        let (next_part, model) =
            (processes.regathered(&scene.model, &self.sim, part)).map_err(setup)?;
        let mut next = Simulation::for_part(model, self.settings).map_err(setup)?;
        attach_heat(scene, &mut next, Some(&next_part))?;
        let sharing = processes.mesh_sharing().ok_or_else(|| {
            setup(SimError::Setup(
                "the processes do not share values between parts".into(),
            ))
        })?;
        let old = |items: &[usize], i: &usize| items.binary_search(i).ok();
        let nodes: Vec<_> = next_part
            .nodes
            .iter()
            .map(|i| old(&part.nodes, i))
            .collect();
        let elements: Vec<_> = (next_part.elements.iter())
            .map(|e| old(&part.elements, e))
            .collect();
        let map = PartMap {
            nodes: &nodes,
            elements: &elements,
        };
        (self.sim)
            .hand_over(&mut next, map, &|values| sharing.copy_from_owners(values))
            .map_err(setup)?;
        // The old simulation goes before the new one's share of the solver is made.
        self.sim = next;
        processes.distribute(&mut self.sim).map_err(setup)?;
        if let Some((_, part)) = &mut self.shared {
            *part = next_part;
        }
        Ok(Some((outgrown, start.elapsed().as_secs_f64())))
    }
}
