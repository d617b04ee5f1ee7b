//! A process's part of a model in a distributed run.
//!
//! The elements are split into parts (one per process) and each node is owned by one process,
//! the lowest-numbered among its elements' (so an owned node is a node of the process's own
//! elements). A process holds its part's elements, every other element around their nodes,
//! and those elements' nodes: the nodes it owns and ghost nodes it holds copies of. Every node
//! of its own elements then has all of its elements on the process — an owned node's lumped
//! mass, loads and rows of the Hessian are whole there, and so is the nodal volume of every
//! node of its own elements, which their pressures need — and a process evaluates the
//! elastic energy of its part's elements only, and everything per node on its owned nodes
//! only (`Model::restrict`), so that the processes' parts add up to the whole potential.
//!
//! Where a term couples nodes that share no element (ice–ice contact), where fracture splits
//! the mesh, or on one process, a part is the whole mesh: every element and node, each process evaluating its own elements and owned
//! nodes as above.

use super::State;
use crate::mesh::MeshError;
use crate::physics::contact::ContactForces;
use crate::physics::term::NodeRestriction;
use crate::physics::Model;

/// Marks a node that is not in a part's mesh.
const NONE: usize = usize::MAX;

/// One process's part of a mesh: its elements and nodes, numbered as in the whole mesh's order.
#[derive(Clone, Debug)]
pub struct Part {
    /// The part's elements, as elements of the whole mesh (ascending).
    pub elements: Vec<usize>,
    /// The part's nodes, as nodes of the whole mesh (ascending).
    pub nodes: Vec<usize>,
    /// Whether the process evaluates each of the part's elements (it is in its partition part).
    pub own_elements: Vec<bool>,
    /// Whether the process owns each of the part's nodes.
    pub owned_nodes: Vec<bool>,
    /// Each node of the whole mesh in the part (`usize::MAX`: not in it).
    local_node: Vec<usize>,
}

impl Part {
    /// The part of process `rank` when element `e` is in partition part `element_part[e]`
    /// and node `i` is owned by process `node_owner[i]` (one of its elements' processes): its
    /// elements, every element around their nodes, and those elements' nodes (`tets`: the
    /// whole mesh's elements). With `whole`, every element and node.
    pub fn new(
        tets: &[[usize; 4]],
        (element_part, node_owner): (&[u32], &[u32]),
        rank: u32,
        whole: bool,
    ) -> Part {
        let n = node_owner.len();
        let mut near = vec![whole; n];
        for (tet, &p) in tets.iter().zip(element_part) {
            if p == rank {
                for &v in tet {
                    near[v] = true;
                }
            }
        }
        let elements: Vec<usize> = (0..tets.len())
            .filter(|&e| tets[e].iter().any(|&v| near[v]))
            .collect();
        let mut local_node = vec![NONE; n];
        for &e in &elements {
            for &v in &tets[e] {
                local_node[v] = 0;
            }
        }
        let nodes: Vec<usize> = (0..n).filter(|&i| local_node[i] != NONE).collect();
        for (k, &i) in nodes.iter().enumerate() {
            local_node[i] = k;
        }
        Part {
            own_elements: elements.iter().map(|&e| element_part[e] == rank).collect(),
            owned_nodes: nodes.iter().map(|&i| node_owner[i] == rank).collect(),
            elements,
            nodes,
            local_node,
        }
    }

    /// The part's node of node `i` of the whole mesh, if the part holds it.
    pub fn local(&self, i: usize) -> Option<usize> {
        Some(self.local_node[i]).filter(|&k| k != NONE)
    }

    /// Whether the part is the whole mesh (every node of it).
    pub fn is_whole(&self) -> bool {
        self.nodes.len() == self.local_node.len()
    }

    /// Number of nodes of the whole mesh.
    pub fn whole_nodes(&self) -> usize {
        self.local_node.len()
    }

    /// Whether the process owns each dof of the part (3 per node).
    pub fn owned_dofs(&self) -> Vec<bool> {
        self.owned_nodes.iter().flat_map(|&o| [o; 3]).collect()
    }

    /// The part's model: `whole` on the part's elements (their history, schedule and
    /// materials inherited), with masses, loads and per-node terms on the owned nodes only
    /// (see `Model::restrict`), and its initial displacement and velocity.
    pub fn model(&self, whole: &Model) -> Result<Model, MeshError> {
        if self.is_whole() {
            return Ok(self.whole_model(whole.clone()));
        }
        let rest: Vec<_> = self.nodes.iter().map(|&i| whole.mesh.rest[i]).collect();
        let tets = self.tets_of(&whole.mesh.tets);
        let mut model = whole.remeshed(&rest, tets, &self.elements, &[])?;
        model.initial_displacement = self.dofs_of(&whole.initial_displacement);
        model.initial_velocity = self.dofs_of(&whole.initial_velocity);
        model.restrict(&self.owned_nodes, &whole.terms, &self.restriction());
        Ok(model)
    }

    /// [`Part::model`] of a part that is the whole mesh, from the whole `model` itself.
    pub fn whole_model(&self, mut model: Model) -> Model {
        debug_assert!(self.is_whole());
        let terms = std::mem::take(&mut model.terms);
        model.restrict(&self.owned_nodes, &terms, &self.restriction());
        model
    }

    /// The restriction of the whole mesh's per-node terms to the nodes this process owns.
    fn restriction(&self) -> NodeRestriction {
        NodeRestriction {
            local: self.local_node.clone(),
            kept: (0..self.whole_nodes())
                .map(|i| self.local_node[i] != NONE && self.owned_nodes[self.local_node[i]])
                .collect(),
            local_nodes: self.nodes.len(),
        }
    }

    /// The part's entries of a vector over the whole mesh's dofs (3 per node; empty stays
    /// empty).
    pub fn dofs_of(&self, whole: &[f64]) -> Vec<f64> {
        if whole.is_empty() {
            return Vec::new();
        }
        self.nodes
            .iter()
            .flat_map(|&i| [whole[3 * i], whole[3 * i + 1], whole[3 * i + 2]])
            .collect()
    }

    /// The part's elements, numbered in the part, from the whole mesh's elements `tets`.
    pub fn tets_of(&self, tets: &[[usize; 4]]) -> Vec<[usize; 4]> {
        self.elements
            .iter()
            .map(|&e| tets[e].map(|v| self.local_node[v]))
            .collect()
    }

    /// The part's rows of a field of `columns` values per node (or per element if
    /// `per_element`) of the whole mesh.
    pub fn rows_of(&self, whole: &[f64], columns: usize, per_element: bool) -> Vec<f64> {
        let items = if per_element {
            &self.elements
        } else {
            &self.nodes
        };
        items
            .iter()
            .flat_map(|&i| &whole[columns * i..columns * (i + 1)])
            .copied()
            .collect()
    }

    /// This process's share of a state for the process that writes it whole
    /// ([`StateShares::place`]): its owned nodes' and own elements' numbers and values, with
    /// the element stresses, contact forces and nodal temperatures (°C; empty without heat).
    pub fn share_of(
        &self,
        state: &State,
        stress: &[[f64; 6]],
        (contact, temperature): (&ContactForces, &[f64]),
    ) -> Vec<f64> {
        let nodes: Vec<usize> = (0..self.nodes.len())
            .filter(|&k| self.owned_nodes[k])
            .collect();
        let elements: Vec<usize> = (0..self.elements.len())
            .filter(|&k| self.own_elements[k])
            .collect();
        let h = &state.history;
        let carried = &state.carried;
        let flags = [
            !(carried.fields.is_empty() && carried.scalars.is_empty()),
            !h.plastic_strain.is_empty(),
            !h.freeze_state.is_empty(),
            !contact.normal.is_empty(),
            !temperature.is_empty(),
        ];
        let mut out = vec![nodes.len() as f64, elements.len() as f64];
        out.extend(flags.map(|f| f64::from(u8::from(f))));
        out.extend(carried.scalars.iter().map(|(_, x)| *x));
        out.extend(nodes.iter().map(|&k| self.nodes[k] as f64));
        out.extend(elements.iter().map(|&k| self.elements[k] as f64));
        let mut node_values = |v: &[f64]| {
            out.extend(nodes.iter().flat_map(|&k| &v[3 * k..3 * k + 3]));
        };
        node_values(&state.u);
        node_values(&state.v);
        for (_, field) in &carried.fields {
            node_values(field);
        }
        if flags[3] {
            node_values(&contact.normal);
            node_values(&contact.friction);
        }
        if flags[4] {
            out.extend(nodes.iter().map(|&k| temperature[k]));
        }
        for &k in &elements {
            out.push(h.eigenstrain[k]);
            if flags[1] {
                out.extend(h.plastic_strain[k].iter());
            }
            if flags[2] {
                out.push(h.freeze_state[k]);
            }
            out.extend(stress[k]);
        }
        out
    }

    /// The whole-mesh dof of each of the part's dofs (3 per node).
    pub fn whole_dofs(&self) -> impl Iterator<Item = usize> + '_ {
        self.nodes
            .iter()
            .flat_map(|&i| [3 * i, 3 * i + 1, 3 * i + 2])
    }
}

/// A state put together from the processes' shares ([`Part::share_of`]): what the writing
/// process of a distributed run writes.
#[derive(Clone, Debug, Default)]
pub struct StateShares {
    /// The state on the whole mesh (time, step and proposed step length left as they are).
    pub state: State,
    /// Element stresses (Pa, Voigt).
    pub stress: Vec<[f64; 6]>,
    /// Contact forces (N, 3 per node; empty without contact).
    pub contact: ContactForces,
    /// Nodal temperatures (°C; empty without heat).
    pub temperature: Vec<f64>,
}

impl StateShares {
    /// The whole state, zero, of a mesh of `nodes` nodes and `elements` elements for shares
    /// laid out as `share` (any process's), to [`StateShares::place`] the shares in, the time
    /// scheme carrying the node fields and scalars `carried` names
    /// ([`crate::sim::TimeIntegrator::carried_fields`] and `carried_scalars`); `None` if
    /// `share` is cut short.
    pub fn for_shares(
        share: &[f64],
        nodes: usize,
        elements: usize,
        carried: (&[&'static str], &[&'static str]),
    ) -> Option<StateShares> {
        let mut whole = StateShares::default();
        let s = &mut whole.state;
        let flags: Vec<bool> = share.get(2..7)?.iter().map(|&f| f != 0.0).collect();
        let dofs = |on: bool| if on { vec![0.0; 3 * nodes] } else { Vec::new() };
        let (carried_fields, carried_scalars) = if flags[0] {
            carried
        } else {
            (&[][..], &[][..])
        };
        let scalars = share.get(7..7 + carried_scalars.len())?;
        s.carried.scalars = carried_scalars
            .iter()
            .copied()
            .zip(scalars.iter().copied())
            .collect();
        s.carried.fields = carried_fields
            .iter()
            .map(|&name| (name, dofs(true)))
            .collect();
        (s.u, s.v) = (dofs(true), dofs(true));
        (whole.contact.normal, whole.contact.friction) = (dofs(flags[3]), dofs(flags[3]));
        s.history.eigenstrain = vec![0.0; elements];
        if flags[1] {
            s.history.plastic_strain = vec![nalgebra::Matrix3::zeros(); elements];
        }
        if flags[2] {
            s.history.freeze_state = vec![0.0; elements];
        }
        whole.stress = vec![[0.0; 6]; elements];
        if flags[4] {
            whole.temperature = vec![0.0; nodes];
        }
        Some(whole)
    }

    /// Puts one process's `share` in its place; `None` if it is cut short or does not fit.
    pub fn place(&mut self, share: &[f64]) -> Option<()> {
        let s = &mut self.state;
        let mut at = share.iter().copied();
        let (n, e) = (at.next()? as usize, at.next()? as usize);
        let flags: Vec<bool> = share.get(2..7)?.iter().map(|&f| f != 0.0).collect();
        let mut at = at.skip(5 + s.carried.scalars.len());
        let node_ids: Vec<usize> = at.by_ref().take(n).map(|x| x as usize).collect();
        let element_ids: Vec<usize> = at.by_ref().take(e).map(|x| x as usize).collect();
        if node_ids.len() != n || element_ids.len() != e {
            return None;
        }
        let mut place = |v: &mut Vec<f64>| {
            for &i in &node_ids {
                for a in 0..3 {
                    *v.get_mut(3 * i + a)? = at.next()?;
                }
            }
            Some(())
        };
        place(&mut s.u)?;
        place(&mut s.v)?;
        for (_, field) in &mut s.carried.fields {
            place(field)?;
        }
        if flags[3] {
            place(&mut self.contact.normal)?;
            place(&mut self.contact.friction)?;
        }
        if flags[4] {
            for &i in &node_ids {
                *self.temperature.get_mut(i)? = at.next()?;
            }
        }
        for &k in &element_ids {
            *s.history.eigenstrain.get_mut(k)? = at.next()?;
            if flags[1] {
                for x in s.history.plastic_strain.get_mut(k)?.iter_mut() {
                    *x = at.next()?;
                }
            }
            if flags[2] {
                *s.history.freeze_state.get_mut(k)? = at.next()?;
            }
            for x in self.stress.get_mut(k)? {
                *x = at.next()?;
            }
        }
        Some(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::history::ElementHistory;
    use crate::sim::SchemeState;

    /// The whole state of a mesh of `nodes` nodes and `elements` elements put together from
    /// every process's share, as the writing process does (`run::frame`), the time scheme
    /// carrying the node fields and scalars `carried` names; `None` if a share is cut short.
    fn whole_of(
        shares: &[Vec<f64>],
        nodes: usize,
        elements: usize,
        carried: (&[&'static str], &[&'static str]),
    ) -> Option<StateShares> {
        let mut whole = StateShares::for_shares(shares.first()?, nodes, elements, carried)?;
        for share in shares {
            whole.place(share)?;
        }
        Some(whole)
    }

    /// Node fields and a scalar a time scheme carries.
    const CARRIED: (&[&str], &[&str]) = (
        &["acceleration", "back_displacement", "back_velocity"],
        &["back_dt"],
    );

    #[test]
    fn a_part_holds_every_element_around_its_elements_nodes() {
        // A chain of three tets sharing faces, and a fourth apart.
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4], [2, 3, 4, 5], [6, 7, 8, 9]];
        // Elements 0 | 1, 2, 3; a node belongs to the lowest part among its elements'.
        let element_part = [0, 1, 1, 1];
        let owner = [0, 0, 0, 0, 1, 1, 1, 1, 1, 1];
        let first = Part::new(&tets, (&element_part, &owner), 0, false);
        // Element 0's nodes 1, 2, 3 are in elements 1 and 2 too; element 3 is apart.
        assert_eq!(first.elements, vec![0, 1, 2]);
        assert_eq!(first.own_elements, vec![true, false, false]);
        assert_eq!(first.nodes, vec![0, 1, 2, 3, 4, 5]);
        assert_eq!(
            first.owned_nodes,
            vec![true, true, true, true, false, false]
        );
        assert!(!first.is_whole());
        let second = Part::new(&tets, (&element_part, &owner), 1, false);
        assert_eq!(second.elements, vec![0, 1, 2, 3]);
        assert!(second.is_whole());
        // Part 1 being element 3 alone: nodes 0 … 5 are not in it.
        let apart = Part::new(
            &tets,
            (&[0, 0, 0, 1], &[0, 0, 0, 0, 0, 0, 1, 1, 1, 1]),
            1,
            false,
        );
        assert_eq!(apart.elements, vec![3]);
        assert_eq!(apart.nodes, vec![6, 7, 8, 9]);
        assert_eq!(apart.owned_dofs(), vec![true; 12]);
        let whole: Vec<f64> = (0..30).map(f64::from).collect();
        assert_eq!(apart.dofs_of(&whole)[..3], [18.0, 19.0, 20.0]);
        assert!(Part::new(&tets, (&element_part, &owner), 0, true).is_whole());
    }

    #[test]
    fn the_parts_shares_put_the_whole_state_back_together() {
        let tets = [[0, 1, 2, 3], [1, 2, 3, 4], [2, 3, 4, 5], [6, 7, 8, 9]];
        let (element_part, owner) = ([0, 1, 1, 1], [0, 0, 0, 0, 1, 1, 1, 1, 1, 1]);
        let value = |k: usize| (k as f64).sin();
        let dofs = |offset: usize| (0..30).map(|d| value(d + offset)).collect::<Vec<f64>>();
        let mut whole = State {
            u: dofs(0),
            v: dofs(100),
            carried: SchemeState {
                fields: vec![
                    (CARRIED.0[0], dofs(200)),
                    (CARRIED.0[1], dofs(300)),
                    (CARRIED.0[2], dofs(400)),
                ],
                scalars: vec![(CARRIED.1[0], 0.5)],
            },
            ..State::default()
        };
        whole.history = ElementHistory {
            eigenstrain: (0..4).map(|e| value(500 + e)).collect(),
            plastic_strain: (0..4)
                .map(|e| nalgebra::Matrix3::from_fn(|i, j| value(600 + 9 * e + 3 * i + j)))
                .collect(),
            freeze_state: (0..4).map(|e| value(700 + e)).collect(),
        };
        let stress: Vec<[f64; 6]> = (0..4)
            .map(|e| std::array::from_fn(|k| value(800 + 6 * e + k)))
            .collect();
        let contact = ContactForces {
            normal: dofs(900),
            friction: dofs(1000),
        };
        let temperature: Vec<f64> = (0..10).map(|i| value(1100 + i)).collect();
        let shares: Vec<Vec<f64>> = (0..2)
            .map(|rank| {
                let part = Part::new(&tets, (&element_part, &owner), rank, false);
                let state = State {
                    u: part.dofs_of(&whole.u),
                    v: part.dofs_of(&whole.v),
                    carried: SchemeState {
                        fields: (whole.carried.fields.iter())
                            .map(|(name, v)| (*name, part.dofs_of(v)))
                            .collect(),
                        scalars: whole.carried.scalars.clone(),
                    },
                    history: whole.history.inherit(&part.elements),
                    ..State::default()
                };
                let stress: Vec<_> = part.elements.iter().map(|&e| stress[e]).collect();
                let contact = ContactForces {
                    normal: part.dofs_of(&contact.normal),
                    friction: part.dofs_of(&contact.friction),
                };
                let temperature = part.rows_of(&temperature, 1, false);
                part.share_of(&state, &stress, (&contact, &temperature))
            })
            .collect();
        let together = whole_of(&shares, 10, 4, CARRIED).unwrap();
        assert_eq!(together.state, whole);
        assert_eq!(together.stress, stress);
        assert_eq!(together.contact.normal, contact.normal);
        assert_eq!(together.contact.friction, contact.friction);
        assert_eq!(together.temperature, temperature);
        // A share cut short is refused, not read past its end.
        let mut cut = shares.clone();
        cut[1].pop();
        assert!(whole_of(&cut, 10, 4, CARRIED).is_none());
    }
}
