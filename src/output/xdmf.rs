//! The XDMF 3 sidecars of a run's file: `RUN.xdmf` (the tet mesh of every complete frame,
//! for ParaView / meshio) and, with fracture, `RUN.cracks.xdmf` (the crack surfaces).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use hdf5::types::{FloatSize, IntSize, TypeDescriptor};
use hdf5::{Dataset, File, Group};

use super::hdf5_io::{
    check_hdf5_signature, check_icefem_layout, close_on_exec, list_frames, open_2d, read_attr,
    read_string, Hdf5Context,
};
use super::{corrupt, invalid, OutputError, RESERVED_FRAME_NAMES};

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

/// XDMF `DataType` and `Precision` of a dataset, or `None` for types XDMF cannot describe.
fn xdmf_number_type(ds: &Dataset) -> Option<(&'static str, usize)> {
    let desc = ds.dtype().ok()?.to_descriptor().ok()?;
    let size = |s: IntSize| s as usize;
    match desc {
        TypeDescriptor::Float(FloatSize::U4) => Some(("Float", 4)),
        TypeDescriptor::Float(FloatSize::U8) => Some(("Float", 8)),
        TypeDescriptor::Integer(s) => Some(("Int", size(s))),
        TypeDescriptor::Unsigned(s) => Some(("UInt", size(s))),
        _ => None,
    }
}

/// One `<DataItem>` referencing `h5_name:h5_path`, or `None` if the dataset's
/// type is not expressible in XDMF.
fn xdmf_data_item(ds: &Dataset, h5_name: &str, indent: &str) -> Option<String> {
    let (ty, prec) = xdmf_number_type(ds)?;
    let dims: Vec<String> = ds.shape().iter().map(|d| d.to_string()).collect();
    Some(format!(
        "{indent}<DataItem Dimensions=\"{}\" DataType=\"{ty}\" Precision=\"{prec}\" Format=\"HDF\">{}:{}</DataItem>\n",
        dims.join(" "),
        xml_escape(h5_name),
        xml_escape(&ds.name())
    ))
}

/// XDMF attribute type for a dataset of per-row values.
///
/// 6-column data (stress, plastic strain) is declared `Matrix`, not
/// `Tensor6`: XDMF's Tensor6 component order is xx xy xz yy yz zz, while
/// icefem stores Voigt order xx yy zz yz xz xy, so `Tensor6` would make
/// ParaView silently mislabel components.
fn xdmf_attribute_type(shape: &[usize]) -> &'static str {
    match shape {
        [_] | [_, 1] => "Scalar",
        [_, 3] => "Vector",
        _ => "Matrix",
    }
}

/// Opens one time step's `<Grid>` in `xml`: its time, topology (type, element count, nodes per
/// element, index data item) and geometry (XYZ data item). The caller adds attributes and
/// closes it.
fn xdmf_grid_start(
    xml: &mut String,
    name: &str,
    time: f64,
    (kind, count, nodes): (&str, usize, usize),
    topology: &str,
    geometry: &str,
) {
    let _ = writeln!(xml, "      <Grid Name=\"{name}\" GridType=\"Uniform\">");
    let _ = writeln!(xml, "        <Time Value=\"{time:e}\"/>");
    let _ = writeln!(
        xml,
        "        <Topology TopologyType=\"{kind}\" NumberOfElements=\"{count}\" NodesPerElement=\"{nodes}\">"
    );
    xml.push_str(topology);
    xml.push_str("        </Topology>\n        <Geometry GeometryType=\"XYZ\">\n");
    xml.push_str(geometry);
    xml.push_str("        </Geometry>\n");
}

/// The crack surfaces of the frames that have any, as a temporal collection (`icefem_cracks`:
/// triangles, with the crack index per triangle) for `RUN.cracks.xdmf`; empty without
/// fracture.
fn xdmf_cracks(h5_path: &Path, h5_name: &str, frames: &Group) -> Result<String, OutputError> {
    let mut xml = String::new();
    let ind = "          ";
    for entry in list_frames(h5_path, frames)?
        .into_iter()
        .filter(|f| f.complete)
    {
        let g = frames
            .group(&entry.name)
            .ctx(h5_path, || format!("opening /frames/{}", entry.name))?;
        let Ok(cracks) = g.group("cracks") else {
            continue;
        };
        let (Ok(triangles), Ok(vertices), Ok(crack)) = (
            cracks.dataset("triangles"),
            cracks.dataset("vertices"),
            cracks.dataset("crack"),
        ) else {
            continue;
        };
        let count = triangles.shape().first().copied().unwrap_or(0);
        let items = [&triangles, &vertices, &crack].map(|d| xdmf_data_item(d, h5_name, ind));
        let [Some(t), Some(v), Some(c)] = items else {
            continue;
        };
        if count == 0 {
            continue;
        }
        let time = read_attr::<f64>(h5_path, &g, "time")?;
        let name = format!("cracks_{}", entry.name);
        xdmf_grid_start(&mut xml, &name, time, ("Triangle", count, 3), &t, &v);
        xml.push_str(
            "        <Attribute Name=\"crack\" AttributeType=\"Scalar\" Center=\"Cell\">\n",
        );
        xml.push_str(&c);
        xml.push_str("        </Attribute>\n      </Grid>\n");
    }
    if xml.is_empty() {
        return Ok(xml);
    }
    Ok(format!(
        "    <Grid Name=\"icefem_cracks\" GridType=\"Collection\" CollectionType=\"Temporal\">\n{xml}    </Grid>\n"
    ))
}

/// Writes `text` to `path` through a temporary file renamed into place, so a reader sees the
/// old file or the new one, never half of one.
fn replace_file(path: &Path, text: &str, what: &str) -> Result<(), OutputError> {
    let tmp = path.with_extension("xdmf.tmp");
    let io = |context: String| {
        move |source| OutputError::Io {
            path: path.to_path_buf(),
            context,
            source,
        }
    };
    std::fs::write(&tmp, text).map_err(io(format!("writing {what}")))?;
    std::fs::rename(&tmp, path).map_err(io(format!("renaming {what} into place")))
}

/// Writes `<file>.xdmf` next to the HDF5 file: an XDMF 3 temporal collection
/// with one uniform grid per complete frame (incomplete frames are skipped).
///
/// Each grid has `Tetrahedron` topology from the frame's `tets`, `XYZ`
/// geometry from `positions` (m), and attributes `velocity` (Node Vector,
/// m/s), `rest_position` (Node Vector, m; displacement = coordinates −
/// rest_position, e.g. with ParaView's Calculator), `stress` (Cell Matrix of
/// 6 Voigt components xx yy zz yz xz xy, Pa) and every element / node field
/// under its own name. HDF5 references use the file name only, i.e. a path
/// relative to the sidecar. The sidecar is written to a temporary file and
/// renamed, so a viewer never sees half of it.
pub fn write_xdmf(h5_path: &Path) -> Result<PathBuf, OutputError> {
    check_hdf5_signature(h5_path)?;
    let file = File::open(h5_path).ctx(h5_path, || "opening to write the XDMF sidecar".into())?;
    close_on_exec(&file);
    check_icefem_layout(h5_path, &file)?;
    write_sidecars(h5_path, &file)
}

/// As [`write_xdmf`], from `file`, the open HDF5 file at `h5_path` (the writer's own handle:
/// a run rewrites its sidecars at every commit without opening its file a second time).
pub(super) fn write_sidecars(h5_path: &Path, file: &File) -> Result<PathBuf, OutputError> {
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
    let frames = file
        .group("frames")
        .ctx(h5_path, || "opening /frames".into())?;

    let mut xml = String::new();
    xml.push_str("<?xml version=\"1.0\" encoding=\"utf-8\"?>\n");
    xml.push_str("<Xdmf xmlns:xi=\"http://www.w3.org/2001/XInclude\" Version=\"3.0\">\n");
    xml.push_str("  <Domain>\n");
    xml.push_str(
        "    <Grid Name=\"icefem\" GridType=\"Collection\" CollectionType=\"Temporal\">\n",
    );
    for entry in list_frames(h5_path, &frames)?
        .into_iter()
        .filter(|f| f.complete)
    {
        let g = frames
            .group(&entry.name)
            .ctx(h5_path, || format!("opening /frames/{}", entry.name))?;
        let time = read_attr::<f64>(h5_path, &g, "time")?;
        let (tets, m) = open_2d(h5_path, &g, "tets", 4)?;
        let (positions, n) = open_2d(h5_path, &g, "positions", 3)?;
        let ind = "          ";
        let item = |ds: &Dataset| {
            xdmf_data_item(ds, &h5_name, ind).ok_or_else(|| {
                corrupt(
                    h5_path,
                    format!("{} has a type XDMF cannot describe", ds.name()),
                )
            })
        };
        let name = format!("frame_{}", entry.name);
        let (topology, geometry) = (item(&tets)?, item(&positions)?);
        xdmf_grid_start(
            &mut xml,
            &name,
            time,
            ("Tetrahedron", m, 4),
            &topology,
            &geometry,
        );

        // (xdmf name, dataset, center). Built-ins first, then fields by name.
        let mut attrs: Vec<(String, Dataset, &str)> = Vec::new();
        for (xname, dname, center) in [
            ("velocity", "velocities", "Node"),
            ("rest_position", "rest_positions", "Node"),
            ("stress", "stress", "Cell"),
        ] {
            if let Ok(ds) = g.dataset(dname) {
                attrs.push((xname.into(), ds, center));
            }
        }
        let names = g
            .member_names()
            .ctx(h5_path, || format!("listing /frames/{}", entry.name))?;
        for name in names {
            if RESERVED_FRAME_NAMES.contains(&name.as_str()) {
                continue;
            }
            let Ok(ds) = g.dataset(&name) else { continue };
            let center = ds.attr("center").ok().and_then(|a| read_string(&a).ok());
            let center = match center.as_deref() {
                Some("Cell") => "Cell",
                Some("Node") => "Node",
                _ => continue, // unknown centering: cannot place it on the mesh
            };
            attrs.push((name, ds, center));
        }
        for (xname, ds, center) in attrs {
            let shape = ds.shape();
            let rows = shape.first().copied().unwrap_or(0);
            let expected = if center == "Node" { n } else { m };
            // Skip anything whose shape does not fit the grid rather than
            // emit a sidecar that crashes the reader.
            if shape.is_empty() || shape.len() > 2 || rows != expected {
                continue;
            }
            let Some(di) = xdmf_data_item(&ds, &h5_name, ind) else {
                continue;
            };
            let _ = writeln!(
                xml,
                "        <Attribute Name=\"{}\" AttributeType=\"{}\" Center=\"{center}\">",
                xml_escape(&xname),
                xdmf_attribute_type(&shape)
            );
            xml.push_str(&di);
            xml.push_str("        </Attribute>\n");
        }
        xml.push_str("      </Grid>\n");
    }
    xml.push_str("    </Grid>\n  </Domain>\n</Xdmf>\n");
    let cracks = xdmf_cracks(h5_path, &h5_name, &frames)?;
    drop(frames);

    let xdmf_path = h5_path.with_extension("xdmf");
    replace_file(&xdmf_path, &xml, "the XDMF sidecar")?;
    // A file of its own: readers that take one grid collection per file (meshio, and
    // ParaView's default view of it) keep reading the tet mesh from RUN.xdmf. Without cracks,
    // a crack sidecar left by an earlier run of the same name is removed.
    let path = h5_path.with_extension("cracks.xdmf");
    if cracks.is_empty() {
        match std::fs::remove_file(&path) {
            Err(source) if source.kind() != std::io::ErrorKind::NotFound => {
                return Err(OutputError::Io {
                    path,
                    context: "removing a crack-surface sidecar of an earlier run".into(),
                    source,
                })
            }
            _ => {}
        }
    } else {
        let xml = format!(
            "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<Xdmf xmlns:xi=\"http://www.w3.org/2001/XInclude\" Version=\"3.0\">\n  <Domain>\n{cracks}  </Domain>\n</Xdmf>\n"
        );
        replace_file(&path, &xml, "the crack-surface XDMF sidecar")?;
    }
    Ok(xdmf_path)
}
