//! Tests of the writer: a run written and read back (frames, hard-linked mesh, `/stats`,
//! sidecar), a sidecar for a file without tensor matrices, the metadata cache over many
//! frames, and the refusal of invalid frames.

use std::path::Path;

use hdf5::types::VarLenUnicode;
use hdf5::File;

use super::super::test_support::{
    frame_data, hdf5_guard, header, mesh, read_f64, split_mesh, write, write_run, FrameData,
};
use super::super::{Field, Frame, OutputError, OutputWriter, StepStats};
use super::STATS_COLUMNS;

#[test]
fn write_three_frames_and_read_back() {
    let _guard = hdf5_guard();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.h5");
    let (data, rows) = write_run(&path);

    let f = File::open(&path).unwrap();
    let s: VarLenUnicode = f.attr("scene").unwrap().read_scalar().unwrap();
    assert_eq!(s.as_str(), "[solver]\ndt = 1e-3 # ünïcode\n");
    let v: VarLenUnicode = f.attr("icefem_version").unwrap().read_scalar().unwrap();
    assert_eq!(v.as_str(), "0.1.0-test");
    assert_eq!(f.dataset("mesh/tets").unwrap().shape(), vec![5, 4]);
    for (k, d) in data.iter().enumerate() {
        assert_frame_reads_back(&f, k, d);
    }
    assert_unchanged_mesh_is_linked(&f);
    assert_stats_rows(&f, &rows);
    assert_sidecar_lists_frames(&path, dir.path());
}

/// Frame `k` of `f` holds what `d` held when written: attributes, fields, the symmetric
/// tensors again as 3 × 3 matrices, and its topology.
fn assert_frame_reads_back(f: &File, k: usize, d: &FrameData) {
    let g = format!("frames/{k:06}");
    let grp = f.group(&g).unwrap();
    assert_eq!(
        grp.attr("complete").unwrap().read_scalar::<u8>().unwrap(),
        1
    );
    assert_eq!(
        grp.attr("step").unwrap().read_scalar::<u64>().unwrap(),
        10 * k as u64
    );
    assert_eq!(read_f64(f, &format!("{g}/positions")), d.pos.as_flattened());
    assert_eq!(
        read_f64(f, &format!("{g}/velocities")),
        d.vel.as_flattened()
    );
    assert_eq!(read_f64(f, &format!("{g}/stress")), d.stress.as_flattened());
    assert_eq!(read_f64(f, &format!("{g}/eigenstrain")), d.eig);
    assert_eq!(
        f.dataset(&format!("{g}/eigenstrain")).unwrap().shape(),
        vec![5]
    );
    assert_eq!(
        f.dataset(&format!("{g}/plastic_strain")).unwrap().shape(),
        vec![5, 6]
    );
    assert_eq!(read_f64(f, &format!("{g}/plastic_strain")), d.plastic);
    // The symmetric tensors again as 3 × 3 matrices, row-major.
    for (name, voigt) in [
        ("stress", d.stress.as_flattened()),
        ("plastic_strain", &d.plastic[..]),
    ] {
        let matrices = read_f64(f, &format!("{g}/tensors/{name}"));
        assert_eq!(matrices.len(), 9 * voigt.len() / 6);
        for (a, v) in matrices.chunks(9).zip(voigt.chunks(6)) {
            let [xx, yy, zz, yz, xz, xy] = [v[0], v[1], v[2], v[3], v[4], v[5]];
            assert_eq!(a, [xx, xy, xz, xy, yy, yz, xz, yz, zz]);
        }
    }
    assert_eq!(read_f64(f, &format!("{g}/temperature")), d.temp);
    let tets = f
        .dataset(&format!("{g}/tets"))
        .unwrap()
        .read_raw::<i64>()
        .unwrap();
    let expect: Vec<i64> = d.tets.as_flattened().iter().map(|&i| i as i64).collect();
    assert_eq!(tets, expect);
}

/// Frames 0 and 1 share /mesh's objects (hard links); frame 2, whose topology changed, has
/// its own.
fn assert_unchanged_mesh_is_linked(f: &File) {
    let token = |p: &str| f.dataset(p).unwrap().loc_info().unwrap().token;
    for name in ["tets", "rest_positions"] {
        let mesh_tok = token(&format!("mesh/{name}"));
        assert_eq!(token(&format!("frames/000000/{name}")), mesh_tok);
        assert_eq!(token(&format!("frames/000001/{name}")), mesh_tok);
        assert_ne!(token(&format!("frames/000002/{name}")), mesh_tok);
        let info = f
            .dataset(&format!("mesh/{name}"))
            .unwrap()
            .loc_info()
            .unwrap();
        assert_eq!(info.num_links, 3);
    }
}

/// /stats holds one row per step (`rows`, 21 of them) in every column.
fn assert_stats_rows(f: &File, rows: &[StepStats]) {
    assert_eq!(
        f.dataset("stats/step").unwrap().read_raw::<u64>().unwrap(),
        rows.iter().map(|r| r.step).collect::<Vec<_>>()
    );
    assert_eq!(rows.len(), 21);
    for (name, _) in STATS_COLUMNS {
        assert_eq!(
            f.dataset(&format!("stats/{name}")).unwrap().shape(),
            vec![21]
        );
    }
    assert_eq!(
        f.dataset("stats/newton_iterations")
            .unwrap()
            .read_raw::<u32>()
            .unwrap(),
        vec![3; 21]
    );
    assert_eq!(read_f64(f, "stats/t_solve"), vec![0.003; 21]);
}

/// The XDMF sidecar of `path` (in `dir`) lists the three frames by relative name, with the
/// tensors as 3 × 3 matrices and the scalars.
fn assert_sidecar_lists_frames(path: &Path, dir: &Path) {
    let xdmf = std::fs::read_to_string(path.with_extension("xdmf")).unwrap();
    assert_eq!(xdmf.matches("GridType=\"Uniform\"").count(), 3);
    assert!(xdmf.contains("run.h5:/frames/000002/tets"));
    assert!(!xdmf.contains(&dir.display().to_string()));
    assert!(xdmf.contains("Name=\"plastic_strain\" AttributeType=\"Tensor\" Center=\"Cell\""));
    assert!(xdmf.contains("Name=\"stress\" AttributeType=\"Tensor\" Center=\"Cell\""));
    assert!(xdmf.contains("Dimensions=\"5 9\" DataType=\"Float\" Precision=\"8\" Format=\"HDF\">run.h5:/frames/000002/tensors/stress<"));
    assert!(xdmf.contains("run.h5:/frames/000002/tensors/plastic_strain<"));
    // Not the Voigt datasets, which VTK's readers cannot read as tensors.
    assert!(!xdmf.contains("Matrix"));
    assert_eq!(
        xdmf.matches("/stress<").count(),
        xdmf.matches("/tensors/stress<").count()
    );
    assert!(xdmf.contains("Name=\"eigenstrain\" AttributeType=\"Scalar\" Center=\"Cell\""));
    assert!(xdmf.contains("Name=\"temperature\" AttributeType=\"Scalar\" Center=\"Node\""));
}

#[test]
fn a_file_without_tensor_matrices_gets_a_sidecar_without_tensors() {
    // As a file written before `tensors/` was stored: its Voigt datasets are not shown
    // (VTK's readers would read them wrong), everything else is.
    let _guard = hdf5_guard();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.h5");
    write_run(&path);
    let written = std::fs::read_to_string(path.with_extension("xdmf")).unwrap();
    let f = File::open_rw(&path).unwrap();
    for k in 0..3 {
        f.unlink(&format!("frames/{k:06}/tensors")).unwrap();
    }
    drop(f);
    super::super::write_xdmf(&path).unwrap();
    let xdmf = std::fs::read_to_string(path.with_extension("xdmf")).unwrap();
    assert_eq!(xdmf.matches("GridType=\"Uniform\"").count(), 3);
    for name in ["stress", "plastic_strain"] {
        let attribute = format!("<Attribute Name=\"{name}\"");
        assert_eq!(written.matches(&attribute).count(), 3);
        assert!(!xdmf.contains(&attribute), "{xdmf}");
    }
    assert!(!xdmf.contains("Matrix"));
    for name in ["eigenstrain", "temperature", "velocity", "rest_position"] {
        assert_eq!(
            xdmf.matches(&format!("<Attribute Name=\"{name}\"")).count(),
            3,
            "{name}"
        );
    }
}

#[test]
fn the_metadata_cache_stays_bounded_over_many_frames() {
    // Committed at every frame (as a slow run is), 3 000 frames: the cache of the open
    // file stays near CACHE_REOPEN_BYTES instead of holding every frame's headers.
    let _guard = hdf5_guard();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("long.h5");
    let (p, t) = mesh();
    let mut w = OutputWriter::create(&path, &header(&p, &t)).unwrap();
    let d = frame_data(0, &p, &t);
    let mut largest = 0;
    for k in 0..3000 {
        w.last_commit = None;
        write(&mut w, k, &d, false);
        largest = largest.max(super::metadata_cache_bytes(w.file.as_ref().unwrap()));
    }
    w.finish().unwrap();
    // 1 MiB plus what one frame adds (a few kB); without the reopening it reached
    // 9.4 MB here (and the 3 000 frames took 6× longer).
    assert!(largest < 5 << 18, "metadata cache reached {largest} bytes");
    let f = File::open(&path).unwrap();
    assert_eq!(
        f.group("frames").unwrap().member_names().unwrap().len(),
        3000
    );
}

#[test]
fn invalid_frames_are_rejected_before_writing() {
    let _guard = hdf5_guard();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.h5");
    let (p, t) = mesh();
    let mut w = OutputWriter::create(&path, &header(&p, &t)).unwrap();
    let d = frame_data(0, &p, &t);
    let short = &d.eig[..3];
    let cases: [(&[Field], &[[usize; 4]]); 4] = [
        (
            &[Field {
                name: "eigenstrain",
                cols: 1,
                data: short,
            }],
            &d.tets,
        ),
        (
            &[Field {
                name: "stress",
                cols: 1,
                data: &d.eig,
            }],
            &d.tets,
        ),
        (
            &[Field {
                name: "a/b",
                cols: 1,
                data: &d.eig,
            }],
            &d.tets,
        ),
        (&[], &[[0, 1, 2, 99]; 5]),
    ];
    for (ef, tets) in cases {
        let r = w.write_frame(&Frame {
            step: 0,
            time: 0.0,
            positions: &d.pos,
            velocities: &d.vel,
            rest_positions: &d.rest,
            tets,
            topology_changed: true,
            stress: &d.stress,
            element_fields: ef,
            node_fields: &[],
            row_fields: &[],
            attributes: &[],
            cracks: None,
        });
        assert!(matches!(r, Err(OutputError::InvalidInput { .. })), "{r:?}");
    }
    // Unchanged topology with a different node count.
    let (p2, t2) = split_mesh();
    let d2 = frame_data(0, &p2, &t2);
    let r = w.write_frame(&Frame {
        step: 0,
        time: 0.0,
        positions: &d2.pos,
        velocities: &d2.vel,
        rest_positions: &d2.rest,
        tets: &d2.tets,
        topology_changed: false,
        stress: &d2.stress,
        element_fields: &[],
        node_fields: &[],
        row_fields: &[],
        attributes: &[],
        cracks: None,
    });
    assert!(matches!(r, Err(OutputError::InvalidInput { .. })), "{r:?}");
    assert_eq!(w.frame_count(), 0);
    write(&mut w, 0, &d, false);
    assert_eq!(w.frame_count(), 1);
}
