//! Fixtures shared by the output module's unit tests: a small tet mesh, run headers, stats
//! rows, frame data, a three-frame run, and the lock that keeps HDF5 tests apart from the
//! test that spawns a child process.

use std::path::Path;
use std::sync::{RwLock, RwLockReadGuard};

use hdf5::File;

use super::{Field, Frame, HeaderMesh, OutputWriter, RunHeader, StepStats};

/// HDF5 opens files without `O_CLOEXEC` and holds an `flock` on them, so a
/// child process spawned while another test has a file open inherits the
/// descriptor and its lock, making that test's next open fail with
/// "unable to lock file" until the child exits. Tests touching HDF5 hold
/// this lock shared; the test that spawns a child holds it exclusively.
pub(super) static SPAWN_GUARD: RwLock<()> = RwLock::new(());

/// Holds [`SPAWN_GUARD`] shared, for a test that opens HDF5 files.
pub(super) fn hdf5_guard() -> RwLockReadGuard<'static, ()> {
    SPAWN_GUARD.read().unwrap_or_else(|e| e.into_inner())
}

/// A 2×1×1 box of 8 nodes split into 5 tets, plus a 9th node used after
/// a "topology change".
pub(super) fn mesh() -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ];
    let t = vec![
        [0, 1, 3, 4],
        [1, 2, 3, 6],
        [1, 4, 5, 6],
        [3, 4, 6, 7],
        [1, 3, 4, 6],
    ];
    (p, t)
}

/// A run header for the mesh `p`, `t`, with a non-ASCII scene text.
pub(super) fn header<'a>(p: &'a [[f64; 3]], t: &'a [[usize; 4]]) -> RunHeader<'a> {
    RunHeader {
        scene_text: "[solver]\ndt = 1e-3 # ünïcode\n",
        scene_path: "scenes/box.toml",
        version: "0.1.0-test",
        mesh: HeaderMesh::Whole {
            rest_positions: p,
            tets: t,
        },
        obstacles: &[],
    }
}

/// A `/stats` row for `step` (1 ms steps; element and crack-face counts grow with `step`).
pub(super) fn stats(step: u64) -> StepStats {
    StepStats {
        step,
        time: step as f64 * 1e-3,
        dt: 1e-3,
        newton_iterations: 3,
        newton_solves: 2,
        linear_iterations: 7,
        factorizations: 2,
        projections: 1,
        substeps: 1,
        residual: 1e-9,
        energy: 1.5,
        kinetic_energy: 0.5,
        elastic_energy: 0.75,
        potential_energy: 0.25,
        contact_energy: 0.0,
        t_assembly: 0.01,
        t_factorization: 0.02,
        t_solve: 0.003,
        t_step: 0.04,
        elements: 6 + step,
        crack_faces: 2 * step,
        fracture_events: 1,
        separation_stress: 2.5e6,
        eligible_nodes: 40,
        nodes_above_toughness: 0,
        refused_nodes: 1,
        refused_splits: 2,
        crack_area: 1e-4 * step as f64,
        crack_polygons: step,
        t_fracture: 0.005,
        t_remesh: 0.0,
        t_resolve: 0.0,
        heat_newton_iterations: 2,
        heat_passes: 1,
        heat_cancelled_edges: 0,
        heat_imbalance: 1e-12,
        t_heat: 0.001,
        local_error: 1e-9,
        error_ratio: 0.5,
        rejected_steps: 1,
    }
}

/// Owned data behind one test frame, values depending on `k` so frames differ.
pub(super) struct FrameData {
    pub(super) pos: Vec<[f64; 3]>,
    pub(super) vel: Vec<[f64; 3]>,
    pub(super) rest: Vec<[f64; 3]>,
    pub(super) tets: Vec<[usize; 4]>,
    pub(super) stress: Vec<[f64; 6]>,
    pub(super) eig: Vec<f64>,
    pub(super) plastic: Vec<f64>,
    pub(super) temp: Vec<f64>,
}

pub(super) fn frame_data(k: usize, rest: &[[f64; 3]], tets: &[[usize; 4]]) -> FrameData {
    let kf = k as f64;
    let n = rest.len();
    let m = tets.len();
    FrameData {
        // Irrational-ish values to catch any precision loss.
        pos: rest
            .iter()
            .map(|p| [p[0] + 0.1 * kf / 3.0, p[1], p[2] - kf * 1e-17])
            .collect(),
        vel: (0..n)
            .map(|i| [i as f64 / 7.0, -kf, std::f64::consts::PI])
            .collect(),
        rest: rest.to_vec(),
        tets: tets.to_vec(),
        stress: (0..m)
            .map(|e| {
                let e = e as f64;
                [e, e + 1.0, e + 2.0, e + 3.0, e + 4.0, kf * 1e6 + 0.1]
            })
            .collect(),
        eig: (0..m).map(|e| e as f64 * 1e-3 + kf).collect(),
        plastic: (0..m * 6).map(|i| i as f64 / 11.0 + kf).collect(),
        temp: (0..n).map(|i| 263.15 + i as f64 + kf).collect(),
    }
}

/// Writes frame `k` (step 10 k) of `d`, with fields `eigenstrain`, `plastic_strain` and
/// `temperature`.
pub(super) fn write(w: &mut OutputWriter, k: usize, d: &FrameData, topology_changed: bool) {
    let ef = [
        Field {
            name: "eigenstrain",
            cols: 1,
            data: &d.eig,
        },
        Field {
            name: "plastic_strain",
            cols: 6,
            data: &d.plastic,
        },
    ];
    let nf = [Field {
        name: "temperature",
        cols: 1,
        data: &d.temp,
    }];
    w.write_frame(&Frame {
        step: 10 * k as u64,
        time: 10.0 * k as f64 * 1e-3,
        positions: &d.pos,
        velocities: &d.vel,
        rest_positions: &d.rest,
        tets: &d.tets,
        topology_changed,
        stress: &d.stress,
        element_fields: &ef,
        node_fields: &nf,
        row_fields: &[],
        attributes: &[],
        cracks: None,
    })
    .unwrap();
}

/// Mesh after a fake fracture: node 9 duplicates node 6 for the last tet.
pub(super) fn split_mesh() -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
    let (mut p, mut t) = mesh();
    p.push(p[6]);
    t[4] = [1, 3, 4, 8];
    (p, t)
}

/// Writes 3 frames (frame 2 with a topology change) and stats rows 0..=20.
pub(super) fn write_run(path: &Path) -> (Vec<FrameData>, Vec<StepStats>) {
    let (p, t) = mesh();
    let (p2, t2) = split_mesh();
    let mut w = OutputWriter::create(path, &header(&p, &t)).unwrap();
    let mut all = Vec::new();
    let mut rows = Vec::new();
    for k in 0..3 {
        let d = if k < 2 {
            frame_data(k, &p, &t)
        } else {
            frame_data(k, &p2, &t2)
        };
        for step in (10 * k as u64).saturating_sub(9)..=10 * k as u64 {
            if k == 0 && step > 0 {
                break;
            }
            let s = stats(step);
            w.append_stats(&s).unwrap();
            rows.push(s);
        }
        write(&mut w, k, &d, k == 2);
        all.push(d);
    }
    assert_eq!(w.frame_count(), 3);
    w.finish().unwrap();
    (all, rows)
}

/// The f64 dataset at `p` in `f`, flattened.
pub(super) fn read_f64(f: &File, p: &str) -> Vec<f64> {
    f.dataset(p).unwrap().read_raw::<f64>().unwrap()
}
