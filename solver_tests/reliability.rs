//! What a run does to files when users and machines misbehave, through the command line where
//! they meet it: an output that exists, is held by a reader, is written by another run or is
//! not an icefem file; a rerun that fails; a full disk; SIGTERM and SIGKILL; a reader of a live
//! run.

mod common;
use std::os::unix::process::CommandExt as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

use icefem::output::FrameReader;

use common::{listing, SAGGING_BAR as BAR};

/// The bar with a Newton limit it cannot meet: the run fails at step 1.
fn failing_bar() -> String {
    BAR.replace(
        "[time]",
        "[solver]\nmax_iterations = 1\ntolerance = 1e-12\n[time]",
    )
    .replace(
        "gravity = [0.0, -3.0, -9.81]",
        "gravity = [0.0, -3000.0, -9810.0]",
    )
    .replace("[material]", "[material]\nmodel = \"corotated\"")
}

/// The bar run long, a frame every step: still running when a test stops it.
fn long_bar() -> String {
    BAR.replace("end_time = 0.02", "end_time = 1000.0")
        .replace("output_every = 2", "output_every = 1")
}

fn exe() -> Command {
    Command::new(env!("CARGO_BIN_EXE_icefem"))
}

fn write_scene(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// `icefem run SCENE --output OUT [extra…]`.
fn run(scene: &Path, out: &Path, extra: &[&str]) -> Output {
    exe()
        .arg("run")
        .arg(scene)
        .arg("--output")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Starts `icefem run` on `scene` and returns once `out` holds at least `frames` complete
/// frames (the run has taken its target's place and is writing it).
fn start(mut command: Command, scene: &Path, out: &Path, frames: usize) -> Child {
    let child = command
        .arg("run")
        .arg(scene)
        .arg("--output")
        .arg(out)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
    while FrameReader::open(out).map_or(0, |r| r.frame_indices().len()) < frames {
        assert!(
            std::time::Instant::now() < deadline,
            "the run wrote no frames"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child
}

fn frames(path: &Path) -> usize {
    FrameReader::open(path).unwrap().frame_indices().len()
}

/// Every frame group the XDMF sidecar of `h5` names is a complete frame of the file (what
/// ParaView and meshio open).
fn assert_sidecar_matches(h5: &Path) {
    let xdmf = std::fs::read_to_string(h5.with_extension("xdmf")).unwrap();
    let named: Vec<usize> = xdmf
        .match_indices("Name=\"frame_")
        .map(|(i, _)| xdmf[i + 12..i + 18].parse().unwrap())
        .collect();
    assert!(!named.is_empty(), "sidecar lists no frame");
    let complete = FrameReader::open(h5).unwrap().frame_indices();
    assert!(
        named.iter().all(|i| complete.contains(i)),
        "sidecar frames {named:?}, complete {complete:?}"
    );
}

#[test]
fn an_existing_output_is_replaced_only_with_force_and_a_failing_rerun_keeps_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "bar.toml", BAR);
    let out = dir.path().join("bar.h5");
    assert!(run(&scene, &out, &[]).status.success());
    let original = std::fs::read(&out).unwrap();
    let sidecar = std::fs::read(out.with_extension("xdmf")).unwrap();
    assert_eq!(frames(&out), 6);

    // Without --force: refused, the file untouched.
    let o = run(&scene, &out, &[]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&out).unwrap(), original);

    // With --force, a rerun that fails at step 1: the old file and its sidecar stay as they
    // were, and nothing is left beside them.
    let failing = write_scene(dir.path(), "failing.toml", &failing_bar());
    let o = run(&failing, &out, &["--force"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("step 1"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&out).unwrap(), original);
    assert_eq!(std::fs::read(out.with_extension("xdmf")).unwrap(), sidecar);
    assert_eq!(
        listing(dir.path()),
        ["bar.h5", "bar.toml", "bar.xdmf", "failing.toml"]
    );

    // With --force, a run that succeeds replaces it.
    let short = write_scene(
        dir.path(),
        "short.toml",
        &BAR.replace("end_time = 0.02", "end_time = 0.008"),
    );
    assert!(run(&short, &out, &["--force"]).status.success());
    assert_eq!(frames(&out), 3);
    assert_sidecar_matches(&out);
}

#[test]
fn an_output_held_open_by_a_reader_is_not_damaged() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "bar.toml", BAR);
    let out = dir.path().join("bar.h5");
    assert!(run(&scene, &out, &[]).status.success());
    // A reader (h5py, ParaView) holds the file open, with HDF5's file locking on.
    let held = hdf5::File::open(&out).unwrap();
    let short = write_scene(
        dir.path(),
        "short.toml",
        &BAR.replace("end_time = 0.02", "end_time = 0.008"),
    );
    let o = run(&short, &out, &["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The reader still reads the old run whole; the path holds the new one.
    assert_eq!(
        held.group("frames").unwrap().member_names().unwrap().len(),
        6
    );
    let positions = held.dataset("frames/000005/positions").unwrap();
    assert_eq!(positions.read_raw::<f64>().unwrap().len(), 44 * 3);
    assert_eq!(frames(&out), 3);
}

#[test]
fn a_file_that_is_not_icefem_output_is_never_written_over() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "bar.toml", BAR);
    for force in [false, true] {
        let extra: &[&str] = if force { &["--force"] } else { &[] };
        // The scene itself as the output.
        let o = run(&scene, &scene, extra);
        assert!(!o.status.success());
        assert!(stderr(&o).contains("not an HDF5 file"), "{}", stderr(&o));
        assert_eq!(std::fs::read_to_string(&scene).unwrap(), BAR);
        // A directory.
        let o = run(&scene, dir.path(), extra);
        assert!(!o.status.success());
        assert!(stderr(&o).contains("not a regular file"), "{}", stderr(&o));
    }
    // An HDF5 file of someone else's.
    let other = dir.path().join("other.h5");
    hdf5::File::create(&other)
        .unwrap()
        .new_dataset::<f64>()
        .shape(3)
        .create("data")
        .unwrap();
    let before = std::fs::read(&other).unwrap();
    let o = run(&scene, &other, &["--force"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("not icefem output"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&other).unwrap(), before);
}

#[test]
fn a_second_run_on_a_file_being_written_is_refused_and_readers_see_its_frames() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "long.toml", &long_bar());
    let out = dir.path().join("long.h5");
    let mut first = start(exe(), &scene, &out, 20);
    for extra in [&[][..], &["--force"][..]] {
        let o = run(&scene, &out, extra);
        assert!(!o.status.success());
        assert!(
            stderr(&o).contains("another icefem run is writing this file"),
            "{}",
            stderr(&o)
        );
    }
    let resumed = exe()
        .args(["run"])
        .arg(&scene)
        .arg("--resume")
        .arg(&out)
        .output()
        .unwrap();
    assert!(stderr(&resumed).contains("another icefem run is writing this file"));
    // Readers open the live file and read its complete frames.
    let info = exe().arg("info").arg(&out).output().unwrap();
    assert!(info.status.success(), "{}", stderr(&info));
    let reader = FrameReader::open(&out).unwrap();
    let last = *reader.frame_indices().last().unwrap();
    reader.read(last).unwrap();
    // (Closed before the file is opened again below: HDF5 shares one open file per process,
    // with the metadata this open read.)
    drop(reader);
    // SIGTERM stops the run like Ctrl-C: after its step, with its last state written.
    // SAFETY: signalling our own child process.
    unsafe { libc::kill(first.id() as i32, libc::SIGTERM) };
    let status = first.wait().unwrap();
    assert_eq!(status.code(), Some(130));
    assert_sidecar_matches(&out);
    assert!(frames(&out) > last);
}

#[test]
fn sigterm_then_resume_ends_bit_identical_to_an_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let text = BAR
        .replace("end_time = 0.02", "end_time = 20.0")
        .replace("output_every = 2", "output_every = 10");
    let scene = write_scene(dir.path(), "bar.toml", &text);
    let whole = dir.path().join("whole.h5");
    assert!(run(&scene, &whole, &[]).status.success());
    let cut = dir.path().join("cut.h5");
    let mut child = start(exe(), &scene, &cut, 3);
    // SAFETY: signalling our own child process.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    assert_eq!(child.wait().unwrap().code(), Some(130));
    assert_sidecar_matches(&cut);
    let stopped = frames(&cut);
    assert!(stopped < 1001, "the run ended before the signal");
    let o = exe()
        .arg("run")
        .arg(&scene)
        .arg("--resume")
        .arg(&cut)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (
        FrameReader::open(&whole).unwrap(),
        FrameReader::open(&cut).unwrap(),
    );
    // The stopped run wrote its last state as a frame of its own: compare the last frames.
    let last = |r: &FrameReader| r.read(*r.frame_indices().last().unwrap()).unwrap();
    let (fa, fb) = (last(&a), last(&b));
    assert_eq!(fa.state.step, 10_000);
    assert_eq!(fb.state.step, 10_000);
    assert_eq!(fa.state.positions, fb.state.positions);
    assert_eq!(fa.state.velocities, fb.state.velocities);
}

#[test]
fn a_killed_run_leaves_a_sidecar_of_its_committed_frames() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "long.toml", &long_bar());
    let out = dir.path().join("long.h5");
    let mut child = start(exe(), &scene, &out, 50);
    std::thread::sleep(std::time::Duration::from_millis(1200));
    child.kill().unwrap(); // SIGKILL: nothing of the run's own runs after it
    child.wait().unwrap();
    assert!(frames(&out) >= 50);
    assert_sidecar_matches(&out);
    // A run killed before it took its target's place leaves its hidden file; the next run
    // that writes in that directory removes it, whatever its target, while the hidden file of
    // a process that still exists (this test's) stays.
    let early = dir.path().join("early.h5");
    let stale = dir.path().join(".early.h5.4000000.partial");
    let other = dir.path().join(".other.h5.4000001.partial");
    let alive = dir
        .path()
        .join(format!(".alive.h5.{}.partial", std::process::id()));
    for file in [&stale, &other, &alive] {
        std::fs::copy(&out, file).unwrap();
    }
    assert!(run(&write_scene(dir.path(), "bar.toml", BAR), &early, &[])
        .status
        .success());
    assert!(!stale.exists() && !other.exists());
    assert!(alive.exists());
}

#[test]
fn a_full_disk_stops_the_run_with_its_committed_frames_readable() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "long.toml", &long_bar());
    let out = dir.path().join("long.h5");
    // A 3 MB file-size limit stands in for a full disk (writes past it fail with EFBIG).
    let mut limited = exe();
    // SAFETY: setrlimit is async-signal-safe; the closure runs in the child before exec.
    unsafe {
        limited.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: 3_000_000,
                rlim_max: 3_000_000,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) == 0 {
                Ok(())
            } else {
                Err(std::io::Error::last_os_error())
            }
        });
    }
    let o = limited
        .arg("run")
        .arg(&scene)
        .arg("--output")
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(stderr(&o).contains("no room for frame"), "{}", stderr(&o));
    let kept = frames(&out);
    assert!(kept > 10, "{kept} frames");
    assert_sidecar_matches(&out);
    let info = exe().arg("info").arg(&out).output().unwrap();
    assert!(info.status.success(), "{}", stderr(&info));
    // With room again the run resumes from its last frame.
    let o = exe()
        .arg("run")
        .arg(&scene)
        .arg("--resume")
        .arg(&out)
        .args(["--end-time", "1.0"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(frames(&out), 501);
}

/// The time of the last complete frame of `path` (s).
fn last_time(path: &Path) -> f64 {
    let reader = FrameReader::open(path).unwrap();
    let last = *reader.frame_indices().last().unwrap();
    reader.read(last).unwrap().state.time
}

#[test]
fn a_resume_with_another_dt_ends_at_the_asked_end_time() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), "bar.toml", BAR);
    let out = dir.path().join("bar.h5");
    assert!(run(&scene, &out, &["--end-time", "0.01"]).status.success());
    let resume = |extra: &[&str]| {
        exe()
            .arg("run")
            .arg(&scene)
            .arg("--resume")
            .arg(&out)
            .args(extra)
            .output()
            .unwrap()
    };
    // An end time the file has passed: an error, the file as it was.
    let o = resume(&["--end-time", "0.005"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("past the end time"), "{}", stderr(&o));
    assert!((last_time(&out) - 0.01).abs() < 1e-12);
    // A smaller step: 10 steps of 1 ms reach 0.02 s.
    let o = resume(&["--end-time", "0.02", "--dt", "0.001"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!((last_time(&out) - 0.02).abs() < 1e-12);
    // A step that does not divide the rest: the last whole step before the end time.
    let o = resume(&["--end-time", "0.03", "--dt", "0.003"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let t = last_time(&out);
    assert!(t <= 0.03 + 1e-12 && t > 0.03 - 0.003, "t = {t}");
    // At the end time already: nothing to do, and not an error.
    let o = resume(&["--end-time", &format!("{t}")]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn errors_name_the_file_and_say_each_cause_once() {
    let dir = tempfile::tempdir().unwrap();
    let one_line = |o: &Output| {
        let text = stderr(o);
        let errors: Vec<&str> = text.lines().filter(|l| l.starts_with("error: ")).collect();
        assert_eq!(errors.len(), 1, "{text}");
        errors[0].to_string()
    };
    // A directory given as a run's file.
    let o = exe().arg("info").arg(dir.path()).output().unwrap();
    let line = one_line(&o);
    assert_eq!(line.matches("Is a directory").count(), 1, "{line}");
    // A truncated HDF5 file: the gist of HDF5's error, not its whole stack.
    let scene = write_scene(dir.path(), "bar.toml", BAR);
    let out = dir.path().join("bar.h5");
    assert!(run(&scene, &out, &[]).status.success());
    let cut = dir.path().join("cut.h5");
    std::fs::write(&cut, &std::fs::read(&out).unwrap()[..3000]).unwrap();
    let line = one_line(&exe().arg("info").arg(&cut).output().unwrap());
    assert!(
        line.contains("cut.h5") && line.contains("truncated file"),
        "{line}"
    );
    assert_eq!(line.matches("unable to open file").count(), 1, "{line}");
    assert!(!line.contains("H5Fopen"), "{line}");
    // An output directory that does not exist: said so, naming the file asked for.
    let missing = dir.path().join("no/such/dir/out.h5");
    let line = one_line(&run(&scene, &missing, &[]));
    assert!(
        line.contains("out.h5") && line.contains("does not exist") && !line.contains("partial"),
        "{line}"
    );
    // A name the XDMF sidecar cannot reference: refused before the run, not after it.
    let line = one_line(&run(&scene, &dir.path().join("a:b.h5"), &[]));
    assert!(line.contains("a:b.h5") && line.contains("':'"), "{line}");
    assert!(!dir.path().join("a:b.h5").exists());
    // A Dirichlet region that holds no node: the scene file and the entry, counted from 1.
    let empty = write_scene(
        dir.path(),
        "empty.toml",
        &BAR.replace("max = [1e-9, 1.0, 1.0]", "max = [-0.5, 1.0, 1.0]"),
    );
    let line = one_line(&run(&empty, &dir.path().join("e.h5"), &[]));
    assert!(
        line.contains("empty.toml") && line.contains("[[dirichlet]] number 1"),
        "{line}"
    );
}

/// A cube of `cells`³ cells in an open container `[0, 0.1]² × [floor, 0.3]` m.
fn cube_in_container(cells: &str, floor: f64, wall: f64) -> String {
    format!(
        r#"
[mesh]
box = {{ size = [0.1, 0.1, 0.1], cells = [{cells}] }}
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
[physics]
gravity = [0.0, 0.0, -9.81]
[[obstacle]]
type = "container"
min = [{wall}, 0.0, {floor}]
max = [0.1, 0.1, 0.3]
[time]
dt = 0.01
end_time = 0.02
"#
    )
}

#[test]
fn a_mesh_that_cannot_fit_is_refused_at_once_without_allocating() {
    let dir = tempfile::tempdir().unwrap();
    for cells in ["1000, 1000, 1000", "100000, 100000, 100000"] {
        let scene = write_scene(dir.path(), "huge.toml", &cube_in_container(cells, 0.0, 0.0));
        let start = std::time::Instant::now();
        let o = run(&scene, &dir.path().join("huge.h5"), &[]);
        assert!(!o.status.success());
        // Process start and the check: well under a second on any machine that runs the
        // suite (it takes ~10 ms here).
        assert!(start.elapsed().as_secs_f64() < 1.0);
        let text = stderr(&o);
        assert!(
            text.contains("mesh.box") && text.contains("use fewer cells"),
            "{text}"
        );
    }
    // The largest resident size of the children so far (kB): nothing near a mesh's worth.
    // SAFETY: getrusage fills the struct it is given.
    let peak_kb = unsafe {
        let mut usage = std::mem::zeroed::<libc::rusage>();
        libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage);
        usage.ru_maxrss
    };
    assert!(peak_kb < 200_000, "a child reached {peak_kb} kB");
}

#[test]
fn ice_that_starts_inside_an_obstacle_or_another_body_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.h5");
    // Half the cube behind a wall, and the cube under the floor.
    for (floor, wall, deepest) in [(0.0, 0.05, "5.000e-2"), (0.5, 0.0, "5.000e-1")] {
        let scene = write_scene(
            dir.path(),
            "inside.toml",
            &cube_in_container("2, 2, 2", floor, wall)
                .replace("max = [0.1, 0.1, 0.3]", "max = [0.1, 0.1, 0.9]"),
        );
        let text = stderr(&run(&scene, &out, &[]));
        assert!(
            text.contains("obstacle[0]") && text.contains("start inside this obstacle"),
            "{text}"
        );
        assert!(text.contains(deepest), "{text}");
    }
    // The ramp of scenes/slide_down_ramp.toml cutting through the ice's lower corner.
    std::fs::copy(
        concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/ramp.obj"),
        dir.path().join("ramp.obj"),
    )
    .unwrap();
    let ramp = |z: f64| {
        format!(
            "[mesh]\nbox = {{ origin = [0.01, 0.08, {z}], size = [0.04, 0.04, 0.04], cells = [3, 3, 3] }}\n\
             [material]\ndensity = 916.0\nlambda = 8.64e10\nmu = 3.70e10\n\
             [[obstacle]]\ntype = \"mesh\"\nfile = \"ramp.obj\"\n\
             [time]\ndt = 0.01\nend_time = 0.02\n"
        )
    };
    let scene = write_scene(dir.path(), "ramp.toml", &ramp(0.08));
    let text = stderr(&run(&scene, &out, &[]));
    assert!(
        text.contains("obstacle[0]") && text.contains("start inside"),
        "{text}"
    );
    let scene = write_scene(dir.path(), "above.toml", &ramp(0.1));
    let o = run(&scene, &dir.path().join("above.h5"), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A 1 cm cube wholly inside the (closed) ramp, 2 cm above its floor face: no node is
    // near the surface, one node per body is tested however deep.
    let buried = ramp(0.0).replace(
        "origin = [0.01, 0.08, 0], size = [0.04, 0.04, 0.04], cells = [3, 3, 3]",
        "origin = [0.05, 0.08, 0.02], size = [0.01, 0.01, 0.01], cells = [2, 2, 2]",
    );
    let scene = write_scene(dir.path(), "buried.toml", &buried);
    let text = stderr(&run(&scene, &out, &[]));
    assert!(
        text.contains("obstacle[0]") && text.contains("start inside") && text.contains("2.000e-2"),
        "{text}"
    );
    // A mesh a thousand times too large (millimetres read as metres): the hint says so.
    let text = cube_in_container("2, 2, 2", 0.0, 0.0)
        .replace("size = [0.1, 0.1, 0.1]", "size = [100.0, 100.0, 100.0]");
    let scene = write_scene(dir.path(), "mm.toml", &text);
    let text = stderr(&run(&scene, &out, &[]));
    assert!(text.contains("scale = 0.001"), "{text}");
    // Resting exactly on the floor and against the walls is not inside.
    let scene = write_scene(
        dir.path(),
        "touching.toml",
        &cube_in_container("2, 2, 2", 0.0, 0.0),
    );
    assert!(run(&scene, &out, &[]).status.success());
    // Two boxes overlapping by 1 mm.
    let text = cube_in_container("2, 2, 2", 0.0, 0.0).replace(
        "box = { size = [0.1, 0.1, 0.1], cells = [2, 2, 2] }",
        "boxes = [{ size = [0.1, 0.1, 0.1], cells = [2, 2, 2] }, { origin = [0.0, 0.0, 0.099], size = [0.1, 0.1, 0.1], cells = [2, 2, 2] }]",
    );
    let scene = write_scene(dir.path(), "overlap.toml", &text);
    let text = stderr(&run(&scene, &dir.path().join("o.h5"), &[]));
    assert!(
        text.contains("mesh.boxes[1]") && text.contains("overlaps mesh.boxes[0]"),
        "{text}"
    );
    // Two bodies of one Gmsh file: 10 cm tets, the second moved by `shift` (m) on each axis.
    let two_tets = |shift: f64| {
        let corners = [
            [0.0, 0.0, 0.0],
            [0.1, 0.0, 0.0],
            [0.0, 0.1, 0.0],
            [0.0, 0.0, 0.1],
        ];
        let nodes: Vec<String> = (0..8)
            .map(|i| {
                let c = corners[i % 4].map(|x| x + if i < 4 { 0.0 } else { shift });
                format!("{} {} {} {}", i + 1, c[0], c[1], c[2])
            })
            .collect();
        format!(
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n8\n{}\n$EndNodes\n\
             $Elements\n2\n1 4 2 0 1 1 2 3 4\n2 4 2 0 2 5 6 7 8\n$EndElements\n",
            nodes.join("\n")
        )
    };
    let gmsh_scene = "[mesh]\nfile = \"two.msh\"\n[material]\ndensity = 916.0\nlambda = 8.64e10\n\
                      mu = 3.70e10\n[time]\ndt = 0.01\nend_time = 0.02\n";
    let scene = write_scene(dir.path(), "two.toml", gmsh_scene);
    // 1 mm into each other: the second tet's corner is inside the first.
    std::fs::write(dir.path().join("two.msh"), two_tets(0.001)).unwrap();
    let text = stderr(&run(&scene, &dir.path().join("two.h5"), &[]));
    assert!(
        text.contains("mesh.file")
            && text.contains("2 separate bodies")
            && text.contains("bodies must start apart"),
        "{text}"
    );
    // 20 cm apart they run.
    std::fs::write(dir.path().join("two.msh"), two_tets(0.2)).unwrap();
    let o = run(&scene, &dir.path().join("two.h5"), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_penalty_stiffness_far_from_the_ice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for k in ["1e25", "1e3"] {
        let text = cube_in_container("2, 2, 2", 0.0, 0.0).replace(
            "max = [0.1, 0.1, 0.3]",
            &format!("max = [0.1, 0.1, 0.3]\nstiffness = {k}"),
        );
        let scene = write_scene(dir.path(), "k.toml", &text);
        let text = stderr(&run(&scene, &dir.path().join("k.h5"), &[]));
        assert!(
            text.contains("obstacle[0].stiffness") && text.contains("the default 10 E / h"),
            "{text}"
        );
    }
    // 100 × the default is accepted.
    let text = cube_in_container("2, 2, 2", 0.0, 0.0).replace(
        "max = [0.1, 0.1, 0.3]",
        "max = [0.1, 0.1, 0.3]\nstiffness = 1.7e15",
    );
    let scene = write_scene(dir.path(), "ok.toml", &text);
    let o = run(&scene, &dir.path().join("ok.h5"), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
}
