//! Frames written in blocks of rows ([`OutputWriter::begin_frame`]): what the writing process
//! of a distributed run does, so that it never holds a whole frame. Each dataset is created
//! whole (chunked and compressed as a frame written at once) and its rows arrive in blocks of
//! whole chunks, each chunk written once; the file is laid out as a frame written at once.

use hdf5::{Dataset, Group};

use super::hdf5_io::{
    check_cracks, chunk_rows, create_values, vlen_str, write_attr, write_cracks, write_rows,
    write_values, Hdf5Context, Stored,
};
use super::xdmf::FrameRecord;
use super::{check_field_name, invalid, Field, FrameOptions, OutputError, OutputWriter, TENSORS};
use crate::fracture::cracks::CrackSurface;

/// Chunks of a dataset written in one block: 16 chunks of 64 Ki values, 8 MiB of doubles.
const BLOCK_CHUNKS: usize = 16;

/// A frame's layout: what it holds, without its values.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameLayout {
    /// Solver time step index.
    pub step: u64,
    /// Simulated time (s).
    pub time: f64,
    /// Scalar attributes besides `step` and `time` (see [`super::Frame::attributes`]).
    pub attributes: Vec<(String, f64)>,
    /// Nodes and elements of the mesh (the current topology's).
    pub nodes: usize,
    pub elements: usize,
    /// Whether the mesh changed since the last frame: the frame then holds its own
    /// `rest_positions` and `tets` (their rows arrive in blocks as the fields' do), else it
    /// links the last ones.
    pub topology_changed: bool,
    /// Element fields besides the stress (name, columns).
    pub element_fields: Vec<(String, usize)>,
    /// Node fields besides positions and velocities (name, columns).
    pub node_fields: Vec<(String, usize)>,
}

/// What one dataset of a frame written in blocks holds.
#[derive(Clone, Debug, PartialEq)]
pub enum ColumnValues {
    /// Positions X + u (m), 3 a node.
    Positions,
    /// Velocities (m/s), 3 a node.
    Velocities,
    /// Element stresses (Pa, Voigt order xx yy zz yz xz xy), 6 an element.
    Stress,
    /// A node or element field of the layout, by name.
    Field(String),
    /// A symmetric tensor — the stress, or a 6-column field by name — as 3 × 3 matrices, 9
    /// values a row ([`super::voigt_to_matrices`]).
    Matrices(String),
    /// Rest positions (m), 3 a node: the mesh's, in a frame whose topology changed and in
    /// the header's mesh.
    RestPositions,
    /// The nodes of each element (stored as integers), 4 an element: as `RestPositions`.
    Tets,
}

/// One dataset of a frame written in blocks: what it holds, its shape, and how many rows go
/// in one block.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameColumn {
    /// What the dataset holds.
    pub values: ColumnValues,
    /// Whether a row is a node's (else an element's).
    pub per_node: bool,
    /// Rows and columns of the dataset.
    pub rows: usize,
    pub cols: usize,
    /// Rows of a block: whole chunks of the dataset, about 8 MiB of values (the last block
    /// holds what is left).
    pub block_rows: usize,
    /// Its path inside the frame group, how it is stored, and whether it carries a `center`
    /// attribute.
    dataset: String,
    stored: Stored,
    center: Option<&'static str>,
}

/// The datasets of a frame laid out as `frame`, written with `options`, in the order they are
/// written: positions, velocities, the mesh where its topology changed ([`mesh_columns`]),
/// stress, the element and node fields, and with `options.tensor_matrices` the stress and
/// every 6-column field as matrices. Every process of a distributed run computes the same
/// list.
pub fn frame_columns(frame: &FrameLayout, options: FrameOptions) -> Vec<FrameColumn> {
    let (n, m) = (frame.nodes, frame.elements);
    let column = |values, per_node, cols, dataset: String, center| {
        let rows = if per_node { n } else { m };
        let single = match &values {
            ColumnValues::Matrices(_) => options.drawn_single,
            _ => options.single(&dataset),
        };
        let stored = match single {
            true => Stored::Single,
            false => Stored::Double,
        };
        FrameColumn::new((values, per_node), (rows, cols), (dataset, stored), center)
    };
    let mut columns = vec![
        column(ColumnValues::Positions, true, 3, "positions".into(), None),
        column(ColumnValues::Velocities, true, 3, "velocities".into(), None),
    ];
    if frame.topology_changed {
        columns.extend(mesh_columns(n, m));
    }
    columns.push(column(
        ColumnValues::Stress,
        false,
        6,
        "stress".into(),
        None,
    ));
    let fields = [
        (&frame.element_fields, false, "Cell"),
        (&frame.node_fields, true, "Node"),
    ];
    for (list, per_node, center) in fields {
        for (name, cols) in list {
            let values = ColumnValues::Field(name.clone());
            columns.push(column(values, per_node, *cols, name.clone(), Some(center)));
        }
    }
    if options.tensor_matrices {
        let tensors = std::iter::once(("stress", false, "Cell")).chain(
            (fields.iter())
                .flat_map(|(list, per_node, center)| {
                    list.iter()
                        .map(move |(name, cols)| (name, cols, per_node, center))
                })
                .filter(|(_, &cols, _, _)| cols == 6)
                .map(|(name, _, &per_node, &center)| (name.as_str(), per_node, center)),
        );
        for (name, per_node, center) in tensors {
            let values = ColumnValues::Matrices(name.into());
            let dataset = format!("{TENSORS}/{name}");
            columns.push(column(values, per_node, 9, dataset, Some(center)));
        }
    }
    columns
}

/// The datasets of the run header's `/mesh` of `nodes` nodes and `elements` elements written
/// in blocks (see [`super::HeaderMesh::InBlocks`]): `rest_positions` (a field of the nodes'
/// rest positions, m) and `tets` (the elements' nodes, stored as integers), in that order.
pub fn mesh_columns(nodes: usize, elements: usize) -> Vec<FrameColumn> {
    vec![
        FrameColumn::new(
            (ColumnValues::RestPositions, true),
            (nodes, 3),
            ("rest_positions".into(), Stored::Double),
            None,
        ),
        FrameColumn::new(
            (ColumnValues::Tets, false),
            (elements, 4),
            ("tets".into(), Stored::Index),
            None,
        ),
    ]
}

impl FrameColumn {
    fn new(
        (values, per_node): (ColumnValues, bool),
        (rows, cols): (usize, usize),
        (dataset, stored): (String, Stored),
        center: Option<&'static str>,
    ) -> Self {
        FrameColumn {
            values,
            per_node,
            rows,
            cols,
            block_rows: chunk_rows(rows, cols)
                .map_or(rows, |c| c * BLOCK_CHUNKS)
                .max(1),
            dataset,
            stored,
            center,
        }
    }
}

/// A frame, or the header's mesh, being written in blocks.
pub(super) struct OpenFrame {
    name: String,
    group: Group,
    columns: Vec<FrameColumn>,
    datasets: Vec<Dataset>,
    /// Rows written so far, per dataset.
    written: Vec<usize>,
    /// The frame's layout; none for the header's mesh.
    layout: Option<FrameLayout>,
    /// What the frame adds to the file at most.
    bytes: u64,
}

impl OpenFrame {
    /// The header's `/mesh` group `group`, its datasets created empty (see [`mesh_columns`]).
    pub(super) fn mesh(
        path: &std::path::Path,
        group: Group,
        (nodes, elements): (usize, usize),
    ) -> Result<Self, OutputError> {
        let columns = mesh_columns(nodes, elements);
        Ok(OpenFrame {
            name: "/mesh".into(),
            datasets: create_datasets(path, &group, &columns)?,
            written: vec![0; columns.len()],
            group,
            columns,
            layout: None,
            bytes: 0,
        })
    }
}

impl OutputWriter {
    /// Begins a frame laid out as `frame` whose datasets' rows arrive in blocks
    /// ([`write_rows`](Self::write_rows), in any order) and which
    /// [`end_frame`](Self::end_frame) completes. Unless its topology changed, the mesh is the
    /// current topology's: its `rest_positions` and `tets` are linked to it. Fields are
    /// written anew in every such frame (none is linked to the last frame's).
    pub fn begin_frame(&mut self, frame: &FrameLayout) -> Result<(), OutputError> {
        let path = self.location.clone();
        if self.open.is_some() {
            return Err(invalid(
                &path,
                "a frame or the header's mesh written in blocks is already open",
            ));
        }
        let counts = (frame.nodes, frame.elements);
        if !frame.topology_changed && counts != (self.n_nodes, self.n_elems) {
            return Err(invalid(
                &path,
                format!(
                    "frame step {}: {} nodes and {} elements, the mesh has {} and {}",
                    frame.step, frame.nodes, frame.elements, self.n_nodes, self.n_elems
                ),
            ));
        }
        let mut seen = Vec::new();
        for (list, kind) in [
            (&frame.element_fields, "element"),
            (&frame.node_fields, "node"),
        ] {
            for (name, cols) in list {
                check_field_name(&path, kind, name, &mut seen)?;
                if *cols == 0 {
                    return Err(invalid(&path, format!("{kind} field {name:?}: no columns")));
                }
            }
        }
        let columns = frame_columns(frame, self.options);
        let values: usize = columns.iter().map(|c| c.rows * c.cols).sum();
        let bytes = 16_384 + 8 * values as u64;
        let (file, name) = self.prepare_frame(bytes)?;
        let attributes: Vec<(&str, f64)> = (frame.attributes.iter())
            .map(|(k, v)| (k.as_str(), *v))
            .collect();
        let group = self.start_frame_group(&file, &name, (frame.step, frame.time), &attributes)?;
        if !frame.topology_changed {
            self.link_topology(&file, &group)?;
        }
        let datasets = create_datasets(&path, &group, &columns)?;
        // The next frame written at once must not link to this one's fields by the last
        // values kept (they are not kept for a frame written in blocks).
        self.last_fields = None;
        self.open = Some(OpenFrame {
            name,
            group,
            written: vec![0; columns.len()],
            columns,
            datasets,
            layout: Some(frame.clone()),
            bytes,
        });
        Ok(())
    }

    /// Writes `values`, whole rows of dataset `column` (an index into
    /// [`frame_columns`]), into its rows from `first` on.
    pub fn write_rows(
        &mut self,
        column: usize,
        first: usize,
        values: &[f64],
    ) -> Result<(), OutputError> {
        let path = &self.location;
        let open = (self.open.as_mut()).ok_or_else(|| invalid(path, "no frame is open"))?;
        let (Some(c), Some(ds)) = (open.columns.get(column), open.datasets.get(column)) else {
            return Err(invalid(path, format!("no dataset {column} in the frame")));
        };
        let rows = values.len() / c.cols;
        if !values.len().is_multiple_of(c.cols) || first + rows > c.rows {
            return Err(invalid(
                path,
                format!(
                    "{}: {} values from row {first} of {} rows × {} columns",
                    c.dataset,
                    values.len(),
                    c.rows,
                    c.cols
                ),
            ));
        }
        // An element's nodes must be nodes of the mesh the frame holds (that they are
        // indices at all is checked as they are stored).
        let nodes = open.layout.as_ref().map_or(self.n_nodes, |l| l.nodes);
        if c.values == ColumnValues::Tets && values.iter().any(|&x| x >= nodes as f64) {
            return Err(invalid(
                path,
                format!(
                    "{}: an element's node is not one of the {nodes} nodes",
                    c.dataset
                ),
            ));
        }
        write_rows(path, ds, (first, c.cols), values, c.stored)?;
        open.written[column] += rows;
        Ok(())
    }

    /// Completes the frame begun by [`begin_frame`](Self::begin_frame), with its crack
    /// surfaces `cracks` (fracture runs) and the fields of rows of any count `row_fields`
    /// (see [`super::Frame::row_fields`]), written at once: an error, and no frame, unless
    /// every row of every dataset was written and the crack surface is whole.
    pub fn end_frame(
        &mut self,
        cracks: Option<&CrackSurface>,
        row_fields: &[Field],
    ) -> Result<(), OutputError> {
        let path = self.location.clone();
        if let Some(c) = cracks {
            check_cracks(&path, c)?;
        }
        let mut seen = Vec::new();
        for f in row_fields {
            check_field_name(&path, "row", f.name, &mut seen)?;
            if f.cols == 0 || !f.data.len().is_multiple_of(f.cols) {
                let message = format!("row field {:?}: {} values", f.name, f.data.len());
                return Err(invalid(&path, message));
            }
        }
        let open = self.take_written(true)?;
        let layout = open.layout.expect("a frame's layout");
        drop(open.datasets);
        if let Some(c) = cracks {
            write_cracks(&path, &open.group, &open.name, c, self.options.drawn_single)?;
        }
        for f in row_fields {
            let shape = (f.name, f.data.len() / f.cols, f.cols);
            let ds = write_values(
                &path,
                &open.group,
                shape,
                f.data,
                self.options.single(f.name),
            )?;
            write_attr(&path, &ds, "center", &vlen_str(&path, "center", "Rows")?)?;
        }
        let record = FrameRecord::of_layout(
            self.next_frame,
            &layout,
            cracks,
            self.options,
            self.last_record(),
        );
        if layout.topology_changed {
            self.topology = format!("/frames/{}", open.name);
            self.unlinked_topology = Some(open.group.clone());
            (self.n_nodes, self.n_elems) = (layout.nodes, layout.elements);
        }
        let file = self.file()?.clone();
        self.frame_written(&file, (open.name, record, open.group), open.bytes)
    }

    /// Completes the header's mesh of a file created with [`super::HeaderMesh::InBlocks`]: an
    /// error unless every row of both datasets was written.
    pub fn end_mesh(&mut self) -> Result<(), OutputError> {
        let open = self.take_written(false)?;
        drop(open.datasets);
        let path = self.location.clone();
        (self.file()?.flush()).ctx(&path, || "flushing the header's mesh".into())
    }

    /// The open frame (the header's mesh unless `frame`), taken, if every row of every
    /// dataset was written; left open if it is the other kind.
    fn take_written(&mut self, frame: bool) -> Result<OpenFrame, OutputError> {
        let path = self.location.clone();
        match self.open.as_ref().map(|o| o.layout.is_some()) {
            None => return Err(invalid(&path, "no frame is open")),
            Some(true) if !frame => {
                return Err(invalid(&path, "a frame is open, not the header's mesh"))
            }
            Some(false) if frame => {
                return Err(invalid(&path, "the header's mesh is open, not a frame"))
            }
            Some(_) => {}
        }
        let open = (self.open.take()).ok_or_else(|| invalid(&path, "no frame is open"))?;
        let short = (open.columns.iter().zip(&open.written)).find(|(c, &w)| w != c.rows);
        if let Some((c, w)) = short {
            return Err(invalid(
                &path,
                format!(
                    "{}: {w} of the {} rows of {} written",
                    match open.layout {
                        Some(_) => format!("frame {}", open.name),
                        None => "the header's /mesh".into(),
                    },
                    c.rows,
                    c.dataset
                ),
            ));
        }
        Ok(open)
    }
}

/// Creates the datasets of `columns` in frame group `g` (the tensors in its group
/// [`TENSORS`]), empty, with their `center` attributes.
fn create_datasets(
    path: &std::path::Path,
    g: &Group,
    columns: &[FrameColumn],
) -> Result<Vec<Dataset>, OutputError> {
    let mut tensors: Option<Group> = None;
    let mut datasets = Vec::with_capacity(columns.len());
    for c in columns {
        let (parent, name) = match c.dataset.split_once('/') {
            Some((_, name)) => {
                if tensors.is_none() {
                    let t = (g.create_group(TENSORS))
                        .ctx(path, || format!("creating {}/{TENSORS}", g.name()))?;
                    tensors = Some(t);
                }
                (tensors.as_ref().unwrap_or(g), name)
            }
            None => (g, c.dataset.as_str()),
        };
        let ds = create_values(path, parent, (name, c.rows, c.cols), c.stored)?;
        if let Some(center) = c.center {
            write_attr(path, &ds, "center", &vlen_str(path, "center", center)?)?;
        }
        datasets.push(ds);
    }
    Ok(datasets)
}

#[cfg(test)]
mod tests;
