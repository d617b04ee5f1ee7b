//! Scene files: every shipped scene runs, and every class of bad input gives an error that
//! names the file and the field — never a panic.

use icefem::run::{run, RunOptions};
use icefem::scene::{Scene, SceneError};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

const GOOD: &str = r#"
[mesh]
box = { size = [0.1, 0.02, 0.02], cells = [5, 1, 1] }
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
[physics]
gravity = [0.0, 0.0, -9.81]
[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1e-9, 1.0, 1.0]
[time]
dt = 0.01
end_time = 0.03
"#;

fn parse(text: &str) -> Result<Scene, SceneError> {
    Scene::parse(text, Path::new("/somewhere/test_scene.toml"))
}

/// The error text for `text`, checked to name the file and (if given) the field.
fn error_of(text: &str, field: Option<&str>) -> String {
    let err = parse(text)
        .expect_err("scene should be rejected")
        .to_string();
    assert!(err.contains("test_scene.toml"), "no file name in: {err}");
    if let Some(f) = field {
        assert!(err.contains(f), "field `{f}` not named in: {err}");
    }
    err
}

#[test]
fn good_scene_parses_with_defaults() {
    let scene = parse(GOOD).unwrap();
    assert_eq!(scene.model.mesh.num_tets(), 30);
    assert_eq!(scene.output_every, 1);
    assert_eq!(scene.output, PathBuf::from("test_scene.h5"));
    assert_eq!(
        scene.model.elasticity.model,
        icefem::fem::ElasticModel::Corotated
    );
}

#[test]
fn restart_points_and_frame_contents_default_and_are_checked() {
    // A frame every step: restart points every 10 steps, no derived copies, drawn fields in
    // single precision.
    let scene = parse(GOOD).unwrap();
    assert_eq!(scene.restart_every, 10);
    let options = scene.frame_options;
    assert!(!options.tensor_matrices && !options.derived_scalars && options.drawn_single);
    assert!(scene.notices.is_empty(), "{:?}", scene.notices);
    // Frames every 3 steps: the copies stored; restart points fall on every 30th step only,
    // which a notice says.
    let every3 =
        parse(&GOOD.replace("end_time = 0.03", "end_time = 0.03\noutput_every = 3")).unwrap();
    assert!(every3.frame_options.tensor_matrices && every3.frame_options.derived_scalars);
    assert!(
        every3
            .notices
            .iter()
            .any(|n| n.contains("restart_every") && n.contains("every 30 steps")),
        "{:?}",
        every3.notices
    );
    let chosen = parse(
        &(GOOD.replace("end_time = 0.03", "end_time = 0.03\nrestart_every = 4")
            + "[output]\ndrawn_precision = \"double\"\nderived_scalars = true\n"),
    )
    .unwrap();
    assert_eq!(chosen.restart_every, 4);
    assert!(chosen.frame_options.derived_scalars && !chosen.frame_options.drawn_single);
    error_of(
        &GOOD.replace("end_time = 0.03", "end_time = 0.03\nrestart_every = 0"),
        Some("time.restart_every"),
    );
    let err = error_of(
        &(GOOD.to_string() + "[output]\ndrawn_precision = \"half\"\n"),
        Some("drawn_precision"),
    );
    assert!(err.contains("single") && err.contains("double"), "{err}");
}

#[test]
fn unknown_keys_are_rejected_with_their_name() {
    let err = error_of(
        &GOOD.replace("mu = 3.70e10", "mu = 3.70e10\nshear = 1.0"),
        Some("shear"),
    );
    assert!(err.contains("unknown field"), "{err}");
    error_of(&GOOD.replace("[time]", "[tiem]"), Some("tiem"));
}

#[test]
fn non_physical_values_name_field_and_range() {
    let young = GOOD.replace(
        "lambda = 8.64e10\nmu = 3.70e10",
        "youngs_modulus = 1e11\npoisson_ratio = 0.5",
    );
    let err = error_of(&young, Some("material.poisson_ratio"));
    assert!(err.contains("(−1, 0.5)"), "{err}");
    error_of(
        &GOOD.replace("density = 916.0", "density = -916.0"),
        Some("material.density"),
    );
    error_of(&GOOD.replace("dt = 0.01", "dt = -0.01"), Some("time.dt"));
    error_of(&GOOD.replace("dt = 0.01", "dt = 0.0"), Some("time.dt"));
    error_of(
        &GOOD.replace("mu = 3.70e10", "mu = nan"),
        Some("material.mu"),
    );
    error_of(
        &GOOD.replace("lambda = 8.64e10", "lambda = nan"),
        Some("material.lambda"),
    );
    error_of(
        &GOOD.replace("gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, inf, -9.81]"),
        Some("physics.gravity[1]"),
    );
    error_of(
        &GOOD.replace("end_time = 0.03", "end_time = nan"),
        Some("time.end_time"),
    );
    error_of(
        &GOOD.replace("lambda = 8.64e10", "lambda = -8.64e10"),
        Some("material.lambda"),
    );
    error_of(
        &GOOD.replace("cells = [5, 1, 1]", "cells = [5, 0, 1]"),
        Some("mesh.box.cells[1]"),
    );
    error_of(
        &GOOD.replace(
            "max = [1e-9, 1.0, 1.0]",
            "max = [1e-9, 1.0, 1.0]\naxes = \"xw\"",
        ),
        Some("dirichlet[0].axes"),
    );
    error_of(
        &GOOD.replace("max = [1e-9, 1.0, 1.0]", "max = [-2.0, 1.0, 1.0]"),
        Some("dirichlet[0].min"),
    );
    error_of(
        &GOOD.replace("[time]", "[solver]\ntolerance = 2.0\n[time]"),
        Some("solver.tolerance"),
    );
    let err = error_of(
        &GOOD.replace("[time]", "[solver]\nfactor_precision = \"half\"\n[time]"),
        Some("factor_precision"),
    );
    assert!(err.contains("single") && err.contains("double"), "{err}");
    error_of(&(GOOD.to_string() + "[[traction]]\nmin = [5.0, 5.0, 5.0]\nmax = [6.0, 6.0, 6.0]\ntraction = [0.0, 0.0, 1.0]\n"), Some("traction[0]"));
    // Time functions: points [time, factor] with non-decreasing times.
    let err = error_of(
        &(GOOD.to_string()
            + "[[traction]]\nmin = [0.0, -1.0, -1.0]\nmax = [1.0, 1.0, 1.0]\ntraction = [0.0, 0.0, 1.0]\namplitude = [[1.0, 0.0], [0.5, 1.0]]\n"),
        Some("traction[0].amplitude"),
    );
    assert!(err.contains("must not decrease"), "{err}");
    error_of(
        &GOOD.replace(
            "max = [1e-9, 1.0, 1.0]",
            "max = [1e-9, 1.0, 1.0]\namplitude = []",
        ),
        Some("dirichlet[0].amplitude"),
    );
    let err = error_of(
        &GOOD.replace(
            "gravity = [0.0, 0.0, -9.81]",
            "gravity = [0.0, 0.0, -9.81]\ngravity_amplitude = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [1.0, 2.0]]",
        ),
        Some("physics.gravity_amplitude"),
    );
    assert!(err.contains("three points"), "{err}");
    error_of(
        &(GOOD.to_string()
            + "[[eigenstrain]]\nmin = [5.0, 5.0, 5.0]\nmax = [6.0, 6.0, 6.0]\nvalue = 0.01\n"),
        Some("eigenstrain[0]"),
    );
    error_of(
        &(GOOD.to_string()
            + "[[eigenstrain]]\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nvalue = 0.7\n"),
        Some("eigenstrain[0].value"),
    );
    // Freezing, plasticity and contact parameters.
    for (extra, field) in [
        ("[physics]\nice_stiffness = -1.0", "physics.ice_stiffness"),
        (
            "[plasticity]\nelastic_limit = 0.0",
            "plasticity.elastic_limit",
        ),
        (
            "[plasticity]\nelastic_limit = 1e-3\nmax_plastic_strain = -1.0",
            "plasticity.max_plastic_strain",
        ),
        (
            "[freezing]\ncooling = [\"sides\"]\nfront_speed = 1e-3",
            "freezing.cooling",
        ),
        (
            "[freezing]\ncooling = []\nfront_speed = 1e-3",
            "freezing.cooling",
        ),
        (
            "[freezing]\ncooling = [\"top\"]\nfront_speed = 0.0",
            "freezing.front_speed",
        ),
        (
            "[freezing]\ncooling = [\"top\"]\nfront_speed = 1e-3\nexpansion_ratio = 3.0",
            "freezing.expansion_ratio",
        ),
        (
            "[freezing]\ncooling = [\"top\"]\nfront_speed = 1e-3\nwater = \"ice\"",
            "freezing.water",
        ),
        (
            "[freezing]\ncooling = [\"top\"]\nfront_speed = 1e-3\nmin = [0.0, 0.0, 0.0]",
            "freezing.min",
        ),
    ] {
        let text = if extra.starts_with("[physics]") {
            GOOD.replace("[physics]", extra)
        } else {
            format!("{GOOD}\n{extra}\n")
        };
        error_of(&text, Some(field));
    }
    // Wrong types and missing sections come from the TOML layer, still with the file name.
    error_of(
        &GOOD.replace("density = 916.0", "density = \"heavy\""),
        Some("density"),
    );
    error_of(
        &GOOD.replace("[time]\ndt = 0.01\nend_time = 0.03\n", ""),
        Some("time"),
    );
    error_of(&GOOD.replace("lambda = 8.64e10\n", ""), Some("material"));
}

#[test]
fn missing_and_bad_mesh_files_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("scene.toml");
    let text = GOOD.replace(
        "box = { size = [0.1, 0.02, 0.02], cells = [5, 1, 1] }",
        "file = \"nowhere.msh\"",
    );
    let err = Scene::parse(&text, &scene_path).unwrap_err().to_string();
    assert!(
        err.contains("scene.toml") && err.contains("mesh.file") && err.contains("nowhere.msh"),
        "{err}"
    );
    // A negatively oriented tet in a Gmsh file (element tag 7, nodes 11–14) is used with two
    // vertices swapped, and the scene says so in one line.
    let msh = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n11 0 0 0\n12 1 0 0\n13 0 1 0\n14 0 0 1\n$EndNodes\n$Elements\n1\n7 4 2 0 1 11 13 12 14\n$EndElements\n";
    std::fs::write(dir.path().join("inverted.msh"), msh).unwrap();
    let text = text
        .replace("nowhere.msh", "inverted.msh")
        .replace("max = [1e-9, 1.0, 1.0]", "max = [1e-9, 1.0, 1e-9]");
    let scene = Scene::parse(&text, &scene_path).unwrap();
    assert_eq!(scene.model.mesh.num_tets(), 1);
    assert!(scene.model.mesh.signed_volume(0) > 0.0);
    assert_eq!(scene.notices.len(), 1, "{:?}", scene.notices);
    assert!(
        scene.notices[0].contains("inverted.msh") && scene.notices[0].contains("1 of 1 tetrahedra"),
        "{:?}",
        scene.notices
    );
    // Correctly oriented: no notice.
    std::fs::write(
        dir.path().join("ok.msh"),
        msh.replace("11 13 12 14", "11 12 13 14"),
    )
    .unwrap();
    let scene = Scene::parse(&text.replace("inverted.msh", "ok.msh"), &scene_path).unwrap();
    assert!(scene.notices.is_empty(), "{:?}", scene.notices);
    // A flat tet stays an error, told by the file's element and node tags.
    std::fs::write(
        dir.path().join("flat.msh"),
        msh.replace("14 0 0 1", "14 1 1 0"),
    )
    .unwrap();
    let err = Scene::parse(&text.replace("inverted.msh", "flat.msh"), &scene_path)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("scene.toml")
            && err.contains("flat.msh")
            && err.contains("element 7 is degenerate")
            && err.contains("[11, 13, 12, 14]"),
        "{err}"
    );
}

#[test]
fn mesh_obstacle_errors_name_field_and_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("scene.toml");
    let with = |extra: &str| format!("{GOOD}\n[[obstacle]]\n{extra}\n");
    let err = |text: &str| Scene::parse(text, &scene_path).unwrap_err().to_string();
    // Missing file, missing `file`, keys of another obstacle type, bad scale.
    let e = err(&with("type = \"mesh\"\nfile = \"nowhere.obj\""));
    assert!(
        e.contains("scene.toml") && e.contains("obstacle[0].file") && e.contains("nowhere.obj"),
        "{e}"
    );
    let e = err(&with("type = \"mesh\""));
    assert!(
        e.contains("obstacle[0].file") && e.contains("missing"),
        "{e}"
    );
    let e = err(&with(
        "type = \"halfspace\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nfile = \"a.obj\"",
    ));
    assert!(e.contains("obstacle[0].file") && e.contains("mesh"), "{e}");
    std::fs::write(
        dir.path().join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let e = err(&with("type = \"mesh\"\nfile = \"tri.obj\"\nscale = -1.0"));
    assert!(e.contains("obstacle[0].scale"), "{e}");
    // A closed surface with inward normals (a tetrahedron wound the wrong way) is turned to
    // face out, with a notice; so is one whose triangles disagree (the first of these faces
    // in, the other three out).
    for (name, faces, reversed) in [
        (
            "inward.obj",
            "f 1 2 3\nf 1 4 2\nf 2 4 3\nf 3 4 1\n",
            "4 of 4 triangles",
        ),
        (
            "mixed.obj",
            "f 1 2 3\nf 1 2 4\nf 2 3 4\nf 3 1 4\n",
            "1 of 4 triangles",
        ),
    ] {
        let vertices = "v 0 0 -1\nv 1 0 -1\nv 0 1 -1\nv 0 0 0\n";
        std::fs::write(dir.path().join(name), format!("{vertices}{faces}")).unwrap();
        let text = with(&format!("type = \"mesh\"\nfile = \"{name}\""));
        let scene = Scene::parse(&text, &scene_path).unwrap();
        assert!(
            scene
                .notices
                .iter()
                .any(|n| n.contains(name) && n.contains(reversed)),
            "{:?}",
            scene.notices
        );
    }
    // An open floor under the bar whose normal points down, away from the ice: the error
    // says which side the ice must be on.
    std::fs::write(
        dir.path().join("floor_down.obj"),
        "v -1 -1 -0.001\nv -1 2 -0.001\nv 2 -1 -0.001\nf 1 2 3\n",
    )
    .unwrap();
    let e = err(&with("type = \"mesh\"\nfile = \"floor_down.obj\""));
    assert!(
        e.contains("obstacle[0]") && e.contains("reverse the triangles"),
        "{e}"
    );
    // The open triangle loads, moved by `translate`.
    let scene = Scene::parse(
        &with("type = \"mesh\"\nfile = \"tri.obj\"\ntranslate = [0.0, 0.0, -1.0]"),
        &scene_path,
    )
    .unwrap();
    let surface = scene.model.obstacle_contact().unwrap().obstacles[0]
        .surface()
        .unwrap();
    assert_eq!(surface.vertices[1], nalgebra::Vector3::new(1.0, 0.0, -1.0));
}

#[test]
fn static_scene_without_supports_is_a_clear_error() {
    let text = GOOD
        .replace(
            "[[dirichlet]]\nmin = [-1.0, -1.0, -1.0]\nmax = [1e-9, 1.0, 1.0]\n",
            "",
        )
        .replace("dt = 0.01", "analysis = \"static\"\ndt = 0.01");
    let scene = parse(&text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let options = RunOptions {
        output: Some(dir.path().join("x.h5")),
        ..Default::default()
    };
    let err = run(&scene, &options, &AtomicBool::new(false), |_| {})
        .unwrap_err()
        .to_string();
    assert!(err.contains("singular: no Dirichlet conditions"), "{err}");
}

#[test]
fn every_shipped_scene_runs_a_few_steps() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut count = 0;
    for entry in std::fs::read_dir(scenes).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let scene = Scene::load(&path).unwrap();
        let options = RunOptions {
            output: Some(
                dir.path()
                    .join(path.file_stem().unwrap())
                    .with_extension("h5"),
            ),
            end_time: Some(3.0 * scene.settings.dt.min(scene.end_time)),
            ..Default::default()
        };
        let summary = run(&scene, &options, &AtomicBool::new(false), |_| {}).unwrap();
        assert!(
            summary.steps >= 1 && summary.max_residual.is_finite(),
            "{}: {summary:?}",
            path.display()
        );
        count += 1;
    }
    assert!(count >= 2);
}

#[test]
fn cli_exits_non_zero_with_a_message_on_bad_input() {
    let exe = env!("CARGO_BIN_EXE_icefem");
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, GOOD.replace("density = 916.0", "density = -1.0")).unwrap();
    let out = std::process::Command::new(exe)
        .arg("run")
        .arg(&bad)
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("bad.toml") && stderr.contains("material.density"),
        "{stderr}"
    );
    let out = std::process::Command::new(exe)
        .args(["info", "/nonexistent.h5"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let out = std::process::Command::new(exe)
        .arg("info")
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("bad.toml"));
}

#[test]
fn fracture_section_defaults_and_errors() {
    let with = |body: &str| GOOD.replace("[time]", &format!("[fracture]\n{body}\n[time]"));
    let scene = parse(&with("toughness = 3e6")).unwrap();
    let f = scene.fracture.expect("fracture on");
    assert_eq!(
        (f.toughness, f.max_events_per_step, f.snap, f.min_quality),
        (3e6, 8, 0.2, 0.1)
    );
    // Default rendering gap: 1e-3 × the mesh's bounding-box diagonal.
    let diagonal = (0.1f64 * 0.1 + 2.0 * 0.02 * 0.02).sqrt();
    assert!((f.render_gap - 1e-3 * diagonal).abs() < 1e-15);
    assert!(parse(GOOD).unwrap().fracture.is_none());
    for (body, field) in [
        ("toughness = -1.0", "fracture.toughness"),
        ("toughness = nan", "fracture.toughness"),
        ("toughness = 3e6\nsnap = 0.5", "fracture.snap"),
        ("toughness = 3e6\nmin_quality = 1.0", "fracture.min_quality"),
        (
            "toughness = 3e6\nmax_events_per_step = 0",
            "fracture.max_events_per_step",
        ),
        ("toughness = 3e6\nrender_gap = -1e-3", "fracture.render_gap"),
        ("toughness = 3e6\nstrength = 1.0", "strength"),
        ("snap = 0.1", "toughness"),
    ] {
        error_of(&with(body), Some(field));
    }
}

#[test]
fn body_errors_name_their_field() {
    let body = "[[body]]\nbox = { size = [0.1, 0.02, 0.02], cells = [5, 1, 1] }\n";
    let bodies = |extra: &str| {
        GOOD.replace(
            "[mesh]\nbox = { size = [0.1, 0.02, 0.02], cells = [5, 1, 1] }\n",
            &format!("{body}{extra}"),
        )
    };
    // The plain body parses; with `[mesh]` as well, or with neither, it is an error.
    assert_eq!(parse(&bodies("")).unwrap().model.mesh.num_tets(), 30);
    error_of(&format!("{body}{GOOD}"), Some("body"));
    error_of(&bodies("").replace(body, ""), Some("mesh"));
    error_of(&bodies("file = \"a.msh\"\n"), Some("body[0]"));
    error_of(&bodies("scale = 2.0\n"), Some("body[0].scale"));
    let err = error_of(
        &bodies("rotate = { axis = [0.0, 0.0, 0.0], degrees = 10.0 }\n"),
        Some("body[0].rotate.axis"),
    );
    assert!(err.contains("zero"), "{err}");
    error_of(
        &bodies("velocity = [nan, 0.0, 0.0]\n"),
        Some("body[0].velocity[0]"),
    );
    error_of(&bodies("spin = [0.0, 0.0, 1.0]\n"), Some("spin"));
    // An initial velocity in a static analysis.
    let err = error_of(
        &bodies("velocity = [1.0, 0.0, 0.0]\n").replace("[time]", "[time]\nanalysis = \"static\""),
        Some("body"),
    );
    assert!(err.contains("dynamic"), "{err}");
    // A second body moved 1 cm into the first.
    let err = error_of(
        &bodies(&format!("{body}translate = [0.09, 0.0, 0.0]\n")),
        Some("body"),
    );
    assert!(err.contains("bodies must start apart"), "{err}");
    // Placed 1 m away it is fine.
    assert_eq!(
        parse(&bodies(&format!("{body}translate = [1.0, 0.0, 0.0]\n")))
            .unwrap()
            .model
            .mesh
            .num_tets(),
        60
    );
}

/// A scene on the fixture box split into named groups ("left", "right" volumes; "end",
/// "floor" surfaces), read as if it were in the fixtures' folder.
const GROUPS: &str = r#"
[mesh]
file = "groups_v41_ascii.msh"
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
[[dirichlet]]
region = "floor"
[time]
dt = 0.01
end_time = 0.03
"#;

fn parse_with_groups(text: &str) -> Result<Scene, SceneError> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("solver_tests/data/msh");
    Scene::parse(text, &dir.join("test_scene.toml"))
}

/// The error text for a scene on the groups fixture, checked to name the file and `field`.
fn group_error(text: &str, field: &str) -> String {
    let err = parse_with_groups(text)
        .expect_err("should be rejected")
        .to_string();
    assert!(
        err.contains("test_scene.toml") && err.contains(field),
        "{field}: {err}"
    );
    err
}

#[test]
fn named_regions_select_what_their_groups_hold() {
    use icefem::physics::loads::traction_faces;
    let scene = parse_with_groups(&format!(
        "{GROUPS}[[traction]]\nregion = \"end\"\ntraction = [1e5, 0.0, 0.0]\n\
         [[eigenstrain]]\nregion = \"right\"\nvalue = 0.01\n\
         [materials.stiff]\ndensity = 2000.0\nyoungs_modulus = 2e11\npoisson_ratio = 0.3\nregion = \"left\"\n"
    ))
    .unwrap();
    let m = &scene.model;
    let rest = &m.mesh.rest;
    // The floor support holds exactly the nodes at z = 0.
    let held: Vec<usize> = m.dirichlet[0].nodes(&m.mesh).collect();
    let floor: Vec<usize> = (0..m.num_nodes()).filter(|&i| rest[i].z == 0.0).collect();
    assert_eq!(held, floor);
    // The traction acts on the end face, 0.1 × 0.05 m² (round-off tolerance).
    let (count, area) = traction_faces(&m.mesh, &m.tractions[0].region);
    assert!(
        count > 0 && (area - 0.005).abs() < 1e-15,
        "{count} faces, {area} m²"
    );
    // Eigenstrain and material by volume: right half 0.01, left half the stiff material.
    for (t, tet) in m.mesh.tets.iter().enumerate() {
        let x = tet.iter().map(|&i| rest[i].x).sum::<f64>() / 4.0;
        let expected = if x > 0.1 { 0.01 } else { 0.0 };
        assert_eq!(m.elasticity.eigenstrain[t], expected);
        let density = m.elasticity.base_material(t).density;
        assert_eq!(density, if x < 0.1 { 2000.0 } else { 916.0 });
    }
    // Lumped mass from each element's own density: 2000 and 916 kg/m³ on 5e-4 m³ each.
    assert!((m.total_mass() - (2000.0 + 916.0) * 5e-4).abs() < 1e-12);
}

#[test]
fn named_region_errors_name_the_field_and_the_groups() {
    let err = group_error(
        &GROUPS.replace("\"floor\"", "\"flor\""),
        "dirichlet[0].region",
    );
    assert!(
        err.contains("\"floor\" (surface)") && err.contains("\"left\" (volume)"),
        "{err}"
    );
    let err = group_error(
        &format!("{GROUPS}[[traction]]\nregion = \"left\"\ntraction = [1.0, 0.0, 0.0]\n"),
        "traction[0].region",
    );
    assert!(
        err.contains("is a volume; this entry needs a surface"),
        "{err}"
    );
    group_error(
        &format!("{GROUPS}[[eigenstrain]]\nregion = \"end\"\nvalue = 0.01\n"),
        "eigenstrain[0].region",
    );
    group_error(
        &GROUPS.replace(
            "region = \"floor\"",
            "region = \"floor\"\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]",
        ),
        "dirichlet[0].region",
    );
    group_error(&GROUPS.replace("region = \"floor\"", ""), "dirichlet[0]");
    // A box scene has no groups at all.
    let err = error_of(
        &GOOD
            .replace("[[dirichlet]]\n", "[[dirichlet]]\nregion = \"floor\"\n")
            .replace("min = [-1.0, -1.0, -1.0]\nmax = [1e-9, 1.0, 1.0]\n", ""),
        Some("dirichlet[0].region"),
    );
    assert!(err.contains("no named physical groups"), "{err}");
    // Cooling from a named surface; a volume or an unknown name is refused.
    let freezing = "[freezing]\ncooling = [\"floor\"]\nfront_speed = 1e-3\n";
    let scene = parse_with_groups(&format!("{GROUPS}{freezing}")).unwrap();
    let f = scene.model.freezing.unwrap();
    let (first, last) = f
        .arrival()
        .unwrap()
        .iter()
        .flatten()
        .fold((f64::MAX, 0.0f64), |(a, b), &t| (a.min(t), b.max(t)));
    assert!(
        first < 10.0 && last > 30.0,
        "the front starts at the floor: {first} … {last} s"
    );
    group_error(
        &format!("{GROUPS}{}", freezing.replace("floor", "left")),
        "freezing.cooling",
    );
    let err = group_error(
        &format!("{GROUPS}{}", freezing.replace("floor", "flor")),
        "freezing.cooling",
    );
    assert!(err.contains("unknown face \"flor\""), "{err}");
    group_error(
        &format!(
            "{GROUPS}{}",
            freezing.replace("[\"floor\"]", "[\"floor\", \"walls\"]")
        ),
        "freezing.cooling",
    );
}

#[test]
fn material_errors_name_their_field() {
    let stiff = "[materials.stiff]\ndensity = 2000.0\nyoungs_modulus = 2e11\npoisson_ratio = 0.3\n";
    let body = "[[body]]\nbox = { size = [0.1, 0.02, 0.02], cells = [5, 1, 1] }\n";
    let with_body = |extra: &str, materials: &str| {
        GOOD.replace(
            "[mesh]\nbox = { size = [0.1, 0.02, 0.02], cells = [5, 1, 1] }\n",
            &format!("{body}{extra}"),
        ) + materials
    };
    // A body of the named material: its density gives the mass.
    let scene = parse(&with_body("material = \"stiff\"\n", stiff)).unwrap();
    assert!((scene.model.total_mass() - 2000.0 * 0.1 * 0.02 * 0.02).abs() < 1e-12);
    let err = error_of(
        &with_body("material = \"steel\"\n", stiff),
        Some("body[0].material"),
    );
    assert!(err.contains("\"stiff\""), "{err}");
    let err = error_of(&with_body("", stiff), Some("materials.stiff"));
    assert!(err.contains("used nowhere"), "{err}");
    error_of(
        &with_body("material = \"stiff\"\n", &stiff.replace("0.3", "0.7")),
        Some("materials.stiff.poisson_ratio"),
    );
    error_of(
        &with_body("material = \"stiff\"\n", &stiff.replace("2000.0", "-1.0")),
        Some("materials.stiff.density"),
    );
    error_of(
        &with_body("material = \"stiff\"\n", &format!("{stiff}lambda = 1e9\n")),
        Some("materials.stiff"),
    );
    error_of(
        &with_body(
            "material = \"stiff\"\n",
            &format!("{stiff}model = \"linear\"\n"),
        ),
        Some("materials.stiff.model"),
    );
    error_of(
        &GOOD.replace("mu = 3.70e10\n", "mu = 3.70e10\nregion = \"base\"\n"),
        Some("material.region"),
    );
    let err = error_of(
        &(with_body("material = \"stiff\"\n", stiff)
            + "[freezing]\ncooling = [\"walls\"]\nfront_speed = 1e-3\n"),
        Some("freezing"),
    );
    assert!(err.contains("[materials.NAME]"), "{err}");
}

#[test]
fn obstacle_motion_errors_name_their_field() {
    let floor =
        "[[obstacle]]\ntype = \"halfspace\"\npoint = [0.0, 0.0, -0.1]\nnormal = [0.0, 0.0, 1.0]\n";
    let scene = parse(&format!(
        "{GOOD}{floor}angular_velocity = [0.0, 0.0, 2.0]\ncentre = [0.1, 0.0, 0.0]\namplitude = [[0.0, 0.0], [1.0, 1.0]]\n"
    ))
    .unwrap();
    let motion = &scene.model.obstacle_contact().unwrap().obstacles[0].motion;
    assert_eq!(motion.angular_velocity.z, 2.0);
    assert_eq!(motion.amplitude.at(0.5), 0.5);
    error_of(
        &format!("{GOOD}{floor}angular_velocity = [0.0, inf, 0.0]\n"),
        Some("obstacle[0].angular_velocity[1]"),
    );
    let err = error_of(
        &format!("{GOOD}{floor}centre = [0.0, 0.0, 0.0]\n"),
        Some("obstacle[0].centre"),
    );
    assert!(err.contains("angular_velocity"), "{err}");
    error_of(
        &format!("{GOOD}{floor}velocity = [0.0, 0.0, 1.0]\namplitude = [[1.0, 0.0], [0.0, 1.0]]\n"),
        Some("obstacle[0].amplitude"),
    );
    let err = error_of(
        &format!("{GOOD}{floor}amplitude = [[0.0, 1.0]]\n"),
        Some("obstacle[0].amplitude"),
    );
    assert!(err.contains("velocity"), "{err}");
}

#[test]
fn every_gallery_scene_runs_a_few_steps() {
    let gallery = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/gallery");
    // The scenes run where they are read; outputs go to a folder of their own, and the
    // released beam starts from the bent one's output, as the gallery says to run them.
    let dir = tempfile::tempdir().unwrap();
    for entry in std::fs::read_dir(&gallery).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml" || e == "msh") {
            std::fs::copy(&path, dir.path().join(path.file_name().unwrap())).unwrap();
        }
    }
    let mut names: Vec<String> = std::fs::read_dir(&gallery)
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "toml").then(|| p.file_stem().unwrap().to_string_lossy().into())
        })
        .collect();
    // beam_bent before beam_released.
    names.sort();
    assert!(names.len() >= 5, "{names:?}");
    for name in &names {
        let path = dir.path().join(name).with_extension("toml");
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let options = RunOptions {
            output: Some(path.with_extension("h5")),
            end_time: Some(3.0 * scene.settings.dt.min(scene.end_time)),
            ..Default::default()
        };
        let summary = run(&scene, &options, &AtomicBool::new(false), |_| {})
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            summary.steps >= 1 && summary.max_residual.is_finite(),
            "{name}: {summary:?}"
        );
    }
}

#[test]
fn command_line_quiet_verbose_and_json() {
    let exe = env!("CARGO_BIN_EXE_icefem");
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bar.toml");
    std::fs::write(&scene, GOOD).unwrap();
    let icefem = |args: &[&str]| {
        let out = std::process::Command::new(exe).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        (
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let h5 = dir.path().join("bar.h5");
    let (h5_arg, scene_arg) = (h5.to_str().unwrap(), scene.to_str().unwrap());
    // Quiet: nothing but the output file.
    let (stdout, stderr) = icefem(&["-q", "run", scene_arg, "-o", h5_arg]);
    assert!(stdout.is_empty() && stderr.is_empty(), "{stdout}{stderr}");
    assert!(h5.exists());
    // Verbose: a line for each of the 3 steps, with the time left.
    let (_, stderr) = icefem(&["run", scene_arg, "-o", h5_arg, "--force", "-v"]);
    let steps: Vec<&str> = stderr.lines().filter(|l| l.starts_with("step ")).collect();
    assert_eq!(steps.len(), 3, "{stderr}");
    assert!(steps.iter().all(|l| l.contains(" left")), "{stderr}");
    // info --json: one object with the counts.
    let (stdout, _) = icefem(&["info", "--json", h5_arg]);
    let info: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(info["elements"], 30);
    assert_eq!(info["complete_frames"], 4);
    assert_eq!(info["last"]["step"], 3);
    assert!(info["last_frame"]
        .as_array()
        .unwrap()
        .iter()
        .any(|d| d["name"] == "positions" && d["shape"][1] == 3));
    // bench --json: the table as columns and rows.
    let (stdout, _) = icefem(&[
        "bench",
        "--tets",
        "300",
        "--steps",
        "1",
        "--repeats",
        "1",
        "--json",
    ]);
    let bench: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let table = &bench["tables"][0];
    assert_eq!(table["columns"][0], "tets");
    assert!(table["rows"][0][0].as_f64().unwrap() > 0.0, "{bench}");
}

/// A scene's model describes its elements without their rest data (most of a model's
/// memory): a simulation builds it on the mesh it runs, and a process's part of a distributed
/// run for its own elements only — the same numbers, to the bit, as built on the whole mesh.
#[test]
fn a_scene_describes_its_elements_and_a_simulation_builds_their_rest_data() {
    use icefem::fem::ElementRest;
    use icefem::physics::elasticity::Volumetric;
    use icefem::sim::{part::Part, Simulation};
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/freezing_container.toml");
    let scene = Scene::load(&path).unwrap();
    let described = &scene.model.elasticity;
    assert!(!described.is_built() && described.rest.is_empty() && described.nodal.is_none());
    assert_eq!(described.volumetric(), Volumetric::Nodal);
    let mesh = &scene.model.mesh;
    let whole = ElementRest::of_mesh(mesh);
    let bits = |r: &ElementRest| {
        let grads = r.grads.iter().flat_map(|g| g.iter().map(|x| x.to_bits()));
        std::iter::once(r.volume.to_bits())
            .chain(grads)
            .collect::<Vec<_>>()
    };
    // The lumped masses come from the same volumes: ρ V / 4 a vertex, summed.
    let density = described.material.density;
    let from_rest: f64 = whole.iter().map(|r| density * r.volume).sum();
    let total: f64 = scene.model.mass.iter().sum();
    // The same 216 volumes summed in two orders (by node, by element): a few ulps apart.
    assert!(
        (total - from_rest).abs() <= 1e-14 * from_rest,
        "{total} vs {from_rest}"
    );
    let sim = Simulation::new(scene.model.clone(), scene.settings).unwrap();
    let built = &sim.model.elasticity;
    assert!(built.is_built() && built.nodal.is_some());
    assert!(built
        .rest
        .iter()
        .zip(&whole)
        .all(|(a, b)| bits(a) == bits(b)));
    // A part of the elements numbered below half, owners the lowest part among a node's
    // elements: the part's model holds the rest data of the part's elements only.
    let m = mesh.num_tets();
    let element_part: Vec<u32> = (0..m).map(|e| u32::from(e >= m / 2)).collect();
    let mut owner = vec![1u32; mesh.num_nodes()];
    for (tet, &p) in mesh.tets.iter().zip(&element_part) {
        for &v in tet {
            owner[v] = owner[v].min(p);
        }
    }
    let part = Part::new(&mesh.tets, (&element_part, &owner), 0, (&[], false));
    assert!(!part.is_whole());
    let model = part.model(&scene.model).unwrap();
    assert_eq!(model.elasticity.rest.len(), part.elements.len());
    assert!(model.elasticity.nodal.is_some());
    for (r, &e) in model.elasticity.rest.iter().zip(&part.elements) {
        assert_eq!(bits(r), bits(&whole[e]));
    }
}
