//! Fracture of a run whose processes each hold a part of the mesh: the driver of
//! `fracture::driver` on the parts.
//!
//! After every converged step each process evaluates the separation of the nodes it owns in
//! the step's equilibrium ([`crate::fracture::separation_on_part`]: its part holds every
//! element around them; the contact forces pressing on them are summed from every process
//! that evaluates a pair at them; the nonlocal averages read the nodes within their length
//! from their owners, [`NodeHalo`]). The processes put the nodes above the toughness in the
//! order one process tries them ([`candidates_in_order`]) and try them in turn
//! ([`try_split`]), a refusal recorded by the node's owner, until one is split. Each process
//! then rebuilds its model on its split part — with ice–ice contact, on the part and the
//! elements of its ghost surface, gathered anew on the split parts, so that crack sides and
//! other pieces meet as on one process ([`model_with_surface`]) — its share of the solver,
//! and carries the state over: a node's displacement and velocity, at the step's end and at
//! its start, from its owner; an element's history from its parent; a pair of crack copies'
//! gap from the pair it was made from. The step is then taken again from its start on the
//! split parts, and the next node found in that equilibrium, as on one process.
//!
//! Every process takes the same decisions. The equilibria differ from one process's within
//! Newton's tolerance, and so do the separations: the splits are one process's until two
//! candidates' stresses are that close, or a split's crack plane passes that close to where
//! it would cut another edge (a split is not continuous in its normal). Tested on three
//! processes against one (`solver_tests/partition.rs`). With heat conduction the heat model
//! stays on the process's part of the scene's mesh, where it was set up (its pattern and
//! share of the solver last the run), and a split part reads it by position as one process's
//! split mesh reads the scene mesh's (`distributed::heat::link_on_part`): an element
//! in its scene element, which lies in that part (every element around a node of an own
//! element lies in a scene element around a node of an own scene element). Between splits
//! the ghost surface is gathered again when the ice has moved too far for it
//! ([`PartFracture::surface_outgrown`], [`PartFracture::gather_surface_again`]), as for runs
//! without fracture.
//!
//! A run resumed from a frame makes its part from the split mesh alone
//! ([`PartFracture::resumed`]): an element goes to its scene element's process (children
//! stay with their parent's), a node to the lowest process among its elements' (as splits
//! give them), and a process holds its own elements and every element around their nodes.
//! A split part also keeps elements no longer around a node of its own; so that the resumed
//! run is the uninterrupted one bit for bit, the uninterrupted run continues at each restart
//! point on the part the resumed one makes ([`PartFracture::restart`]).

use super::components::connected_parts;
use super::components::crack_ids;
use super::ghost_surface::{gathered, Surface};
use super::ghosts::all_gathered;
use super::heat::link_on_part;
use super::node_halo::NodeHalo;
use super::rebuild::{
    model_after_split, model_with_surface, numbering_after_split, share_after_split,
};
use super::splits::{candidates_in_order, try_split, SplitPart};
use super::surface_hold::{SurfaceHold, ALLOWANCE_EDGES};
use super::{agreed, largest, sum_in_order, MpiCollective};
use crate::fracture::cracks::{
    crack_area, crack_faces, polygon_sides, CrackFace, CrackSurface, OriginalBoundary,
};
use crate::fracture::driver::{
    pressing_forces, retake, solved_history, RefusedNode, CONTINUE_ANGLE, MIN_ELEMENT_FRACTION,
};
use crate::fracture::split::Fracturable;
use crate::fracture::{
    separation_on_part, FractureEvent, FractureReport, FractureSettings, NodeSeparation, OnPart,
    PartAverages,
};
use crate::mesh::TetMesh;
use crate::physics::ice_contact::{renumbered_gaps, IceContact, IceContactTerm, CRACK_GAPS};
use crate::physics::term::TermHistory;
use crate::run::{CrackTotals, FracturePart, ResumedSplit, CRACK_ROW};
use crate::sim::integrator::SchemeState;
use crate::sim::part::Part;
use crate::sim::potential::Collective;
use crate::sim::{SimError, Simulation, State};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::collections::BTreeMap;
use std::time::Instant;

/// Fracture of a run on this process's part of the mesh.
pub struct PartFracture {
    /// The parameters.
    pub settings: FractureSettings,
    /// The part that splits: this process's elements, those around their nodes, its mesh.
    held: SplitPart,
    /// The scene boundary's planes of the part's scene elements.
    original: OriginalBoundary,
    /// The refused splits of the nodes this process owns (the mesh's numbers).
    refused: BTreeMap<usize, RefusedNode>,
    /// Smallest rest volume of a piece a split may cut off (m³), and the smallest area A(n)
    /// (m²): those of the scene's whole mesh (see [`crate::fracture::Fracture`]).
    min_piece: f64,
    area_floor: f64,
    /// The simulation's part: `held`'s, with the elements of its ghost surface once the
    /// mesh has ice–ice contact; its nodes' owners and the sums over it.
    part: Part,
    node_owner: Vec<u32>,
    collective: MpiCollective,
    /// The nonlocal averages' gathered nodes (none: the local criterion).
    halo: Option<NodeHalo>,
    /// The ghost surface held, once the mesh has ice–ice contact.
    hold: Option<SurfaceHold>,
    /// CG's relative tolerance and iteration cap of the shared solver.
    solve: (f64, usize),
    /// The whole mesh's cracks (none until the first split).
    cracks: CrackTotals,
    /// This process's part of the scene's mesh, on which the heat model (with `[thermal]`)
    /// is solved through the run: a split part reads its temperatures by position.
    heat_part: Part,
}

impl PartFracture {
    /// Fracture with `settings` of the simulation `sim`, on the part `on_sim` (its mesh,
    /// state, nodes' owners and elements' processes; the part of the scene's mesh the run
    /// started on, on which the heat model stays), whose scene boundary planes are
    /// `original`; `min_piece` (m³) and `area_floor` (m²) are the whole scene mesh's (see
    /// [`crate::fracture::Fracture`]) and `solve` the shared solver's CG tolerance and cap.
    /// The part that splits is its own elements and those around their nodes; with ice–ice
    /// contact (bodies in contact from the start) `sim` continues on that part with a ghost
    /// surface the fracture gathers and holds. Every process of `world` calls it.
    pub fn new(
        world: &SimpleCommunicator,
        settings: FractureSettings,
        (on_sim, original): (SplitPart, OriginalBoundary),
        (min_piece, area_floor): (f64, f64),
        (solve, sim): ((f64, usize), &mut Simulation),
    ) -> Result<Self, SimError> {
        let (part, node_owner) = (on_sim.part.clone(), on_sim.node_owner.clone());
        let mesh = (&on_sim.mesh.rest[..], &on_sim.mesh.tets[..]);
        let halo = nonlocal_halo(world, &settings, &part, mesh, &node_owner);
        // A part holding a ghost surface for ice–ice contact holds more than splits.
        let held = canonical_part(&on_sim, world.rank() as u32);
        let mut fracture = PartFracture {
            heat_part: part.clone(),
            settings,
            collective: MpiCollective::new(&part, &node_owner),
            original,
            refused: BTreeMap::new(),
            min_piece,
            area_floor,
            halo,
            hold: None,
            part,
            node_owner,
            held,
            solve,
            cracks: CrackTotals::default(),
        };
        if sim.model.ice_contact().is_some() {
            fracture.continue_on_held(world, sim, false)?;
        }
        Ok(fracture)
    }

    /// The simulation's part (see [`PartFracture::new`]): it changes with each split.
    pub fn part(&self) -> &Part {
        &self.part
    }

    /// Whether the ghost surface held no longer holds what the next step of `sim` needs (see
    /// [`super::surface_hold`]): alike on every process of `world`, which all call it (never,
    /// before the mesh has ice–ice contact).
    pub fn surface_outgrown(&self, world: &SimpleCommunicator, sim: &Simulation) -> bool {
        let contact = sim.model.term::<IceContactTerm>();
        let (Some(hold), Some(contact)) = (&self.hold, contact.and_then(|t| t.active.as_ref()))
        else {
            return false;
        };
        let vmax = sim.state.v.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
        hold.outgrown(
            world,
            contact,
            (&self.part, &sim.state.u),
            (vmax, sim.settings.dt),
        )
    }

    /// Gathers the ghost surface again at the state of `sim` and continues `sim` on the new
    /// part: its own elements and owned nodes stay, and so does its state. Every process of
    /// `world` calls it.
    pub fn gather_surface_again(
        &mut self,
        world: &SimpleCommunicator,
        sim: &mut Simulation,
    ) -> Result<(), SimError> {
        self.continue_on_held(world, sim, false)
    }

    /// Continues `sim` at a restart point on the part a resumed run makes from the split mesh
    /// alone ([`PartFracture::resumed`]): this process's own elements (those of its scene
    /// elements), every element around their nodes, and its ghost surface gathered at the
    /// state of `sim`; numbered, owned and shared out as that part is. The elements a split
    /// left beside the part (no longer around a node of its own) and the nodes no element
    /// uses go. Every process of `world` calls it.
    pub fn restart(
        &mut self,
        world: &SimpleCommunicator,
        sim: &mut Simulation,
    ) -> Result<(), SimError> {
        self.continue_on_held(world, sim, true)?;
        // With heat, the freeze states found again from the temperatures on the new part, as
        // a resumed run finds them: those inherited were found on the part before, where a
        // split's node outside the own elements may read its temperature in another
        // element (the same value within round-off).
        sim.freeze_states_from_temperatures();
        Ok(())
    }

    /// [`PartFracture::gather_surface_again`], and with `canonical` the split part first
    /// made the one [`PartFracture::restart`] continues on.
    fn continue_on_held(
        &mut self,
        world: &SimpleCommunicator,
        sim: &mut Simulation,
        canonical: bool,
    ) -> Result<(), SimError> {
        self.carry_state_into_held(sim, None);
        let carried = SchemeState {
            fields: (sim.state.carried.fields.iter())
                .map(|(name, field)| (*name, self.ring_rows(field)))
                .collect(),
            scalars: sim.state.carried.scalars.clone(),
        };
        if canonical {
            self.held = canonical_part(&self.held, world.rank() as u32);
        }
        let mesh = &mut self.held.mesh;
        mesh.parent = (0..mesh.tets.len()).collect();
        mesh.node_parent = (0..mesh.rest.len()).collect();
        self.rebuild(world, sim, None, carried).map(|_| ())
    }

    /// The process of each element of the scene's mesh (its own elements' on every
    /// process). Every process of `world` calls it.
    pub fn scene_processes(&self, world: &SimpleCommunicator) -> Vec<u32> {
        scene_processes(world, &self.heat_part)
    }

    /// This fracture resumed from a frame, on `split`, this process's part of the frame's
    /// split mesh (see [`ResumedSplit`]): `sim` is the run as set up on
    /// [`PartFracture::part`] (no split made yet, so its elements are the scene's), with the
    /// frame's temperatures where it has a heat model. The split part's model is made from
    /// `sim`'s, each element's from its scene element's, as a split makes it; then the run is
    /// continued on the part with its ghost surface as [`PartFracture::restart`] continues
    /// it, at the frame's displacements and velocities: returned with the fracture. The
    /// parameters and what was found of the scene's mesh at set-up stay. Every process of
    /// `world` calls it.
    pub fn resumed(
        &self,
        world: &SimpleCommunicator,
        mut sim: Simulation,
        split: ResumedSplit,
    ) -> Result<(Self, Simulation), SimError> {
        let elsewhere = || SimError::Setup("another process's resumed part failed".into());
        let invalid = |e: crate::mesh::MeshError| SimError::Setup(format!("resumed part: {e}"));
        // Every element of the part lies in a scene element this part holds: an own element
        // in an own one, one around an own element's node in one sharing a node with it.
        let parent: Result<Vec<usize>, SimError> = (split.origin.iter())
            .map(|&o| {
                self.part.elements.binary_search(&o).map_err(|_| {
                    SimError::Setup(format!(
                        "resumed part: scene element {o} is not held by this process"
                    ))
                })
            })
            .collect();
        let parent = agreed(world, parent, elsewhere)?;
        let rank = world.rank() as u32;
        let refused = (split.refused.chunks_exact(4).zip(&split.part.nodes))
            .zip(&split.node_owner)
            .filter(|(_, &owner)| owner == rank)
            .filter_map(|((row, &node), _)| Some((node, RefusedNode::from_row(row)?)))
            .collect();
        let mut mesh = Fracturable::new(split.rest, split.tets, split.u, split.v);
        mesh.parent = parent;
        let held = SplitPart {
            part: split.part,
            mesh,
            node_owner: split.node_owner,
            origin: split.origin,
            process: split.process,
        };
        let model = model_after_split(world, &held, &sim.model, &self.original).map_err(invalid);
        let model = agreed(world, model, elsewhere)?;
        let mut on_split = agreed(world, Simulation::for_part(model, sim.settings), elsewhere)?;
        let parent = &held.mesh.parent;
        let heat = sim.hand_heat_to(&mut on_split, parent, |link, mesh| {
            link_on_part(link, (mesh, &held.part, &held.origin), &self.heat_part)
        });
        agreed(world, heat, elsewhere)?;
        // What the time scheme and the terms carry is the frame's, set on the final part.
        on_split.state = State {
            u: held.mesh.u.clone(),
            v: held.mesh.v.clone(),
            history: sim.state.history.inherit(parent),
            carried: SchemeState::default(),
            term_history: TermHistory::default(),
            ..sim.state.clone()
        };
        drop(sim);
        let mut resumed = PartFracture {
            settings: self.settings,
            collective: MpiCollective::new(&held.part, &held.node_owner),
            original: self.original.clone(),
            refused,
            min_piece: self.min_piece,
            area_floor: self.area_floor,
            halo: None,
            hold: None,
            node_owner: held.node_owner.clone(),
            part: held.part.clone(),
            held,
            solve: self.solve,
            cracks: CrackTotals::default(),
            heat_part: self.heat_part.clone(),
        };
        resumed.continue_on_held(world, &mut on_split, false)?;
        Ok((resumed, on_split))
    }

    /// Fractures `sim` (on [`PartFracture::part`]) after a converged step, as
    /// [`crate::fracture::Fracture::after_step`] does on one process; the report is the
    /// same on every process. Every process of `world` calls it.
    pub fn after_step(
        &mut self,
        world: &SimpleCommunicator,
        sim: &mut Simulation,
    ) -> Result<FractureReport, SimError> {
        let rank = world.rank() as u32;
        let mut report = FractureReport::default();
        loop {
            let clock = Instant::now();
            let sep = self.separations(world, sim);
            let offered: Vec<(usize, NodeSeparation)> = (0..sep.len())
                .filter(|&k| self.candidate(self.part.nodes[k], &sep[k]))
                .map(|k| (self.part.nodes[k], sep[k]))
                .collect();
            if report.events.is_empty() {
                let mine = (sep.iter().filter(|s| s.eligible))
                    .map(NodeSeparation::stress)
                    .fold(0.0, f64::max);
                report.largest_stress = largest(world, mine);
                report.t_check = clock.elapsed().as_secs_f64();
            } else {
                report.t_split += clock.elapsed().as_secs_f64();
            }
            let unresolved = sum_in_order(world, offered.len() as f64) as usize;
            if report.events.len() >= self.settings.max_events_per_step || report.resolve_failed {
                self.count_above(world, &sep, unresolved, &mut report);
                break;
            }
            let clock = Instant::now();
            let start = sim.step_start().cloned();
            self.carry_state_into_held(sim, start.as_ref());
            let mut made = None;
            for (node, owner, s) in candidates_in_order(world, &offered) {
                let tried = try_split(
                    world,
                    &mut self.held,
                    &self.original,
                    (node, owner, s.normal),
                    (
                        self.settings.snap,
                        self.settings.min_quality,
                        self.min_piece,
                    ),
                )
                .map_err(SimError::Setup)?;
                match tried {
                    Ok(split) => {
                        made = Some((split, s));
                        break;
                    }
                    Err(reason) => {
                        if owner == rank {
                            let normal = s.normal;
                            self.refused.insert(node, RefusedNode { reason, normal });
                        }
                        report.refused += 1;
                    }
                }
            }
            report.t_split += clock.elapsed().as_secs_f64();
            let Some((split, s)) = made else {
                self.count_above(world, &sep, 0, &mut report);
                break;
            };
            report.events.push(FractureEvent {
                rest: split.rest,
                normal: split.normal,
                stress: s.stress(),
            });
            // The star of every node around the split changed: their refusals lapse.
            for i in &split.lapsed {
                self.refused.remove(i);
            }
            let clock = Instant::now();
            let start = self.rebuild(world, sim, start, SchemeState::default())?;
            report.t_remesh += clock.elapsed().as_secs_f64();
            retake(sim, start, &mut report);
        }
        Ok(report)
    }

    /// The whole mesh's cracks, as the last split or gathering of the ghost surface left
    /// them: the same on every process.
    pub fn crack_totals(&self) -> CrackTotals {
        self.cracks
    }

    /// What a frame of `sim` (on [`PartFracture::part`]) holds of fracture on this process's
    /// part (see [`FracturePart`]): the crack triangles drawn at the current positions as on
    /// one process (the other side of a crack is in the ghost surface the part holds), with
    /// the cracks numbered over the processes. Every process of `world` calls it.
    pub fn frame_part(
        &self,
        world: &SimpleCommunicator,
        sim: &Simulation,
    ) -> Result<FracturePart, SimError> {
        let part = &self.part;
        let origin = self.part_origins();
        let refused = (part.nodes.iter())
            .flat_map(|i| match self.refused.get(i) {
                None => [0.0; 4],
                Some(r) => {
                    let n = r.normal;
                    [r.reason.code(), n.x, n.y, n.z]
                }
            })
            .collect();
        let mesh = &sim.model.mesh;
        let faces = crack_faces(mesh, &origin, &self.original);
        let own: Vec<usize> = (0..faces.len())
            .filter(|&k| part.own_elements[faces[k].element])
            .collect();
        let own_faces: Vec<[usize; 3]> = own.iter().map(|&k| faces[k].nodes).collect();
        let ids = crack_ids(world, &own_faces, (&mesh.rest, &part.nodes));
        let positions: Vec<nalgebra::Vector3<f64>> =
            sim.positions().iter().map(|&p| p.into()).collect();
        let gap = self.settings.render_gap;
        let surface = CrackSurface::new(&faces, &mesh.rest, &positions, gap);
        let mut cracks = Vec::with_capacity(own.len() * CRACK_ROW);
        for (&k, id) in own.iter().zip(ids) {
            let mut key = faces[k].nodes.map(|i| part.nodes[i]);
            key.sort_unstable();
            cracks.extend(key.map(|i| i as f64));
            cracks.push(id as f64);
            for v in surface.triangles[k] {
                cracks.extend(surface.vertices[v]);
            }
        }
        let gaps = (sim.state.term_history.get(CRACK_GAPS).chunks_exact(3))
            .filter(|r| part.owned_nodes[r[0] as usize])
            .flat_map(|r| {
                [
                    part.nodes[r[0] as usize] as f64,
                    part.nodes[r[1] as usize] as f64,
                    r[2],
                ]
            })
            .collect();
        Ok(FracturePart {
            origin: origin.iter().map(|&o| o as f64).collect(),
            refused,
            cracks,
            gaps,
        })
    }

    /// The scene element of each element of the simulation's part: a ghost-surface element
    /// (never evaluated here) stands in with the split part's first own element's, as
    /// [`PartFracture::with_surface`] gives it.
    fn part_origins(&self) -> Vec<usize> {
        let held = &self.held;
        let first_own = held.part.own_elements.iter().position(|&o| o).unwrap_or(0);
        (self.part.elements.iter())
            .map(|e| match held.part.elements.binary_search(e) {
                Ok(h) => held.origin[h],
                Err(_) => held.origin[first_own],
            })
            .collect()
    }

    /// Whether the node `node` (the mesh's number), with separation `s`, is a candidate for
    /// a split, as on one process; only its owner (where it is eligible) tells.
    fn candidate(&self, node: usize, s: &NodeSeparation) -> bool {
        s.eligible
            && s.stress() > self.settings.toughness
            && (self.refused.get(&node))
                .is_none_or(|r| r.normal.dot(&s.normal).abs() < CONTINUE_ANGLE.cos())
    }

    /// The separations of the simulation's part's nodes in the equilibrium of its last step
    /// (eligible at the owned nodes only): as one process reads them, from the plastic
    /// strains the step was solved with and the contact forces pressing on the nodes,
    /// summed over the processes.
    fn separations(&self, world: &SimpleCommunicator, sim: &Simulation) -> Vec<NodeSeparation> {
        let dofs = 3 * self.part.nodes.len();
        let forces = pressing_forces(sim);
        // A pair or an obstacle node is evaluated by the processes owning its nodes: each
        // keeps its owned dofs' forces, and the sum brings every holder the whole.
        let pressed = largest(world, f64::from(u8::from(forces.is_some()))) > 0.0;
        let mut pressing = match pressed {
            true => forces.unwrap_or_else(|| vec![0.0; dofs]),
            false => Vec::new(),
        };
        if pressed {
            for (k, p) in pressing.chunks_exact_mut(3).enumerate() {
                if !self.part.owned_nodes[k] {
                    p.fill(0.0);
                }
            }
            self.collective.exchange(&mut pressing);
        }
        let history = solved_history(sim);
        let model = &sim.model;
        separation_on_part(
            &model.elasticity,
            &history,
            (&model.mesh.tets, &sim.state.u, &pressing),
            self.area_floor,
            self.halo.as_ref().map(|h| h as &dyn PartAverages),
            &OnPart {
                collective: &self.collective,
                owned_nodes: &self.part.owned_nodes,
            },
        )
    }

    /// Records in `report` the eligible nodes and those above the toughness in `sep` (this
    /// process's separations after the step's last split), over the processes; `unresolved`
    /// of them are candidates left.
    fn count_above(
        &self,
        world: &SimpleCommunicator,
        sep: &[NodeSeparation],
        unresolved: usize,
        report: &mut FractureReport,
    ) {
        let tau = self.settings.toughness;
        let eligible = sep.iter().filter(|s| s.eligible).count() as u64;
        let above = (sep.iter())
            .filter(|s| s.eligible && s.stress() > tau)
            .count() as u64;
        let mut all = [0u64; 2];
        world.all_reduce_into(&[eligible, above][..], &mut all[..], SystemOperation::sum());
        report.eligible_nodes = all[0] as usize;
        report.nodes_above = unresolved;
        report.refused_above = all[1] as usize - unresolved;
    }

    /// Puts the simulation's displacements and velocities, and those of the step's `start`,
    /// into the split part's mesh, which carries them through a split.
    fn carry_state_into_held(&mut self, sim: &Simulation, start: Option<&State>) {
        let (u, v) = (self.ring_rows(&sim.state.u), self.ring_rows(&sim.state.v));
        let extra = start.map_or(Vec::new(), |s| {
            vec![self.ring_rows(&s.u), self.ring_rows(&s.v)]
        });
        let mesh = &mut self.held.mesh;
        (mesh.u, mesh.v, mesh.extra) = (u, v, extra);
        mesh.min_volume = MIN_ELEMENT_FRACTION * self.min_piece;
    }

    /// The rows of the split part's nodes of `field` (3 per node of the simulation's part).
    fn ring_rows(&self, field: &[f64]) -> Vec<f64> {
        (self.held.part.nodes.iter())
            .map(|&i| {
                self.part
                    .local(i)
                    .expect("the simulation's part holds the split part")
            })
            .flat_map(|k| [field[3 * k], field[3 * k + 1], field[3 * k + 2]])
            .collect()
    }

    /// Continues `sim` on the split part: gathers the ghost surface where the mesh has
    /// ice–ice contact, rebuilds the model, the numbering and the solver's share on the new
    /// part, and carries the state (and the step's `start`, returned on the new part) over,
    /// with what the time scheme carries as `carried` gives it (rows of the split part's
    /// nodes; after a split, nothing, as on one process). Every process calls it.
    fn rebuild(
        &mut self,
        world: &SimpleCommunicator,
        sim: &mut Simulation,
        start: Option<State>,
        carried: SchemeState,
    ) -> Result<Option<State>, SimError> {
        let invalid = |e: crate::mesh::MeshError| SimError::Setup(format!("split part: {e}"));
        let held = &self.held;
        let (rest, tets) = (held.mesh.rest.clone(), held.mesh.tets.clone());
        let elsewhere = || SimError::Setup("another process's split part failed".into());
        let mesh = TetMesh::with_unused_nodes(rest, tets).map_err(invalid);
        let mesh = agreed(world, mesh, elsewhere)?;
        let (piece, pieces) = connected_parts(world, &held.part, &mesh.tets, &held.node_owner);
        let faces = crack_faces(&mesh, &held.origin, &self.original);
        let cracks: Vec<[usize; 3]> = faces.iter().map(|c| c.nodes).collect();
        let totals = crack_totals(world, (held, &mesh), faces);
        let contact = pieces >= 2 || totals.faces > 0;
        let surface = contact.then(|| {
            let given = Surface::given(
                &held.part,
                &mesh,
                (&held.mesh.u, &held.node_owner, &piece),
                &cracks,
            );
            let reach = surface_reach(world, sim, (&held.part, &mesh));
            (gathered(world, &given, reach), reach)
        });
        let (surface, reach) = surface.unzip();
        let next = self.with_surface(surface.as_ref());
        let model = match &surface {
            Some(surface) => model_with_surface(
                world,
                &next.held,
                &sim.model,
                (&self.original, surface, pieces),
            ),
            None => model_after_split(world, &next.held, &sim.model, &self.original),
        }
        .map_err(invalid);
        let model = agreed(world, model, elsewhere)?;
        let renumbered = |history: &TermHistory| {
            let old = renumbered_gaps(history, |i| next.held.part.local(self.part.nodes[i]));
            model.inherited_history(&old, &next.node_parent)
        };
        let term_history = renumbered(&sim.state.term_history);
        let start_history = start.as_ref().map(|st| renumbered(&st.term_history));
        let part = &next.held.part;
        let collective = MpiCollective::new(part, &next.held.node_owner);
        // Every node's rows from its owner, which holds it in its split part.
        let from_owners = |rows: &[f64]| -> Vec<f64> {
            let mut values: Vec<f64> = (0..part.nodes.len())
                .flat_map(|k| match (part.owned_nodes[k], next.in_ring[k]) {
                    (true, Some(h)) => [rows[3 * h], rows[3 * h + 1], rows[3 * h + 2]],
                    _ => [0.0; 3],
                })
                .collect();
            collective.exchange(&mut values);
            values
        };
        let parent = &next.held.mesh.parent;
        let mut on_next = agreed(world, Simulation::for_part(model, sim.settings), elsewhere)?;
        let held_next = (&next.held.part, &next.held.origin[..]);
        let heat = sim.hand_heat_to(&mut on_next, parent, |link, mesh| {
            link_on_part(link, (mesh, held_next.0, held_next.1), &self.heat_part)
        });
        agreed(world, heat, elsewhere)?;
        let state = &sim.state;
        on_next.state = State {
            u: from_owners(&held.mesh.u),
            v: from_owners(&held.mesh.v),
            history: state.history.inherit(parent),
            carried: SchemeState {
                fields: (carried.fields.iter())
                    .map(|(name, field)| (*name, from_owners(field)))
                    .collect(),
                scalars: carried.scalars,
            },
            term_history,
            ..state.clone()
        };
        on_next.set_time(state.time);
        let start = start.zip(start_history).map(|(st, term_history)| {
            let (u, v) = match &held.mesh.extra[..] {
                [u, v] => (from_owners(u), from_owners(v)),
                _ => (on_next.state.u.clone(), on_next.state.v.clone()),
            };
            State {
                u,
                v,
                history: st.history.inherit(parent),
                carried: Default::default(),
                term_history,
                ..st
            }
        });
        let numbering = numbering_after_split(
            world,
            part,
            &next.held.node_owner,
            next.held.process.clone(),
        );
        let shared_mesh = on_next.model.mesh.clone();
        let share = share_after_split(part, numbering, &shared_mesh, self.solve);
        // The old simulation goes before the new one's share of the solver is made.
        *sim = on_next;
        sim.distribute(share)?;
        let (rest, tets) = (&sim.model.mesh.rest, &sim.model.mesh.tets);
        self.halo = nonlocal_halo(
            world,
            &self.settings,
            part,
            (rest, tets),
            &next.held.node_owner,
        );
        self.hold = reach.map(|reach| SurfaceHold::with_reach(reach, part, &sim.state.u));
        self.collective = collective;
        self.cracks = totals;
        self.part = next.held.part;
        self.node_owner = next.held.node_owner;
        Ok(start)
    }

    /// The simulation's next part: the split part and, with a `surface`, the elements of its
    /// faces (the mesh's numbers) beside it, their nodes owned as the surface says; its
    /// elements' parents in the simulation's part before the split (a surface element it did
    /// not hold: its first own element, as a stand-in never evaluated here).
    fn with_surface(&self, surface: Option<&Surface>) -> NextPart {
        let held = &self.held;
        let mut ghost: Vec<(usize, [usize; 4])> = surface.map_or(Vec::new(), |s| {
            (s.elements.iter())
                .filter(|(e, _)| held.part.elements.binary_search(e).is_err())
                .map(|(e, nodes)| (*e, nodes.map(|k| s.nodes[k].node)))
                .collect()
        });
        // An element of several faces comes once for each.
        ghost.sort_unstable_by_key(|(e, _)| *e);
        ghost.dedup_by_key(|(e, _)| *e);
        let ghost_nodes: BTreeMap<usize, (u32, nalgebra::Vector3<f64>)> =
            surface.map_or(BTreeMap::new(), |s| {
                (s.nodes.iter())
                    .filter(|n| held.part.local(n.node).is_none())
                    .map(|n| (n.node, (n.owner, n.rest)))
                    .collect()
            });
        let mut elements: Vec<usize> = (held.part.elements.iter().copied())
            .chain(ghost.iter().map(|(e, _)| *e))
            .collect();
        elements.sort_unstable();
        elements.dedup();
        // The nodes its elements use: a split can leave the split part a node none of its
        // elements uses (those it held around the node went to the node's copy), dropped.
        let mut nodes: Vec<usize> = (held.mesh.tets.iter().flatten())
            .map(|&k| held.part.nodes[k])
            .chain(ghost.iter().flat_map(|(_, nodes)| *nodes))
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        let in_held = |i: usize| held.part.local(i);
        let ghost_of = |e: usize| ghost.binary_search_by_key(&e, |(g, _)| *g).ok();
        let local = |i: usize| nodes.binary_search(&i).expect("a node of the next part");
        let stand_in = (self.part.own_elements.iter())
            .position(|&o| o)
            .unwrap_or(0);
        let old_element = |whole: usize| self.part.elements.binary_search(&whole).ok();
        let first_own = held.part.own_elements.iter().position(|&o| o).unwrap_or(0);
        let mut tets = Vec::with_capacity(elements.len());
        let (mut parent, mut origin, mut process, mut own) = (vec![], vec![], vec![], vec![]);
        for &e in &elements {
            match held.part.elements.binary_search(&e) {
                Ok(k) => {
                    let t = held.mesh.tets[k].map(|a| local(held.part.nodes[a]));
                    tets.push(t);
                    // The part keeps its elements' numbers through a split.
                    let was = held.part.elements[held.mesh.parent[k]];
                    parent.push(old_element(was).expect("a split element's parent was held"));
                    origin.push(held.origin[k]);
                    process.push(held.process[k]);
                    own.push(held.part.own_elements[k]);
                }
                Err(_) => {
                    let (_, whole) = ghost[ghost_of(e).expect("a surface element")];
                    tets.push(whole.map(local));
                    parent.push(old_element(e).unwrap_or(stand_in));
                    origin.push(held.origin[first_own]);
                    // No node of a surface element is owned here (else it would be in the
                    // ring): its first node's owner stands for its process.
                    let owner = match in_held(whole[0]) {
                        Some(h) => held.node_owner[h],
                        None => ghost_nodes[&whole[0]].0,
                    };
                    process.push(owner);
                    own.push(false);
                }
            }
        }
        let node_of = |i: usize| (in_held(i), ghost_nodes.get(&i));
        let mut rest = Vec::with_capacity(nodes.len());
        let mut node_owner = Vec::with_capacity(nodes.len());
        let mut in_ring = Vec::with_capacity(nodes.len());
        let mut node_parent = Vec::with_capacity(nodes.len());
        for (k, &i) in nodes.iter().enumerate() {
            match node_of(i) {
                (Some(h), _) => {
                    rest.push(held.mesh.rest[h]);
                    node_owner.push(held.node_owner[h]);
                    in_ring.push(Some(h));
                    // The node it is a copy of (the mesh's number), by this split or none.
                    let p = held.mesh.node_parent[h];
                    let was = match held.part.nodes.get(p) {
                        Some(&was) => was,
                        None => usize::MAX - p,
                    };
                    node_parent.push(was);
                }
                (None, Some(&(owner, at))) => {
                    rest.push(at);
                    node_owner.push(owner);
                    in_ring.push(None);
                    node_parent.push(i);
                }
                (None, None) => {
                    unreachable!("node {i} of the next part comes from somewhere ({k})")
                }
            }
        }
        // Parents in the next part's numbering; one it does not hold matches no node.
        let node_parent: Vec<usize> = (node_parent.iter().enumerate())
            .map(|(k, &p)| nodes.binary_search(&p).unwrap_or(usize::MAX - k))
            .collect();
        let whole = (held.part.whole_nodes(), held.part.whole_elements());
        let owned_nodes = (nodes.iter())
            .map(|&i| in_held(i).is_some_and(|h| held.part.owned_nodes[h]))
            .collect();
        let part = Part::from_lists((elements, nodes), (own, owned_nodes), whole);
        let mesh = Fracturable {
            rest,
            tets,
            u: Vec::new(),
            v: Vec::new(),
            parent,
            node_parent: Vec::new(),
            extra: Vec::new(),
            min_volume: 0.0,
        };
        NextPart {
            held: SplitPart {
                part,
                mesh,
                node_owner,
                origin,
                process,
            },
            in_ring,
            node_parent,
        }
    }
}

/// The process of every scene element, from the processes' parts `scene_part` of the scene's
/// mesh (each evaluating its own elements). Every process of `world` calls it.
fn scene_processes(world: &SimpleCommunicator, scene_part: &Part) -> Vec<u32> {
    let rank = u64::from(world.rank() as u32);
    let own: Vec<u64> = (scene_part.elements.iter().zip(&scene_part.own_elements))
        .filter(|(_, &own)| own)
        .flat_map(|(&e, _)| [e as u64, rank])
        .collect();
    let mut process = vec![0; scene_part.whole_elements()];
    for pair in all_gathered(world, &own).chunks_exact(2) {
        process[pair[0] as usize] = pair[1] as u32;
    }
    process
}

/// The simulation's part after a split (see [`PartFracture::with_surface`]).
struct NextPart {
    /// The part, its mesh (rest positions, elements and their parents in the simulation's
    /// part before the split), its nodes' owners, its elements' scene elements and processes.
    held: SplitPart,
    /// Each node's number in the split part, if it holds it.
    in_ring: Vec<Option<usize>>,
    /// Each node's parent in this part's numbering (the node it is a copy of, itself if none;
    /// `usize::MAX − k` for node `k` whose parent it does not hold).
    node_parent: Vec<usize>,
}

/// The whole mesh's cracks from this process's split part `held` (its mesh `mesh`, numbered
/// in the part) and the crack faces `faces` of that mesh: the faces of the elements each
/// process evaluates, their area and polygons, added over the processes. Every process of
/// `world` calls it.
fn crack_totals(
    world: &SimpleCommunicator,
    (held, mesh): (&SplitPart, &TetMesh),
    faces: Vec<CrackFace>,
) -> CrackTotals {
    let own: Vec<_> = (faces.into_iter())
        .filter(|c| held.part.own_elements[c.element])
        .collect();
    let scale = largest(
        world,
        mesh.rest.iter().map(|x| x.amax()).fold(0.0, f64::max),
    );
    let sides = polygon_sides(&own, &mesh.rest, &held.origin, scale);
    CrackTotals {
        faces: sum_in_order(world, own.len() as f64) as u64,
        area: sum_in_order(world, crack_area(&own, &mesh.rest)),
        polygons: (sum_in_order(world, sides as f64) as u64).div_ceil(2),
    }
}

/// `held` as the part a resumed run makes from the split mesh alone (see
/// [`PartFracture::restart`]) for process `rank`: its own elements, every element around
/// their nodes, and those elements' nodes, in the mesh's order.
fn canonical_part(held: &SplitPart, rank: u32) -> SplitPart {
    let (part, mesh) = (&held.part, &held.mesh);
    let mut near = vec![false; part.nodes.len()];
    for (tet, _) in (mesh.tets.iter().zip(&part.own_elements)).filter(|(_, &own)| own) {
        tet.iter().for_each(|&k| near[k] = true);
    }
    let elements: Vec<usize> = (0..mesh.tets.len())
        .filter(|&k| mesh.tets[k].iter().any(|&i| near[i]))
        .collect();
    let mut used = vec![false; part.nodes.len()];
    for &k in &elements {
        mesh.tets[k].iter().for_each(|&i| used[i] = true);
    }
    let nodes: Vec<usize> = (0..part.nodes.len()).filter(|&i| used[i]).collect();
    let mut number = vec![usize::MAX; part.nodes.len()];
    for (n, &i) in nodes.iter().enumerate() {
        number[i] = n;
    }
    let rows = |values: &[f64]| -> Vec<f64> {
        (nodes.iter())
            .flat_map(|&i| [values[3 * i], values[3 * i + 1], values[3 * i + 2]])
            .collect()
    };
    let restricted = Fracturable {
        rest: nodes.iter().map(|&i| mesh.rest[i]).collect(),
        tets: (elements.iter())
            .map(|&k| mesh.tets[k].map(|i| number[i]))
            .collect(),
        u: rows(&mesh.u),
        v: rows(&mesh.v),
        parent: (0..elements.len()).collect(),
        node_parent: (0..nodes.len()).collect(),
        extra: mesh.extra.iter().map(|field| rows(field)).collect(),
        min_volume: mesh.min_volume,
    };
    let own_elements: Vec<bool> = elements.iter().map(|&k| part.own_elements[k]).collect();
    debug_assert!(own_elements
        .iter()
        .zip(&elements)
        .all(|(&own, &k)| own == (held.process[k] == rank)));
    SplitPart {
        part: Part::from_lists(
            (
                elements.iter().map(|&k| part.elements[k]).collect(),
                nodes.iter().map(|&i| part.nodes[i]).collect(),
            ),
            (
                own_elements,
                nodes.iter().map(|&i| part.owned_nodes[i]).collect(),
            ),
            (part.whole_nodes(), part.whole_elements()),
        ),
        mesh: restricted,
        node_owner: nodes.iter().map(|&i| held.node_owner[i]).collect(),
        origin: elements.iter().map(|&k| held.origin[k]).collect(),
        process: elements.iter().map(|&k| held.process[k]).collect(),
    }
}

/// How far (m) from its owned boundary nodes a process gathers its ghost surface after a
/// split: what ice–ice contact's next step needs (see `surface_hold`) with the whole
/// boundary's mean edge, the process holding `part` with mesh `mesh` at `sim`'s state.
fn surface_reach(
    world: &SimpleCommunicator,
    sim: &Simulation,
    (part, mesh): (&Part, &TetMesh),
) -> f64 {
    let (_, boundary) = part.whole_boundary_faces(mesh);
    let own: Vec<_> = (boundary.into_iter())
        .filter(|f| part.own_elements[f.tet])
        .collect();
    let perimeter = sum_in_order(world, mesh.perimeters(&own).iter().sum());
    let faces = sum_in_order(world, own.len() as f64);
    let edge = perimeter / (3.0 * faces.max(1.0));
    let vmax = largest(
        world,
        sim.state.v.iter().fold(0.0, |m: f64, x| m.max(x.abs())),
    );
    let h = sim.settings.dt;
    IceContact::reach_for(edge, vmax, h) + 4.0 * vmax * h + ALLOWANCE_EDGES * edge
}

/// The nonlocal averages' gathered nodes for `settings` on `part` (mesh `rest`, `tets`
/// numbered in the part, its nodes owned by `node_owner`), if they average.
fn nonlocal_halo(
    world: &SimpleCommunicator,
    settings: &FractureSettings,
    part: &Part,
    mesh: (&[nalgebra::Vector3<f64>], &[[usize; 4]]),
    node_owner: &[u32],
) -> Option<NodeHalo> {
    let length = settings.nonlocal_length;
    (length > 0.0).then(|| NodeHalo::new(world, part, mesh, node_owner, length))
}
