//! Tests of frames written in blocks: the same file as a frame written at once (datasets,
//! types, chunks, filters, values, attributes, sidecar), and the refusal of incomplete or
//! misplaced blocks.

use std::path::Path;

use hdf5::{File, Group};

use super::super::test_support::{frame_data, hdf5_guard, header, FrameData};
use super::super::{Field, Frame, FrameOptions, OutputWriter};
use super::{frame_columns, ColumnValues, FrameLayout};
use crate::fracture::cracks::CrackSurface;

/// A "mesh" large enough for every frame dataset to be chunked and compressed (at least
/// 2 048 values): 3 000 nodes and elements, the tets' indices valid but not a real mesh.
fn large_mesh() -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
    mesh_of(3000)
}

/// A "mesh" of `n` nodes and elements, as [`large_mesh`].
fn mesh_of(n: usize) -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
    let rest = (0..n)
        .map(|i| [i as f64 / 7.0, (i % 13) as f64, 1.0 / (1.0 + i as f64)])
        .collect();
    let tets = (0..n)
        .map(|e| [e, (e + 1) % n, (e + 2) % n, (e + 5) % n])
        .collect();
    (rest, tets)
}

/// The element and node fields of the test frame.
fn fields(d: &FrameData) -> ([Field<'_>; 2], [Field<'_>; 1]) {
    let field = |name, cols, data| Field { name, cols, data };
    (
        [
            field("eigenstrain", 1, &d.eig[..]),
            field("plastic_strain", 6, &d.plastic[..]),
        ],
        [field("temperature", 1, &d.temp[..])],
    )
}

/// Writes frame `d` at once into a new file `path` with `options`.
fn write_at_once(path: &Path, d: &FrameData, options: FrameOptions) {
    write_at_once_after(path, (d, d), options, None);
}

/// Writes frame `d` at once into a new file `path` whose header holds the mesh of `first`,
/// with `options`; a frame whose topology changed if the meshes differ, with crack surfaces
/// `cracks`.
fn write_at_once_after(
    path: &Path,
    (first, d): (&FrameData, &FrameData),
    options: FrameOptions,
    cracks: Option<&CrackSurface>,
) {
    let mut w = OutputWriter::create(path, &header(&first.rest, &first.tets)).unwrap();
    w.set_frame_options(options);
    let (ef, nf) = fields(d);
    w.write_frame(&Frame {
        step: 7,
        time: 0.25,
        positions: &d.pos,
        velocities: &d.vel,
        rest_positions: &d.rest,
        tets: &d.tets,
        topology_changed: first.rest.len() != d.rest.len(),
        stress: &d.stress,
        element_fields: &ef,
        node_fields: &nf,
        row_fields: &[],
        attributes: &[("restart_point", 1.0), ("next_dt", 1e-3)],
        cracks,
    })
    .unwrap();
    w.finish().unwrap();
}

/// The layout of the test frame `d`.
fn layout(d: &FrameData) -> FrameLayout {
    let (ef, nf) = fields(d);
    let names = |f: &[Field]| f.iter().map(|f| (f.name.to_string(), f.cols)).collect();
    FrameLayout {
        step: 7,
        time: 0.25,
        attributes: vec![("restart_point".into(), 1.0), ("next_dt".into(), 1e-3)],
        nodes: d.rest.len(),
        elements: d.tets.len(),
        topology_changed: false,
        element_fields: names(&ef),
        node_fields: names(&nf),
    }
}

/// The values of dataset `column` of the test frame `d`.
fn values(d: &FrameData, column: &ColumnValues) -> Vec<f64> {
    let (ef, nf) = fields(d);
    let field = |name: &str| ef.iter().chain(&nf).find(|f| f.name == name).unwrap().data;
    match column {
        ColumnValues::Positions => d.pos.as_flattened().to_vec(),
        ColumnValues::Velocities => d.vel.as_flattened().to_vec(),
        ColumnValues::Stress => d.stress.as_flattened().to_vec(),
        ColumnValues::RestPositions => d.rest.as_flattened().to_vec(),
        ColumnValues::Tets => d.tets.as_flattened().iter().map(|&v| v as f64).collect(),
        ColumnValues::Field(name) => field(name).to_vec(),
        ColumnValues::Matrices(name) => {
            let voigt = match name.as_str() {
                "stress" => d.stress.as_flattened(),
                name => field(name),
            };
            super::super::voigt_to_matrices(voigt)
        }
    }
}

/// Writes frame `d` in blocks into a new file `path` with `options`: each dataset in two
/// blocks, the second half first.
fn write_in_blocks(path: &Path, d: &FrameData, options: FrameOptions) {
    write_in_blocks_after(path, (d, d), options, None);
}

/// Writes frame `d` in blocks into a new file `path` whose header holds the mesh of
/// `first`, as [`write_at_once_after`].
fn write_in_blocks_after(
    path: &Path,
    (first, d): (&FrameData, &FrameData),
    options: FrameOptions,
    cracks: Option<&CrackSurface>,
) {
    let mut w = OutputWriter::create(path, &header(&first.rest, &first.tets)).unwrap();
    w.set_frame_options(options);
    let layout = FrameLayout {
        topology_changed: first.rest.len() != d.rest.len(),
        ..layout(d)
    };
    w.begin_frame(&layout).unwrap();
    for (k, c) in frame_columns(&layout, options).iter().enumerate() {
        let v = values(d, &c.values);
        let half = c.rows / 2;
        w.write_rows(k, half, &v[half * c.cols..]).unwrap();
        w.write_rows(k, 0, &v[..half * c.cols]).unwrap();
    }
    w.end_frame(cracks, &[]).unwrap();
    w.finish().unwrap();
}

/// Every dataset under group `g`, by path from it.
fn datasets(g: &Group, prefix: &str) -> Vec<String> {
    let mut all = Vec::new();
    for name in g.member_names().unwrap() {
        let path = format!("{prefix}{name}");
        match g.group(&name) {
            Ok(sub) => all.extend(datasets(&sub, &format!("{path}/"))),
            Err(_) => all.push(path),
        }
    }
    all
}

/// Asserts that frame 0 of the files `a` and `b` holds the same datasets — type, shape,
/// chunks, filters, values and `center` attribute — and attributes.
fn assert_same_frame(a: &File, b: &File) {
    let (ga, gb) = (
        a.group("frames/000000").unwrap(),
        b.group("frames/000000").unwrap(),
    );
    let names = datasets(&ga, "");
    assert_eq!(names, datasets(&gb, ""));
    assert!(names.contains(&"tensors/plastic_strain".to_string()));
    for name in names
        .iter()
        .filter(|n| n.contains("tets") || n.starts_with("cracks/t"))
    {
        let indices = |g: &Group| g.dataset(name).unwrap().read_raw::<i64>().unwrap();
        assert_eq!(indices(&ga), indices(&gb), "{name}");
    }
    for name in &names {
        let (x, y) = (ga.dataset(name).unwrap(), gb.dataset(name).unwrap());
        assert_eq!(
            x.dtype().unwrap().to_descriptor().unwrap(),
            y.dtype().unwrap().to_descriptor().unwrap(),
            "{name}"
        );
        assert_eq!(x.shape(), y.shape(), "{name}");
        assert_eq!(x.chunk(), y.chunk(), "{name}");
        assert_eq!(x.filters(), y.filters(), "{name}");
        if !["tets", "cracks/triangles", "cracks/crack"].contains(&name.as_str()) {
            assert_eq!(
                x.read_raw::<f64>().unwrap(),
                y.read_raw::<f64>().unwrap(),
                "{name}"
            );
        }
        let center = |ds: &hdf5::Dataset| {
            ds.attr("center")
                .ok()
                .map(|c| super::super::hdf5_io::read_string(&c).unwrap())
        };
        assert_eq!(center(&x), center(&y), "{name}");
    }
    let mut attrs = ga.attr_names().unwrap();
    attrs.sort();
    let mut attrs_b = gb.attr_names().unwrap();
    attrs_b.sort();
    assert_eq!(attrs, attrs_b);
    for name in ["step", "complete"] {
        assert_eq!(
            ga.attr(name).unwrap().read_raw::<u64>().unwrap(),
            gb.attr(name).unwrap().read_raw::<u64>().unwrap()
        );
    }
    for name in ["time", "restart_point", "next_dt"] {
        assert_eq!(
            ga.attr(name).unwrap().read_raw::<f64>().unwrap(),
            gb.attr(name).unwrap().read_raw::<f64>().unwrap()
        );
    }
}

#[test]
fn a_frame_written_in_blocks_is_the_frame_written_at_once() {
    let _guard = hdf5_guard();
    let (rest, tets) = large_mesh();
    let d = frame_data(3, &rest, &tets);
    let drawn_single = FrameOptions {
        drawn_single: true,
        ..FrameOptions::default()
    };
    for options in [FrameOptions::default(), drawn_single] {
        let (da, db) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let (pa, pb) = (da.path().join("run.h5"), db.path().join("run.h5"));
        write_at_once(&pa, &d, options);
        write_in_blocks(&pb, &d, options);
        assert_same_frame(&File::open(&pa).unwrap(), &File::open(&pb).unwrap());
        // The sidecars describe the same datasets.
        let sidecar = |p: &Path| std::fs::read_to_string(p.with_extension("xdmf")).unwrap();
        assert_eq!(sidecar(&pa), sidecar(&pb));
    }
}

#[test]
fn a_frame_of_a_changed_mesh_with_cracks_written_in_blocks_is_the_frame_written_at_once() {
    // The mesh gains a node and an element (as a split makes), the frame holds its own
    // rest positions and tets and two crack triangles.
    let _guard = hdf5_guard();
    let ((rest, tets), (more_rest, more_tets)) = (large_mesh(), mesh_of(3001));
    let (first, d) = (
        frame_data(3, &rest, &tets),
        frame_data(4, &more_rest, &more_tets),
    );
    let cracks = CrackSurface {
        vertices: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.5, 0.5, 0.1],
        ],
        triangles: vec![[0, 1, 2], [1, 3, 2]],
        crack: vec![0, 0],
    };
    let options = FrameOptions::default();
    let (da, db) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (pa, pb) = (da.path().join("run.h5"), db.path().join("run.h5"));
    write_at_once_after(&pa, (&first, &d), options, Some(&cracks));
    write_in_blocks_after(&pb, (&first, &d), options, Some(&cracks));
    let (a, b) = (File::open(&pa).unwrap(), File::open(&pb).unwrap());
    assert_same_frame(&a, &b);
    let frame = b.group("frames/000000").unwrap();
    assert_eq!(frame.dataset("rest_positions").unwrap().shape(), [3001, 3]);
    assert_eq!(frame.dataset("cracks/triangles").unwrap().shape(), [2, 3]);
    let sidecar = |p: &Path, ext| std::fs::read_to_string(p.with_extension(ext)).unwrap();
    assert_eq!(sidecar(&pa, "xdmf"), sidecar(&pb, "xdmf"));
    assert_eq!(sidecar(&pa, "cracks.xdmf"), sidecar(&pb, "cracks.xdmf"));
    // An element naming a node the frame does not have is refused.
    let pc = db.path().join("other.h5");
    let mut w = OutputWriter::create(&pc, &header(&first.rest, &first.tets)).unwrap();
    let layout = FrameLayout {
        topology_changed: true,
        ..layout(&d)
    };
    w.begin_frame(&layout).unwrap();
    let columns = frame_columns(&layout, options);
    let tets = columns
        .iter()
        .position(|c| c.values == ColumnValues::Tets)
        .unwrap();
    let e = w.write_rows(tets, 0, &[0.0, 1.0, 2.0, 3001.0]).unwrap_err();
    assert!(e.to_string().contains("not one of the 3001 nodes"), "{e}");
    w.write_rows(tets, 0, &[0.0, 1.0, 2.0, 3000.0]).unwrap();
}

#[test]
fn a_frame_missing_rows_or_given_misplaced_rows_is_refused() {
    let _guard = hdf5_guard();
    let (rest, tets) = large_mesh();
    let d = frame_data(1, &rest, &tets);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.h5");
    let mut w = OutputWriter::create(&path, &header(&d.rest, &d.tets)).unwrap();
    let layout = layout(&d);
    // Another mesh's counts.
    let other = FrameLayout {
        nodes: 10,
        ..layout.clone()
    };
    assert!(w.begin_frame(&other).is_err());
    assert!(w.write_rows(0, 0, &[0.0; 3]).is_err(), "no frame open");
    w.begin_frame(&layout).unwrap();
    assert!(w.begin_frame(&layout).is_err(), "a frame is open");
    let columns = frame_columns(&layout, FrameOptions::default());
    // Past the last row, a partial row, an unknown dataset.
    assert!(w.write_rows(0, 2999, &[0.0; 6]).is_err());
    assert!(w.write_rows(0, 0, &[0.0; 4]).is_err());
    assert!(w.write_rows(columns.len(), 0, &[0.0; 3]).is_err());
    for (k, c) in columns.iter().enumerate() {
        let v = values(&d, &c.values);
        // The positions' last row never written.
        let rows = if k == 0 { c.rows - 1 } else { c.rows };
        w.write_rows(k, 0, &v[..rows * c.cols]).unwrap();
    }
    let e = w.end_frame(None, &[]).unwrap_err().to_string();
    assert!(e.contains("2999 of the 3000 rows of positions"), "{e}");
    assert_eq!(w.frame_count(), 0);
    w.finish().unwrap();
    let f = File::open(&path).unwrap();
    assert!(f
        .group("frames")
        .unwrap()
        .member_names()
        .unwrap()
        .is_empty());
}

/// The test header with its mesh `d` to come in blocks.
fn header_in_blocks(d: &FrameData) -> super::super::RunHeader<'static> {
    super::super::RunHeader {
        mesh: super::super::HeaderMesh::InBlocks {
            nodes: d.rest.len(),
            elements: d.tets.len(),
        },
        ..header(&[], &[])
    }
}

#[test]
fn a_header_mesh_written_in_blocks_is_the_mesh_written_at_once() {
    let _guard = hdf5_guard();
    let (rest, tets) = large_mesh();
    let d = frame_data(2, &rest, &tets);
    let (da, db) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (pa, pb) = (da.path().join("run.h5"), db.path().join("run.h5"));
    write_at_once(&pa, &d, FrameOptions::default());
    let mut w = OutputWriter::create(&pb, &header_in_blocks(&d)).unwrap();
    let layout = layout(&d);
    assert!(w.begin_frame(&layout).is_err(), "the mesh is open");
    let columns = super::mesh_columns(d.rest.len(), d.tets.len());
    let flat: [Vec<f64>; 2] = [
        d.rest.as_flattened().to_vec(),
        d.tets.as_flattened().iter().map(|&v| v as f64).collect(),
    ];
    // Each dataset in two blocks, the second half first.
    for (k, c) in columns.iter().enumerate() {
        let half = c.rows / 2;
        w.write_rows(k, half, &flat[k][half * c.cols..]).unwrap();
        w.write_rows(k, 0, &flat[k][..half * c.cols]).unwrap();
    }
    assert!(w.end_frame(None, &[]).is_err(), "the mesh is not a frame");
    w.end_mesh().unwrap();
    w.begin_frame(&layout).unwrap();
    for (k, c) in frame_columns(&layout, FrameOptions::default())
        .iter()
        .enumerate()
    {
        w.write_rows(k, 0, &values(&d, &c.values)).unwrap();
    }
    w.end_frame(None, &[]).unwrap();
    w.finish().unwrap();
    let (a, b) = (File::open(&pa).unwrap(), File::open(&pb).unwrap());
    for name in ["mesh/rest_positions", "mesh/tets"] {
        let (x, y) = (a.dataset(name).unwrap(), b.dataset(name).unwrap());
        assert_eq!(
            x.dtype().unwrap().to_descriptor().unwrap(),
            y.dtype().unwrap().to_descriptor().unwrap(),
            "{name}"
        );
        assert_eq!((x.shape(), x.chunk()), (y.shape(), y.chunk()), "{name}");
        assert_eq!(x.filters(), y.filters(), "{name}");
        assert!(x.chunk().is_some(), "{name}: chunked and compressed");
    }
    let rows = |f: &File| f.dataset("mesh/rest_positions").unwrap().read_raw::<f64>();
    assert_eq!(rows(&a).unwrap(), rows(&b).unwrap());
    let tets = |f: &File| f.dataset("mesh/tets").unwrap().read_raw::<i64>();
    assert_eq!(tets(&a).unwrap(), tets(&b).unwrap());
    // The frames link the same topology.
    assert_same_frame(&a, &b);
}

#[test]
fn a_header_mesh_missing_rows_or_given_no_index_is_refused() {
    let _guard = hdf5_guard();
    let (rest, tets) = large_mesh();
    let d = frame_data(1, &rest, &tets);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.h5");
    let mut w = OutputWriter::create(&path, &header_in_blocks(&d)).unwrap();
    // A node number that is not one.
    let e = w.write_rows(1, 0, &[0.0, 1.0, 2.5, 3.0]).unwrap_err();
    assert!(e.to_string().contains("2.5 is not an index"), "{e}");
    w.write_rows(0, 0, d.rest.as_flattened()).unwrap();
    let e = w.end_mesh().unwrap_err().to_string();
    assert!(e.contains("0 of the 3000 rows of tets"), "{e}");
    // The file never took its place.
    drop(w);
    assert!(!path.exists());
}
