//! Pictures from output files: silhouettes against the geometry, crack colour where the
//! fracture module put cracks, sequences and figures, and clear errors for bad files.

use icefem::mesh::box_mesh;
use icefem::output::{FrameReader, OutputError, OutputWriter, RunHeader, StoredFrame};
use icefem::render::{
    self, Background, ColorField, Cut, FigureOptions, Lens, Picture, RenderOptions, Renderer, Style,
};
use icefem::run::{run, RunOptions};
use icefem::scene::Scene;
use nalgebra::Vector3;
use std::path::Path;
use std::sync::atomic::AtomicBool;

/// Writes an icefem file of `frames` frames of a box mesh at rest (positions = rest, scene
/// text empty: no obstacles); returns the box's corners.
fn write_box_file(path: &Path, frames: usize) -> (Vector3<f64>, Vector3<f64>) {
    write_box_file_with_scene(path, frames, "")
}

/// [`write_box_file`] with `scene_text` stored as the run's scene (its obstacles are drawn).
/// A one-frame box file of `scene_text` in a temporary folder (kept while the first value
/// lives), its reader and its frame.
fn box_frame(scene_text: &str) -> (tempfile::TempDir, FrameReader, StoredFrame) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.h5");
    write_box_file_with_scene(&path, 1, scene_text);
    let reader = FrameReader::open(&path).unwrap();
    let frame = reader.read(0).unwrap();
    (dir, reader, frame)
}

fn write_box_file_with_scene(
    path: &Path,
    frames: usize,
    scene_text: &str,
) -> (Vector3<f64>, Vector3<f64>) {
    let (lo, size) = ([0.01, -0.02, 0.0], [0.1, 0.2, 0.05]);
    let mesh = box_mesh(lo, size, [2, 3, 1], 6).unwrap();
    let rest: Vec<[f64; 3]> = mesh.rest.iter().map(|x| [x.x, x.y, x.z]).collect();
    let mut writer = OutputWriter::create(
        path,
        &RunHeader {
            scene_text,
            scene_path: "box.toml",
            version: "test",
            mesh: icefem::output::HeaderMesh::Whole {
                rest_positions: &rest,
                tets: &mesh.tets,
            },
            obstacles: &[],
        },
    )
    .unwrap();
    let velocities = vec![[0.0; 3]; rest.len()];
    let stress = vec![[0.0; 6]; mesh.tets.len()];
    for k in 0..frames {
        writer
            .write_frame(&icefem::output::Frame {
                step: k as u64,
                time: k as f64 * 0.1,
                positions: &rest,
                velocities: &velocities,
                rest_positions: &rest,
                tets: &mesh.tets,
                topology_changed: k == 0,
                stress: &stress,
                element_fields: &[],
                node_fields: &[],
                row_fields: &[],
                attributes: &[],
                cracks: None,
            })
            .unwrap();
    }
    writer.finish().unwrap();
    let lo = Vector3::from(lo);
    (lo, lo + Vector3::from(size))
}

/// Whether the pixel centre `p` is inside the convex polygon `hull` (counter-clockwise or
/// clockwise), and its distance to the polygon's boundary (pixels).
fn inside_and_distance(hull: &[[f64; 2]], p: [f64; 2]) -> (bool, f64) {
    let mut sign = 0.0;
    let mut inside = true;
    let mut distance = f64::MAX;
    for k in 0..hull.len() {
        let (a, b) = (hull[k], hull[(k + 1) % hull.len()]);
        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
        let cross = ex * (p[1] - a[1]) - ey * (p[0] - a[0]);
        if sign == 0.0 {
            sign = cross.signum();
        } else if cross * sign < 0.0 {
            inside = false;
        }
        let t = (((p[0] - a[0]) * ex + (p[1] - a[1]) * ey) / (ex * ex + ey * ey)).clamp(0.0, 1.0);
        let (dx, dy) = (a[0] + t * ex - p[0], a[1] + t * ey - p[1]);
        distance = distance.min((dx * dx + dy * dy).sqrt());
    }
    (inside, distance)
}

/// Convex hull (monotone chain) of points in the picture plane.
fn convex_hull(mut points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::new();
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

#[test]
fn silhouette_of_a_box_covers_exactly_its_projected_hull() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.h5");
    let (lo, hi) = write_box_file(&path, 1);
    let reader = FrameReader::open(&path).unwrap();
    let frame = reader.read(0).unwrap();
    // The box's cells along y end at −0.02, 0.0467, 0.1133, 0.18 m: a cut at y = 0.05 keeps
    // the tets of the first layer of cells (their centroids are at y ≤ 0.03 or ≥ 0.063),
    // whose silhouette is that of the box [lo, hi] with hi.y = 0.0467.
    let first_layer = Vector3::new(hi.x, lo.y + 0.2 / 3.0, hi.z);
    let cases = [
        ("30,20", Style::Solid, None, hi),
        ("-120,-35", Style::Glass, None, hi),
        ("top", Style::Solid, None, hi),
        ("30,20", Style::Solid, Some("y=0.05"), first_layer),
    ];
    for (view, style, cut, hi) in cases {
        let options = RenderOptions {
            width: 240,
            height: 180,
            view: view.parse().unwrap(),
            style,
            cut: cut.map(|c| c.parse().unwrap()),
            ..Default::default()
        };
        let renderer = Renderer::new(&reader, options).unwrap();
        let picture = renderer.draw_scene(&reader, &frame).unwrap();
        let empty = render::background(picture.width, picture.height);
        // The expected silhouette, from the geometry: the convex hull of the box's projected
        // corners (a box is convex, so its silhouette is that hull).
        let corners: Vec<[f64; 2]> = (0..8)
            .map(|k| {
                let c = Vector3::new(
                    [lo.x, hi.x][k & 1],
                    [lo.y, hi.y][(k >> 1) & 1],
                    [lo.z, hi.z][(k >> 2) & 1],
                );
                let [x, y, _] = renderer.camera().project(c);
                [x, y]
            })
            .collect();
        let hull = convex_hull(corners);
        let (mut wrong, mut covered) = (0, 0);
        for y in 0..picture.height {
            for x in 0..picture.width {
                let (inside, distance) =
                    inside_and_distance(&hull, [x as f64 + 0.5, y as f64 + 0.5]);
                let drawn = picture.pixel(x, y) != empty.pixel(x, y);
                covered += drawn as usize;
                // Pixels within 1.5 px of the outline are partly covered (2 × 2 supersampling)
                // and carry the edge lines (1.2 px wide): either answer is right there.
                if distance > 1.5 && drawn != inside {
                    wrong += 1;
                }
            }
        }
        assert_eq!(
            wrong, 0,
            "{view}: {wrong} pixels disagree with the projected hull"
        );
        // And the drawn area is the hull's area, up to the boundary band (perimeter × 1.5 px).
        let n = hull.len();
        let area = (0..n)
            .map(|k| hull[k][0] * hull[(k + 1) % n][1] - hull[(k + 1) % n][0] * hull[k][1])
            .sum::<f64>()
            .abs()
            / 2.0;
        let perimeter: f64 = (0..n)
            .map(|k| {
                ((hull[(k + 1) % n][0] - hull[k][0]).powi(2)
                    + (hull[(k + 1) % n][1] - hull[k][1]).powi(2))
                .sqrt()
            })
            .sum();
        assert!(area > 2000.0, "{view}: a sizeable silhouette, {area} px²");
        assert!(
            (covered as f64 - area).abs() <= 1.5 * perimeter,
            "{view}: {covered} pixels drawn, hull area {area:.0} px², perimeter {perimeter:.0} px"
        );
    }
}

const PULLED_BAR: &str = include_str!("../scenes/pulled_bar.toml");

#[test]
fn cracks_are_drawn_in_crack_colour_where_the_fracture_put_them() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("pulled_bar.toml");
    std::fs::write(&scene_path, PULLED_BAR).unwrap();
    let scene = Scene::load(&scene_path).unwrap();
    let path = dir.path().join("bar.h5");
    let options = RunOptions {
        output: Some(path.clone()),
        ..Default::default()
    };
    run(&scene, &options, &AtomicBool::new(false), |_| {}).unwrap();

    let reader = FrameReader::open(&path).unwrap();
    let indices = reader.frame_indices();
    let first = reader.read(indices[0]).unwrap();
    let last = reader.read(*indices.last().unwrap()).unwrap();
    assert!(first.crack_triangles.is_empty());
    assert!(
        last.crack_triangles.len() > 20,
        "the bar should have cracked"
    );
    // The bar is pulled along x, so its crack faces the x axis: look from +x through the
    // translucent ice, straight at the crack.
    let options = RenderOptions {
        width: 320,
        height: 240,
        view: "side".parse().unwrap(),
        style: Style::Glass,
        ..Default::default()
    };
    let renderer = Renderer::new(&reader, options).unwrap();
    // Crack red: red well above green and blue. Ice and background are white-blue (r ≤ g ≤ b).
    let reddish = |c: [u8; 3]| c[0] as i32 > c[1] as i32 + 60 && c[0] as i32 > c[2] as i32 + 60;

    let before = renderer.draw_scene(&reader, &first).unwrap();
    let red_before = before
        .rgba
        .chunks_exact(4)
        .filter(|c| reddish([c[0], c[1], c[2]]))
        .count();
    assert_eq!(red_before, 0, "no crack, no red");

    let after = renderer.draw_scene(&reader, &last).unwrap();
    let (mut hits, mut total) = (0, 0);
    for (x, _) in &last.crack_triangles {
        let c = x.iter().map(|p| Vector3::from(*p)).sum::<Vector3<f64>>() / 3.0;
        let [px, py, _] = renderer.camera().project(c);
        total += 1;
        hits += reddish(after.pixel(px as usize, py as usize)) as usize;
    }
    // Crack triangles facing the camera cover their centroid's pixel; one whose projection
    // is under a pixel wide can have its centroid pixel averaged with the ice beside it by
    // the 2 × 2 supersampling. All of them here are larger: every centroid must be red.
    assert_eq!(
        hits, total,
        "{hits} of {total} crack centroids drawn in crack colour"
    );
    let red_after = after
        .rgba
        .chunks_exact(4)
        .filter(|c| reddish([c[0], c[1], c[2]]))
        .count();
    assert!(
        red_after > 100,
        "the crack covers a region, {red_after} red pixels"
    );
}

#[test]
fn sequences_gifs_and_figures_from_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.h5");
    write_box_file(&path, 5);
    let reader = FrameReader::open(&path).unwrap();
    let options = RenderOptions {
        width: 160,
        height: 120,
        ..Default::default()
    };
    let pngs = dir.path().join("seq.png");
    let summary = render::render_frames(&reader, &[1, 2, 3], options, &pngs, 30.0).unwrap();
    assert_eq!(summary.frames, 3);
    // Numbered 0, 1, 2 whatever the frames' indices (what ffmpeg's %06d expects).
    assert_eq!(
        summary.files,
        (0..3)
            .map(|k| render::numbered_path(&pngs, k))
            .collect::<Vec<_>>()
    );
    for k in 0..3 {
        let file = render::numbered_path(&pngs, k);
        assert_eq!(
            file.file_name().unwrap().to_string_lossy(),
            format!("seq_{k:06}.png")
        );
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&file).unwrap()));
        let info = decoder.read_info().unwrap();
        assert_eq!((info.info().width, info.info().height), (160, 120));
    }
    let gif_path = dir.path().join("seq.gif");
    render::render_frames(&reader, &[0, 1, 2, 3, 4], options, &gif_path, 10.0).unwrap();
    let mut decoder = gif::DecodeOptions::new()
        .read_info(std::fs::File::open(&gif_path).unwrap())
        .unwrap();
    let mut frames = 0;
    while decoder.read_next_frame().unwrap().is_some() {
        frames += 1;
    }
    assert_eq!(frames, 5);

    // A run of 5 frames (cut off long before the paper's steps): four panels spread over it.
    let (picture, panels) = render::figure(
        &reader,
        &FigureOptions {
            frames: Vec::new(),
            panel: options,
            size: None,
        },
    )
    .unwrap();
    assert_eq!(
        panels.iter().map(|p| p.frame).collect::<Vec<_>>(),
        vec![0, 1, 2, 4]
    );
    assert!(panels
        .iter()
        .all(|p| p.elements == 36 && p.crack_polygons == 0));
    assert!(picture.width > 4 * 160 && picture.height > 120);

    // A whole-figure size is the picture's size, with or without a colour bar; one too small
    // for four panels is refused.
    for (size, color_by) in [
        ((1920, 1080), None),
        ((1000, 301), Some(ColorField::VonMises)),
    ] {
        let (picture, _) = render::figure(
            &reader,
            &FigureOptions {
                frames: Vec::new(),
                panel: RenderOptions {
                    color_by,
                    ..options
                },
                size: Some(size),
            },
        )
        .unwrap();
        assert_eq!((picture.width, picture.height), size);
    }
    let tiny = FigureOptions {
        frames: Vec::new(),
        panel: options,
        size: Some((90, 60)),
    };
    let message = render::figure(&reader, &tiny).unwrap_err().to_string();
    assert!(
        message.contains("90x60") && message.contains("--size"),
        "{message}"
    );
}

#[test]
fn bad_files_and_frames_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    // No frames: the run died before writing one.
    let empty = dir.path().join("empty.h5");
    let mesh = box_mesh([0.0; 3], [0.1; 3], [1, 1, 1], 6).unwrap();
    let rest: Vec<[f64; 3]> = mesh.rest.iter().map(|x| [x.x, x.y, x.z]).collect();
    let header = RunHeader {
        scene_text: "",
        scene_path: "x.toml",
        version: "test",
        mesh: icefem::output::HeaderMesh::Whole {
            rest_positions: &rest,
            tets: &mesh.tets,
        },
        obstacles: &[],
    };
    OutputWriter::create(&empty, &header)
        .unwrap()
        .finish()
        .unwrap();
    let e = FrameReader::open(&empty).err().unwrap();
    assert!(matches!(e, OutputError::NoCompleteFrame { .. }), "{e}");
    assert!(e.to_string().contains("empty.h5") && e.to_string().contains("no complete frame"));

    // A frame that is not there.
    let one = dir.path().join("one.h5");
    write_box_file(&one, 2);
    let reader = FrameReader::open(&one).unwrap();
    let e = reader.read(7).err().unwrap();
    assert!(
        e.to_string()
            .contains("no complete frame 7 (the file has 2 complete frames, 0 … 1)"),
        "{e}"
    );

    // HDF5, but not icefem's; and not HDF5 at all.
    let other = dir.path().join("other.h5");
    hdf5::File::create(&other)
        .unwrap()
        .new_dataset::<f64>()
        .shape(3)
        .create("x")
        .unwrap();
    let e = FrameReader::open(&other).err().unwrap();
    assert!(matches!(e, OutputError::NotIcefem { .. }), "{e}");
    let text = dir.path().join("text.h5");
    std::fs::write(&text, "not hdf5").unwrap();
    assert!(matches!(
        FrameReader::open(&text),
        Err(OutputError::NotHdf5 { .. })
    ));

    // The same through the command line: exit code 1 and the message, never a panic.
    let exe = env!("CARGO_BIN_EXE_icefem");
    let cases: [(&[&str], &str); 5] = [
        (&["render", empty.to_str().unwrap()], "no complete frame"),
        (
            &["render", one.to_str().unwrap(), "--frame", "7"],
            "no complete frame 7",
        ),
        (
            &["render", one.to_str().unwrap(), "--frames", "0:5"],
            "frame 2 is not a complete frame",
        ),
        (&["figure", other.to_str().unwrap()], "not icefem output"),
        (
            &["render", one.to_str().unwrap(), "--size", "10x10"],
            "each 64 … 4096 pixels",
        ),
    ];
    for (args, message) in cases {
        let out = std::process::Command::new(exe).args(args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(stderr.contains(message), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
    // A field the run does not have.
    let out = std::process::Command::new(exe)
        .args(["render", one.to_str().unwrap(), "--color-by", "freeze"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("has no freeze_state (the scene has no [freezing])"),
        "{stderr}"
    );
}

#[test]
fn outputs_are_png_gif_or_mp4_and_mp4_goes_through_ffmpeg() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("box.h5");
    write_box_file(&run, 3);
    let exe = env!("CARGO_BIN_EXE_icefem");
    let icefem = |args: &[&str], path: &str| {
        let out = std::process::Command::new(exe)
            .args(args)
            .env("PATH", path)
            .output()
            .unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let run_arg = run.to_str().unwrap();
    let out = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    // Other extensions are refused before anything is drawn.
    let (ok, err) = icefem(&["render", run_arg, "-o", &out("x.jpg")], "");
    assert!(!ok && err.contains("cannot write .jpg files"), "{err}");
    assert!(!dir.path().join("x.jpg").exists());
    let (ok, err) = icefem(&["figure", run_arg, "-o", &out("f.gif")], "");
    assert!(!ok && err.contains("give a .png output"), "{err}");
    // `figure --size` is the whole figure's.
    let (ok, err) = icefem(
        &["figure", run_arg, "--size", "1280x360", "-o", &out("f.png")],
        "",
    );
    assert!(ok, "{err}");
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(out("f.png")).unwrap(),
    ));
    let info = decoder.read_info().unwrap();
    assert_eq!((info.info().width, info.info().height), (1280, 360));
    // Without ffmpeg on the PATH: a clear error, nothing left behind.
    let (ok, err) = icefem(
        &["render", run_arg, "--frames", "0:2", "-o", &out("v.mp4")],
        "",
    );
    assert!(!ok && err.contains("needs ffmpeg on the PATH"), "{err}");
    assert!(!dir.path().join("v.frames").exists());
    // A stand-in ffmpeg records how it is called and writes the output it is given.
    let bin = dir.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    let fake = bin.join("ffmpeg");
    std::fs::write(
        &fake,
        "#!/bin/sh\necho \"$@\" >> \"$(dirname \"$0\")/calls\"\nfor last; do :; done\n\
         [ \"$1\" = -version ] || ls \"$(dirname \"$last\")\"/v.frames > \"$last\"\n",
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let path = format!("{}:/usr/bin:/bin", bin.display());
    let (ok, err) = icefem(
        &[
            "render",
            run_arg,
            "--frames",
            "0:2",
            "--fps",
            "12",
            "-o",
            &out("v.mp4"),
        ],
        &path,
    );
    assert!(ok, "{err}");
    let calls = std::fs::read_to_string(bin.join("calls")).unwrap();
    assert!(
        calls.contains("-framerate 12 -i") && calls.contains("frame_%06d.png"),
        "{calls}"
    );
    // It was handed the three frames numbered from 0, and they are gone afterwards.
    let listed = std::fs::read_to_string(dir.path().join("v.mp4")).unwrap();
    assert_eq!(
        listed.split_whitespace().collect::<Vec<_>>(),
        ["frame_000000.png", "frame_000001.png", "frame_000002.png"]
    );
    assert!(!dir.path().join("v.frames").exists());
    // The real encoder, where the machine has it: an MP4 container.
    if std::process::Command::new("ffmpeg")
        .arg("-version")
        .output()
        .is_ok()
    {
        let system = std::env::var("PATH").unwrap_or_default();
        let (ok, err) = icefem(
            &["render", run_arg, "--frames", "0:2", "-o", &out("real.mp4")],
            &system,
        );
        assert!(ok, "{err}");
        let bytes = std::fs::read(dir.path().join("real.mp4")).unwrap();
        assert_eq!(&bytes[4..8], b"ftyp", "not an MP4 file");
    } else {
        eprintln!("ffmpeg is not on this machine's PATH: the real-encoder check was skipped");
    }
}

#[test]
fn mesh_obstacles_are_drawn_from_the_file_after_the_scene_folder_moved() {
    // scenes/slide_down_ramp.toml cut to two steps: a ramp read from ramp.obj
    // ([[obstacle]] 0) and a container ([[obstacle]] 1).
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    std::fs::create_dir(&scene_dir).unwrap();
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let text = std::fs::read_to_string(scenes.join("slide_down_ramp.toml"))
        .unwrap()
        .replace("end_time = 1.5", "end_time = 0.02");
    std::fs::write(scene_dir.join("ramp.toml"), text).unwrap();
    std::fs::copy(scenes.join("ramp.obj"), scene_dir.join("ramp.obj")).unwrap();
    let scene = Scene::load(&scene_dir.join("ramp.toml")).unwrap();
    let path = dir.path().join("ramp.h5");
    let options = RunOptions {
        output: Some(path.clone()),
        ..Default::default()
    };
    run(&scene, &options, &AtomicBool::new(false), |_| {}).unwrap();

    let picture = |path: &Path| {
        let reader = FrameReader::open(path).unwrap();
        let frame = reader.read(0).unwrap();
        let options = RenderOptions {
            width: 240,
            height: 180,
            ..Default::default()
        };
        let renderer = Renderer::new(&reader, options).unwrap();
        renderer.draw_scene(&reader, &frame).unwrap().rgba
    };
    // The file holds the ramp's surface as the scene placed it.
    let reader = FrameReader::open(&path).unwrap();
    let stored = reader.obstacle_meshes().unwrap();
    assert_eq!(stored.len(), 1, "only the mesh obstacle has a surface");
    assert_eq!((stored[0].index, stored[0].vertices.len()), (0, 6));
    assert!(stored[0].vertices.contains(&[0.0, 0.2, 0.1]));
    drop(reader);
    let before = picture(&path);
    // A file without the stored surface (as written before surfaces were stored) reads the
    // ramp from beside the scene: the same picture while the scene is where it was.
    let bare = dir.path().join("bare.h5");
    std::fs::copy(&path, &bare).unwrap();
    hdf5::File::open_rw(&bare)
        .unwrap()
        .unlink("obstacles")
        .unwrap();
    assert_eq!(picture(&bare), before);

    // The scene's folder moved away: the file still draws the ramp, as before; the file
    // without it lost the ramp (and its camera, fitted to the ice and the obstacles).
    std::fs::rename(&scene_dir, dir.path().join("moved")).unwrap();
    assert_eq!(
        picture(&path),
        before,
        "the picture changed with the scene folder"
    );
    assert_ne!(picture(&bare), before, "the ramp was not drawn at all");
}

/// A box inside a container obstacle, coloured by von Mises stress, on a white background.
fn boxed_options(width: usize, height: usize) -> RenderOptions {
    RenderOptions {
        width,
        height,
        style: Style::Solid,
        color_by: Some(ColorField::VonMises),
        range: Some((0.0, 2.0e6)),
        background: Background::Color([1.0; 3]),
        ..Default::default()
    }
}

/// A one-step scene of the box file with `obstacle` (an `[[obstacle]]` table's keys).
fn box_scene(obstacle: &str) -> String {
    format!(
        "[material]\ndensity = 916.0\n[time]\ndt = 0.1\nend_time = 0.1\n[[obstacle]]\n{obstacle}"
    )
}

/// A container around the box file's box.
const CONTAINER: &str =
    "type = \"container\"\nmin = [-0.02, -0.05, -0.01]\nmax = [0.14, 0.21, 0.08]\n";

#[test]
fn text_lines_and_colour_bar_scale_with_the_picture() {
    let (_dir, reader, frame) = box_frame(&box_scene(CONTAINER));
    let luminance = |c: [u8; 3]| 0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64;
    // What the picture's label, colour bar and obstacle lines measure (pixels).
    let measure = |picture: &Picture, strip: usize| {
        let (w, h) = (picture.width, picture.height);
        // The label's ink: its height, top left.
        let rows: Vec<usize> = (0..h / 10)
            .filter(|&y| (0..w / 3).any(|x| picture.pixel(x, y).iter().all(|&c| c < 100)))
            .collect();
        let label = (rows.last().unwrap() - rows[0] + 1) as f64;
        // The bar's width: the first run of non-white pixels in the strip, median over rows
        // (rows with a tick mark run longer).
        let mut runs: Vec<usize> = (h / 3..2 * h / 3)
            .map(|y| {
                let start = (w - strip..w)
                    .find(|&x| picture.pixel(x, y) != [255; 3])
                    .unwrap();
                (start..w)
                    .take_while(|&x| picture.pixel(x, y) != [255; 3])
                    .count()
            })
            .collect();
        runs.sort_unstable();
        let bar = runs[runs.len() / 2] as f64;
        // The obstacle's outline: grey ink over the white background, as a darkness
        // integral (anti-aliased pixels count by their coverage); the ice is viridis purple
        // and its edges blue, neither grey.
        let obstacle = luminance([64, 64, 71]);
        let mut ink = 0.0;
        for y in h / 10..h {
            for x in 0..w - strip {
                let c = picture.pixel(x, y);
                let grey = (c[0] as i32 - c[2] as i32).abs() < 24
                    && (c[0] as i32 - c[1] as i32).abs() < 24;
                if grey {
                    ink += ((255.0 - luminance(c)) / (255.0 - obstacle)).clamp(0.0, 1.0);
                }
            }
        }
        (label, bar, ink)
    };
    let small = boxed_options(960, 540);
    let large = boxed_options(3840, 2160);
    let draw = |o: RenderOptions| {
        let picture = Renderer::new(&reader, o)
            .unwrap()
            .render(&reader, &frame, true)
            .unwrap();
        measure(&picture, o.bar_strip())
    };
    let (label_s, bar_s, ink_s) = draw(small);
    let (label_l, bar_l, ink_l) = draw(large);
    // Sizes go as the picture's height over 600 px, never below 1: 1 at 540 px, 3.6 at
    // 2160. Text and bar: 3.6 times, to the rounding of a few pixels at the small size.
    // Outline ink: 4 times the length (the scene is 4 times larger) × 3.6 times the width.
    assert_eq!(small.overlay().scale, 1.0);
    assert!((large.overlay().scale - 3.6).abs() < 1e-12);
    assert!(
        (label_l / label_s - 3.6).abs() < 0.4,
        "label {label_s} → {label_l} px"
    );
    assert!(
        (bar_l / bar_s - 3.6).abs() < 0.3,
        "bar {bar_s} → {bar_l} px"
    );
    assert!(
        (ink_l / ink_s / 14.4 - 1.0).abs() < 0.12,
        "outline ink {ink_s:.0} → {ink_l:.0} px²"
    );
    assert!(
        label_s >= 9.0 && bar_s >= 15.0,
        "legible at scale 1: {label_s}, {bar_s}"
    );
}

#[test]
fn a_transparent_background_leaves_only_the_scene_opaque() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.h5");
    let (lo, hi) = write_box_file(&path, 2);
    let reader = FrameReader::open(&path).unwrap();
    let frame = reader.read(0).unwrap();
    for (style, centre_alpha) in [(Style::Solid, 255..=255), (Style::Glass, 60..=254)] {
        let options = RenderOptions {
            width: 200,
            height: 150,
            style,
            background: Background::Transparent,
            ..Default::default()
        };
        let renderer = Renderer::new(&reader, options).unwrap();
        let picture = renderer.render(&reader, &frame, false).unwrap();
        let [x, y, _] = renderer.camera().project((lo + hi) / 2.0);
        assert_eq!(
            picture.alpha(0, 149),
            0,
            "{style:?}: a corner away from the box"
        );
        let a = picture.alpha(x as usize, y as usize);
        assert!(
            centre_alpha.contains(&a),
            "{style:?}: the box's centre has alpha {a}"
        );
        // Written as an RGBA PNG that keeps the alpha.
        let png_path = dir.path().join("t.png");
        render::save_png(&picture, &png_path).unwrap();
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(&png_path).unwrap(),
        ));
        let mut png_reader = decoder.read_info().unwrap();
        let mut buffer = vec![0; png_reader.output_buffer_size().unwrap()];
        let info = png_reader.next_frame(&mut buffer).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgba);
        assert_eq!(&buffer[..info.buffer_size()], &picture.rgba[..]);
    }
    // GIF and MP4 frames are opaque: refused with the reason.
    let options = RenderOptions {
        background: Background::Transparent,
        ..Default::default()
    };
    let err = render::render_frames(&reader, &[0, 1], options, &dir.path().join("a.gif"), 10.0)
        .unwrap_err()
        .to_string();
    assert!(err.contains("transparent background needs PNG"), "{err}");
}

#[test]
fn the_ice_shows_through_a_glass_container() {
    let dir = tempfile::tempdir().unwrap();
    let (boxed, bare) = (dir.path().join("boxed.h5"), dir.path().join("bare.h5"));
    let (lo, hi) = write_box_file_with_scene(&boxed, 1, &box_scene(CONTAINER));
    write_box_file(&bare, 1);
    let centre = (lo + hi) / 2.0;
    // One camera for both files (a fitted one would differ: the container widens the box).
    let picture = |path: &Path, style: Style, view: &str, background, cut| {
        let reader = FrameReader::open(path).unwrap();
        let frame = reader.read(0).unwrap();
        let options = RenderOptions {
            width: 240,
            height: 180,
            style,
            cut,
            view: view.parse().unwrap(),
            lens: Lens {
                target: Some(centre),
                distance: Some(0.9),
                ..Lens::default()
            },
            background: Background::Color(background),
            ..Default::default()
        };
        let renderer = Renderer::new(&reader, options).unwrap();
        let picture = renderer.draw_scene(&reader, &frame).unwrap();
        (picture, *renderer.camera())
    };
    let gap = |a: [u8; 3], b: [u8; 3]| (0..3).map(|k| a[k].abs_diff(b[k])).max().unwrap();
    for style in [Style::Solid, Style::Glass] {
        // The ice's centre seen through the container's front wall (from the front: from
        // above, the eye would look in through the open top): the ice's colour under a faint
        // tint, far from the walls' own colour over the background beside the ice.
        let (with, camera) = picture(&boxed, style, "front", [0.0; 3], None);
        let (without, _) = picture(&bare, style, "front", [0.0; 3], None);
        let at = |x: Vector3<f64>| {
            let [px, py, _] = camera.project(x);
            (px as usize, py as usize)
        };
        let (x, y) = at(centre);
        let (seen, ice) = (with.pixel(x, y), without.pixel(x, y));
        let (bx, by) = at(Vector3::new(0.125, -0.05, centre.z));
        let walls = with.pixel(bx, by);
        assert!(
            (1..=60).contains(&gap(seen, ice)),
            "{style:?}: {seen:?} behind glass, {ice:?} bare"
        );
        assert!(
            gap(seen, walls) > 2 * gap(seen, ice),
            "{style:?}: {seen:?} behind glass, {walls:?} glass alone"
        );
        assert!(
            gap(walls, [0; 3]) > 5,
            "{style:?}: the walls are drawn: {walls:?}"
        );
    }
    // A cut opens the container as it opens the ice: the cut face shows as without it, and
    // the walls beyond the cut are still drawn.
    let cut = Some(Cut {
        axis: 1,
        value: centre.y,
    });
    let (with, camera) = picture(&boxed, Style::Solid, "front", [0.0; 3], cut);
    let (without, _) = picture(&bare, Style::Solid, "front", [0.0; 3], cut);
    let [x, y, _] = camera.project(centre);
    let (seen, ice) = (
        with.pixel(x as usize, y as usize),
        without.pixel(x as usize, y as usize),
    );
    assert!(gap(seen, ice) <= 1, "cut face {seen:?}, bare {ice:?}");
    let [x, y, _] = camera.project(Vector3::new(0.125, 0.2, centre.z));
    let back_wall = with.pixel(x as usize, y as usize);
    assert!(gap(back_wall, [0; 3]) > 5, "the far wall: {back_wall:?}");
    // From the top, the container's floor beside the ice (face-on): tinted, still light.
    let (top, camera) = picture(&boxed, Style::Solid, "top", [1.0; 3], None);
    let [x, y, _] = camera.project(Vector3::new(-0.012, 0.195, -0.01));
    let floor = top.pixel(x as usize, y as usize);
    assert!(
        floor.iter().all(|&c| c > 180) && floor.iter().any(|&c| c < 250),
        "container floor {floor:?}"
    );
}

/// A floor under the box file's box.
const FLOOR: &str = "type = \"halfspace\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n";

#[test]
fn a_floor_reaches_the_horizon_from_under_the_camera() {
    let (_dir, reader, frame) = box_frame(&box_scene(FLOOR));
    let (width, height) = (240, 180);
    let picture = |view: &str| {
        let options = RenderOptions {
            width,
            height,
            view: view.parse().unwrap(),
            background: Background::Transparent,
            ..Default::default()
        };
        let renderer = Renderer::new(&reader, options).unwrap();
        let picture = renderer.draw_scene(&reader, &frame).unwrap();
        // A horizontal plane's horizon: the row of the directions at zero elevation.
        let elevation = view.split(',').nth(1).unwrap().parse::<f64>().unwrap();
        let camera = renderer.camera();
        let horizon = height as f64 / 2.0 - camera.focal() * elevation.to_radians().tan();
        (picture, horizon)
    };
    // From above: the ground, which runs on behind the camera, covers every pixel below the
    // horizon up to it (opaque) and none above.
    let (above, horizon) = picture("-60,10");
    assert!((10.0..height as f64 - 10.0).contains(&horizon));
    let row = |dy: f64| (horizon + dy) as usize;
    for x in [2, width / 2, width - 3] {
        assert_eq!(
            above.alpha(x, row(3.0)),
            255,
            "ground below the horizon at x = {x}"
        );
        assert_eq!(
            above.alpha(x, height - 1),
            255,
            "ground under the camera at x = {x}"
        );
    }
    assert_eq!(above.alpha(2, row(-3.0)), 0, "sky above the horizon");
    // From below the floor (its solid side): see-through above the horizon, nothing below.
    let (below, horizon) = picture("-60,-8");
    let a = below.alpha(2, (horizon - 5.0) as usize);
    assert!((1..=200).contains(&a), "ground from below: alpha {a}");
    assert_eq!(below.alpha(2, (horizon + 5.0) as usize), 0);
}
