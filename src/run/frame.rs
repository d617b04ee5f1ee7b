//! Frames: what a run writes of its state at a step, on one process or gathered from the
//! processes of a distributed run.

use super::fracture_parts::{crack_surface, gap_rows, FractureOnParts, CRACK_ROW};
use super::{as_rows, rows, Processes, RunError};
use crate::fem;
use crate::fracture::Fracture;
use crate::mesh::TetMesh;
use crate::output::{
    frame_columns, mesh_columns, voigt_to_matrices, BackgroundWriter, ColumnValues, Field, Frame,
    FrameColumn, FrameLayout, FrameOptions, OutputError, OutputWriter,
};
use crate::physics::contact::ContactForces;
use crate::physics::ice_contact::CRACK_GAPS;
use crate::sim::part::Part;
use crate::sim::{SimError, Simulation, State};

/// Writes the current state of `sim` as a frame on the writing process (`writer`). In a
/// distributed run whose processes hold parts of the mesh (`shared`: the processes, this
/// one's part, and its fracture where the run fractures on the parts), every process first
/// gives its part of the state to the writing one.
pub(super) fn emit_frame(
    writer: Option<&mut BackgroundWriter>,
    (sim, fracture): (&Simulation, Option<&Fracture>),
    shared: Option<SharedFrame>,
    (flags, options): (FrameFlags, FrameOptions),
) -> Result<(), RunError> {
    let Some(shared) = shared else {
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
    write_in_blocks(writer, sim, shared, flags, options)
}

/// What a process of a run whose processes hold parts of the mesh gives to a frame: the
/// processes, its part, and its fracture where the run fractures on the parts.
pub(super) type SharedFrame<'a> = (&'a dyn Processes, &'a Part, Option<&'a dyn FractureOnParts>);

/// Writes the state of `sim`, whose mesh is this process's `part`, as a frame on the
/// writing process (`writer`) of `processes`, in blocks of rows: every process computes its
/// part's fields and, block by block, gives the rows of its owned nodes and own elements to
/// the writing process, which places them in the block and hands the block to its writer.
/// The writing process holds one block (at most 8 MiB of values) and one process's rows of
/// it at a time besides its own part's fields; with `fracture`, also the crack triangles
/// and the crack gaps of every process.
fn write_in_blocks(
    mut writer: Option<&mut BackgroundWriter>,
    sim: &Simulation,
    (processes, part, fracture): SharedFrame,
    flags: FrameFlags,
    options: FrameOptions,
) -> Result<(), RunError> {
    let source = FrameSource::of(sim);
    let mut derived = DerivedFields::of(&source, None, options.derived_scalars);
    // The crack triangles and gaps this process gives, where the run fractures on the parts.
    let mut crack_rows = None;
    if let Some(f) = fracture {
        let part = f.frame_part(sim)?;
        (derived.origin, derived.refused) = (part.origin, part.refused);
        crack_rows = Some((part.cracks, part.gaps));
    }
    let element_fields = element_fields(&source, &derived, fracture.is_some());
    let node_fields = node_fields(&source, &derived, fracture.is_some());
    let names = |fields: &[Field]| {
        fields
            .iter()
            .map(|f| (f.name.to_string(), f.cols))
            .collect()
    };
    let layout = FrameLayout {
        step: sim.state.step,
        time: sim.state.time,
        attributes: (frame_attributes(&sim.state, flags).into_iter())
            .map(|(name, value)| (name.to_string(), value))
            .collect(),
        nodes: part.whole_nodes(),
        elements: part.whole_elements(),
        topology_changed: flags.topology_changed && fracture.is_some(),
        element_fields: names(&element_fields),
        node_fields: names(&node_fields),
    };
    let given = (part.given_rows(false), part.given_rows(true));
    let columns = frame_columns(&layout, options);
    let values = |column: &FrameColumn| {
        column_values(
            &column.values,
            (&source, &derived, part),
            (&element_fields, &node_fields),
        )
    };
    let rows = (&columns[..], (&given.0[..], &given.1[..]));
    let began = writer.as_deref_mut().map(|w| w.begin_frame(&layout));
    let gathered = match (writer.as_deref_mut(), &began) {
        (Some(w), Some(Ok(()))) => {
            let mut write = |index, first, values| Ok(w.write_rows(index, first, values)?);
            gather_in_blocks(processes, rows, &values, Some(&mut write))
        }
        _ => gather_in_blocks(processes, rows, &values, None),
    };
    // The crack triangles and gaps of every process, on the writing process.
    let (mut cracks, mut gaps) = (Vec::new(), Vec::new());
    if let Some((my_cracks, my_gaps)) = crack_rows {
        processes.gather_values(my_cracks, &mut |rows| {
            cracks.extend(rows.as_chunks::<CRACK_ROW>().0.iter().copied())
        });
        processes.gather_values(my_gaps, &mut |rows| {
            gaps.extend(rows.as_chunks::<3>().0.iter().copied())
        });
    }
    began.transpose()?;
    gathered?;
    let Some(w) = writer else {
        return Ok(());
    };
    let gaps = gap_rows(gaps);
    let row_fields = match gaps.is_empty() {
        true => Vec::new(),
        false => vec![Field {
            name: CRACK_GAPS,
            cols: 3,
            data: &gaps,
        }],
    };
    let cracks = fracture.map(|_| crack_surface(cracks));
    Ok(w.end_frame(cracks, &row_fields)?)
}

/// The elements of this process's `part`, whose mesh is `mesh` (numbered in the part), as
/// rows of their nodes' numbers in the whole mesh.
fn whole_tets(part: &Part, mesh: &TetMesh) -> Vec<f64> {
    (mesh.tets.iter())
        .flat_map(|t| t.map(|v| part.nodes[v] as f64))
        .collect()
}

/// Writes the run header's mesh (`writer`'s, created with `HeaderMesh::InBlocks`) on the
/// writing process of `processes`, from their parts: this process's `part`, whose mesh is
/// `mesh` (numbered in the part), gives its owned nodes' rest positions and its own
/// elements' nodes (numbered in the whole mesh).
pub(super) fn write_mesh_in_blocks(
    writer: Option<&mut OutputWriter>,
    processes: &dyn Processes,
    part: &Part,
    mesh: &TetMesh,
) -> Result<(), RunError> {
    let given = (part.given_rows(false), part.given_rows(true));
    let columns = mesh_columns(part.whole_nodes(), part.whole_elements());
    let values = |column: &FrameColumn| -> std::borrow::Cow<[f64]> {
        match column.per_node {
            true => mesh.rest.iter().flat_map(|x| [x.x, x.y, x.z]).collect(),
            false => whole_tets(part, mesh).into(),
        }
    };
    let rows = (&columns[..], (&given.0[..], &given.1[..]));
    match writer {
        Some(w) => {
            let mut write =
                |index, first, values: Vec<f64>| Ok(w.write_rows(index, first, &values)?);
            gather_in_blocks(processes, rows, &values, Some(&mut write))?;
            Ok(w.end_mesh()?)
        }
        None => gather_in_blocks(processes, rows, &values, None),
    }
}

/// The rows a process gives to the datasets of its nodes and of its elements: (row of the
/// dataset, row of the process's values).
type GivenRows<'a> = (&'a [(usize, usize)], &'a [(usize, usize)]);

/// Writes a block put together: the dataset's index, its first row, its values.
type WriteBlock<'a> = &'a mut dyn FnMut(usize, usize, Vec<f64>) -> Result<(), RunError>;

/// Gives the rows of `columns` this process holds to the writing process of `processes`,
/// block by block: its nodes' and elements' rows (`given`: row of the dataset, row of
/// `values(column)`). On the writing process, `write` writes each block put together (the
/// dataset's index in `columns`, its first row, its values); it holds one block (at most
/// 8 MiB of values) and one process's rows of it at a time. Returns `write`'s first error;
/// the blocks are still gathered after it, as the other processes send them.
pub(super) fn gather_in_blocks<'v>(
    processes: &dyn Processes,
    (columns, (nodes, elements)): (&[FrameColumn], GivenRows),
    values: &dyn Fn(&FrameColumn) -> std::borrow::Cow<'v, [f64]>,
    mut write: Option<WriteBlock>,
) -> Result<(), RunError> {
    let mut failed: Option<RunError> = None;
    for (index, column) in columns.iter().enumerate() {
        let values = values(column);
        let cols = column.cols;
        let rows = if column.per_node { nodes } else { elements };
        let mut at = 0;
        for first in (0..column.rows).step_by(column.block_rows) {
            let end = (first + column.block_rows).min(column.rows);
            let stop = at + rows[at..].partition_point(|&(i, _)| i < end);
            let mut share = Vec::with_capacity((stop - at) * (1 + cols));
            share.extend(rows[at..stop].iter().map(|&(i, _)| i as f64));
            for &(_, k) in &rows[at..stop] {
                share.extend_from_slice(&values[cols * k..cols * (k + 1)]);
            }
            at = stop;
            let mut block = BlockRows::new(first, end, cols, write.is_some());
            processes.gather_values(share, &mut |rows| block.place(&rows));
            let Some(write) = write.as_deref_mut().filter(|_| failed.is_none()) else {
                continue;
            };
            failed = match block.take() {
                Some(values) => write(index, first, values).err(),
                None => Some(RunError::from(SimError::Setup(format!(
                    "rows {first}..{end} of {:?} did not arrive whole",
                    column.values
                )))),
            };
        }
    }
    failed.map_or(Ok(()), Err)
}

/// A block of rows `first..end` of a frame's dataset of `cols` columns, put together on the
/// writing process from the processes' rows.
struct BlockRows {
    first: usize,
    cols: usize,
    values: Vec<f64>,
    /// Whether each row arrived.
    arrived: Vec<bool>,
    /// Whether rows arrived that are not in the block, or twice.
    wrong: bool,
}

impl BlockRows {
    /// The empty block; with `holds` false (a process that does not write), nothing is kept.
    fn new(first: usize, end: usize, cols: usize, holds: bool) -> Self {
        let rows = if holds { end - first } else { 0 };
        BlockRows {
            first,
            cols,
            values: vec![0.0; rows * cols],
            arrived: vec![false; rows],
            wrong: false,
        }
    }

    /// Places one process's rows: their numbers in the dataset, then their values.
    fn place(&mut self, given: &[f64]) {
        let count = given.len() / (1 + self.cols);
        self.wrong |= given.len() != count * (1 + self.cols);
        let (numbers, values) = given.split_at(count);
        for (&number, row) in numbers.iter().zip(values.chunks_exact(self.cols)) {
            let r = (number as usize).wrapping_sub(self.first);
            match self.arrived.get_mut(r) {
                Some(arrived) if !*arrived => {
                    *arrived = true;
                    self.values[self.cols * r..self.cols * (r + 1)].copy_from_slice(row);
                }
                _ => self.wrong = true,
            }
        }
    }

    /// The block's values, if every row arrived once.
    fn take(&mut self) -> Option<Vec<f64>> {
        (!self.wrong && self.arrived.iter().all(|&a| a)).then(|| std::mem::take(&mut self.values))
    }
}

/// The values of a frame's dataset on a process's `part`, a row per part node or element.
fn column_values<'a>(
    values: &ColumnValues,
    (source, derived, part): (&'a FrameSource, &'a DerivedFields, &Part),
    (element_fields, node_fields): (&'a [Field<'a>], &'a [Field<'a>]),
) -> std::borrow::Cow<'a, [f64]> {
    use std::borrow::Cow;
    let field = |name: &str| {
        (element_fields.iter().chain(node_fields))
            .find(|f| f.name == name)
            .map_or(&[][..], |f| f.data)
    };
    match values {
        ColumnValues::Positions => Cow::Borrowed(derived.positions.as_flattened()),
        ColumnValues::Velocities => Cow::Borrowed(&source.state.v),
        ColumnValues::Stress => Cow::Borrowed(source.stress.as_flattened()),
        ColumnValues::Field(name) => Cow::Borrowed(field(name)),
        ColumnValues::Matrices(name) => {
            let voigt = match name.as_str() {
                "stress" => source.stress.as_flattened(),
                name => field(name),
            };
            Cow::Owned(voigt_to_matrices(voigt))
        }
        ColumnValues::RestPositions => Cow::Borrowed(derived.rest.as_flattened()),
        ColumnValues::Tets => Cow::Owned(whole_tets(part, source.mesh)),
    }
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

/// The scalar attributes of a frame of `state` besides its step and time: whether it is a
/// restart point, what the time scheme carries, and the step length proposed next (s).
fn frame_attributes(state: &State, flags: FrameFlags) -> Vec<(&'static str, f64)> {
    let restart_point = f64::from(u8::from(flags.restart_point));
    let mut attributes = vec![("restart_point", restart_point)];
    attributes.extend(state.carried.scalars.iter().copied());
    // With adaptive steps: the length the control proposes for the next step.
    if state.next_dt > 0.0 {
        attributes.push(("next_dt", state.next_dt));
    }
    attributes
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
    let attributes = frame_attributes(state, flags);
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

#[cfg(test)]
mod tests {
    use super::BlockRows;

    #[test]
    fn a_block_is_put_together_from_the_processes_rows_and_refused_if_not_whole() {
        // Rows 10..14 of a 2-column dataset, given by two processes (row numbers, then values).
        let first = [10.0, 12.0, 1.0, 2.0, 5.0, 6.0];
        let second = [11.0, 13.0, 3.0, 4.0, 7.0, 8.0];
        let mut block = BlockRows::new(10, 14, 2, true);
        block.place(&first);
        block.place(&second);
        assert_eq!(
            block.take(),
            Some(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0])
        );
        // A row missing, a row given twice, a row outside the block, a share cut short.
        let refused = |shares: &[&[f64]]| {
            let mut block = BlockRows::new(10, 14, 2, true);
            shares.iter().for_each(|s| block.place(s));
            block.take().is_none()
        };
        assert!(refused(&[&first]));
        assert!(refused(&[&first, &second, &[11.0, 0.0, 0.0]]));
        assert!(refused(&[&first, &second, &[14.0, 0.0, 0.0]]));
        assert!(refused(&[&first, &second[..5]]));
    }
}
