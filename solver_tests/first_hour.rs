//! What a new user meets in the first hour, through the command line: Gmsh meshes made the
//! way users make them (`solver_tests/data/user_meshes`, from `make_user_meshes.py`), a mesh
//! in millimetres, named surfaces that are also box-face words, a plain build under mpirun,
//! and a run's summary of what happened physically.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn exe() -> Command {
    Command::new(env!("CARGO_BIN_EXE_icefem"))
}

fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("solver_tests/data/user_meshes")
        .join(name)
        .display()
        .to_string()
}

fn write_scene(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// `icefem run SCENE --output OUT [extra…]`.
fn run(scene: &Path, extra: &[&str]) -> Output {
    exe()
        .arg("run")
        .arg(scene)
        .arg("--output")
        .arg(scene.with_extension("h5"))
        .args(extra)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Water (a Gmsh tet mesh `body`, read with `scale`) falling into a Gmsh obstacle surface.
fn falling_into(body: &str, scale: f64, obstacle: &str) -> String {
    format!(
        r#"[[body]]
file = "{}"
scale = {scale}

[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10

[physics]
gravity = [0.0, 0.0, -9.81]

[[obstacle]]
type = "mesh"
file = "{}"

[time]
dt = 0.01
end_time = 0.05
"#,
        fixture(body),
        fixture(obstacle)
    )
}

#[test]
fn gmsh_cups_and_glasses_with_reversed_faces_are_turned_outward() {
    // Gmsh writes the cavity floor of an OCC cut the other way round: 273 of the cup's and
    // 223 of the glass's triangles (counted independently by make_user_meshes.py against the
    // exact solids). Read as written, the water in the cavity started "inside" the obstacle.
    let dir = tempfile::tempdir().unwrap();
    for (body, obstacle, reversed) in [
        ("water_in_cup.msh", "cup_occ.msh", "273 of 2578 triangles"),
        ("water_glass.msh", "glass_occ.msh", "223 of 3284 triangles"),
    ] {
        let scene = write_scene(dir.path(), "s.toml", &falling_into(body, 1.0, obstacle));
        let o = run(&scene, &["--force"]);
        let text = stderr(&o);
        assert!(o.status.success(), "{text}");
        assert!(
            text.contains(reversed) && text.contains("used reversed"),
            "{text}"
        );
        assert!(!text.contains("warning"), "{text}");
    }
}

#[test]
fn a_mesh_in_millimetres_is_warned_about_before_and_after_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let text = falling_into("water_glass_mm.msh", 1.0, "glass_occ.msh")
        .replace("end_time = 0.05", "end_time = 30.0")
        .replace("dt = 0.01", "dt = 0.5");
    let scene = write_scene(dir.path(), "mm.toml", &text);
    let o = run(&scene, &[]);
    let text = stderr(&o);
    assert!(o.status.success(), "{text}");
    // Before the run, by size (104 m of ice against a 14 cm glass), repeated after it with
    // the fall: 4.4 km, out of the glass's reach.
    let size = "the ice is 1.039e2 m across and the largest container or mesh obstacle 1.387e-1 m";
    assert_eq!(text.matches(size).count(), 2, "{text}");
    assert!(text.contains("[[body]] scale = 0.001"), "{text}");
    assert!(
        text.contains("the ice fell") && text.contains("out of every obstacle's reach"),
        "{text}"
    );
    // Read at scale 1e-3 it is the glass of water it is meant to be: no warning.
    let scene = write_scene(
        dir.path(),
        "scaled.toml",
        &falling_into("water_glass_mm.msh", 1e-3, "glass_occ.msh"),
    );
    let o = run(&scene, &[]);
    assert!(
        o.status.success() && !stderr(&o).contains("warning"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn named_surfaces_called_bottom_and_top_are_the_meshs_groups_in_every_key() {
    // named_faces.msh has physical surfaces "bottom" (z = 0), "top" (z = 0.03) and "side".
    let dir = tempfile::tempdir().unwrap();
    let scene = |freezing: &str| {
        format!(
            r#"[mesh]
file = "{}"

[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10

[[dirichlet]]
region = "bottom"

{freezing}

[time]
dt = 0.1
end_time = 0.2
"#,
            fixture("named_faces.msh")
        )
    };
    let prescribed = "[freezing]\ncooling = [\"bottom\", \"side\"]\nfront_speed = 1e-3";
    let thermal = "[thermal]\ninitial_temperature = 1.0\n\n[[thermal.fixed]]\nfaces = [\"top\", \"side\"]\ntemperature = -10.0";
    for freezing in [prescribed, thermal] {
        let path = write_scene(dir.path(), "named.toml", &scene(freezing));
        let o = run(&path, &["--force"]);
        let text = stderr(&o);
        assert!(o.status.success(), "{freezing}\n{text}");
        assert!(text.contains("physical surface of that name"), "{text}");
    }
    // A box-face word the mesh does not define cannot be mixed with its groups.
    let mixed = prescribed.replace("\"side\"", "\"walls\"");
    let o = run(
        &write_scene(dir.path(), "mixed.toml", &scene(&mixed)),
        &["--force"],
    );
    assert!(
        !o.status.success() && stderr(&o).contains("\"walls\" (a box face"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn a_build_without_mpi_started_by_mpirun_refuses_once() {
    // The variables Open MPI's mpirun sets for each of 2 processes (MPICH's PMI_SIZE and
    // PMI_RANK are read alike); `mpirun -n 2` itself is run in `make test-mpi`'s machine only.
    if cfg!(feature = "mpi") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(
        dir.path(),
        "s.toml",
        &falling_into("water_in_cup.msh", 1.0, "cup_occ.msh"),
    );
    let mut messages = Vec::new();
    for rank in ["0", "1"] {
        let o = exe()
            .arg("run")
            .arg(&scene)
            .env("OMPI_COMM_WORLD_SIZE", "2")
            .env("OMPI_COMM_WORLD_RANK", rank)
            .current_dir(dir.path())
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1));
        messages.push(stderr(&o));
    }
    assert!(
        messages[0].contains("built without MPI") && messages[0].contains("--features mpi"),
        "{}",
        messages[0]
    );
    assert!(messages[1].is_empty(), "{}", messages[1]);
    assert!(!dir.path().join("s.h5").exists());
}

#[test]
fn a_run_that_does_not_crack_says_why() {
    // The paper's container with a toughness no stress reaches: the summary gives the largest
    // separation stress against it.
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/freezing_container_fracture.toml"),
    )
    .unwrap();
    let text = text.replace("end_time = 80.0", "end_time = 10.0");
    let text = replace_line(&text, "toughness = ", "toughness = 3e9");
    let o = run(&write_scene(dir.path(), "tough.toml", &text), &[]);
    let out = stderr(&o);
    assert!(o.status.success(), "{out}");
    assert!(
        out.contains("no cracks: the largest separation stress")
            && out.contains("below the toughness 3000.000 MPa")
            && out.contains("[plasticity] caps"),
        "{out}"
    );
    assert!(
        out.contains("frozen: ") && out.contains("largest inelastic strain"),
        "{out}"
    );
}

/// `text` with the rest of the line after `key` replaced by `value` (the line then reads
/// `value`).
fn replace_line(text: &str, key: &str, value: &str) -> String {
    text.lines()
        .map(|line| {
            if line.trim_start().starts_with(key) {
                value.to_string()
            } else {
                line.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// `icefem mesh SURFACE --size SIZE --output OUT [extra…]`.
fn mesh(surface: &Path, size: &str, out: &Path, extra: &[&str]) -> Output {
    exe()
        .arg("mesh")
        .arg(surface)
        .args(["--size", size, "--output"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

/// The gmsh wheel `make gmsh` installs beside the build (`make test` runs it first).
fn require_gmsh() {
    let venv = Path::new(env!("CARGO_BIN_EXE_icefem"))
        .parent()
        .and_then(Path::parent)
        .unwrap()
        .join("gmsh-venv/bin/gmsh");
    assert!(
        venv.is_file() || std::env::var_os("GMSH").is_some(),
        "icefem mesh needs Gmsh: run `make gmsh` (make test does) or set GMSH"
    );
}

/// Tets and their total volume of a Gmsh file.
fn tets_and_volume(path: &Path) -> (usize, f64) {
    let (nodes, tets) = icefem::mesh::gmsh::read_msh(path).unwrap();
    let volume = tets
        .iter()
        .map(|t| {
            let [a, b, c, d] = t.map(|i| nalgebra::Vector3::from(nodes[i]));
            ((b - a).cross(&(c - a)).dot(&(d - a)) / 6.0).abs()
        })
        .sum();
    (tets.len(), volume)
}

#[test]
fn a_closed_surface_becomes_a_tet_mesh_a_scene_runs_on() {
    require_gmsh();
    let dir = tempfile::tempdir().unwrap();
    let stl = fixture("blob.stl");
    let surface = icefem::mesh::surface::TriSurface::read(Path::new(&stl), 1.0).unwrap();
    let enclosed = surface.enclosed_volume();
    // Remeshed at 6 mm (a 4 × 3 × 2.4 cm ellipsoid): the surface's nodes lie on its facets,
    // so chords cut its curve; 5 % bounds that at this size (measured 3.8 %).
    let out = dir.path().join("blob.msh");
    let o = mesh(Path::new(&stl), "0.006", &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (tets, volume) = tets_and_volume(&out);
    assert!(tets > 100, "{tets} tets");
    assert!(
        (volume / enclosed - 1.0).abs() < 0.05,
        "{volume} vs {enclosed}"
    );
    // The mesh is a body a scene runs on.
    let scene = format!(
        "[mesh]\nfile = \"{}\"\n\n[material]\ndensity = 916.0\nlambda = 8.64e10\nmu = 3.70e10\n\n[physics]\ngravity = [0.0, 0.0, -9.81]\n\n[time]\ndt = 0.01\nend_time = 0.03\n",
        out.display()
    );
    let o = run(&write_scene(dir.path(), "blob.toml", &scene), &[]);
    assert!(o.status.success(), "{}", stderr(&o));

    // The same surface as OBJ with a third of its triangles reversed, and as PLY: kept as
    // the boundary, the tets fill exactly the volume it encloses (single-precision STL on
    // the way to Gmsh: 1e-6).
    let mut obj = String::new();
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        surface.vertices.len(),
        surface.triangles.len()
    );
    for v in &surface.vertices {
        obj += &format!("v {} {} {}\n", v.x, v.y, v.z);
        ply += &format!("{} {} {}\n", v.x, v.y, v.z);
    }
    for (k, t) in surface.triangles.iter().enumerate() {
        let t = if k % 3 == 0 { [t[0], t[2], t[1]] } else { *t };
        obj += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        ply += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    for (name, text) in [("mixed.obj", &obj), ("mixed.ply", &ply)] {
        let file = write_scene(dir.path(), name, text);
        let out = dir.path().join(format!("{name}.msh"));
        let o = mesh(&file, "0.006", &out, &["--keep-surface"]);
        let said = stderr(&o);
        assert!(o.status.success(), "{said}");
        assert!(said.contains("107 of 320 triangles faced inward"), "{said}");
        let (_, volume) = tets_and_volume(&out);
        assert!(
            (volume / enclosed - 1.0).abs() < 1e-6,
            "{name}: {volume} vs {enclosed}"
        );
    }
}

#[test]
fn surfaces_that_cannot_be_meshed_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let stl = fixture("blob.stl");
    let surface = icefem::mesh::surface::TriSurface::read(Path::new(&stl), 1.0).unwrap();
    let obj = |scale: f64, skip: usize| {
        let mut text = String::new();
        for v in &surface.vertices {
            text += &format!("v {} {} {}\n", scale * v.x, scale * v.y, scale * v.z);
        }
        for t in surface.triangles.iter().skip(skip) {
            text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        text
    };
    let out = dir.path().join("out.msh");
    // A hole: one triangle missing (Gmsh itself would exit 0 with no tets).
    let open = write_scene(dir.path(), "open.obj", &obj(1.0, 1));
    let o = mesh(&open, "0.006", &out, &[]);
    assert!(
        !o.status.success() && stderr(&o).contains("not closed: 3 edges"),
        "{}",
        stderr(&o)
    );
    // A surface in millimetres with a size in metres: 1e14 tets, refused before Gmsh runs.
    let mm = write_scene(dir.path(), "mm.obj", &obj(1000.0, 0));
    let o = mesh(&mm, "0.006", &out, &[]);
    assert!(
        !o.status.success()
            && stderr(&o).contains("a surface in millimetres needs a size in millimetres"),
        "{}",
        stderr(&o)
    );
    // No Gmsh where it is said to be; an output that is not a Gmsh file.
    let o = mesh(Path::new(&stl), "0.006", &out, &["--gmsh", "/nowhere/gmsh"]);
    assert!(
        !o.status.success() && stderr(&o).contains("Gmsh not found (tried /nowhere/gmsh)"),
        "{}",
        stderr(&o)
    );
    let o = mesh(Path::new(&stl), "0.006", &dir.path().join("out.vtu"), &[]);
    assert!(
        !o.status.success() && stderr(&o).contains(".msh"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
}

#[test]
fn a_gmsh_ball_cooled_in_air_makes_no_warmer_node() {
    // The gallery's Gmsh ball (969 tets, 489 edges with an obtuse angle) at 1 °C in −20 °C
    // air: plain P1 conduction left its warmest node 0.23 K warmer from one frame to the next
    // (water at 0.53 °C after 80 min). Nothing here may warm by more than the heat step's
    // extremum check (1e-9 K).
    let dir = tempfile::tempdir().unwrap();
    let gallery = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gallery");
    let text = std::fs::read_to_string(gallery.join("water_sphere_thermal.toml"))
        .unwrap()
        .replace(
            "file = \"water_sphere.msh\"",
            &format!("file = \"{}\"", gallery.join("water_sphere.msh").display()),
        )
        .replace("end_time = 14400.0", "end_time = 7200.0")
        .replace("output_every = 5", "output_every = 1");
    let scene = write_scene(dir.path(), "ball.toml", &text);
    let o = run(&scene, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let reader = icefem::output::FrameReader::open(&scene.with_extension("h5")).unwrap();
    let warmest: Vec<f64> = reader
        .frame_indices()
        .into_iter()
        .map(|i| {
            let frame = reader.read(i).unwrap();
            let (_, t) = frame.node_field("temperature").unwrap();
            t.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v))
        })
        .collect();
    assert_eq!(warmest.len(), 121);
    for pair in warmest.windows(2) {
        assert!(
            pair[1] <= pair[0] + 1e-9,
            "the warmest node warmed: {pair:?}"
        );
    }
}

#[test]
fn a_deliberately_obtuse_mesh_heated_in_the_middle_makes_no_new_extremum() {
    // A 3 cm box of 6³ cells (the generator's orthoschemes) with its interior nodes moved
    // randomly by up to 0.15 of a cell: obtuse angles everywhere inside. Written as a Gmsh file, a warm
    // core in cold water cooled in −20 °C air: no node may end a frame warmer than the
    // warmest or colder than the coldest node (or the air) of the frame before.
    let dir = tempfile::tempdir().unwrap();
    let moved = common::irregular_box([6, 6, 6], [0.03; 3], 0.15, 23);
    let mut msh = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    msh += &format!("{}\n", moved.rest.len());
    // The warm core: 5 °C at the nodes within 8 mm of the centre (an irregular set on the
    // moved nodes, one 0.2 µm box each), 0.5 °C elsewhere.
    let mut warm = String::new();
    for (i, x) in moved.rest.iter().enumerate() {
        msh += &format!("{} {} {} {}\n", i + 1, x.x, x.y, x.z);
        if x.iter().map(|c| (c - 0.015).powi(2)).sum::<f64>() < 0.008f64.powi(2) {
            let corner = |d: f64| format!("[{}, {}, {}]", x[0] + d, x[1] + d, x[2] + d);
            warm += &format!(
                "[[thermal.initial]]\nmin = {}\nmax = {}\ntemperature = 5.0\n",
                corner(-1e-7),
                corner(1e-7)
            );
        }
    }
    msh += &format!("$EndNodes\n$Elements\n{}\n", moved.tets.len());
    for (e, t) in moved.tets.iter().enumerate() {
        msh += &format!(
            "{} 4 2 1 1 {} {} {} {}\n",
            e + 1,
            t[0] + 1,
            t[1] + 1,
            t[2] + 1,
            t[3] + 1
        );
    }
    msh += "$EndElements\n";
    let mesh = write_scene(dir.path(), "moved.msh", &msh);
    let scene = format!(
        r#"[mesh]
file = "{}"

[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
volumetric = "nodal"

[[dirichlet]]
min = [-0.001, -0.001, -0.001]
max = [0.031, 0.031, 0.0001]
displacement = [0.0, 0.0, 0.0]

[thermal]
initial_temperature = 0.5
{}[[thermal.convection]]
faces = ["surface"]
h = 200.0
ambient_temperature = -20.0

[time]
analysis = "static"
dt = 2.0
end_time = 60.0
"#,
        mesh.display(),
        warm
    );
    let scene = write_scene(dir.path(), "moved.toml", &scene);
    let o = run(&scene, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let reader = icefem::output::FrameReader::open(&scene.with_extension("h5")).unwrap();
    let ranges: Vec<(f64, f64)> = reader
        .frame_indices()
        .into_iter()
        .map(|i| {
            let frame = reader.read(i).unwrap();
            let (_, t) = frame.node_field("temperature").unwrap();
            t.iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                    (lo.min(v), hi.max(v))
                })
        })
        .collect();
    assert_eq!(ranges.len(), 31);
    drop(reader);
    // The mesh provokes new extrema: some steps cancel couplings and solve again.
    let stats = hdf5::File::open(scene.with_extension("h5")).unwrap();
    let passes: Vec<u32> = stats
        .dataset("stats/heat_passes")
        .unwrap()
        .read_raw()
        .unwrap();
    let cancelled: Vec<u64> = stats
        .dataset("stats/heat_cancelled_edges")
        .unwrap()
        .read_raw()
        .unwrap();
    assert!(passes.iter().any(|&p| p > 1), "{passes:?}");
    assert!(cancelled.iter().sum::<u64>() > 0);
    for pair in ranges.windows(2) {
        let ((lo, hi), (new_lo, new_hi)) = (pair[0], pair[1]);
        assert!(
            new_hi <= hi + 1e-9 && new_lo >= lo.min(-20.0) - 1e-9,
            "{pair:?}"
        );
    }
}
