//! A process's simulation continued on another part of the mesh: the same run, its owned
//! nodes and own elements the same, with other elements held beside them (a ghost surface
//! gathered again, see `distributed::surface_hold`).

use super::{SchemeState, SimError, Simulation, State};

/// Where the nodes and elements of the new part come from.
pub struct PartMap<'a> {
    /// For each node of the new part, the same node in the old part, if it held it.
    pub nodes: &'a [Option<usize>],
    /// For each element of the new part, the same element in the old part, if it held it.
    pub elements: &'a [Option<usize>],
}

impl Simulation {
    /// Gives `next` — this run's simulation on another part of the mesh, built from the
    /// scene's model with its heat model attached, not yet distributed — the state reached:
    /// displacements, velocities, what the time scheme carries and temperatures node by node
    /// as `map` says, the other nodes' values from their owners through `from_owners` (which
    /// sets every node the process does not own to its owner's value, 3 per node); the
    /// elements' history element by element. An element the old part did not hold has no
    /// node the process owns and is never evaluated here: it takes the first element's
    /// history as a stand-in. The terms' carried rows belong to fractured runs, which hold
    /// the whole mesh, and do not pass.
    pub fn hand_over(
        &self,
        next: &mut Simulation,
        map: PartMap,
        from_owners: &dyn Fn(&mut [f64]),
    ) -> Result<(), SimError> {
        if !self.state.term_history.0.is_empty() {
            return Err(SimError::NotDistributed(
                "carrying a term's rows to another part of the mesh",
            ));
        }
        let nodes = |old: &[f64], columns: usize| -> Vec<f64> {
            if old.is_empty() {
                return Vec::new();
            }
            // Three columns per node, as `from_owners` reads them.
            let mut new = vec![0.0; 3 * map.nodes.len()];
            for (k, from) in map.nodes.iter().enumerate() {
                if let Some(i) = from {
                    new[3 * k..3 * k + columns]
                        .copy_from_slice(&old[columns * i..columns * (i + 1)]);
                }
            }
            from_owners(&mut new);
            (new.chunks_exact(3))
                .flat_map(|row| row[..columns].to_vec())
                .collect()
        };
        let parent: Vec<usize> = map.elements.iter().map(|e| e.unwrap_or(0)).collect();
        let state = &self.state;
        next.state = State {
            u: nodes(&state.u, 3),
            v: nodes(&state.v, 3),
            time: state.time,
            step: state.step,
            history: state.history.inherit(&parent),
            temperature: next.state.temperature.clone(),
            carried: SchemeState {
                fields: (state.carried.fields.iter())
                    .map(|(name, field)| (*name, nodes(field, 3)))
                    .collect(),
                scalars: state.carried.scalars.clone(),
            },
            term_history: Default::default(),
            next_dt: state.next_dt,
        };
        if next.heat().is_some() {
            next.set_temperature(nodes(&state.temperature, 1));
        }
        next.set_time(state.time);
        Ok(())
    }
}
