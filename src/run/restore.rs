//! Resuming a run: the state of its last complete frame put back into a simulation.

use super::{rows, RunError};
use crate::fem;
use crate::fracture::split::Fracturable;
use crate::fracture::Fracture;
use crate::mesh::TetMesh;
use crate::output::{ResumeFrame, StoredField};
use crate::sim::part::Part;
use crate::sim::{SchemeState, Simulation};
use std::path::Path;

/// The part `part` of a frame of the whole mesh `mesh` (checked to be the frame's): its nodes'
/// and elements' rows, its elements numbered in the part.
pub(super) fn part_frame(part: &Part, frame: &ResumeFrame, mesh: &TetMesh) -> ResumeFrame {
    let pick = |rows: &[[f64; 3]]| part.nodes.iter().map(|&i| rows[i]).collect();
    let fields = |fields: &[StoredField], count: usize, per_element: bool| {
        fields
            .iter()
            .filter(|f| f.data.len() == f.columns * count)
            .map(|f| StoredField {
                name: f.name.clone(),
                columns: f.columns,
                data: part.rows_of(&f.data, f.columns, per_element),
            })
            .collect()
    };
    ResumeFrame {
        step: frame.step,
        time: frame.time,
        scene_text: frame.scene_text.clone(),
        positions: pick(&frame.positions),
        velocities: pick(&frame.velocities),
        rest_positions: pick(&frame.rest_positions),
        tets: part.tets_of(&mesh.tets),
        element_fields: fields(&frame.element_fields, mesh.num_tets(), true),
        node_fields: fields(&frame.node_fields, mesh.num_nodes(), false),
        row_fields: frame.row_fields.clone(),
        attributes: frame.attributes.clone(),
    }
}

/// Puts `sim` (and `fracture`, if the run fractures) in the state of the resumed `frame` of
/// the file at `path`, written from `scene_text`.
pub(super) fn restore(
    sim: &mut Simulation,
    mut fracture: Option<&mut Fracture>,
    path: &Path,
    frame: &crate::output::ResumeFrame,
    scene_text: &str,
) -> Result<(), RunError> {
    let bad = |reason: String| RunError::Resume {
        path: path.into(),
        reason,
    };
    if frame.scene_text != scene_text {
        return Err(bad(
            "it was written from a different scene text (resume needs the same scene)".into(),
        ));
    }
    let rest = rows(&sim.model.mesh.rest);
    if frame.rest_positions != rest || frame.tets != sim.model.mesh.tets {
        // A fractured run: rebuild its mesh from the scene's, element by element.
        let Some(fracture) = fracture.as_deref_mut() else {
            return Err(bad("its mesh differs from the scene's mesh".into()));
        };
        rebuild_split_mesh(sim, fracture, frame).map_err(|e| match e {
            RebuildError::Reason(reason) => bad(reason),
            RebuildError::Run(e) => e,
        })?;
    }
    let rest = rows(&sim.model.mesh.rest);
    let n = 3 * rest.len();
    if let (Some(fracture), Some(f)) = (
        fracture,
        frame.node_fields.iter().find(|f| {
            f.name == "refused_split" && f.columns == 4 && f.data.len() == 4 * rest.len()
        }),
    ) {
        fracture.restore_refusals(&f.data);
    }
    let field = |name: &str| {
        frame
            .node_fields
            .iter()
            .find(|f| f.name == name && f.columns == 3 && f.data.len() == n)
            .map(|f| f.data.clone())
    };
    let u = field("displacement")
        .ok_or_else(|| bad("the last complete frame has no node field `displacement`".into()))?;
    if frame.velocities.len() != rest.len() {
        return Err(bad("the velocities do not match the mesh".into()));
    }
    sim.state.u = u;
    sim.state.v = frame.velocities.iter().flatten().copied().collect();
    // What the time scheme carries (absent in a frame written before the first step or after
    // a split: then the next step starts as the first does).
    sim.state.carried = SchemeState::read(sim.integrator(), field, |name| frame.attribute(name));
    // What the terms carry (absent in a frame written before the first step that needed it).
    for term in &sim.model.terms {
        let Some((name, columns)) = term.carried() else {
            continue;
        };
        let stored = (frame.row_fields.iter()).find(|f| f.name == name && f.columns == columns);
        if let Some(f) = stored {
            sim.state.term_history.set(name, columns, f.data.clone());
        }
    }
    sim.state.next_dt = frame.attribute("next_dt").unwrap_or(0.0);
    sim.state.time = frame.time;
    sim.state.step = frame.step;
    if let Some(scene_nodes) = sim.heat().map(|l| l.heat.temperature().len()) {
        // The scene mesh's nodes keep their numbers through splits: its temperatures are the
        // first entries of the frame's node field.
        let t = frame
            .node_fields
            .iter()
            .find(|f| f.name == "temperature" && f.columns == 1 && f.data.len() >= scene_nodes)
            .ok_or_else(|| bad("the last complete frame has no node field `temperature`".into()))?;
        sim.set_temperature(t.data[..scene_nodes].to_vec());
    }
    let tets = sim.model.mesh.num_tets();
    if let Some(e) = frame
        .element_fields
        .iter()
        .find(|f| f.name == "eigenstrain")
    {
        if e.columns == 1 && e.data.len() == tets {
            sim.state.history.eigenstrain = e.data.clone();
        }
    }
    sim.set_time(frame.time);
    if sim.model.elasticity.inelastic() {
        let p = frame
            .element_fields
            .iter()
            .find(|f| f.name == "plastic_strain" && f.columns == 6 && f.data.len() == 6 * tets)
            .ok_or_else(|| {
                bad("the last complete frame has no element field `plastic_strain`".into())
            })?;
        sim.state.history.plastic_strain = p.data.chunks(6).map(fem::from_voigt).collect();
    }
    Ok(())
}

/// Why a fractured run's mesh could not be rebuilt.
enum RebuildError {
    /// The frame does not say how (a reason for the resume error).
    Reason(String),
    /// Rebuilding failed.
    Run(RunError),
}

/// Rebuilds a fractured run's split mesh in `sim` from the scene's, element by element, as
/// the frame's element field `origin` gives it.
fn rebuild_split_mesh(
    sim: &mut Simulation,
    fracture: &mut Fracture,
    frame: &ResumeFrame,
) -> Result<(), RebuildError> {
    let origin: Vec<usize> = frame
        .element_fields
        .iter()
        .find(|f| f.name == "origin" && f.columns == 1 && f.data.len() == frame.tets.len())
        .filter(|f| {
            let scene_tets = sim.model.mesh.num_tets() as f64;
            f.data
                .iter()
                .all(|&o| o >= 0.0 && o < scene_tets && o.fract() == 0.0)
        })
        .map(|f| f.data.iter().map(|&o| o as usize).collect())
        .ok_or_else(|| {
            RebuildError::Reason(
                "its mesh was split but the frame has no valid element field `origin`".into(),
            )
        })?;
    let frame_rest: Vec<nalgebra::Vector3<f64>> =
        frame.rest_positions.iter().map(|p| (*p).into()).collect();
    let zeros = vec![0.0; 3 * frame_rest.len()];
    let mut split = Fracturable::new(frame_rest, frame.tets.clone(), zeros.clone(), zeros);
    split.parent = origin.clone();
    fracture
        .rebuild(sim, split, origin)
        .map_err(|e| RebuildError::Run(e.into()))?;
    Ok(())
}
