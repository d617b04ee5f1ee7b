//! `icefem export`: the paper's scene with fracture, cut short after its first cracks, exported
//! in every format and read back — frame counts and numbering, the surfaces' face counts
//! against the run's tets and crack triangles, and point attributes against volume-weighted
//! averages computed here; a run without freezing or plasticity writes neither field; an
//! earlier export is replaced only when forced.

mod common;

use base64::Engine as _;
use common::listing;
use icefem::export::{export, ExportError, ExportFormat, ExportOptions, DEFAULT_FPS};
use icefem::mesh::TetMesh;
use icefem::output::{FrameReader, StoredFrame};
use icefem::run::{run, RunOptions};
use icefem::scene::Scene;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// Runs `scenes/NAME.toml` to `end_time` (s; `None`: the scene's) into `dir/run.h5`.
fn run_scene(dir: &Path, name: &str, end_time: Option<f64>) -> PathBuf {
    let scene =
        Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.toml")))
            .unwrap();
    let path = dir.join("run.h5");
    let options = RunOptions {
        output: Some(path.clone()),
        end_time,
        ..Default::default()
    };
    run(&scene, &options, &AtomicBool::new(false), |_| {}).unwrap();
    path
}

fn export_to(run: &Path, format: ExportFormat, frames: &str, output: &Path) -> Vec<PathBuf> {
    export_at(run, format, frames, output, 1.0)
}

/// `export_to` with USD time codes at `speed` simulated seconds per second of animation.
fn export_at(
    run: &Path,
    format: ExportFormat,
    frames: &str,
    output: &Path,
    speed: f64,
) -> Vec<PathBuf> {
    let reader = FrameReader::open(run).unwrap();
    let options = ExportOptions {
        format,
        frames: Some(frames.into()),
        output: Some(output.to_path_buf()),
        force: true,
        fps: DEFAULT_FPS,
        speed,
    };
    export(&reader, &options).unwrap().files
}

/// What the export of one frame must hold, computed from the stored frame.
struct Expected {
    time: f64,
    /// Outer faces: the tets' boundary faces less the crack faces.
    outer: usize,
    /// Crack triangles.
    cracks: usize,
    positions: Vec<[f64; 3]>,
    /// Node attributes: volume-weighted averages of the element fields, and velocity.
    nodal: HashMap<&'static str, Vec<f64>>,
    velocities: Vec<[f64; 3]>,
}

fn expected(frame: &StoredFrame) -> Expected {
    let state = &frame.state;
    let mesh = TetMesh::from_arrays(&state.rest_positions, state.tets.clone()).unwrap();
    let von_mises = frame
        .stress
        .iter()
        .map(|s| {
            let p = (s[0] + s[1] + s[2]) / 3.0;
            let d2 = (s[0] - p).powi(2) + (s[1] - p).powi(2) + (s[2] - p).powi(2);
            (1.5 * (d2 + 2.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]))).sqrt()
        })
        .collect();
    let mut fields = vec![("von_mises", von_mises)];
    if let Some((1, s)) = frame.element_field("freeze_state") {
        fields.push(("freeze_state", s.to_vec()));
    }
    if let Some((6, e)) = frame.element_field("plastic_strain") {
        let norm = |e: &[f64]| {
            (e[..3].iter().map(|x| x * x).sum::<f64>()
                + 2.0 * e[3..].iter().map(|x| x * x).sum::<f64>())
            .sqrt()
        };
        fields.push(("plastic_strain", e.chunks(6).map(norm).collect()));
    }
    let volume: Vec<f64> = (0..mesh.num_tets())
        .map(|t| mesh.signed_volume(t).abs())
        .collect();
    let nodal = fields
        .into_iter()
        .map(|(name, values)| {
            let (mut sum, mut weight) = (vec![0.0; mesh.num_nodes()], vec![0.0; mesh.num_nodes()]);
            for (t, tet) in mesh.tets.iter().enumerate() {
                for &i in tet {
                    sum[i] += volume[t] * values[t];
                    weight[i] += volume[t];
                }
            }
            (name, sum.iter().zip(&weight).map(|(s, w)| s / w).collect())
        })
        .collect();
    Expected {
        time: state.time,
        outer: mesh.boundary_faces().len() - frame.crack_triangles.len(),
        cracks: frame.crack_triangles.len(),
        positions: state.positions.clone(),
        nodal,
        velocities: state.velocities.clone(),
    }
}

/// One `.vtu` read back: counts and every array by name (`Points` for the points).
struct Vtu {
    points: usize,
    cells: usize,
    arrays: HashMap<String, Vec<f64>>,
}

fn read_vtu(path: &Path) -> Vtu {
    let text = std::fs::read_to_string(path).unwrap();
    let attribute = |line: &str, key: &str| -> Option<String> {
        let start = line.find(&format!(" {key}=\""))? + key.len() + 3;
        Some(line[start..start + line[start..].find('"')?].to_string())
    };
    let piece = text.lines().find(|l| l.starts_with("<Piece")).unwrap();
    let count = |key| attribute(piece, key).unwrap().parse().unwrap();
    let mut arrays = HashMap::new();
    for line in text.lines().filter(|l| l.starts_with("<DataArray")) {
        let name = attribute(line, "Name").unwrap_or("Points".into());
        let encoded = &line[line.find('>').unwrap() + 1..line.rfind("</").unwrap()];
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(encoded)
            .unwrap();
        let (head, data) = bytes.split_at(8);
        assert_eq!(
            u64::from_le_bytes(head.try_into().unwrap()) as usize,
            data.len()
        );
        let values = match attribute(line, "type").unwrap().as_str() {
            "Float64" => data
                .chunks(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
                .collect(),
            "Int64" => data
                .chunks(8)
                .map(|c| i64::from_le_bytes(c.try_into().unwrap()) as f64)
                .collect(),
            "UInt8" => data.iter().map(|&b| b as f64).collect(),
            other => panic!("{}: array type {other}", path.display()),
        };
        arrays.insert(name, values);
    }
    Vtu {
        points: count("NumberOfPoints"),
        cells: count("NumberOfCells"),
        arrays,
    }
}

/// One binary little-endian `.ply` read back: vertex property names and values, faces.
struct Ply {
    properties: Vec<String>,
    vertices: Vec<Vec<f32>>,
    faces: Vec<[i32; 3]>,
}

fn read_ply(path: &Path) -> Ply {
    let bytes = std::fs::read(path).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
    let number = |prefix: &str| -> usize {
        let line = header.lines().find(|l| l.starts_with(prefix)).unwrap();
        line[prefix.len()..].trim().parse().unwrap()
    };
    let (n, m) = (number("element vertex "), number("element face "));
    let properties: Vec<String> = header
        .lines()
        .filter_map(|l| l.strip_prefix("property float "))
        .map(String::from)
        .collect();
    assert!(header.contains("property list uchar int vertex_indices"));
    let mut at = end;
    let f32_at = |at: &mut usize| {
        let v = f32::from_le_bytes(bytes[*at..*at + 4].try_into().unwrap());
        *at += 4;
        v
    };
    let vertices = (0..n)
        .map(|_| properties.iter().map(|_| f32_at(&mut at)).collect())
        .collect();
    let faces = (0..m)
        .map(|_| {
            assert_eq!(bytes[at], 3);
            let face = std::array::from_fn(|k| {
                let start = at + 1 + 4 * k;
                i32::from_le_bytes(bytes[start..start + 4].try_into().unwrap())
            });
            at += 13;
            face
        })
        .collect();
    assert_eq!(at, bytes.len());
    Ply {
        properties,
        vertices,
        faces,
    }
}

/// The sample lines of `attribute` (e.g. `point3f[] points`) of the prim `prim` in a USDA
/// text: (time code, the text between the sample's brackets).
fn usd_samples<'a>(text: &'a str, prim: &str, attribute: &str) -> Vec<(f64, &'a str)> {
    let start = text.find(&format!("def Mesh \"{prim}\"")).unwrap();
    let block = &text[start..];
    let block = &block[..block[1..].find("def Mesh").map_or(block.len(), |e| e + 1)];
    let Some(at) = block.find(&format!("{attribute}.timeSamples = {{\n")) else {
        return Vec::new();
    };
    block[at..]
        .lines()
        .skip(1)
        .take_while(|l| l.trim() != "}")
        .map(|l| {
            let (k, rest) = l.trim().split_once(": [").unwrap();
            (k.parse().unwrap(), rest.strip_suffix("],").unwrap())
        })
        .collect()
}

/// The numbers of a sample's text (`(x, y, z), …` or `a, b, …`).
fn numbers(sample: &str) -> Vec<f64> {
    sample
        .split([',', '(', ')', ' '])
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect()
}

/// Whether `a` (an f32 from a file) is `b` to f32 precision.
fn close32(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-6 * b.abs() + 1e-30
}

#[test]
fn every_format_holds_each_frames_surfaces_and_their_attributes() {
    let dir = tempfile::tempdir().unwrap();
    // Written every 10 steps; the shell first cracks at step 652: frames 0 … 72.
    let run = run_scene(dir.path(), "freezing_container_fracture", Some(24.0));
    let reader = FrameReader::open(&run).unwrap();
    let frames: Vec<usize> = (0..=72).step_by(8).collect();
    assert_eq!(*reader.frame_indices().last().unwrap(), 72);
    let expect: Vec<Expected> = frames
        .iter()
        .map(|&i| expected(&reader.read(i).unwrap()))
        .collect();
    assert_eq!(expect[0].cracks, 0);
    assert!(
        expect.last().unwrap().cracks > 0,
        "the shell should have cracked"
    );
    let n = frames.len();
    let out = dir.path().join("out");
    let spec = "0::8";

    // VTU: every object of every frame at its time, values equal to the nodes' averages.
    let files = export_to(&run, ExportFormat::Vtu, spec, &out);
    assert_eq!(files.len(), 3 * n + 1);
    // The container (min 0, max (0.1, 0.1, 0.12)): its floor and four walls, still.
    for k in 0..n {
        let container = read_vtu(&out.join(format!("run_obstacles_{k:06}.vtu")));
        assert_eq!((container.points, container.cells), (8, 10), "frame {k}");
        let mut corners: Vec<[f64; 3]> = container.arrays["Points"]
            .chunks(3)
            .map(|x| [x[0], x[1], x[2]])
            .collect();
        corners.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let mut want: Vec<[f64; 3]> = (0..8)
            .map(|i| {
                [
                    0.1 * (i & 1) as f64,
                    0.1 * (i >> 1 & 1) as f64,
                    0.12 * (i >> 2) as f64,
                ]
            })
            .collect();
        want.sort_by(|a, b| a.partial_cmp(b).unwrap());
        assert_eq!(corners, want);
        assert!(container.arrays["velocity"].iter().all(|&v| v == 0.0));
    }
    let mut vtu_frames = Vec::new();
    for (k, e) in expect.iter().enumerate() {
        let ice = read_vtu(&out.join(format!("run_ice_{k:06}.vtu")));
        let cracks = read_vtu(&out.join(format!("run_cracks_{k:06}.vtu")));
        assert_eq!((ice.cells, cracks.cells), (e.outer, e.cracks), "frame {k}");
        assert_eq!(cracks.points, 3 * e.cracks);
        assert!(ice.arrays["types"].iter().all(|&t| t == 5.0));
        for (name, nodal) in &e.nodal {
            let values = &ice.arrays[*name];
            let by_position: HashMap<[u64; 3], usize> = e
                .positions
                .iter()
                .enumerate()
                .map(|(i, x)| (x.map(f64::to_bits), i))
                .collect();
            for (p, x) in ice.arrays["Points"].chunks(3).enumerate() {
                let node = by_position[&[x[0], x[1], x[2]].map(f64::to_bits)];
                let want = nodal[node];
                // The run stores what is only drawn (stress, ‖ε_p‖) in single precision:
                // a value read back is within 2⁻²⁴ ≈ 6e-8 of the double it was, and so is a
                // volume-weighted mean of such values; 1e-6 leaves room for the sums.
                assert!(
                    (values[p] - want).abs() <= 1e-6 * want.abs(),
                    "frame {k} {name} at point {p}: {} != {want}",
                    values[p]
                );
                if *name == "von_mises" {
                    let v = &ice.arrays["velocity"][3 * p..3 * p + 3];
                    assert_eq!(v, e.velocities[node]);
                }
            }
        }
        assert_eq!(
            ice.arrays.len(),
            8,
            "points, velocity, 3 fields, 3 cell arrays"
        );
        vtu_frames.push(ice);
    }
    let pvd = std::fs::read_to_string(out.join("run.pvd")).unwrap();
    let sets: Vec<&str> = pvd.lines().filter(|l| l.starts_with("<DataSet")).collect();
    assert_eq!(sets.len(), 3 * n);
    assert!(sets[3 * n - 1].contains(&format!("timestep=\"{}\"", expect[n - 1].time)));

    // PLY: the same counts and, to f32, the same values as the VTU files.
    export_to(&run, ExportFormat::Ply, spec, &out);
    for (k, e) in expect.iter().enumerate() {
        let ice = read_ply(&out.join(format!("run_ice_{k:06}.ply")));
        let cracks = read_ply(&out.join(format!("run_cracks_{k:06}.ply")));
        assert_eq!((ice.faces.len(), cracks.faces.len()), (e.outer, e.cracks));
        assert_eq!(cracks.vertices.len(), 3 * e.cracks);
        let names = ["x", "y", "z", "vx", "vy", "vz"];
        let names = names.map(String::from).to_vec();
        let fields = ["freeze_state", "plastic_strain", "von_mises"].map(String::from);
        assert_eq!(ice.properties, [names, fields.to_vec()].concat());
        let vtu = &vtu_frames[k];
        for (p, v) in ice.vertices.iter().enumerate() {
            assert!(
                close32(v[8] as f64, vtu.arrays["von_mises"][p]),
                "frame {k}"
            );
            assert!(close32(v[0] as f64, vtu.arrays["Points"][3 * p]));
        }
    }

    // OBJ: the ice and crack objects of each frame.
    export_to(&run, ExportFormat::Obj, spec, &out);
    for (k, e) in expect.iter().enumerate() {
        let path = out.join(format!("run_{k:06}.obj"));
        let (models, _) = tobj::load_obj(&path, &tobj::LoadOptions::default()).unwrap();
        let faces: Vec<(String, usize)> = models
            .iter()
            .map(|m| (m.name.clone(), m.mesh.indices.len() / 3))
            .collect();
        // tobj leaves out an object with no faces before another one (the cracks before the
        // first crack).
        let want: Vec<(String, usize)> = [
            ("ice".to_string(), e.outer),
            ("cracks".into(), e.cracks),
            ("obstacles".into(), 10),
        ]
        .into_iter()
        .filter(|(name, faces)| *faces > 0 || name != "cracks")
        .collect();
        assert_eq!(faces, want, "frame {k}");
    }
    let obj: Vec<String> = listing(&out)
        .into_iter()
        .filter(|f| f.ends_with(".obj"))
        .collect();
    let numbered: Vec<String> = (0..n).map(|k| format!("run_{k:06}.obj")).collect();
    assert_eq!(
        obj, numbered,
        "numbered 0, 1, 2, … whatever the run's frames"
    );

    // USD: one sample per frame of every attribute, counts per frame, values as the VTU's.
    let stage = dir.path().join("run.usda");
    export_to(&run, ExportFormat::Usd, spec, &stage);
    let text = std::fs::read_to_string(&stage).unwrap();
    assert!(text.starts_with("#usda 1.0\n"));
    // 30 steps per second, a frame every 10 steps, every 8th frame exported: frames 8/3 s
    // apart, 80 time codes at 30 fps in real time.
    for line in [
        "upAxis = \"Z\"",
        "metersPerUnit = 1",
        "startTimeCode = 0",
        &format!("endTimeCode = {}", 80 * (n - 1)),
        "framesPerSecond = 30",
        "timeCodesPerSecond = 30",
        "double icefem_speed = 1",
    ] {
        assert!(text.contains(line), "{line}");
    }
    for (prim, e_faces) in [("Ice", 0), ("Cracks", 1)] {
        let points = usd_samples(&text, prim, "point3f[] points");
        let counts = usd_samples(&text, prim, "int[] faceVertexCounts");
        let indices = usd_samples(&text, prim, "int[] faceVertexIndices");
        let velocities = usd_samples(&text, prim, "vector3f[] velocities");
        let von_mises = usd_samples(&text, prim, "float[] primvars:von_mises");
        for samples in [&points, &counts, &indices, &velocities, &von_mises] {
            let codes: Vec<f64> = samples.iter().map(|s| s.0).collect();
            let want: Vec<f64> = (0..n).map(|k| 80.0 * k as f64).collect();
            assert_eq!(codes, want, "{prim}");
        }
        for (k, e) in expect.iter().enumerate() {
            let faces = [e.outer, e.cracks][e_faces];
            assert_eq!(numbers(counts[k].1), vec![3.0; faces], "{prim} @{k}");
            assert_eq!(numbers(indices[k].1).len(), 3 * faces);
            let p = numbers(points[k].1).len() / 3;
            assert_eq!(numbers(velocities[k].1).len(), 3 * p);
            if prim == "Ice" {
                let vtu = &vtu_frames[k];
                assert_eq!(p, vtu.points);
                for (a, b) in numbers(von_mises[k].1).iter().zip(&vtu.arrays["von_mises"]) {
                    assert!(close32(*a, *b), "{prim} @{k}: {a} != {b}");
                }
            } else {
                assert_eq!(p, 3 * e.cracks);
            }
        }
        assert!(text
            .contains("float[] primvars:freeze_state (\n            interpolation = \"vertex\""));
    }
    // A time-lapse of 8/3 simulated seconds per second: one frame a second, 30 codes apart.
    export_at(&run, ExportFormat::Usd, spec, &stage, 8.0 / 3.0);
    let text = std::fs::read_to_string(&stage).unwrap();
    let codes: Vec<f64> = usd_samples(&text, "Ice", "point3f[] points")
        .iter()
        .map(|s| s.0)
        .collect();
    assert_eq!(codes, (0..n).map(|k| 30.0 * k as f64).collect::<Vec<_>>());
    assert!(text.contains(&format!("endTimeCode = {}", 30 * (n - 1))));
}

#[test]
fn a_run_without_freezing_or_plasticity_exports_stress_and_velocity_only() {
    let dir = tempfile::tempdir().unwrap();
    let run = run_scene(dir.path(), "pulled_bar", None);
    let out = dir.path().join("out");
    export_to(&run, ExportFormat::Ply, "::", &out);
    let ply = read_ply(&out.join("run_ice_000000.ply"));
    assert_eq!(
        ply.properties,
        ["x", "y", "z", "vx", "vy", "vz", "von_mises"]
    );
    export_to(&run, ExportFormat::Vtu, "::", &out);
    let last = listing(&out)
        .into_iter()
        .rfind(|f| f.starts_with("run_cracks_"))
        .unwrap();
    let vtu = read_vtu(&out.join(last));
    assert!(vtu.cells > 0, "the bar cracked");
    let mut names: Vec<&String> = vtu.arrays.keys().collect();
    names.sort();
    assert_eq!(
        names,
        [
            "Points",
            "connectivity",
            "offsets",
            "types",
            "velocity",
            "von_mises"
        ]
    );
    let stage = dir.path().join("bar.usda");
    export_to(&run, ExportFormat::Usd, "::", &stage);
    let text = std::fs::read_to_string(&stage).unwrap();
    assert!(text.contains("primvars:von_mises") && !text.contains("primvars:freeze_state"));
    assert!(!text.contains("primvars:plastic_strain"));
}

#[test]
fn an_earlier_export_is_replaced_only_when_forced_and_bad_options_name_file_and_option() {
    let dir = tempfile::tempdir().unwrap();
    let run = run_scene(dir.path(), "pulled_bar", Some(0.0006));
    let reader = FrameReader::open(&run).unwrap();
    assert_eq!(reader.frame_indices(), [0, 1, 2, 3]);
    let out = dir.path().join("out");
    let mut options = ExportOptions {
        format: ExportFormat::Ply,
        frames: None,
        output: Some(out.clone()),
        force: false,
        fps: DEFAULT_FPS,
        speed: 1.0,
    };
    assert_eq!(export(&reader, &options).unwrap().files.len(), 8);
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let again = export(&reader, &options).unwrap_err();
    assert!(matches!(again, ExportError::Exists { .. }), "{again}");
    assert!(again.to_string().contains("--force"), "{again}");
    // Forced with fewer frames: the frames it does not write go, other files stay.
    options.force = true;
    options.frames = Some("1:3:2".into());
    export(&reader, &options).unwrap();
    assert_eq!(
        listing(&out),
        [
            "notes.txt",
            "run_cracks_000000.ply",
            "run_cracks_000001.ply",
            "run_ice_000000.ply",
            "run_ice_000001.ply"
        ]
    );
    // Another format into the same folder is no conflict.
    options.format = ExportFormat::Obj;
    options.force = false;
    export(&reader, &options).unwrap();

    options.frames = Some("2:9".into());
    let range = export(&reader, &options).unwrap_err().to_string();
    assert!(
        range.contains("run.h5") && range.contains("--frames") && range.contains("frame 4"),
        "{range}"
    );
    // A .usda that is not a USD stage is never replaced.
    let foreign = dir.path().join("notes.usda");
    std::fs::write(&foreign, "mine").unwrap();
    let usd = ExportOptions {
        format: ExportFormat::Usd,
        frames: None,
        output: Some(foreign.clone()),
        force: true,
        fps: DEFAULT_FPS,
        speed: 1.0,
    };
    let refused = export(&reader, &usd).unwrap_err().to_string();
    assert!(refused.contains("not a USDA file"), "{refused}");
    assert_eq!(std::fs::read_to_string(&foreign).unwrap(), "mine");
}

#[test]
fn the_command_prints_one_line_and_its_errors_name_the_file_and_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let run = run_scene(dir.path(), "pulled_bar", Some(0.0006));
    let icefem = |args: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_icefem"))
            .args(args)
            .output()
            .unwrap();
        let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
        (out.status.code(), text(&out.stdout), text(&out.stderr))
    };
    let file = run.to_str().unwrap();
    let (code, stdout, _) = icefem(&["export", file, "--format", "vtu"]);
    assert_eq!(code, Some(0));
    assert_eq!(stdout.lines().count(), 1);
    assert!(
        stdout.starts_with("exported 4 frames to ") && stdout.contains("9 files"),
        "{stdout}"
    );
    assert!(dir.path().join("run_export/run.pvd").exists());
    let (code, stdout, _) = icefem(&["export", file, "--format", "usd", "--frames", "1:3"]);
    assert_eq!(code, Some(0), "{stdout}");
    assert!(
        dir.path().join("run.usda").exists(),
        "the stage beside the run"
    );

    let failures = [
        (vec!["--format", "vtu"], "exists: pass --force"),
        (
            vec!["--format", "ply", "--frames", "2:9"],
            "--frames \"2:9\"",
        ),
        (vec!["--format", "usd", "-o", "x.obj"], "--output x.obj"),
        (vec!["--format", "stl"], "--format"),
        (
            vec!["--format", "usd", "--force", "--fps", "0"],
            "--fps 0: an animation's frames per second must be in (0, 1000]",
        ),
        (
            vec!["--format", "usd", "--force", "--speed", "-1"],
            "--speed -1: simulated seconds per second",
        ),
        (
            vec!["--format", "usd", "--force", "--speed", "1e12"],
            "fall on the same time code",
        ),
    ];
    for (args, message) in failures {
        let args = [&["export", file][..], &args].concat();
        let (code, _, stderr) = icefem(&args);
        assert_ne!(code, Some(0), "{args:?}");
        assert!(
            stderr.contains(message) && !stderr.contains("panicked"),
            "{args:?}: {stderr}"
        );
    }
    let missing = dir.path().join("missing.h5");
    let (code, _, stderr) = icefem(&["export", missing.to_str().unwrap(), "--format", "obj"]);
    assert_eq!(code, Some(1));
    assert!(stderr.contains("missing.h5"), "{stderr}");
    let (code, stdout, stderr) = icefem(&["-q", "export", file, "--format", "vtu", "--force"]);
    assert_eq!(code, Some(0));
    assert!(stdout.is_empty() && stderr.is_empty(), "{stdout}{stderr}");
}

#[test]
fn a_thermal_run_exports_each_points_temperature() {
    // The container frozen by conduction, 10 minutes: its last frame's ice points carry the
    // temperatures of the nodes they sit on, exactly in VTU (Float64) and as f32 in PLY.
    let dir = tempfile::tempdir().unwrap();
    let run = run_scene(dir.path(), "freezing_container_thermal", Some(600.0));
    let reader = FrameReader::open(&run).unwrap();
    let last = *reader.frame_indices().last().unwrap();
    let frame = reader.read(last).unwrap();
    let (_, temperature) = frame.node_field("temperature").unwrap();
    let node_at: HashMap<[u64; 3], usize> = frame
        .state
        .positions
        .iter()
        .enumerate()
        .map(|(i, x)| (x.map(f64::to_bits), i))
        .collect();
    let out = dir.path().join("out");
    export_to(&run, ExportFormat::Vtu, &format!("{last}:{last}"), &out);
    let vtu = read_vtu(&out.join("run_ice_000000.vtu"));
    let points = &vtu.arrays["Points"];
    let exported = &vtu.arrays["temperature"];
    assert_eq!(exported.len(), vtu.points);
    for (k, t) in exported.iter().enumerate() {
        let p = [points[3 * k], points[3 * k + 1], points[3 * k + 2]];
        assert_eq!(*t, temperature[node_at[&p.map(f64::to_bits)]], "point {k}");
    }
    // The surface is not at one temperature: the test sees the field, not a constant.
    assert!(exported.iter().any(|&t| t != exported[0]));
    export_to(&run, ExportFormat::Ply, &format!("{last}:{last}"), &out);
    let ply = read_ply(&out.join("run_ice_000000.ply"));
    let at = ply
        .properties
        .iter()
        .position(|p| p == "temperature")
        .unwrap();
    for (vertex, t) in ply.vertices.iter().zip(exported) {
        assert_eq!(vertex[at], *t as f32);
    }
}

#[test]
fn obstacles_are_exported_where_they_are_at_each_frame() {
    // The gallery's paddle (a Gmsh mesh turning once a second about z) over a floor plane:
    // each frame's obstacles are the floor's square at z = 0, still, and the paddle's stored
    // surface turned by 2π t, its points moving at ω × x.
    let dir = tempfile::tempdir().unwrap();
    let run = run_scene(dir.path(), "gallery/thrown_cube_paddle", Some(0.1));
    let reader = FrameReader::open(&run).unwrap();
    let paddle = reader.obstacle_meshes().unwrap();
    assert_eq!(paddle.len(), 1);
    let paddle = &paddle[0];
    let out = dir.path().join("out");
    export_to(&run, ExportFormat::Vtu, "::", &out);
    let times: Vec<f64> = reader
        .frame_indices()
        .iter()
        .map(|&i| reader.read(i).unwrap().state.time)
        .collect();
    assert!(times.len() >= 3);
    for (k, t) in times.iter().enumerate() {
        let o = read_vtu(&out.join(format!("run_obstacles_{k:06}.vtu")));
        assert_eq!(o.cells, 2 + paddle.triangles.len(), "frame {k}");
        let points: Vec<&[f64]> = o.arrays["Points"].chunks(3).collect();
        let velocity: Vec<&[f64]> = o.arrays["velocity"].chunks(3).collect();
        // The floor first (scene order): four corners on z = 0, at rest.
        for p in 0..4 {
            assert_eq!(points[p][2], 0.0);
            assert_eq!(velocity[p], [0.0; 3]);
        }
        let (c, s) = (
            (2.0 * std::f64::consts::PI * t).cos(),
            (2.0 * std::f64::consts::PI * t).sin(),
        );
        for (j, x0) in paddle.vertices.iter().enumerate() {
            let (p, v) = (points[4 + j], velocity[4 + j]);
            let want = [c * x0[0] - s * x0[1], s * x0[0] + c * x0[1], x0[2]];
            let speed = [
                -2.0 * std::f64::consts::PI * want[1],
                2.0 * std::f64::consts::PI * want[0],
                0.0,
            ];
            for a in 0..3 {
                // Rotation matrices from nalgebra against cos/sin here: round-off of 1e-15 m.
                assert!((p[a] - want[a]).abs() < 1e-14, "frame {k} vertex {j}");
                assert!((v[a] - speed[a]).abs() < 1e-13, "frame {k} vertex {j}");
            }
        }
    }
}
