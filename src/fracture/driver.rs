//! Fracture between time steps: find the node whose separation most exceeds the toughness,
//! split it, take the step again on the new mesh, and repeat until no node is above it.
//!
//! After every converged step the separation tensor of every node is evaluated in the step's
//! equilibrium. While some node's v⁺/A(n) exceeds the toughness τ and fewer than
//! `max_events_per_step` splits were made, the worst such node is split along the plane with
//! its separation eigenvector as normal, the simulation is rebuilt on the new mesh (mass,
//! loads, contact with the crack's sides, sparsity pattern and symbolic factorisation: only
//! here), and the step is taken again from its start state carried over to the new mesh. The
//! next worst node is then found in that new equilibrium. Re-solving matters: after a split
//! the old displacements are no longer in equilibrium, and a node one element away from the
//! crack, loaded only because the crack has not yet relaxed the stress around it, would
//! otherwise split next and send the crack off its plane (a bar pulled apart breaks along a
//! clean plane with it, and chips off corners without). The cap bounds the work of one step;
//! what exceeds it is reconsidered after the next step (and counted in the step's report).
//! If taking the step again fails, the split is kept with the step's end state (as O'Brien &
//! Hodgins keep every split) and no further splits are made in that step.
//!
//! A split can be refused: the plane misses the node's star (all its tets on one side), or
//! it would cut off a piece smaller than the scene's mean element volume (below what the mesh
//! resolves; a free piece of one or two tiny tets, held only by stiff contact, stalls the
//! Newton solve). A refused node is recorded with its reason and crack normal and is not
//! tried again until its crack normal has turned by more than [`CONTINUE_ANGLE`] or a split
//! changes its star: the same refusal would otherwise be retried, on a copy of the mesh,
//! every step.
//!
//! A node on an existing crack (a crack tip, or a face of one) is split like any other: its
//! star is one side of the crack only, so the new plane continues the crack from there.

use super::cracks::{
    crack_area, crack_faces, crack_polygons, CrackFace, CrackSurface, OriginalBoundary,
};
use super::patch::Patch;
use super::split::Fracturable;
use super::{separation, Averaging, NodeSeparation};
use crate::mesh::parts_of;
use crate::mesh::TetMesh;
use crate::physics::history::ElementHistory;
use crate::sim::{SimError, Simulation, State};
use nalgebra::Vector3;
use std::borrow::Cow;
use std::time::Instant;

/// Largest angle (rad) between a node's separation plane and the crack it lies on for the
/// split to continue that crack in the crack's plane (20°).
pub const CONTINUE_ANGLE: f64 = 20.0 * std::f64::consts::PI / 180.0;

/// Smallest element a split may create, as a fraction of the scene's mean element volume: a
/// crossing that would cut a smaller one snaps instead (as for poor quality).
pub const MIN_ELEMENT_FRACTION: f64 = 1e-2;

/// Separation tensors of `sim`'s nodes in the equilibrium its last step found: the stress
/// of the solve (returned onto the yield surface from the plastic strains of the step's
/// start, exactly the forces the solve balanced), and the contact forces counted as pressing
/// (see [`separation`]).
fn equilibrium_separation(
    sim: &mut Simulation,
    area_floor: f64,
    averaging: Option<&Averaging>,
) -> Vec<super::NodeSeparation> {
    let pressing = pressing_forces(sim).unwrap_or_default();
    let model = &sim.model;
    separation(
        &model.elasticity,
        &solved_history(sim),
        &model.mesh.tets,
        &sim.state.u,
        &pressing,
        area_floor,
        averaging,
    )
}

/// The contact forces pressing on `sim`'s nodes after its last step (N, 3 per node: normal
/// and friction), if its model has contact.
pub fn pressing_forces(sim: &Simulation) -> Option<Vec<f64>> {
    sim.contact_forces().map(|c| {
        (c.normal.iter().zip(&c.friction))
            .map(|(n, f)| n + f)
            .collect()
    })
}

/// The element history `sim`'s last step was solved with: its end state's, with the plastic
/// strains of the step's start (from which the solve's stress is returned onto the yield
/// surface).
pub fn solved_history(sim: &Simulation) -> Cow<'_, ElementHistory> {
    match sim.step_start() {
        Some(start) if !start.history.plastic_strain.is_empty() => Cow::Owned(ElementHistory {
            plastic_strain: start.history.plastic_strain.clone(),
            ..sim.state.history.clone()
        }),
        _ => Cow::Borrowed(&sim.state.history),
    }
}

/// The nonlocal neighbourhoods of `mesh` for `settings`, if it asks for averaging.
fn averaging(settings: &FractureSettings, mesh: &TetMesh) -> Option<Averaging> {
    (settings.nonlocal_length > 0.0).then(|| Averaging::new(mesh, settings.nonlocal_length))
}

/// The crack normal for splitting `node` of `patch` with separation normal `normal`, the
/// scene mesh's boundary being `original` (it must have the planes of the scene elements of
/// `node`'s elements): a node on an existing crack whose faces there (area-weighted) are
/// within [`CONTINUE_ANGLE`] of the plane continues that crack in its plane. The separation
/// eigenvector at a crack front is resolved by one ring of elements only; without this,
/// mesh-scale noise in it (10–20° at a bar's corner) kinks a straight crack and chips off
/// single elements.
pub fn continued(
    original: &OriginalBoundary,
    patch: &Patch,
    node: usize,
    normal: &Vector3<f64>,
) -> Vector3<f64> {
    let f = &patch.mesh;
    let star: Vec<usize> = (0..f.tets.len())
        .filter(|&e| f.tets[e].contains(&node))
        .collect();
    let mut sum = Vector3::zeros();
    for &e in &star {
        let t = f.tets[e];
        for face in [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
            let nodes = face.map(|k| t[k]);
            if !nodes.contains(&node) {
                continue;
            }
            let mut key = nodes;
            key.sort_unstable();
            let shared = star
                .iter()
                .any(|&o| o != e && key.iter().all(|i| f.tets[o].contains(i)));
            let points = nodes.map(|i| f.rest[i]);
            if shared || original.on_boundary(patch.origin[f.parent[e]], &points) {
                continue;
            }
            let [a, b, c] = nodes.map(|i| f.position(i));
            let area_normal = 0.5 * (b - a).cross(&(c - a));
            // Both sides of the crack count, oriented alike.
            sum += area_normal * area_normal.dot(normal).signum();
        }
    }
    if sum.norm() > 0.0 && sum.normalize().dot(normal).abs() > CONTINUE_ANGLE.cos() {
        sum.normalize()
    } else {
        *normal
    }
}

/// Why a node's split was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// All of the node's tets lie on one side of its crack plane.
    PlaneMissesStar,
    /// The split would cut off a piece smaller than the scene's mean element volume.
    PieceTooSmall,
}

impl Refusal {
    /// Its code in a frame's `refused_split` rows (see [`Fracture::refusals_as_rows`]).
    pub fn code(self) -> f64 {
        match self {
            Refusal::PlaneMissesStar => 1.0,
            Refusal::PieceTooSmall => 2.0,
        }
    }
}

/// A node whose split was refused, and the crack normal it was refused for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefusedNode {
    /// Why.
    pub reason: Refusal,
    /// The crack normal (unit) of the refused split.
    pub normal: Vector3<f64>,
}

impl RefusedNode {
    /// The refusal a row written by [`Fracture::refusals_as_rows`] holds, if any (an unknown
    /// code reads as none).
    pub fn from_row(row: &[f64]) -> Option<RefusedNode> {
        let reason = match row[0] {
            1.0 => Refusal::PlaneMissesStar,
            2.0 => Refusal::PieceTooSmall,
            _ => return None,
        };
        Some(RefusedNode {
            reason,
            normal: Vector3::new(row[1], row[2], row[3]),
        })
    }
}

/// A split made on a copy of the mesh.
struct SplitAttempt {
    /// The split mesh, carrying the state and (in `extra`) the step's start displacements and
    /// velocities.
    mesh: Fracturable,
    /// The crack normal used.
    normal: Vector3<f64>,
    /// The step's start state (on the mesh before the split).
    start: Option<State>,
    /// The nodes sharing an element with the split node, its copy, or a node the split
    /// added: their stars changed.
    lapsed: Vec<usize>,
}

/// Fracture parameters of a scene (`[fracture]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FractureSettings {
    /// Toughness τ as a stress (Pa): a node fractures when v⁺ / A(n) > τ (see `fracture`).
    pub toughness: f64,
    /// Most node splits per time step.
    pub max_events_per_step: usize,
    /// Fraction of an edge within which a crack plane's crossing snaps to the edge's end,
    /// in [0, 0.5).
    pub snap: f64,
    /// Smallest rest radius ratio (3 × inradius / circumradius, 1 for a regular tet) a split
    /// may create, in [0, 1).
    pub min_quality: f64,
    /// Smallest opening drawn between the two sides of a crack in the crack-surface output
    /// (m).
    pub render_gap: f64,
    /// Length over which the separation is averaged (m; 0: each node on its own), see
    /// [`super::nonlocal`].
    pub nonlocal_length: f64,
}

/// One node split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FractureEvent {
    /// Rest position of the split node (m).
    pub rest: Vector3<f64>,
    /// Crack plane normal (unit, current configuration).
    pub normal: Vector3<f64>,
    /// The node's v⁺ / A(n) (Pa).
    pub stress: f64,
}

/// What the fracture check after one step did and what it cost.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FractureReport {
    /// Node splits made, in order.
    pub events: Vec<FractureEvent>,
    /// Largest v⁺ / A(n) of an eligible node before any split (Pa).
    pub largest_stress: f64,
    /// Wall-clock time of the first separation evaluation (s): the cost of a step without
    /// fracture.
    pub t_check: f64,
    /// Wall-clock time of the splits and the separation re-evaluations between them (s).
    pub t_split: f64,
    /// Wall-clock time of rebuilding the simulation on the new meshes (s).
    pub t_remesh: f64,
    /// Wall-clock time of taking the step again on the new meshes (s).
    pub t_resolve: f64,
    /// Splits refused in this step (plane missing the star, or a piece below the smallest
    /// allowed); each refused node is recorded (see [`Fracture::refused`]).
    pub refused: usize,
    /// Nodes eligible for fracture after the step's processing: every element around them
    /// holds ice (freeze state s > 0, however little frozen).
    pub eligible_nodes: usize,
    /// Eligible nodes still above the toughness after the processing, not counting those
    /// whose split is refused: nonzero only when the step's cap on splits was reached or a
    /// re-solve failed.
    pub nodes_above: usize,
    /// Eligible nodes above the toughness whose split is refused.
    pub refused_above: usize,
    /// Whether taking the step again on a split mesh failed (the split was kept with the
    /// step's end state, and no further splits were made in this step).
    pub resolve_failed: bool,
}

/// Fracture state of a run: the settings, where every element came from, and the crack faces.
#[derive(Clone, Debug)]
pub struct Fracture {
    /// The parameters.
    pub settings: FractureSettings,
    /// For each current element, the scene element it lies in.
    pub origin: Vec<usize>,
    /// The scene mesh's boundary, to tell crack faces from it.
    original: OriginalBoundary,
    /// Crack faces of the current mesh.
    pub faces: Vec<CrackFace>,
    /// Smallest rest volume of a piece a split may cut off (m³): the scene's mean element
    /// volume.
    min_piece_volume: f64,
    /// Smallest area A(n) a node's separation stress is divided by (m²), see
    /// [`super::area_floor`].
    pub area_floor: f64,
    /// Per node, its refused split, if any.
    pub refused: Vec<Option<RefusedNode>>,
    /// The neighbourhoods of the nonlocal separation on the current mesh (none: local).
    averaging: Option<Averaging>,
}

impl Fracture {
    /// Fracture of a run on the scene mesh `mesh` (nothing split yet).
    pub fn new(settings: FractureSettings, mesh: &TetMesh) -> Self {
        Fracture {
            settings,
            origin: (0..mesh.num_tets()).collect(),
            original: OriginalBoundary::new(mesh),
            faces: Vec::new(),
            min_piece_volume: mesh.volume() / mesh.num_tets() as f64,
            area_floor: super::area_floor(mesh),
            refused: Vec::new(),
            averaging: averaging(&settings, mesh),
        }
    }

    /// Continues `sim` on the split mesh `f` (whose `parent`s index `sim`'s elements), whose
    /// element `e` lies in scene element `origin[e]`: finds its crack faces and rebuilds the
    /// simulation with them (their sides in contact).
    pub fn rebuild(
        &mut self,
        sim: &mut Simulation,
        f: Fracturable,
        origin: Vec<usize>,
    ) -> Result<(), SimError> {
        let invalid = |e: crate::mesh::MeshError| SimError::Setup(format!("split mesh: {e}"));
        let mesh = TetMesh::new(f.rest, f.tets).map_err(invalid)?;
        self.origin = origin;
        self.faces = crack_faces(&mesh, &self.origin, &self.original);
        self.averaging = averaging(&self.settings, &mesh);
        let cracks: Vec<[usize; 3]> = self.faces.iter().map(|c| c.nodes).collect();
        let model = sim
            .model
            .remeshed(&mesh.rest, mesh.tets, &f.parent, &cracks)
            .map_err(invalid)?;
        let carried = model.inherited_history(&sim.state.term_history, &f.node_parent);
        sim.remesh(model, f.u, f.v, carried, &f.parent)
    }

    /// Number of distinct cracks.
    pub fn cracks(&self) -> usize {
        self.faces.iter().map(|f| f.crack + 1).max().unwrap_or(0)
    }

    /// The refused splits of a mesh of `nodes` nodes as rows of four: the reason (0 none,
    /// 1 [`Refusal::PlaneMissesStar`], 2 [`Refusal::PieceTooSmall`]) and the crack normal.
    pub fn refusals_as_rows(&self, nodes: usize) -> Vec<f64> {
        (0..nodes)
            .flat_map(|i| match self.refused.get(i).copied().flatten() {
                None => [0.0; 4],
                Some(r) => [r.reason.code(), r.normal.x, r.normal.y, r.normal.z],
            })
            .collect()
    }

    /// Restores the refused splits from rows written by [`Fracture::refusals_as_rows`]
    /// (unknown codes read as none).
    pub fn restore_refusals(&mut self, rows: &[f64]) {
        self.refused = rows.chunks_exact(4).map(RefusedNode::from_row).collect();
    }

    /// Total crack area at rest, one side (m²), on the mesh with rest positions `rest`.
    pub fn crack_area(&self, rest: &[Vector3<f64>]) -> f64 {
        crack_area(&self.faces, rest)
    }

    /// Number of crack polygons (see [`crack_polygons`]) on the mesh with rest positions `rest`.
    pub fn crack_polygons(&self, rest: &[Vector3<f64>]) -> usize {
        crack_polygons(&self.faces, rest, &self.origin)
    }

    /// The crack faces as triangles at the simulation's current positions.
    pub fn surface(&self, sim: &Simulation) -> CrackSurface {
        let positions: Vec<Vector3<f64>> = sim
            .positions()
            .iter()
            .map(|p| Vector3::new(p[0], p[1], p[2]))
            .collect();
        CrackSurface::new(
            &self.faces,
            &sim.model.mesh.rest,
            &positions,
            self.settings.render_gap,
        )
    }

    /// Rest volume of the smallest piece (connected part) of `f` (m³).
    fn smallest_piece(&self, f: &Fracturable) -> f64 {
        let (part, count) = parts_of(f.rest.len(), &f.tets);
        let mut volume = vec![0.0; count];
        for (tet, v) in f.tets.iter().zip(f.volumes()) {
            volume[part[tet[0]] as usize] += v;
        }
        volume.into_iter().fold(f64::INFINITY, f64::min)
    }

    /// Whether `node`, with separation `s`, is a candidate for a split: eligible, above the
    /// toughness, and not refused for a crack normal within [`CONTINUE_ANGLE`] of its own.
    fn candidate(&self, node: usize, s: &NodeSeparation) -> bool {
        s.eligible
            && s.stress() > self.settings.toughness
            && self.refused[node]
                .is_none_or(|r| r.normal.dot(&s.normal).abs() < CONTINUE_ANGLE.cos())
    }

    /// Fractures `sim` after a converged step (see the module docs).
    pub fn after_step(&mut self, sim: &mut Simulation) -> Result<FractureReport, SimError> {
        let mut report = FractureReport::default();
        loop {
            let clock = Instant::now();
            let sep = equilibrium_separation(sim, self.area_floor, self.averaging.as_ref());
            self.refused.resize(sep.len(), None);
            if report.events.is_empty() {
                report.largest_stress = sep
                    .iter()
                    .filter(|s| s.eligible)
                    .map(|s| s.stress())
                    .fold(0.0, f64::max);
                report.t_check = clock.elapsed().as_secs_f64();
            } else {
                report.t_split += clock.elapsed().as_secs_f64();
            }
            let mut candidates: Vec<(usize, NodeSeparation)> = sep
                .iter()
                .enumerate()
                .filter(|(i, s)| self.candidate(*i, s))
                .map(|(i, s)| (i, *s))
                .collect();
            if report.events.len() >= self.settings.max_events_per_step || report.resolve_failed {
                self.count_above(&sep, candidates.len(), &mut report);
                break;
            }
            // Worst first; each refusal is recorded and the next candidate tried on the same
            // equilibrium (a refusal changes nothing).
            candidates.sort_by(|a, b| b.1.stress().total_cmp(&a.1.stress()));
            let clock = Instant::now();
            let mut made = None;
            for &(node, s) in &candidates {
                match self.try_split(sim, node, &s) {
                    Ok(split) => {
                        made = Some((split, node, s));
                        break;
                    }
                    Err(refused) => {
                        self.refused[node] = Some(refused);
                        report.refused += 1;
                    }
                }
            }
            report.t_split += clock.elapsed().as_secs_f64();
            let Some((attempt, node, s)) = made else {
                // Every candidate refused (or none): no node is left above the toughness
                // unrecorded.
                self.count_above(&sep, 0, &mut report);
                break;
            };
            report.events.push(FractureEvent {
                rest: attempt.mesh.rest[node],
                normal: attempt.normal,
                stress: s.stress(),
            });
            let clock = Instant::now();
            let f = attempt.mesh;
            // The star of every node around the split changed: their refusals lapse.
            for &i in &attempt.lapsed {
                if let Some(r) = self.refused.get_mut(i) {
                    *r = None;
                }
            }
            let origin = f.parent.iter().map(|&p| self.origin[p]).collect();
            // The step's start state on the new mesh: nodal fields were carried through the
            // split (`extra`), element fields follow the parent element.
            let mut start = attempt.start.map(|st| State {
                u: f.extra[0].clone(),
                v: f.extra[1].clone(),
                history: st.history.inherit(&f.parent),
                ..st
            });
            let node_parent = f.node_parent.clone();
            self.rebuild(sim, f, origin)?;
            if let Some(start) = &mut start {
                let carried = &start.term_history;
                start.term_history = sim.model.inherited_history(carried, &node_parent);
            }
            report.t_remesh += clock.elapsed().as_secs_f64();
            retake(sim, start, &mut report);
        }
        Ok(report)
    }

    /// Records in `report` the eligible nodes and those above the toughness in `sep`, the
    /// separation after the step's last split; `unresolved` of them are candidates left.
    fn count_above(&self, sep: &[NodeSeparation], unresolved: usize, report: &mut FractureReport) {
        let tau = self.settings.toughness;
        report.eligible_nodes = sep.iter().filter(|s| s.eligible).count();
        let above = sep
            .iter()
            .filter(|s| s.eligible && s.stress() > tau)
            .count();
        report.nodes_above = unresolved;
        report.refused_above = above - unresolved;
    }

    /// Splits `node` of `sim`'s mesh (separation `s`) on a copy of the mesh carrying the
    /// step's start state; the refusal if the split is not made.
    fn try_split(
        &self,
        sim: &Simulation,
        node: usize,
        s: &NodeSeparation,
    ) -> Result<SplitAttempt, RefusedNode> {
        let model = &sim.model;
        let mut f = Fracturable::new(
            model.mesh.rest.clone(),
            model.mesh.tets.clone(),
            sim.state.u.clone(),
            sim.state.v.clone(),
        );
        let start = sim.step_start().cloned();
        f.min_volume = MIN_ELEMENT_FRACTION * self.min_piece_volume;
        if let Some(start) = &start {
            f.extra = vec![start.u.clone(), start.v.clone()];
        }
        // The split reads and changes the elements around the node only (see `patch`).
        let (mut patch, local) = Patch::of(&f, &self.origin, node);
        let normal = continued(&self.original, &patch, local, &s.normal);
        let refused = |reason| RefusedNode {
            reason,
            normal: s.normal,
        };
        let split = (patch.mesh)
            .split_node(
                local,
                &normal,
                self.settings.snap,
                self.settings.min_quality,
            )
            .ok_or(refused(Refusal::PlaneMissesStar))?;
        patch.apply(&mut f);
        if self.smallest_piece(&f) < self.min_piece_volume {
            return Err(refused(Refusal::PieceTooSmall));
        }
        let mut touched = split.edge_nodes;
        touched.extend(split.pinched);
        touched.extend([local, split.new_node]);
        Ok(SplitAttempt {
            mesh: f,
            normal,
            start,
            lapsed: patch.neighbours(&touched),
        })
    }
}

/// Takes the step that ended in `sim`'s current state again from `start` (if the step had
/// one) on the split mesh, adding the time to `report`; if that fails, keeps the split mesh
/// with the step's end state unchanged (as O'Brien & Hodgins do for every split) and marks
/// the report's re-solve failed.
pub fn retake(sim: &mut Simulation, start: Option<State>, report: &mut FractureReport) {
    let Some(start) = start else {
        return;
    };
    let clock = Instant::now();
    let end = sim.state.clone();
    report.resolve_failed = sim.retake_step(start).is_err();
    if report.resolve_failed {
        let time = end.time;
        sim.state = end;
        sim.set_time(time);
    }
    report.t_resolve += clock.elapsed().as_secs_f64();
}
