//! HDF5 output: layout, XDMF sidecar, and resume — a run cut off halfway and resumed ends
//! bit-identical to an uninterrupted one.

mod common;
use icefem::run::{run, RunOptions};
use icefem::scene::Scene;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use common::SAGGING_BAR as SCENE;

use common::run_options as options;

fn scene(dir: &Path) -> Scene {
    scene_from(dir, SCENE)
}

fn scene_from(dir: &Path, text: &str) -> Scene {
    common::load_scene(dir, text).unwrap()
}

/// Freezing with plasticity: the state a resume must restore includes each element's plastic
/// strain (the freeze state and expansion follow from the time).
const FREEZING: &str = r#"
[mesh]
box = { size = [0.04, 0.04, 0.04], cells = [2, 2, 2] }
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
[physics]
gravity = [0.0, 0.0, -9.81]
[[obstacle]]
type = "container"
min = [0.0, 0.0, 0.0]
max = [0.04, 0.04, 0.06]
friction = 0.3
[freezing]
cooling = ["walls", "bottom"]
front_speed = 0.01
transition_time = 0.5
[plasticity]
elastic_limit = 1e-4
[time]
dt = 0.1
end_time = 2.0
output_every = 3
restart_every = 3
"#;

#[test]
fn freezing_run_with_plasticity_resumes_bit_identically() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_from(dir.path(), FREEZING);
    let never = AtomicBool::new(false);
    let full = dir.path().join("full.h5");
    run(&scene, &options(&full, None, false), &never, |_| {}).unwrap();
    let half = dir.path().join("half.h5");
    run(&scene, &options(&half, Some(1.0), false), &never, |_| {}).unwrap();
    run(&scene, &options(&half, None, true), &never, |_| {}).unwrap();
    let plastic = |path: &Path| {
        let file = hdf5::File::open(path).unwrap();
        let mut frames = file.group("frames").unwrap().member_names().unwrap();
        frames.sort();
        let last = frames.last().unwrap();
        file.dataset(&format!("frames/{last}/plastic_strain"))
            .unwrap()
            .read_raw::<f64>()
            .unwrap()
    };
    assert!(
        plastic(&full).iter().any(|p| *p != 0.0),
        "no plastic flow to restore"
    );
    assert_eq!(
        last_frame(&full),
        last_frame(&half),
        "resumed end state differs"
    );
    assert_eq!(
        plastic(&full),
        plastic(&half),
        "resumed plastic strain differs"
    );
    // Frames at restart points (every third step, and the first) are marked so; the
    // final frame (step 20) is not.
    let file = hdf5::File::open(&full).unwrap();
    for name in file.group("frames").unwrap().member_names().unwrap() {
        let (step, restart) = restart_point(&file, &name);
        assert_eq!(restart, step.is_multiple_of(3), "frame of step {step}");
    }
    // ‖ε_p‖ per element and ε_p as 3 × 3 matrices, in the file and in the sidecar.
    let mut names = file.group("frames").unwrap().member_names().unwrap();
    names.sort();
    let last = names.last().unwrap();
    let g = file.group(&format!("frames/{last}")).unwrap();
    let (norm, m) = read_rows(&g, "plastic_strain_norm");
    let (matrices, _) = read_rows(&g, "tensors/plastic_strain");
    let voigt = plastic(&full);
    assert_eq!((norm.len(), matrices.len(), voigt.len()), (m, 9 * m, 6 * m));
    for ((e, a), v) in norm.iter().zip(matrices.chunks(9)).zip(voigt.chunks(6)) {
        let (xx, yy, zz, yz, xz, xy) = (v[0], v[1], v[2], v[3], v[4], v[5]);
        // Drawn copies in single precision: the doubles rounded.
        let exact = [xx, xy, xz, xy, yy, yz, xz, yz, zz];
        assert_eq!(a, exact.map(|x| f64::from(x as f32)));
        let frobenius = exact.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert_eq!(*e, f64::from(frobenius as f32), "{e} vs {frobenius}");
    }
    assert!(norm.iter().any(|&e| e > 0.0));
    let sidecar = grids(&std::fs::read_to_string(full.with_extension("xdmf")).unwrap());
    let grid = &sidecar.last().unwrap().2;
    let p = attribute(grid, "plastic_strain").unwrap();
    assert!(
        p.contains("AttributeType=\"Tensor\" Center=\"Cell\"")
            && p.contains(&format!("Dimensions=\"{m} 9\""))
            && p.contains(&format!("/frames/{last}/tensors/plastic_strain<")),
        "{p}"
    );
    let n = attribute(grid, "plastic_strain_norm").unwrap();
    assert!(
        n.contains("AttributeType=\"Scalar\" Center=\"Cell\""),
        "{n}"
    );
}

fn last_frame(path: &Path) -> (f64, u64, Vec<Vec<f64>>) {
    let g = last_complete_frame(path);
    let time = g.attr("time").unwrap().read_scalar::<f64>().unwrap();
    let step = g.attr("step").unwrap().read_scalar::<u64>().unwrap();
    let data = ["positions", "velocities", "displacement", "stress"]
        .iter()
        .map(|d| g.dataset(d).unwrap().read_raw::<f64>().unwrap())
        .collect();
    (time, step, data)
}

/// The group of the last frame of `path` marked complete (a killed run may leave a partial
/// group after it).
fn last_complete_frame(path: &Path) -> hdf5::Group {
    let file = hdf5::File::open(path).unwrap();
    let mut frames = file.group("frames").unwrap().member_names().unwrap();
    frames.sort();
    frames
        .iter()
        .rev()
        .map(|f| file.group(&format!("frames/{f}")).unwrap())
        .find(|g| {
            g.attr("complete")
                .is_ok_and(|a| a.read_scalar::<u8>().unwrap_or(0) == 1)
        })
        .expect("a complete frame")
}

fn stats_column(path: &Path, name: &str) -> Vec<f64> {
    hdf5::File::open(path)
        .unwrap()
        .dataset(&format!("stats/{name}"))
        .unwrap()
        .read_raw::<f64>()
        .unwrap()
}

#[test]
fn layout_is_as_documented() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene(dir.path());
    let out = dir.path().join("full.h5");
    let options = RunOptions {
        output: Some(out.clone()),
        ..Default::default()
    };
    let summary = run(&scene, &options, &AtomicBool::new(false), |_| {}).unwrap();
    assert_eq!((summary.steps, summary.frames), (10, 6)); // frame 0 and every 2nd step
    let file = hdf5::File::open(&out).unwrap();
    let n = scene.model.num_nodes();
    let m = scene.model.mesh.num_tets();
    assert_eq!(
        file.dataset("mesh/rest_positions").unwrap().shape(),
        vec![n, 3]
    );
    assert_eq!(file.dataset("mesh/tets").unwrap().shape(), vec![m, 4]);
    let f = file.group("frames/000003").unwrap();
    assert_eq!(f.attr("step").unwrap().read_scalar::<u64>().unwrap(), 6);
    assert!((f.attr("time").unwrap().read_scalar::<f64>().unwrap() - 0.012).abs() < 1e-15);
    assert_eq!(f.dataset("stress").unwrap().shape(), vec![m, 6]);
    assert_eq!(f.dataset("positions").unwrap().shape(), vec![n, 3]);
    assert_eq!(f.dataset("velocities").unwrap().shape(), vec![n, 3]);
    assert_eq!(f.dataset("tets").unwrap().shape(), vec![m, 4]);
    assert_eq!(stats_column(&out, "newton_iterations").len(), 10);
    let scene_attr = file
        .attr("scene")
        .unwrap()
        .read_scalar::<hdf5::types::VarLenUnicode>()
        .unwrap();
    assert_eq!(scene_attr.as_str(), SCENE);
    // positions = rest + displacement
    let rest = file
        .dataset("mesh/rest_positions")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    // positions are only drawn: single precision, rest + displacement rounded
    let pos = f.dataset("positions").unwrap().read_raw::<f32>().unwrap();
    let disp = f
        .dataset("displacement")
        .unwrap()
        .read_raw::<f64>()
        .unwrap();
    for k in 0..rest.len() {
        assert_eq!(pos[k], (rest[k] + disp[k]) as f32);
    }
    let xdmf = std::fs::read_to_string(out.with_extension("xdmf")).unwrap();
    assert_eq!(
        xdmf.matches("<Grid Name=").count() - 1,
        6,
        "one grid per frame plus the collection"
    );
    // `icefem info` reads it.
    let info = icefem::output::describe(&out).unwrap();
    assert!(info.contains("6 complete"), "{info}");
}

#[test]
fn resumed_run_is_bit_identical_to_uninterrupted_one() {
    let dir = tempfile::tempdir().unwrap();
    // Restart points every second step, with the frames.
    let text = SCENE.replace(
        "output_every = 2\n",
        "output_every = 2\nrestart_every = 2\n",
    );
    let scene = scene_from(dir.path(), &text);
    let never = AtomicBool::new(false);
    let full = dir.path().join("full.h5");
    run(
        &scene,
        &RunOptions {
            output: Some(full.clone()),
            ..Default::default()
        },
        &never,
        |_| {},
    )
    .unwrap();

    // Cut off at t = 0.01 s (step 5 is not a frame step: the last frame is written anyway).
    let half = dir.path().join("half.h5");
    let first = RunOptions {
        output: Some(half.clone()),
        end_time: Some(0.01),
        ..Default::default()
    };
    assert_eq!(run(&scene, &first, &never, |_| {}).unwrap().final_step, 5);
    let resume = RunOptions {
        output: Some(half.clone()),
        resume: true,
        ..Default::default()
    };
    // It continues from the last frame at a restart point (step 4: every second step): the
    // frame of step 5 is computed again, as the uninterrupted run computed it.
    let summary = run(&scene, &resume, &never, |_| {}).unwrap();
    assert_eq!((summary.steps, summary.final_step), (6, 10));
    assert_eq!(
        last_frame(&full),
        last_frame(&half),
        "resumed end state differs"
    );
    for column in ["energy", "residual", "newton_iterations", "time"] {
        assert_eq!(
            stats_column(&full, column),
            stats_column(&half, column),
            "/stats/{column}"
        );
    }

    // Interrupted (Ctrl-C) after step 3, then resumed.
    let cut = dir.path().join("cut.h5");
    let flag = AtomicBool::new(false);
    let options = RunOptions {
        output: Some(cut.clone()),
        ..Default::default()
    };
    let summary = run(&scene, &options, &flag, |p| {
        if p.step == 3 {
            flag.store(true, Ordering::SeqCst);
        }
    })
    .unwrap();
    assert!(summary.interrupted && summary.final_step == 3);
    let resume = RunOptions {
        output: Some(cut.clone()),
        resume: true,
        ..Default::default()
    };
    run(&scene, &resume, &never, |_| {}).unwrap();
    assert_eq!(
        last_frame(&full),
        last_frame(&cut),
        "interrupted-and-resumed end state differs"
    );
}

#[test]
fn killed_process_leaves_a_readable_file_that_resumes() {
    let exe = env!("CARGO_BIN_EXE_icefem");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("long.toml");
    // Long enough that it is still running when killed.
    std::fs::write(
        &path,
        SCENE
            .replace("end_time = 0.02", "end_time = 1000.0")
            .replace("output_every = 2", "output_every = 1"),
    )
    .unwrap();
    let out = dir.path().join("long.h5");
    // Killed at several points of the run, once its metadata outgrows HDF5's default cache
    // (~0.5 s): with HDF5's default settings most such kills left a `/frames` that could not
    // be listed, the cache having written parts of it between commits.
    for delay_ms in [1500, 700, 1100] {
        let mut child = std::process::Command::new(exe)
            .arg("run")
            .arg(&path)
            .arg("--output")
            .arg(&out)
            .arg("--force")
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Wait for the first step's log line (frame 1 is written before it), then a little
        // more, so the kill lands in the middle of a run with complete frames, whatever the
        // load.
        let mut log = std::io::BufReader::new(child.stderr.take().unwrap());
        let mut line = String::new();
        while std::io::BufRead::read_line(&mut log, &mut line).unwrap() > 0
            && !line.contains("step 1/")
        {
            line.clear();
        }
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        child.kill().unwrap(); // SIGKILL: no destructor, no HDF5 close
        child.wait().unwrap();
        let info = icefem::output::describe(&out).unwrap();
        assert!(
            info.contains("complete"),
            "killed after {delay_ms} ms: {info}"
        );
        // Reads the last complete frame: `/frames` lists, the frame's data is whole.
        last_frame(&out);
    }
    let (_, killed_at, _) = last_frame(&out);
    let target = killed_at + 50;
    let status = std::process::Command::new(exe)
        .arg("run")
        .arg(&path)
        .arg("--resume")
        .arg(&out)
        .args(["--end-time", &format!("{}", target as f64 * 0.002)])
        .stderr(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let (time, step, _) = last_frame(&out);
    assert_eq!(step, target);
    assert!((time - target as f64 * 0.002).abs() < 1e-9);
}

#[test]
fn fractured_run_resumes_bit_identically_on_its_split_mesh() {
    // scenes/pulled_bar.toml cut short: the bar cracks in steps 6, 7 and 8; the run is cut
    // after step 7 (mesh split, crack faces in contact) and resumed to step 12.
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/pulled_bar.toml"
    ))
    .unwrap()
    .replace("end_time = 0.004           # 40 steps", "end_time = 0.0012");
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_from(dir.path(), &text);
    let never = AtomicBool::new(false);
    let full = dir.path().join("full.h5");
    run(&scene, &options(&full, None, false), &never, |_| {}).unwrap();
    let half = dir.path().join("half.h5");
    run(&scene, &options(&half, Some(0.0007), false), &never, |_| {}).unwrap();
    let elements = |path: &Path| stats_column(path, "elements");
    let at_cut = *elements(&half).last().unwrap();
    assert!(
        at_cut > 768.0,
        "no split before the cut ({at_cut} elements)"
    );
    run(&scene, &options(&half, None, true), &never, |_| {}).unwrap();
    assert!(
        elements(&full).last().unwrap() > &at_cut,
        "no split after the cut"
    );
    // The crack surfaces get an XDMF sidecar of their own (triangles with a crack index).
    let cracks = std::fs::read_to_string(full.with_extension("cracks.xdmf")).unwrap();
    assert!(cracks.contains("TopologyType=\"Triangle\"") && cracks.contains("Name=\"crack\""));
    // The sidecars a run writes from what it wrote (resumed or not) are those read from the
    // file afterwards.
    for path in [&full, &half] {
        let sidecars = |p: &Path| {
            ["xdmf", "cracks.xdmf"].map(|e| std::fs::read_to_string(p.with_extension(e)).unwrap())
        };
        let written = sidecars(path);
        icefem::output::write_xdmf(path).unwrap();
        assert_eq!(written, sidecars(path), "{}", path.display());
    }
    assert_eq!(
        last_frame(&full),
        last_frame(&half),
        "resumed end state differs"
    );
    // Frames carry the gaps of the crack's pairs of copies (rows p, q, g; what the resumed
    // run continued from), the same in both runs.
    let gaps = |path: &Path| -> Vec<f64> {
        let ds = last_complete_frame(path).dataset("crack_gaps").unwrap();
        assert_eq!(ds.shape()[1], 3);
        ds.read_raw::<f64>().unwrap()
    };
    assert!(!gaps(&full).is_empty());
    assert_eq!(gaps(&full), gaps(&half));
    for column in ["elements", "crack_faces", "fracture_events", "energy"] {
        assert_eq!(
            stats_column(&full, column),
            stats_column(&half, column),
            "/stats/{column}"
        );
    }
}

/// The uniform grids of an XDMF sidecar: each one's time, its topology's number of elements,
/// and its text.
fn grids(xdmf: &str) -> Vec<(f64, usize, String)> {
    let value = |text: &str, key: &str| -> String {
        let start = text
            .find(key)
            .unwrap_or_else(|| panic!("no {key} in {text}"))
            + key.len();
        text[start..].split('"').next().unwrap().to_string()
    };
    xdmf.split("<Grid Name=")
        .filter(|g| g.contains("GridType=\"Uniform\""))
        .map(|g| {
            let time = value(g, "<Time Value=\"").parse().unwrap();
            let cells = value(g, "NumberOfElements=\"").parse().unwrap();
            (time, cells, g.to_string())
        })
        .collect()
}

/// The `<Attribute>` named `name` in grid text `grid`, if it has one.
fn attribute<'a>(grid: &'a str, name: &str) -> Option<&'a str> {
    let start = grid.find(&format!("<Attribute Name=\"{name}\""))?;
    let end = start + grid[start..].find("</Attribute>")?;
    Some(&grid[start..end])
}

fn read_rows(group: &hdf5::Group, name: &str) -> (Vec<f64>, usize) {
    let ds = group.dataset(name).unwrap();
    (ds.read_raw::<f64>().unwrap(), ds.shape()[0])
}

#[test]
fn sidecars_of_a_fractured_run_show_every_time_with_its_cracks_and_tensors() {
    // scenes/pulled_bar.toml cut short (frames every 2 steps to step 12; the bar cracks in
    // steps 6 to 8), run from a scene path relative to the working directory.
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/pulled_bar.toml"
    ))
    .unwrap()
    .replace("end_time = 0.004           # 40 steps", "end_time = 0.0012");
    let dir = tempfile::Builder::new()
        .prefix(".scene_path_test")
        .tempdir_in(".")
        .unwrap();
    std::fs::write(dir.path().join("bar.toml"), &text).unwrap();
    let relative = Path::new(dir.path().file_name().unwrap()).join("bar.toml");
    assert!(relative.is_relative() && relative.exists());
    let scene = Scene::load(&relative).unwrap();
    let out = dir.path().join("bar.h5");
    run(
        &scene,
        &options(&out, None, false),
        &AtomicBool::new(false),
        |_| {},
    )
    .unwrap();

    let file = hdf5::File::open(&out).unwrap();
    let scene_path = file
        .attr("scene_path")
        .unwrap()
        .read_scalar::<hdf5::types::VarLenUnicode>()
        .unwrap();
    assert_eq!(
        Path::new(scene_path.as_str()),
        std::fs::canonicalize(&relative).unwrap(),
        "scene_path is the scene's absolute path"
    );

    let mut names = file.group("frames").unwrap().member_names().unwrap();
    names.sort();
    let main = grids(&std::fs::read_to_string(out.with_extension("xdmf")).unwrap());
    let cracks = grids(&std::fs::read_to_string(out.with_extension("cracks.xdmf")).unwrap());
    assert_eq!((names.len(), main.len(), cracks.len()), (7, 7, 7));
    assert_eq!(
        (cracks[0].0, cracks[0].1),
        (0.0, 0),
        "the crack series starts at t = 0 with no crack"
    );
    let mut cracked = 0;
    for (k, name) in names.iter().enumerate() {
        let g = file.group(&format!("frames/{name}")).unwrap();
        let time = g.attr("time").unwrap().read_scalar::<f64>().unwrap();
        let (stress, m) = read_rows(&g, "stress");
        let n = g.dataset("positions").unwrap().shape()[0];
        let t = g.dataset("cracks/triangles").unwrap().shape()[0];
        cracked += usize::from(t > 0);
        // Every time of the run: the tets and the crack triangles there were then.
        assert_eq!((main[k].0, main[k].1), (time, m), "{name}");
        assert_eq!((cracks[k].0, cracks[k].1), (time, t), "{name}");
        if t == 0 {
            assert!(!cracks[k].2.contains("cracks/triangles"), "{name}");
        }
        let grid = &main[k].2;
        assert!(!grid.contains("Matrix"), "{name}: {grid}");
        // The stress as 3 × 3 matrices, declared Tensor.
        let s = attribute(grid, "stress").unwrap();
        assert!(
            s.contains("AttributeType=\"Tensor\" Center=\"Cell\""),
            "{s}"
        );
        assert!(
            s.contains(&format!(
                "Dimensions=\"{m} 9\" DataType=\"Float\" Precision=\"4\" Format=\"HDF\">bar.h5:/frames/{name}/tensors/stress<"
            )),
            "{s}"
        );
        let (matrices, rows) = read_rows(&g, "tensors/stress");
        assert_eq!(rows, m);
        for (a, v) in matrices.chunks(9).zip(stress.chunks(6)) {
            let (xx, yy, zz, yz, xz, xy) = (v[0], v[1], v[2], v[3], v[4], v[5]);
            assert_eq!(a, [xx, xy, xz, xy, yy, yz, xz, yz, zz]);
        }
        // Von Mises and the largest principal stress per element, as scalars.
        for scalar in ["von_mises", "max_principal_stress"] {
            let a = attribute(grid, scalar).unwrap();
            assert!(
                a.contains("AttributeType=\"Scalar\" Center=\"Cell\""),
                "{a}"
            );
            assert!(a.contains(&format!("Dimensions=\"{m}\" ")), "{scalar}: {a}");
        }
        let (von_mises, _) = read_rows(&g, "von_mises");
        let (principal, _) = read_rows(&g, "max_principal_stress");
        for ((v, vm), p) in stress.chunks(6).zip(&von_mises).zip(&principal) {
            let s = nalgebra::Matrix3::new(v[0], v[5], v[4], v[5], v[1], v[3], v[4], v[3], v[2]);
            let expect = (0.5
                * ((v[0] - v[1]).powi(2) + (v[1] - v[2]).powi(2) + (v[2] - v[0]).powi(2))
                + 3.0 * (v[3] * v[3] + v[4] * v[4] + v[5] * v[5]))
                .sqrt();
            // Stored in single precision from the double stress, and recomputed here from the
            // stress as stored (also single): each within a few f32 ulps (6e-8) of the exact.
            let scale = s.norm().max(1.0);
            assert!((vm - expect).abs() <= 1e-6 * scale, "{vm} vs {expect}");
            let eig = s.symmetric_eigenvalues();
            let largest = eig.iter().copied().fold(f64::MIN, f64::max);
            assert!((p - largest).abs() <= 1e-6 * scale, "{p} vs {largest}");
        }
        // The 4-column refusal record, as 4 components.
        let r = attribute(grid, "refused_split").unwrap();
        assert!(
            r.contains("AttributeType=\"Vector\" Center=\"Node\"")
                && r.contains(&format!("Dimensions=\"{n} 4\"")),
            "{r}"
        );
    }
    assert!(
        (1..names.len() - 1).contains(&cracked),
        "frames with cracks and frames before: {cracked} of {} cracked",
        names.len()
    );
}

#[test]
fn tensor_matrices_can_be_left_out_to_save_space() {
    let dir = tempfile::tempdir().unwrap();
    let never = AtomicBool::new(false);
    let with = dir.path().join("with.h5");
    run(
        &scene_from(dir.path(), FREEZING),
        &options(&with, None, false),
        &never,
        |_| {},
    )
    .unwrap();
    let without = dir.path().join("without.h5");
    let text = format!("{FREEZING}\n[output]\ntensor_matrices = false\n");
    run(
        &scene_from(dir.path(), &text),
        &options(&without, None, false),
        &never,
        |_| {},
    )
    .unwrap();
    // Same run, same results: only the matrices are missing.
    assert_eq!(last_frame(&with), last_frame(&without));
    let file = hdf5::File::open(&without).unwrap();
    let frames = file.group("frames").unwrap().member_names().unwrap();
    for name in &frames {
        let g = file.group(&format!("frames/{name}")).unwrap();
        assert!(g.group("tensors").is_err(), "frame {name} has tensors/");
        assert!(g.dataset("von_mises").is_ok() && g.dataset("plastic_strain_norm").is_ok());
    }
    // The sidecar shows the scalars and no tensor (a 6-column Voigt dataset would be misread).
    let xdmf = std::fs::read_to_string(without.with_extension("xdmf")).unwrap();
    assert!(
        !xdmf.contains("Tensor") && !xdmf.contains("/tensors/"),
        "{xdmf}"
    );
    let sidecar = grids(&xdmf);
    let grid = &sidecar.last().unwrap().2;
    for scalar in ["von_mises", "max_principal_stress", "plastic_strain_norm"] {
        assert!(attribute(grid, scalar).is_some(), "{scalar} missing");
    }
    // The file shrinks (on this 48-tet mesh little: group metadata dominates; the paper's
    // fractured scene loses a third, see docs/output.md).
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    assert!(
        size(&without) < size(&with),
        "{} vs {} bytes",
        size(&without),
        size(&with)
    );
}

/// The paper's fractured container cut at 24 s (720 steps; it cracks from step 652), with a
/// frame every `output_every` steps.
fn paper_container(output_every: u64) -> Scene {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/freezing_container_fracture.toml"
    ))
    .unwrap();
    let text = text
        .replace("end_time = 80.0 ", "end_time = 24.0 ")
        .replace(
            "output_every = 10 ",
            &format!("output_every = {output_every} "),
        );
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/paper.toml");
    Scene::parse(&text, &path).unwrap()
}

#[test]
fn the_frames_written_never_change_the_results() {
    // Restart points (a fresh factorisation) fall every 10 steps whatever the frames, so a
    // frame every step and one frame at the end take the same steps, bit for bit.
    let dir = tempfile::tempdir().unwrap();
    let never = AtomicBool::new(false);
    let every = dir.path().join("every.h5");
    let once = dir.path().join("once.h5");
    for (path, output_every) in [(&every, 1), (&once, 720)] {
        let scene = paper_container(output_every);
        assert_eq!(scene.restart_every, 10);
        run(&scene, &options(path, None, false), &never, |_| {}).unwrap();
    }
    let frames = |p: &Path| -> usize {
        let file = hdf5::File::open(p).unwrap();
        file.group("frames").unwrap().len() as usize
    };
    assert_eq!((frames(&every), frames(&once)), (721, 2));
    assert!(*stats_column(&every, "crack_area").last().unwrap() > 0.0);
    for column in [
        "newton_iterations",
        "factorizations",
        "elements",
        "crack_area",
        "energy",
    ] {
        assert_eq!(
            stats_column(&every, column),
            stats_column(&once, column),
            "/stats/{column}"
        );
    }
    assert_eq!(last_frame(&every), last_frame(&once));
    // The frames at restart points say so: those at steps that are multiples of 10.
    let file = hdf5::File::open(&every).unwrap();
    for name in ["000009", "000010", "000011", "000650", "000720"] {
        let (step, restart) = restart_point(&file, name);
        assert_eq!(restart, step.is_multiple_of(10), "frame {name}");
    }
    // A field whose values did not change since the last frame is that frame's dataset
    // (a hard link), read back the same: `origin` changes only at splits (from step 652).
    let token = |frame: &str, field: &str| {
        let ds = file.dataset(&format!("frames/{frame}/{field}")).unwrap();
        (ds.loc_info().unwrap().token, ds.read_raw::<f64>().unwrap())
    };
    let (a, b) = (token("000100", "origin"), token("000101", "origin"));
    assert!(a == b, "origin of frames 100 and 101: one dataset");
    let (a, b) = (token("000100", "velocities"), token("000101", "velocities"));
    assert!(a.0 != b.0 && a.1 != b.1, "velocities change: two datasets");
}

/// Frame `name`'s step and whether it is marked a restart point.
fn restart_point(file: &hdf5::File, name: &str) -> (u64, bool) {
    let g = file.group(&format!("frames/{name}")).unwrap();
    let step = g.attr("step").unwrap().read_scalar::<u64>().unwrap();
    let restart = g.attr("restart_point").unwrap().read_scalar::<f64>();
    (step, restart.unwrap() == 1.0)
}

#[test]
fn an_animations_frames_are_small_and_store_what_is_drawn_in_single_precision() {
    // The 3 840-tet cantilever writes a frame every step: by default without the derived
    // copies, and what is only drawn in single precision.
    let dir = tempfile::tempdir().unwrap();
    let never = AtomicBool::new(false);
    let path = |name: &str| dir.path().join(name);
    let scene = Scene::load(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scenes/cantilever.toml"
    )))
    .unwrap();
    assert_eq!(scene.output_every, 1);
    let size = |p: &Path| std::fs::metadata(p).unwrap().len() as f64;
    // 7 and 19 frames: the difference is what 12 frames add to the file.
    for (name, end) in [("short.h5", 0.2), ("long.h5", 0.6)] {
        run(
            &scene,
            &options(&path(name), Some(end), false),
            &never,
            |_| {},
        )
        .unwrap();
    }
    let per_frame = (size(&path("long.h5")) - size(&path("short.h5"))) / 12.0;
    assert!(per_frame <= 200e3, "{per_frame} bytes per frame");
    let file = hdf5::File::open(path("long.h5")).unwrap();
    let g = file.group("frames/000012").unwrap();
    let bits = |name: &str| g.dataset(name).unwrap().dtype().unwrap().size();
    assert_eq!((bits("positions"), bits("stress")), (4, 4));
    assert_eq!((bits("displacement"), bits("velocities")), (8, 8));
    assert!(g.dataset("von_mises").is_err() && g.group("tensors").is_err());
    // The sidecar says which are single.
    let xdmf = std::fs::read_to_string(path("long.h5").with_extension("xdmf")).unwrap();
    assert!(xdmf.contains("Precision=\"4\" Format=\"HDF\">long.h5:/frames/000012/positions"));

    // Asked for: doubles throughout, and the derived copies.
    let text = std::fs::read_to_string(&scene.path).unwrap()
        + "\n[output]\ndrawn_precision = \"double\"\nderived_scalars = true\ntensor_matrices = true\n";
    let full = Scene::parse(&text, &scene.path).unwrap();
    run(
        &full,
        &options(&path("full.h5"), Some(0.2), false),
        &never,
        |_| {},
    )
    .unwrap();
    let file = hdf5::File::open(path("full.h5")).unwrap();
    let g = file.group("frames/000006").unwrap();
    assert_eq!(g.dataset("positions").unwrap().dtype().unwrap().size(), 8);
    assert!(g.dataset("von_mises").is_ok() && g.dataset("tensors/stress").is_ok());
    // The same run: the positions single precision keeps are the doubles rounded.
    let single = hdf5::File::open(path("short.h5")).unwrap();
    let narrow: Vec<f32> = single
        .dataset("frames/000006/positions")
        .unwrap()
        .read_raw()
        .unwrap();
    let wide: Vec<f64> = g.dataset("positions").unwrap().read_raw().unwrap();
    assert!(narrow.iter().zip(&wide).all(|(a, b)| *a == *b as f32));
}
