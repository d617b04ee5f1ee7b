//! Frames: what a run writes of its state at a step, on one process or gathered from the
//! processes of a distributed run.

use super::{as_rows, rows, Processes, RunError};
use crate::fem;
use crate::fracture::Fracture;
use crate::mesh::TetMesh;
use crate::output::{BackgroundWriter, Field, Frame, OutputError};
use crate::physics::contact::ContactForces;
use crate::sim::part::{Part, StateShares};
use crate::sim::{SimError, Simulation, State};

/// Writes the current state of `sim` as a frame on the writing process (`writer`). In a
/// distributed run whose processes hold parts of the mesh (`shared`: the processes, this
/// one's part, the whole mesh), every process first gives its part of the state to the
/// writing one.
pub(super) fn emit_frame(
    writer: Option<&mut BackgroundWriter>,
    (sim, fracture): (&Simulation, Option<&Fracture>),
    shared: Option<(&dyn Processes, &Part, &TetMesh)>,
    flags: FrameFlags,
) -> Result<(), RunError> {
    let Some((processes, part, mesh)) = shared else {
        if let Some(writer) = writer {
            write_frame(
                writer,
                &FrameSource::of(sim),
                fracture.map(|f| (f, sim)),
                flags,
            )?;
        }
        return Ok(());
    };
    let contact = sim.contact_forces();
    let temperature = sim.node_temperatures().unwrap_or_default();
    let share = part.share_of(
        &sim.state,
        &sim.stresses(),
        (contact.unwrap_or(&ContactForces::default()), &temperature),
    );
    // Each share placed as it arrives: the writing process holds the whole state and one
    // other process's share at a time.
    let carried = (
        sim.integrator().carried_fields(),
        sim.integrator().carried_scalars(),
    );
    let (nodes, elements) = (mesh.num_nodes(), mesh.num_tets());
    let mut whole: Option<StateShares> = None;
    let mut complete = true;
    processes.gather_values(share, &mut |values| {
        let shares = whole.get_or_insert_with(|| {
            StateShares::for_shares(&values, nodes, elements, carried).unwrap_or_default()
        });
        complete &= shares.place(&values).is_some();
    });
    let Some(writer) = writer else {
        return Ok(());
    };
    let whole = whole.filter(|_| complete).ok_or_else(|| {
        SimError::Setup("a process's part of the state did not arrive whole".into())
    })?;
    let state = State {
        time: sim.state.time,
        step: sim.state.step,
        next_dt: sim.state.next_dt,
        ..whole.state
    };
    let source = FrameSource {
        mesh,
        state: &state,
        stress: whole.stress,
        contact: contact.map(|_| &whole.contact),
        temperature: (!whole.temperature.is_empty()).then_some(whole.temperature),
    };
    Ok(write_frame(writer, &source, None, flags)?)
}

/// What a frame is written from: a simulation's mesh and state, or the whole state of a
/// distributed run put together from the processes' parts.
struct FrameSource<'a> {
    mesh: &'a TetMesh,
    state: &'a State,
    /// Element stresses (Pa, Voigt).
    stress: Vec<[f64; 6]>,
    /// Contact forces, if the model has contact.
    contact: Option<&'a ContactForces>,
    /// Temperature of every node (°C), with `[thermal]`.
    temperature: Option<Vec<f64>>,
}

impl<'a> FrameSource<'a> {
    /// The simulation's current state.
    fn of(sim: &'a Simulation) -> Self {
        FrameSource {
            mesh: &sim.model.mesh,
            state: &sim.state,
            stress: sim.stresses(),
            contact: sim.contact_forces(),
            temperature: sim.node_temperatures(),
        }
    }
}

/// What a frame marks besides its state.
#[derive(Clone, Copy, Debug)]
pub(super) struct FrameFlags {
    /// The mesh changed since the last frame written.
    pub(super) topology_changed: bool,
    /// The frame is at a restart point, after which the run forgets its solver memory (see
    /// [`Simulation::forget_solver_memory`]): `--resume` continues from the last such frame.
    pub(super) restart_point: bool,
}

/// The fields of a frame computed from its state (owned; the frame's fields borrow them).
struct DerivedFields {
    /// Positions X + u (m).
    positions: Vec<[f64; 3]>,
    /// Rest positions (m).
    rest: Vec<[f64; 3]>,
    /// Contact forces where the model has contact but no step has computed them yet (N).
    zero_forces: Vec<f64>,
    /// Whether each node is in contact (1) or not (0), with contact and the derived scalars.
    contact_active: Vec<f64>,
    /// Von Mises stress per element (Pa); empty when the frames leave the derived scalars out.
    von_mises: Vec<f64>,
    /// Largest principal stress per element (Pa).
    principal: Vec<f64>,
    /// Plastic strain per element (Voigt), and its norm.
    plastic: Vec<f64>,
    plastic_norm: Vec<f64>,
    /// Which scene element each element lies in (fracture): what a resumed fracture run
    /// rebuilds from.
    origin: Vec<f64>,
    /// Refused splits (reason code and crack normal per node; fracture): what a resumed run
    /// must not retry either.
    refused: Vec<f64>,
}

impl DerivedFields {
    /// The fields of `source`, with the derived scalars if `scalars`.
    fn of(source: &FrameSource, fracture: Option<&Fracture>, scalars: bool) -> Self {
        let state = source.state;
        let positions = source
            .mesh
            .rest
            .iter()
            .enumerate()
            .map(|(i, p)| std::array::from_fn(|a| p[a] + state.u[3 * i + a]))
            .collect();
        let zero_forces = match source.contact {
            Some(forces) if forces.normal.is_empty() => vec![0.0; state.u.len()],
            _ => Vec::new(),
        };
        let contact_active = match source.contact {
            Some(forces) if scalars => {
                let normal = if forces.normal.is_empty() {
                    &zero_forces
                } else {
                    &forces.normal
                };
                normal
                    .chunks(3)
                    .map(|f| f64::from(u8::from(f.iter().any(|x| *x != 0.0))))
                    .collect()
            }
            _ => Vec::new(),
        };
        // What ParaView users would otherwise compute with a calculator, per element.
        let tensors: Vec<_> = match scalars {
            true => source.stress.iter().map(|s| fem::from_voigt(s)).collect(),
            false => Vec::new(),
        };
        let history = &state.history;
        let plastic_norm = match scalars {
            true => history.plastic_strain.iter().map(|e| e.norm()).collect(),
            false => Vec::new(),
        };
        DerivedFields {
            positions,
            rest: rows(&source.mesh.rest),
            zero_forces,
            contact_active,
            von_mises: tensors.iter().map(fem::von_mises).collect(),
            principal: tensors.iter().map(fem::max_principal).collect(),
            plastic: (history.plastic_strain.iter())
                .flat_map(fem::to_voigt)
                .collect(),
            plastic_norm,
            origin: fracture.map_or(Vec::new(), |f| f.origin.iter().map(|&o| o as f64).collect()),
            refused: fracture.map_or(Vec::new(), |f| f.refusals_as_rows(source.mesh.num_nodes())),
        }
    }
}

/// The node fields of a frame besides positions and velocities.
fn node_fields<'a>(
    source: &'a FrameSource,
    derived: &'a DerivedFields,
    fracture: bool,
) -> Vec<Field<'a>> {
    let state = source.state;
    let field = |name, cols, data| Field { name, cols, data };
    // The displacement is stored exactly (positions = rest + u are rounded), so that a
    // resumed run continues bit for bit.
    let mut fields = vec![field("displacement", 3, &state.u[..])];
    // What the time scheme carries from step to step (Newmark's acceleration, BDF2's step
    // back): what a resumed run continues from. The initial frame has none.
    for (name, data) in &state.carried.fields {
        fields.push(field(name, 3, data));
    }
    // With [thermal]: the temperature at every node (°C), read where the heat is solved.
    if let Some(t) = &source.temperature {
        fields.push(field("temperature", 1, t));
    }
    if let Some(forces) = source.contact {
        let (normal, friction) = if forces.normal.is_empty() {
            (&derived.zero_forces[..], &derived.zero_forces[..])
        } else {
            (&forces.normal[..], &forces.friction[..])
        };
        fields.push(field("contact_normal_force", 3, normal));
        fields.push(field("contact_friction_force", 3, friction));
        if !derived.contact_active.is_empty() {
            fields.push(field("contact_active", 1, &derived.contact_active));
        }
    }
    if fracture {
        fields.push(field("refused_split", 4, &derived.refused));
    }
    fields
}

/// The fields of rows of any count of a frame: what the terms carry.
fn row_fields(state: &State) -> Vec<Field<'_>> {
    (state.term_history.0.iter())
        .map(|r| Field {
            name: r.name,
            cols: r.columns,
            data: &r.data,
        })
        .collect()
}

/// The element fields of a frame besides the stress.
fn element_fields<'a>(
    source: &'a FrameSource,
    derived: &'a DerivedFields,
    fracture: bool,
) -> Vec<Field<'a>> {
    let history = &source.state.history;
    let field = |name, cols, data| Field { name, cols, data };
    let mut fields = vec![field("eigenstrain", 1, &history.eigenstrain[..])];
    if !history.freeze_state.is_empty() {
        fields.push(field("freeze_state", 1, &history.freeze_state));
    }
    if !derived.von_mises.is_empty() {
        fields.push(field("von_mises", 1, &derived.von_mises));
        fields.push(field("max_principal_stress", 1, &derived.principal));
    }
    if !derived.plastic.is_empty() {
        fields.push(field("plastic_strain", 6, &derived.plastic));
    }
    if !derived.plastic_norm.is_empty() {
        fields.push(field("plastic_strain_norm", 1, &derived.plastic_norm));
    }
    if fracture {
        fields.push(field("origin", 1, &derived.origin));
    }
    fields
}

/// Writes the state of `source` as a frame (with the crack surfaces and what a resumed run
/// needs of `fracture`, if the run fractures).
fn write_frame(
    writer: &mut BackgroundWriter,
    source: &FrameSource,
    fracture: Option<(&Fracture, &Simulation)>,
    flags: FrameFlags,
) -> Result<(), OutputError> {
    let state = source.state;
    let scalars = writer.frame_options().derived_scalars;
    let derived = DerivedFields::of(source, fracture.map(|(f, _)| f), scalars);
    let restart_point = f64::from(u8::from(flags.restart_point));
    let mut attributes = vec![("restart_point", restart_point)];
    attributes.extend(state.carried.scalars.iter().copied());
    // With adaptive steps: the length the control proposes for the next step.
    if state.next_dt > 0.0 {
        attributes.push(("next_dt", state.next_dt));
    }
    let cracks = fracture.map(|(f, sim)| f.surface(sim));
    writer.write_frame(&Frame {
        step: state.step,
        time: state.time,
        positions: &derived.positions,
        velocities: as_rows(&state.v),
        rest_positions: &derived.rest,
        tets: &source.mesh.tets,
        topology_changed: flags.topology_changed,
        stress: &source.stress,
        element_fields: &element_fields(source, &derived, fracture.is_some()),
        node_fields: &node_fields(source, &derived, fracture.is_some()),
        row_fields: &row_fields(state),
        attributes: &attributes,
        cracks: cracks.as_ref(),
    })
}
