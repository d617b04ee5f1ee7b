//! The XDMF 3 sidecars of a run's file: `RUN.xdmf` (the tet mesh of every complete frame,
//! for ParaView and VTK's XDMF readers) and, with fracture, `RUN.cracks.xdmf` (the crack
//! surfaces of every complete frame).
//!
//! The sidecars are made from a [`FrameRecord`] per complete frame — the names, shapes and
//! types of its datasets — which the writer keeps as it writes frames, so a running run rewrites
//! its sidecars without reading its file back (that would load every frame's metadata into
//! HDF5's cache). [`write_xdmf`] reads the records of a finished file.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use hdf5::types::{FloatSize, IntSize, TypeDescriptor};
use hdf5::{Dataset, File, Group};

use super::hdf5_io::{
    check_hdf5_signature, check_icefem_layout, list_frames, open_2d, open_read, read_attr,
    read_string, Hdf5Context,
};
use super::{
    corrupt, invalid, Frame, FrameLayout, FrameOptions, OutputError, RESERVED_FRAME_NAMES, TENSORS,
};
use crate::fracture::cracks::CrackSurface;

/// One dataset as a sidecar describes it: shape and number type.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Item {
    /// Rows.
    rows: usize,
    /// Columns; 0 for a 1-D dataset.
    cols: usize,
    /// XDMF `DataType` ("Float", "Int", "UInt").
    kind: &'static str,
    /// Bytes per number.
    precision: usize,
}

/// A f64 dataset of `rows` × `cols` (0: 1-D), as the writer stores them.
fn float(rows: usize, cols: usize) -> Item {
    Item {
        rows,
        cols,
        kind: "Float",
        precision: 8,
    }
}

/// An i64 index dataset of `rows` × `cols` (0: 1-D), as the writer stores them.
fn indices(rows: usize, cols: usize) -> Item {
    Item {
        rows,
        cols,
        kind: "Int",
        precision: 8,
    }
}

/// One `<Attribute>` of a frame's grid: its name in the sidecar, the dataset inside the
/// frame group, centering and item.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct AttributeRecord {
    name: String,
    dataset: String,
    center: &'static str,
    item: Item,
}

/// What the sidecars say of one complete frame.
#[derive(Clone, Debug)]
pub(super) struct FrameRecord {
    /// Frame index (group `/frames/NNNNNN`).
    index: usize,
    /// Simulated time (s).
    time: f64,
    /// `positions` and `tets`.
    positions: Item,
    tets: Item,
    /// Attributes in sidecar order; shared between consecutive frames with the same layout.
    attributes: Arc<[AttributeRecord]>,
    /// `cracks/triangles`, `cracks/vertices`, `cracks/crack`, when the frame has crack faces.
    cracks: Option<[Item; 3]>,
}

impl FrameRecord {
    /// The record of `frame`, written as group `index` with `options` (without tensor
    /// matrices, no tensor is listed); `previous` (the last record) lends its attribute list
    /// when the layout is the same.
    pub(super) fn of(
        index: usize,
        frame: &Frame,
        options: FrameOptions,
        previous: Option<&FrameRecord>,
    ) -> Self {
        let names = |fields: &[super::Field]| -> Vec<(String, usize)> {
            fields
                .iter()
                .map(|f| (f.name.to_string(), f.cols))
                .collect()
        };
        let layout = FrameLayout {
            step: frame.step,
            time: frame.time,
            attributes: Vec::new(),
            nodes: frame.positions.len(),
            elements: frame.tets.len(),
            topology_changed: frame.topology_changed,
            element_fields: names(frame.element_fields),
            node_fields: names(frame.node_fields),
        };
        Self::of_layout(index, &layout, frame.cracks, options, previous)
    }

    /// The record of a frame laid out as `frame`, with crack surfaces `cracks`, written as
    /// group `index` with `options` (see [`FrameRecord::of`]).
    pub(super) fn of_layout(
        index: usize,
        frame: &FrameLayout,
        cracks: Option<&CrackSurface>,
        options: FrameOptions,
        previous: Option<&FrameRecord>,
    ) -> Self {
        let (n, m) = (frame.nodes, frame.elements);
        let tensor_matrices = options.tensor_matrices;
        // The item of a dataset of doubles, or of singles where the options store it so.
        let float = |rows, cols, single: bool| Item {
            precision: if single { 4 } else { 8 },
            ..float(rows, cols)
        };
        let tensor = float(m, 9, options.drawn_single);
        let mut attributes = vec![
            builtin("velocity", "velocities", "Node", float(n, 3, false)),
            builtin(
                "rest_position",
                "rest_positions",
                "Node",
                float(n, 3, false),
            ),
        ];
        if tensor_matrices {
            attributes.push(builtin(
                "stress",
                &format!("{TENSORS}/stress"),
                "Cell",
                tensor,
            ));
        }
        let builtins = attributes.len();
        for (fields, center, rows) in [
            (&frame.element_fields, "Cell", m),
            (&frame.node_fields, "Node", n),
        ] {
            for (name, cols) in fields.iter().filter(|(_, c)| tensor_matrices || *c != 6) {
                let single = options.single(name);
                attributes.push(match cols {
                    6 => builtin(
                        name,
                        &format!("{TENSORS}/{name}"),
                        center,
                        float(rows, 9, options.drawn_single),
                    ),
                    1 => builtin(name, name, center, float(rows, 0, single)),
                    &cols => builtin(name, name, center, float(rows, cols, single)),
                });
            }
        }
        // Fields in name order (as `read_record` lists them).
        attributes[builtins..].sort_by(|a, b| a.name.cmp(&b.name));
        let attributes = shared(attributes, previous);
        let cracks = cracks.map(|c| {
            let t = c.triangles.len();
            let vertices = float(c.vertices.len(), 3, options.drawn_single);
            [indices(t, 3), vertices, indices(t, 0)]
        });
        Self {
            index,
            time: frame.time,
            positions: float(n, 3, options.single("positions")),
            tets: indices(m, 4),
            attributes,
            cracks,
        }
    }
}

/// `attributes`, sharing the previous record's list when they are the same.
fn shared(
    attributes: Vec<AttributeRecord>,
    previous: Option<&FrameRecord>,
) -> Arc<[AttributeRecord]> {
    match previous {
        Some(p) if *p.attributes == *attributes => p.attributes.clone(),
        _ => attributes.into(),
    }
}

fn builtin(name: &str, dataset: &str, center: &'static str, item: Item) -> AttributeRecord {
    AttributeRecord {
        name: name.into(),
        dataset: dataset.into(),
        center,
        item,
    }
}

fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            _ => out.push(c),
        }
    }
    out
}

/// The item of dataset `ds`, or `None` for a type XDMF cannot describe or a shape that is
/// not 1-D or 2-D.
fn item_of(ds: &Dataset) -> Option<Item> {
    let desc = ds.dtype().ok()?.to_descriptor().ok()?;
    let size = |s: IntSize| s as usize;
    let (kind, precision) = match desc {
        TypeDescriptor::Float(FloatSize::U4) => ("Float", 4),
        TypeDescriptor::Float(FloatSize::U8) => ("Float", 8),
        TypeDescriptor::Integer(s) => ("Int", size(s)),
        TypeDescriptor::Unsigned(s) => ("UInt", size(s)),
        _ => return None,
    };
    let (rows, cols) = match ds.shape().as_slice() {
        [r] => (*r, 0),
        [r, c] => (*r, *c),
        _ => return None,
    };
    Some(Item {
        rows,
        cols,
        kind,
        precision,
    })
}

/// One `<DataItem>` referencing `h5_name:/frames/NNNNNN/dataset`.
fn data_item(xml: &mut String, item: &Item, h5_name: &str, frame: &str, dataset: &str) {
    let dims = if item.cols == 0 {
        item.rows.to_string()
    } else {
        format!("{} {}", item.rows, item.cols)
    };
    let _ = writeln!(
        xml,
        "          <DataItem Dimensions=\"{dims}\" DataType=\"{}\" Precision=\"{}\" Format=\"HDF\">{}:/frames/{frame}/{}</DataItem>",
        item.kind,
        item.precision,
        xml_escape(h5_name),
        xml_escape(dataset)
    );
}

/// XDMF attribute type for a dataset of per-row values.
///
/// Symmetric tensors (6-column Voigt datasets) are never listed themselves: their attribute
/// reads `tensors/<name>`, the same tensor as 9 components (a 3 × 3 matrix, row-major), declared
/// `Tensor`. That is the one layout both of VTK's XDMF readers read as the tensor it is:
/// `Tensor6` is read as 9 components in XDMF's order xx xy xz yy yz zz by `vtkXdmfReader`,
/// but passed on as its 6 raw columns by `vtkXdmf3Reader` (ParaView's), which ParaView then
/// labels in VTK's own symmetric order xx yy zz xy yz xz; `Matrix` is one tuple of all values
/// in `vtkXdmfReader`. Other column counts (`refused_split`'s 4) are declared `Vector`, which
/// both readers read as that many components (a `Matrix` again would be one tuple).
fn attribute_type(item: &Item) -> &'static str {
    match item.cols {
        0 | 1 => "Scalar",
        9 => "Tensor",
        _ => "Vector",
    }
}

/// Opens one time step's `<Grid>` in `xml`: its time, topology and geometry. The caller adds
/// attributes and closes it.
fn grid_start(
    xml: &mut String,
    (name, time): (&str, f64),
    (kind, nodes): (&str, usize),
    (topology, geometry): (&Item, &Item),
    (h5_name, frame, topology_set, geometry_set): (&str, &str, &str, &str),
) {
    let _ = writeln!(xml, "      <Grid Name=\"{name}\" GridType=\"Uniform\">");
    let _ = writeln!(xml, "        <Time Value=\"{time:e}\"/>");
    let _ = writeln!(
        xml,
        "        <Topology TopologyType=\"{kind}\" NumberOfElements=\"{}\" NodesPerElement=\"{nodes}\">",
        topology.rows
    );
    data_item(xml, topology, h5_name, frame, topology_set);
    xml.push_str("        </Topology>\n        <Geometry GeometryType=\"XYZ\">\n");
    data_item(xml, geometry, h5_name, frame, geometry_set);
    xml.push_str("        </Geometry>\n");
}

/// The name of frame group `index` (6+ digits, as the writer names them).
fn group_name(index: usize) -> String {
    format!("{index:06}")
}

const HEADER: &str = "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<Xdmf xmlns:xi=\"http://www.w3.org/2001/XInclude\" Version=\"3.0\">\n  <Domain>\n";
const FOOTER: &str = "  </Domain>\n</Xdmf>\n";

/// Writes `<file>.xdmf` next to the HDF5 file: an XDMF 3 temporal collection
/// with one uniform grid per complete frame (incomplete frames are skipped), and with fracture
/// `<file>.cracks.xdmf` (see `write_sidecars`).
///
/// Each grid has `Tetrahedron` topology from the frame's `tets`, `XYZ`
/// geometry from `positions` (m), and attributes `velocity` (Node Vector,
/// m/s), `rest_position` (Node Vector, m; displacement = coordinates −
/// rest_position, e.g. with ParaView's Calculator), `stress` (Cell Tensor, 3 × 3 per element
/// from `tensors/stress`, Pa) and every element / node field under its own name (symmetric
/// tensors from `tensors/<name>`). HDF5 references use the file name only, i.e. a path
/// relative to the sidecar. The sidecar is written to a temporary file and
/// renamed, so a viewer never sees half of it.
pub fn write_xdmf(h5_path: &Path) -> Result<PathBuf, OutputError> {
    check_hdf5_signature(h5_path)?;
    let file = open_read(h5_path, "opening to write the XDMF sidecar")?;
    check_icefem_layout(h5_path, &file)?;
    let records = read_records(h5_path, &file)?;
    drop(file);
    write_sidecars(h5_path, &records)
}

/// The records of the complete frames of `file` (at `h5_path`).
pub(super) fn read_records(h5_path: &Path, file: &File) -> Result<Vec<FrameRecord>, OutputError> {
    let frames = file
        .group("frames")
        .ctx(h5_path, || "opening /frames".into())?;
    let mut records: Vec<FrameRecord> = Vec::new();
    for entry in list_frames(h5_path, &frames)?
        .into_iter()
        .filter(|f| f.complete)
    {
        let g = frames
            .group(&entry.name)
            .ctx(h5_path, || format!("opening /frames/{}", entry.name))?;
        let record = read_record(h5_path, &g, entry.index, records.last())?;
        records.push(record);
    }
    Ok(records)
}

/// The record of frame group `g` (index `index`).
fn read_record(
    h5_path: &Path,
    g: &Group,
    index: usize,
    previous: Option<&FrameRecord>,
) -> Result<FrameRecord, OutputError> {
    let time = read_attr::<f64>(h5_path, g, "time")?;
    let undescribable = |ds: &Dataset| {
        corrupt(
            h5_path,
            format!("{} has a type XDMF cannot describe", ds.name()),
        )
    };
    let (tets, m) = open_2d(h5_path, g, "tets", 4)?;
    let (positions, n) = open_2d(h5_path, g, "positions", 3)?;
    let tets = item_of(&tets).ok_or_else(|| undescribable(&tets))?;
    let positions = item_of(&positions).ok_or_else(|| undescribable(&positions))?;

    // The attribute `name` read from dataset `dataset` of `g`, placed by `center`, if its
    // shape fits the grid (anything else is left out rather than emit a sidecar that crashes
    // the reader).
    let attribute = |name: &str, dataset: &str, center: &'static str| {
        let item = g.dataset(dataset).ok().as_ref().and_then(item_of)?;
        let rows = if center == "Node" { n } else { m };
        (item.rows == rows && item.cols != 6).then(|| AttributeRecord {
            name: name.into(),
            dataset: dataset.into(),
            center,
            item,
        })
    };
    let tensor = |name: &str, center| {
        attribute(name, &format!("{TENSORS}/{name}"), center).filter(|a| a.item.cols == 9)
    };
    // Built-ins first (the stress only as matrices: a file written before they were stored
    // shows none), then fields by name.
    let mut attributes: Vec<AttributeRecord> = [
        attribute("velocity", "velocities", "Node"),
        attribute("rest_position", "rest_positions", "Node"),
        tensor("stress", "Cell"),
    ]
    .into_iter()
    .flatten()
    .collect();
    let builtins = attributes.len();
    let names = g
        .member_names()
        .ctx(h5_path, || format!("listing {}", g.name()))?;
    for name in names {
        if RESERVED_FRAME_NAMES.contains(&name.as_str()) {
            continue;
        }
        let Ok(ds) = g.dataset(&name) else { continue };
        let center = match ds.attr("center").ok().and_then(|a| read_string(&a).ok()) {
            Some(c) if c == "Cell" => "Cell",
            Some(c) if c == "Node" => "Node",
            _ => continue, // unknown centering: cannot place it on the mesh
        };
        // A symmetric tensor (Voigt, 6 columns) shows as its matrices.
        let found = match ds.shape().as_slice() {
            [_, 6] => tensor(&name, center),
            _ => attribute(&name, &name, center),
        };
        attributes.extend(found);
    }
    // Fields in name order, whatever order the group lists its links in.
    attributes[builtins..].sort_by(|a, b| a.name.cmp(&b.name));
    let attributes = shared(attributes, previous);
    let cracks = g.group("cracks").ok().and_then(|c| {
        let items = ["triangles", "vertices", "crack"]
            .map(|name| c.dataset(name).ok().as_ref().and_then(item_of));
        match items {
            [Some(t), Some(v), Some(k)] => Some([t, v, k]),
            _ => None,
        }
    });
    Ok(FrameRecord {
        index,
        time,
        positions,
        tets,
        attributes,
        cracks,
    })
}

/// Writes the sidecars of the HDF5 file at `h5_path` from the records of its complete frames:
/// `RUN.xdmf`, and `RUN.cracks.xdmf` when the frames have a crack group (a run with fracture;
/// removed otherwise, so one left by an earlier run of the same name does not stay). The crack
/// series has a grid for every frame, with no cells before the first crack, so that every time
/// of the run shows the cracks there were then.
pub(super) fn write_sidecars(
    h5_path: &Path,
    records: &[FrameRecord],
) -> Result<PathBuf, OutputError> {
    let h5_name = h5_path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .ok_or_else(|| invalid(h5_path, "path has no file name"))?;
    if h5_name.contains(':') {
        // XDMF separates file and dataset with ':'; a colon in the name is ambiguous.
        return Err(invalid(
            h5_path,
            "file name contains ':', which XDMF cannot reference",
        ));
    }
    let xdmf_path = h5_path.with_extension("xdmf");
    replace_file(&xdmf_path, "the XDMF sidecar", |out| {
        out.write_all(HEADER.as_bytes())?;
        out.write_all(
            b"    <Grid Name=\"icefem\" GridType=\"Collection\" CollectionType=\"Temporal\">\n",
        )?;
        let mut xml = String::new();
        for r in records {
            xml.clear();
            let frame = group_name(r.index);
            grid_start(
                &mut xml,
                (&format!("frame_{frame}"), r.time),
                ("Tetrahedron", 4),
                (&r.tets, &r.positions),
                (&h5_name, &frame, "tets", "positions"),
            );
            for a in r.attributes.iter() {
                let _ = writeln!(
                    xml,
                    "        <Attribute Name=\"{}\" AttributeType=\"{}\" Center=\"{}\">",
                    xml_escape(&a.name),
                    attribute_type(&a.item),
                    a.center
                );
                data_item(&mut xml, &a.item, &h5_name, &frame, &a.dataset);
                xml.push_str("        </Attribute>\n");
            }
            xml.push_str("      </Grid>\n");
            out.write_all(xml.as_bytes())?;
        }
        out.write_all(b"    </Grid>\n")?;
        out.write_all(FOOTER.as_bytes())
    })?;

    // A file of its own: readers that take one grid collection per file (meshio, and
    // ParaView's default view of it) keep reading the tet mesh from RUN.xdmf.
    let path = h5_path.with_extension("cracks.xdmf");
    if records.iter().all(|r| r.cracks.is_none()) {
        return match std::fs::remove_file(&path) {
            Err(source) if source.kind() != std::io::ErrorKind::NotFound => Err(OutputError::Io {
                path,
                context: "removing a crack-surface sidecar of an earlier run".into(),
                source,
            }),
            _ => Ok(xdmf_path),
        };
    }
    replace_file(&path, "the crack-surface XDMF sidecar", |out| {
        out.write_all(HEADER.as_bytes())?;
        out.write_all(b"    <Grid Name=\"icefem_cracks\" GridType=\"Collection\" CollectionType=\"Temporal\">\n")?;
        let mut xml = String::new();
        for r in records {
            xml.clear();
            let frame = group_name(r.index);
            let name = format!("cracks_{frame}");
            match &r.cracks {
                Some([triangles, vertices, crack]) if triangles.rows > 0 => {
                    grid_start(
                        &mut xml,
                        (&name, r.time),
                        ("Triangle", 3),
                        (triangles, vertices),
                        (&h5_name, &frame, "cracks/triangles", "cracks/vertices"),
                    );
                    xml.push_str(
                        "        <Attribute Name=\"crack\" AttributeType=\"Scalar\" Center=\"Cell\">\n",
                    );
                    data_item(&mut xml, crack, &h5_name, &frame, "cracks/crack");
                    xml.push_str("        </Attribute>\n");
                }
                _ => empty_grid(&mut xml, (&name, r.time), &r.positions, (&h5_name, &frame)),
            }
            xml.push_str("      </Grid>\n");
            out.write_all(xml.as_bytes())?;
        }
        out.write_all(b"    </Grid>\n")?;
        out.write_all(FOOTER.as_bytes())
    })?;
    Ok(xdmf_path)
}

/// A time step's grid without crack triangles, opened in `xml` (the caller closes it):
/// `Triangle` topology with 0 elements and no data, over the frame's nodes (`positions`),
/// which no cell uses. VTK's XDMF readers take no empty arrays (an inline empty `DataItem`
/// crashes both, a 0-row HDF5 dataset is an error for `vtkXdmfReader`) and `vtkXdmfReader`
/// needs a geometry it can read, so the grid has the nodes, not nothing.
fn empty_grid(
    xml: &mut String,
    (name, time): (&str, f64),
    positions: &Item,
    (h5_name, frame): (&str, &str),
) {
    let _ = writeln!(xml, "      <Grid Name=\"{name}\" GridType=\"Uniform\">");
    let _ = writeln!(xml, "        <Time Value=\"{time:e}\"/>");
    xml.push_str(
        "        <Topology TopologyType=\"Triangle\" NumberOfElements=\"0\" NodesPerElement=\"3\"/>\n",
    );
    xml.push_str("        <Geometry GeometryType=\"XYZ\">\n");
    data_item(xml, positions, h5_name, frame, "positions");
    xml.push_str("        </Geometry>\n");
}

/// Writes `path` through a temporary file renamed into place, so a reader sees the old file or
/// the new one, never half of one; `write` streams the text.
fn replace_file(
    path: &Path,
    what: &str,
    write: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<(), OutputError> {
    let tmp = path.with_extension("xdmf.tmp");
    let io = |context: String| {
        move |source| OutputError::Io {
            path: path.to_path_buf(),
            context,
            source,
        }
    };
    let file = std::fs::File::create(&tmp).map_err(io(format!("creating {what}")))?;
    let mut out = std::io::BufWriter::new(file);
    write(&mut out)
        .and_then(|()| out.flush())
        .map_err(io(format!("writing {what}")))?;
    drop(out);
    std::fs::rename(&tmp, path).map_err(io(format!("renaming {what} into place")))
}
